// The runtime's linear and hybrid blend (runtime/blend.h) on hand-made spaces.
#include "runtime/blend.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <numbers>
#include <vector>

#include "pipeline/core/error.h"
#include "tests/motionspace/test_meshes.h"

namespace fourd {
namespace {

constexpr double kDeg = std::numbers::pi / 180;
// References are read back from fp16 displacements (runtime/blend.h). The hand-made ones here
// are far from the linear blend (up to 0.7 m on a 1 m tube), where fp16 steps are 0.25 to 0.5
// mm: a blend through them is exact to a fraction of that.
constexpr double kHalfTolerance = 5e-4;

// Frame f of input k: the tube bent by a pose that depends on both.
Eigen::Matrix3Xd pose(const test::TestMesh& m, int k, int f) {
  return test::bend_tube(m.positions, (20.0 + 40 * k + 7 * f) * kDeg, {}, 50.0 * k * kDeg);
}

BlendSpace make_space(const test::TestMesh& m, int inputs, int frames) {
  BlendSpace space = make_blend_space(inputs, static_cast<int>(m.positions.cols()), frames);
  for (int k = 0; k < inputs; ++k) {
    for (int f = 0; f < frames; ++f) set_frame(&space, k, f, test::to_vec3f(pose(m, k, f)));
  }
  return space;
}

Eigen::Matrix3Xd to_matrix(const BlendedFrame& frame) {
  Eigen::Matrix3Xd x(3, frame.num_vertices);
  for (int v = 0; v < frame.num_vertices; ++v) x.col(v) = frame.position(v).cast<double>();
  return x;
}

TEST(Blend, LayoutIsPaddedAndAligned) {
  EXPECT_EQ(blend_plane_stride(1), 16);
  EXPECT_EQ(blend_plane_stride(16), 16);
  EXPECT_EQ(blend_plane_stride(3001), 3008);
  const test::TestMesh m = test::make_tube(9, 7);  // 65 vertices
  const BlendSpace space = make_space(m, 3, 4);
  EXPECT_EQ(space.plane_stride, 80);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(space.frame(2, 3)) % 64, 0u);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(make_blended_frame(space).data.data()) % 64, 0u);
  EXPECT_NO_THROW(space.check());
}

TEST(Blend, LinearBlendOfIdenticalInputsIsExact) {
  const test::TestMesh m = test::make_tube(9, 7);
  BlendSpace space = make_blend_space(3, static_cast<int>(m.positions.cols()), 1);
  const std::vector<Vec3f> p = test::to_vec3f(pose(m, 1, 0));
  for (int k = 0; k < 3; ++k) set_frame(&space, k, 0, p);
  BlendedFrame out = make_blended_frame(space);
  const std::vector<float> w{1.f / 3, 1.f / 3, 1.f / 3};
  blend_linear(space, 0.0, w, &out);
  for (int v = 0; v < out.num_vertices; ++v) EXPECT_LT((out.position(v) - p[v]).norm(), 1e-6f);
  blend_hybrid(space, 0.0, w, &out);  // no references: the hybrid is the linear blend
  for (int v = 0; v < out.num_vertices; ++v) EXPECT_LT((out.position(v) - p[v]).norm(), 1e-6f);
}

TEST(Blend, LinearBlendIsTheNormalisedWeightedSumAtContinuousTime) {
  const test::TestMesh m = test::make_tube(9, 7);
  const int frames = 5;
  const BlendSpace space = make_space(m, 3, frames);
  BlendedFrame out = make_blended_frame(space);
  const std::vector<float> w{2.f, 1.f, 1.f};  // sums to 4: normalised to (0.5, 0.25, 0.25)
  const double t = 0.6;                       // frame position 2.4: frames 2 and 3
  blend_linear(space, t, w, &out);
  Eigen::Matrix3Xd expected = Eigen::Matrix3Xd::Zero(3, m.positions.cols());
  for (int k = 0; k < 3; ++k) {
    expected += w[k] / 4 * (0.6 * pose(m, k, 2) + 0.4 * pose(m, k, 3));
  }
  EXPECT_LT(test::max_vertex_distance(to_matrix(out), expected), 1e-5);

  // Time is clamped to [0, 1] and the last frame is reached exactly at t = 1.
  blend_linear(space, 1.0, std::vector<float>{0, 1, 0}, &out);
  EXPECT_LT(test::max_vertex_distance(to_matrix(out), pose(m, 1, frames - 1)), 1e-5);
  blend_linear(space, 7.0, std::vector<float>{0, 1, 0}, &out);
  EXPECT_LT(test::max_vertex_distance(to_matrix(out), pose(m, 1, frames - 1)), 1e-5);
  blend_linear(space, -1.0, std::vector<float>{0, 0, 1}, &out);
  EXPECT_LT(test::max_vertex_distance(to_matrix(out), pose(m, 2, 0)), 1e-5);
}

TEST(Blend, SourcesSkipZeroCoefficients) {
  const test::TestMesh m = test::make_tube(9, 7);
  const BlendSpace space = make_space(m, 3, 4);
  BlendSources s;
  linear_blend_sources(space, 0.5, std::vector<float>{0.2f, 0.8f, 0.f}, &s);
  EXPECT_EQ(s.count, 4);  // two inputs at frames 1 and 2
  linear_blend_sources(space, 1.0 / 3, std::vector<float>{0.2f, 0.8f, 0.f}, &s);  // frame 1 exactly
  EXPECT_EQ(s.count, 2);
  EXPECT_EQ(s.sources[0], space.frame(0, 1));
  hybrid_blend_sources(space, 0.0, std::vector<float>{1.f, 0.f, 0.f}, &s);
  EXPECT_EQ(s.count, 1);
  EXPECT_EQ(s.sources[0], space.frame(0, 0));
  EXPECT_FLOAT_EQ(s.coefficients[0], 1.f);
}

// A hand-made hybrid space over 3 inputs: one reference at the centre of the weight triangle
// splitting it into three cells. The blend must reproduce the reference there, and stay
// continuous across the cell edges.
TEST(Blend, HybridInterpolatesReferencesAndIsContinuous) {
  const test::TestMesh m = test::make_tube(9, 7);
  BlendSpace space = make_space(m, 3, 2);
  const std::vector<double> centre{1.0 / 3, 1.0 / 3, 1.0 / 3};
  const int r = add_reference(&space, centre);
  // A reference shape far from the linear blend, so that interpolation errors would show.
  const Eigen::Matrix3Xd special = test::bend_tube(m.positions, -90 * kDeg);
  for (int f = 0; f < 2; ++f) set_frame(&space, r, f, test::to_vec3f(special));
  space.cells = {{r, 0, 1}, {r, 1, 2}, {r, 2, 0}};
  ASSERT_NO_THROW(space.check());

  BlendedFrame out = make_blended_frame(space);
  blend_hybrid(space, 0.3, std::vector<float>{1, 1, 1}, &out);
  EXPECT_LT(test::max_vertex_distance(to_matrix(out), special), kHalfTolerance);
  // At an input the hybrid is that input.
  blend_hybrid(space, 1.0, std::vector<float>{0, 0, 1}, &out);
  EXPECT_LT(test::max_vertex_distance(to_matrix(out), pose(m, 2, 1)), 1e-5);
  // Half way between the centre and input 0: the mean of the two.
  blend_hybrid(space, 0.0, std::vector<float>{4, 1, 1}, &out);  // = 0.5 e0 + 0.5 centre
  EXPECT_LT(test::max_vertex_distance(to_matrix(out), 0.5 * (pose(m, 0, 0) + special)),
            kHalfTolerance);

  // Across the edge between cells {r,0,1} and {r,1,2} (the segment centre - input 1).
  const float d = 1e-4f;
  BlendedFrame other = make_blended_frame(space);
  blend_hybrid(space, 0.5, std::vector<float>{0.25f + d, 0.5f, 0.25f - d}, &out);
  blend_hybrid(space, 0.5, std::vector<float>{0.25f - d, 0.5f, 0.25f + d}, &other);
  EXPECT_LT(test::max_vertex_distance(to_matrix(out), to_matrix(other)), 1e-3);

  // Two inputs: cells are segments of the weight line.
  BlendSpace line = make_space(m, 2, 2);
  const int mid = add_reference(&line, std::vector<double>{0.5, 0.5});
  for (int f = 0; f < 2; ++f) set_frame(&line, mid, f, test::to_vec3f(special));
  line.cells = {{0, mid, -1}, {mid, 1, -1}};
  ASSERT_NO_THROW(line.check());
  BlendedFrame out2 = make_blended_frame(line);
  blend_hybrid(line, 0.0, std::vector<float>{0.25f, 0.75f}, &out2);
  EXPECT_LT(test::max_vertex_distance(to_matrix(out2), 0.5 * (special + pose(m, 1, 0))),
            kHalfTolerance);
}

// Decoded displacements (the web build's path): the sources point at the float twins of the
// halves, and the sum is the generic kernel's on the halves to the bit.
TEST(Blend, DecodedDisplacementsGiveTheSameSum) {
  const test::TestMesh m = test::make_tube(9, 7);
  BlendSpace space = make_space(m, 3, 3);
  const int r = add_reference(&space, std::vector<double>{1.0 / 3, 1.0 / 3, 1.0 / 3});
  const Eigen::Matrix3Xd special = test::bend_tube(m.positions, -90 * kDeg);
  for (int f = 0; f < 3; ++f) set_frame(&space, r, f, test::to_vec3f(special));
  space.cells = {{r, 0, 1}, {r, 1, 2}, {r, 2, 0}};
  ASSERT_NO_THROW(space.check());
  BlendSources halves;
  hybrid_blend_sources(space, 0.3, std::vector<float>{0.5f, 0.3f, 0.2f}, &halves);
  ASSERT_GT(halves.displacement_count, 0);
  EXPECT_FALSE(halves.decoded());

  decode_displacements(&space);
  ASSERT_EQ(space.displacement_floats.size(), space.displacements.size());
  for (std::size_t i = 0; i < space.displacements.size(); ++i) {
    ASSERT_EQ(space.displacement_floats[i], half_to_float(space.displacements[i])) << i;
  }
  BlendSources floats;
  hybrid_blend_sources(space, 0.3, std::vector<float>{0.5f, 0.3f, 0.2f}, &floats);
  ASSERT_TRUE(floats.decoded());
  for (int k = 0; k < floats.displacement_count; ++k) {
    EXPECT_EQ(floats.displacement_floats[k], space.displacement_float(floats.displacement_sources[k]));
  }
  EXPECT_EQ(floats.read_bytes(10), halves.read_bytes(10) + 10 * 2 * halves.displacement_count);
  const std::size_t n = space.frame_stride();
  for (bool accumulate : {false, true}) {
    std::vector<float> a(n, 0.25f), b(n, 0.25f);
    portable_weighted_sum(halves, n, accumulate, a.data());
    portable_weighted_sum(floats, n, accumulate, b.data());
    EXPECT_EQ(std::memcmp(a.data(), b.data(), n * sizeof(float)), 0) << "accumulate " << accumulate;
  }
}

// Quadratic cells: a reference at the midpoint of a cell edge is that cell's P2 node. On a
// segment the blend is (1 - s)(1 - 2s) M_a + 4 s (1 - s) M_m + s (2s - 1) M_b; in a triangle
// lambda_i (2 lambda_i - 1) at the corners and 4 lambda_i lambda_k at the edge midpoints.
TEST(Blend, QuadraticCellsUseTheLagrangeBasis) {
  const test::TestMesh m = test::make_tube(9, 7);
  const Eigen::Matrix3Xd special = test::bend_tube(m.positions, -90 * kDeg);
  BlendSpace line = make_space(m, 2, 2);
  const int mid = add_reference(&line, std::vector<double>{0.5, 0.5});
  for (int f = 0; f < 2; ++f) set_frame(&line, mid, f, test::to_vec3f(special));
  line.cells = {{0, 1, -1}};  // one P2 segment: the reference is its midpoint node
  ASSERT_NO_THROW(line.check());
  EXPECT_EQ(cell_midpoints(line, line.cells[0]), (std::array<int, 3>{mid, -1, -1}));
  BlendedFrame out = make_blended_frame(line);
  for (double s : {0.0, 0.2, 0.5, 0.75, 1.0}) {
    blend_hybrid(line, 0.0, std::vector<float>{static_cast<float>(1 - s), static_cast<float>(s)},
                 &out);
    const Eigen::Matrix3Xd expected = (1 - s) * (1 - 2 * s) * pose(m, 0, 0) +
                                      4 * s * (1 - s) * special + s * (2 * s - 1) * pose(m, 1, 0);
    EXPECT_LT(test::max_vertex_distance(to_matrix(out), expected), kHalfTolerance) << "s = " << s;
  }
  // Exactly at the midpoint only the midpoint's frame is read: its linear part (the two inputs
  // at 1/2 each) and its displacement; elsewhere the 2 inputs and 1 displacement x 2 times.
  BlendSources src;
  hybrid_blend_sources(line, 0.0, std::vector<float>{0.5f, 0.5f}, &src);
  ASSERT_EQ(src.count, 2);
  ASSERT_EQ(src.displacement_count, 1);
  EXPECT_EQ(src.displacement_sources[0], line.displacement(mid, 0));
  EXPECT_EQ(src.coefficients[0], 0.5f);
  EXPECT_EQ(src.displacement_coefficients[0], 1.f);
  hybrid_blend_sources(line, 0.3, std::vector<float>{0.7f, 0.3f}, &src);
  EXPECT_EQ(src.count, 4);
  EXPECT_EQ(src.displacement_count, 2);

  // A 6-node triangle: references at the three edge midpoints of the weight triangle.
  BlendSpace tri = make_space(m, 3, 1);
  const std::array<std::array<double, 3>, 3> mids{{{0, 0.5, 0.5}, {0.5, 0, 0.5}, {0.5, 0.5, 0}}};
  std::array<Eigen::Matrix3Xd, 3> mid_shapes;
  for (int k = 0; k < 3; ++k) {
    const int r = add_reference(&tri, mids[k]);
    mid_shapes[k] = test::bend_tube(m.positions, (-30.0 - 20 * k) * kDeg, {}, 30.0 * k * kDeg);
    set_frame(&tri, r, 0, test::to_vec3f(mid_shapes[k]));
  }
  ASSERT_NO_THROW(tri.check());
  EXPECT_EQ(cell_midpoints(tri, tri.cells[0]), (std::array<int, 3>{3, 4, 5}));
  BlendedFrame out3 = make_blended_frame(tri);
  for (const std::array<double, 3>& l : std::vector<std::array<double, 3>>{
           {0.2, 0.3, 0.5}, {1.0 / 3, 1.0 / 3, 1.0 / 3}, {0.5, 0.5, 0}, {0.9, 0.05, 0.05}}) {
    blend_hybrid(tri, 0.0,
                 std::vector<float>{static_cast<float>(l[0]), static_cast<float>(l[1]),
                                    static_cast<float>(l[2])},
                 &out3);
    Eigen::Matrix3Xd expected = Eigen::Matrix3Xd::Zero(3, m.positions.cols());
    for (int k = 0; k < 3; ++k) {
      expected += l[k] * (2 * l[k] - 1) * pose(m, k, 0);
      expected += 4 * l[(k + 1) % 3] * l[(k + 2) % 3] * mid_shapes[k];
    }
    EXPECT_LT(test::max_vertex_distance(to_matrix(out3), expected), kHalfTolerance);
  }
  // The quadratic blend reproduces the linear one when the midpoints are linear blends, and a
  // triangle missing a midpoint is linear along that edge.
  BlendSources s3;
  hybrid_blend_sources(tri, 0.0, std::vector<float>{0.2f, 0.3f, 0.5f}, &s3);
  EXPECT_EQ(s3.count, 3);               // the inputs, a_k = sum_j g_j w_{j,k}
  EXPECT_EQ(s3.displacement_count, 3);  // the midpoints' displacements
  float sum = 0;
  for (int k = 0; k < s3.count; ++k) sum += s3.coefficients[k];
  EXPECT_NEAR(sum, 1.f, 1e-6);
}

// The arc basis of a segment reproduces a rotation about a fixed axis exactly: nodes at 0,
// theta / 2 and theta, the blend at s is the shape turned by s theta.
TEST(Blend, ArcSegmentFollowsARotationExactly) {
  const test::TestMesh m = test::make_tube(9, 7);
  const Eigen::Matrix3Xd shape = test::bend_tube(m.positions, 40 * kDeg);
  const double theta = 110 * kDeg;
  const Eigen::Vector3d axis = Eigen::Vector3d(0.2, 1, 0.4).normalized();
  auto turned = [&](double angle) {
    return Eigen::Matrix3Xd(Eigen::AngleAxisd(angle, axis).toRotationMatrix() * shape);
  };
  BlendSpace line = make_blend_space(2, static_cast<int>(m.positions.cols()), 1);
  set_frame(&line, 0, 0, test::to_vec3f(shape));
  set_frame(&line, 1, 0, test::to_vec3f(turned(theta)));
  const int mid = add_reference(&line, std::vector<double>{0.5, 0.5});
  set_frame(&line, mid, 0, test::to_vec3f(turned(0.5 * theta)));
  line.cell_arc_angles = {theta};
  ASSERT_NO_THROW(line.check());
  BlendedFrame out = make_blended_frame(line);
  double worst_arc = 0;
  for (double s : {0.1, 0.25, 0.4, 0.5, 0.7, 0.9}) {
    const std::vector<float> w{static_cast<float>(1 - s), static_cast<float>(s)};
    blend_hybrid(line, 0.0, w, &out);
    worst_arc = std::max(worst_arc, test::max_vertex_distance(to_matrix(out), turned(s * theta)));
  }
  EXPECT_LT(worst_arc, kHalfTolerance);
  // The quadratic basis (theta = 0) does not: the tube's far end is centimetres off.
  line.cell_arc_angles.clear();
  blend_hybrid(line, 0.0, std::vector<float>{0.75f, 0.25f}, &out);
  EXPECT_GT(test::max_vertex_distance(to_matrix(out), turned(0.25 * theta)), 1e-3);
  // Tiny angles tend to the quadratic basis.
  line.cell_arc_angles = {1e-7};
  BlendedFrame quadratic = make_blended_frame(line);
  blend_hybrid(line, 0.0, std::vector<float>{0.75f, 0.25f}, &out);
  line.cell_arc_angles.clear();
  blend_hybrid(line, 0.0, std::vector<float>{0.75f, 0.25f}, &quadratic);
  EXPECT_LT(test::max_vertex_distance(to_matrix(out), to_matrix(quadratic)), 1e-6);

  BlendSpace bad = line;
  for (const std::vector<double>& angles :
       std::vector<std::vector<double>>{{-0.1}, {4.0}, {0.5, 0.5}, {std::nan("")}}) {
    bad.cell_arc_angles = angles;
    EXPECT_THROW(bad.check(), InputError);
  }
  BlendSpace tri = make_space(m, 3, 1);
  tri.cell_arc_angles = {0.5};  // arcs are for segments only
  EXPECT_THROW(tri.check(), InputError);
}

// accumulate_weighted_sum adds to what the output holds; weighted_sum overwrites. Every count
// of float and half sources, over a length that is not a whole number of vectors.
TEST(Blend, WeightedSumsHandleEveryCount) {
  constexpr int kN = 37;
  AlignedFloats a(kN), b(kN);
  AlignedHalfs h(kN);
  for (int i = 0; i < kN; ++i) {
    a[i] = static_cast<float>(i);
    b[i] = 1.f;
    h[i] = float_to_half(0.25f * (i - 20));  // exact in fp16
  }
  for (int count = 0; count <= kMaxBlendSources; ++count) {
    for (int halves = count == 0 ? 1 : 0; halves <= kMaxBlendDisplacements; ++halves) {
      BlendSources s;
      s.count = count;
      for (int k = 0; k < count; ++k) {
        s.sources[k] = k % 2 ? b.data() : a.data();
        s.coefficients[k] = 0.5f * (k + 1);
      }
      s.displacement_count = halves;
      for (int k = 0; k < halves; ++k) {
        s.displacement_sources[k] = h.data();
        s.displacement_coefficients[k] = 0.25f * (k + 1);
      }
      AlignedFloats out(kN, 100.f), acc(kN, 100.f), pout(kN, 100.f), pacc(kN, 100.f);
      weighted_sum(s, kN, out.data());
      accumulate_weighted_sum(s, kN, acc.data());
      portable_weighted_sum(s, kN, false, pout.data());  // the kernel of CPUs without AVX2
      portable_weighted_sum(s, kN, true, pacc.data());
      for (int i = 0; i < kN; ++i) {
        float expected = 0;
        for (int k = 0; k < count; ++k) expected += 0.5f * (k + 1) * (k % 2 ? 1.f : float(i));
        for (int k = 0; k < halves; ++k) expected += 0.25f * (k + 1) * 0.25f * (i - 20);
        ASSERT_NEAR(out[i], expected, 1e-3) << count << " floats, " << halves << " halves";
        ASSERT_NEAR(acc[i], 100.f + expected, 1e-3) << count << " floats, " << halves << " halves";
        ASSERT_NEAR(pout[i], expected, 1e-3) << count << " floats, " << halves << " halves";
        ASSERT_NEAR(pacc[i], 100.f + expected, 1e-3) << count << " floats, " << halves << " halves";
      }
    }
  }
}

// Half precision: every half converts to float exactly and back; float to half rounds to
// nearest (ties to even), subnormals and zeros included.
TEST(Blend, HalfConversionsAreExactAndRoundToNearest) {
  for (std::uint32_t h = 0; h <= 0xffff; ++h) {
    const float f = half_to_float(static_cast<std::uint16_t>(h));
    const std::uint32_t exponent = (h >> 10) & 0x1f, mantissa = h & 0x3ff;
    if (exponent == 0x1f && mantissa != 0) {
      ASSERT_TRUE(std::isnan(f)) << h;
      ASSERT_TRUE(std::isnan(half_to_float(float_to_half(f)))) << h;
      continue;
    }
    const double magnitude = exponent == 0    ? std::ldexp(mantissa, -24)
                             : exponent == 31 ? HUGE_VAL
                                              : std::ldexp(1024 + mantissa, exponent - 25);
    ASSERT_EQ(f, static_cast<float>(h & 0x8000 ? -magnitude : magnitude)) << h;
    ASSERT_EQ(std::signbit(f), (h & 0x8000) != 0) << h;
    ASSERT_EQ(float_to_half(f), h) << h;
  }
  EXPECT_EQ(half_to_float(float_to_half(kMaxHalf)), kMaxHalf);
  EXPECT_EQ(float_to_half(1e6f), 0x7c00);     // beyond the range: infinity
  EXPECT_EQ(float_to_half(65520.f), 0x7c00);  // half way to 2^16 rounds up (ties to even)
  EXPECT_EQ(float_to_half(65519.f), 0x7bff);
  EXPECT_EQ(float_to_half(1e-9f), 0);                  // below half the smallest subnormal
  EXPECT_EQ(float_to_half(std::ldexp(1.5f, -24)), 2);  // a tie between subnormals: to even
  EXPECT_EQ(float_to_half(std::ldexp(2.5f, -24)), 2);
  EXPECT_EQ(float_to_half(1.f + std::ldexp(1.f, -11)), 0x3c00);  // a tie: to even (1.0)
  EXPECT_EQ(float_to_half(1.f + 3 * std::ldexp(1.f, -11)), 0x3c02);
  // Nearest: random floats against the neighbouring halves.
  std::uint32_t state = 12345;
  for (int i = 0; i < 100000; ++i) {
    state = state * 1664525u + 1013904223u;
    const float x = std::ldexp(static_cast<float>(state >> 8) / (1 << 24), (state & 31) - 26) *
                    ((state & 0x80) ? -1.f : 1.f);
    const float y = half_to_float(float_to_half(x));
    const float up = half_to_float(static_cast<std::uint16_t>(float_to_half(x) + 1));
    const float down = half_to_float(static_cast<std::uint16_t>(float_to_half(x) - 1));
    ASSERT_LE(std::abs(y - x), std::abs(up - x)) << x;
    if ((float_to_half(x) & 0x7fff) != 0) {
      ASSERT_LE(std::abs(y - x), std::abs(down - x)) << x;
    }
  }
}

// References are stored as displacements from the inputs, so the inputs come first, and a
// displacement must fit half precision.
TEST(Blend, ReferencesNeedTheirInputsAndHalfRange) {
  const test::TestMesh m = test::make_tube(9, 7);
  BlendSpace space = make_space(m, 2, 2);
  const int r = add_reference(&space, std::vector<double>{0.5, 0.5});
  EXPECT_THROW(set_frame(&space, 0, 0, test::to_vec3f(pose(m, 0, 0))), InputError);
  Eigen::Matrix3Xd far = pose(m, 0, 0);
  far(1, 3) = 1e5;
  EXPECT_THROW(set_frame(&space, r, 0, test::to_vec3f(far)), InputError);
  far(1, 3) = std::nan("");
  EXPECT_THROW(set_frame(&space, r, 0, test::to_vec3f(far)), InputError);
  // An unset reference is the linear blend; a set one reads back within fp16's rounding.
  std::vector<float> x(space.frame_stride());
  reference_frame(space, r, 1, x.data());
  for (std::size_t i = 0; i < x.size(); ++i) {
    ASSERT_NEAR(x[i], 0.5f * (space.frame(0, 1)[i] + space.frame(1, 1)[i]), 1e-6);
  }
  const Eigen::Matrix3Xd special = test::bend_tube(m.positions, -90 * kDeg);
  set_frame(&space, r, 1, test::to_vec3f(special));
  reference_frame(space, r, 1, x.data());
  for (int v = 0; v < space.num_vertices; ++v) {
    const Eigen::Vector3d p(x[v], x[space.plane_stride + v], x[2 * space.plane_stride + v]);
    ASSERT_LT((p - special.col(v)).norm(), 2.5e-4);
  }
}

TEST(Blend, CheckRejectsMalformedSpaces) {
  const test::TestMesh m = test::make_tube(9, 7);
  BlendSpace space = make_space(m, 3, 2);
  BlendSpace bad = space;
  bad.cells = {{0, 1, -1}};
  EXPECT_THROW(bad.check(), InputError);
  bad = space;
  const int r = add_reference(&bad, std::vector<double>{0.5, 0.5, 0.0});
  bad.cells = {{r, 0, 2}};  // covers only half the weight triangle
  EXPECT_THROW(bad.check(), InputError);
  bad = space;
  bad.reference_weights[0] = 0.5;  // input 0 must sit at e_0
  EXPECT_THROW(bad.check(), InputError);
  bad = space;
  bad.frames.pop_back();
  EXPECT_THROW(bad.check(), InputError);
  bad = space;
  add_reference(&bad, std::vector<double>{0.5, 0.5, 0.0});
  bad.displacements.pop_back();
  EXPECT_THROW(bad.check(), InputError);
  EXPECT_THROW(make_blend_space(4, 10, 2), InputError);
  EXPECT_THROW(set_frame(&space, 0, 0, std::vector<Vec3f>(3)), InputError);
}

}  // namespace
}  // namespace fourd
