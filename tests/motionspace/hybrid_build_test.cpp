// Hybrid non-linear blending end to end: offline bisection (stages/motionspace/hybrid_build.h)
// and the runtime evaluation (runtime/blend.h) against the non-linear blend.
#include "stages/motionspace/hybrid_build.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cstdio>
#include <map>
#include <numbers>
#include <set>
#include <vector>

#include "pipeline/core/error.h"
#include "stages/motionspace/nonlinear_blend.h"
#include "tests/motionspace/test_meshes.h"

namespace fourd {
namespace {

constexpr double kDeg = std::numbers::pi / 180;
constexpr int kFrames = 3;

// Time-aligned sequences of an elbow: input 0 almost straight; with 2 inputs, input 1 bent by
// about 120 degrees in the same plane; with 3 inputs (a 2D weight space needs many more cells
// for the same error), input 1 bent by about 60 degrees and input 2 by about 40 degrees in a
// plane turned 90 degrees.
struct Sequences {
  test::TestMesh rest;
  std::vector<std::vector<Eigen::Matrix3Xd>> frames;  // [input][frame]
};

Sequences elbow_sequences(int inputs) {
  Sequences s;
  s.rest = test::make_tube(17, 12);
  s.frames.resize(inputs);
  for (int f = 0; f < kFrames; ++f) {
    s.frames[0].push_back(test::bend_tube(s.rest.positions, (5.0 * f) * kDeg));
    s.frames[1].push_back(
        test::bend_tube(s.rest.positions, ((inputs == 2 ? 120.0 : 60.0) - 10 * f) * kDeg));
    if (inputs > 2)
      s.frames[2].push_back(
          test::bend_tube(s.rest.positions, (40.0 + 5 * f) * kDeg, {}, 90 * kDeg));
  }
  return s;
}

BlendSpace space_of(const Sequences& s) {
  const int n = static_cast<int>(s.frames.size());
  BlendSpace space = make_blend_space(n, static_cast<int>(s.rest.positions.cols()), kFrames);
  for (int k = 0; k < n; ++k) {
    for (int f = 0; f < kFrames; ++f) set_frame(&space, k, f, test::to_vec3f(s.frames[k][f]));
  }
  return space;
}

Eigen::Matrix3Xd evaluate(const BlendSpace& space, int f, std::span<const double> w, bool hybrid) {
  BlendedFrame out = make_blended_frame(space);
  const std::vector<float> wf(w.begin(), w.end());
  const double t = space.num_frames > 1 ? static_cast<double>(f) / (space.num_frames - 1) : 0.0;
  if (hybrid) {
    blend_hybrid(space, t, wf, &out);
  } else {
    blend_linear(space, t, wf, &out);
  }
  Eigen::Matrix3Xd x(3, out.num_vertices);
  for (int v = 0; v < out.num_vertices; ++v) x.col(v) = out.position(v).cast<double>();
  return x;
}

// Non-linear blends of every frame, for the weights asked.
class NonlinearOracle {
 public:
  explicit NonlinearOracle(const Sequences& s) : s_(s) {
    nonlinear_blend_precompute(s.rest.positions, s.rest.triangles, &data_);
    for (int f = 0; f < kFrames; ++f) {
      std::vector<Eigen::Matrix3Xd> inputs;
      for (const auto& seq : s.frames) inputs.push_back(seq[f]);
      nonlinear_blend_prepare(data_, inputs, &prepared_[f]);
    }
  }
  Eigen::Matrix3Xd blend(int f, std::span<const double> w) const {
    Eigen::Matrix3Xd x;
    nonlinear_blend_solve(data_, prepared_[f], w, &x);
    return x;
  }

 private:
  const Sequences& s_;
  NonlinearBlendData data_;
  NonlinearBlendInputs prepared_[kFrames];
};

// Weights of cell corners mixed by g.
std::vector<double> mix(const BlendSpace& space, const std::array<int, 3>& cell,
                        const std::array<double, 3>& g) {
  const int n = space.num_inputs;
  std::vector<double> w(n, 0.0);
  for (int k = 0; k < n; ++k) {
    for (int i = 0; i < n; ++i) w[i] += g[k] * space.reference_weights[cell[k] * n + i];
  }
  return w;
}

// The space of `s` with the references a build at `options` adds.
BlendSpace built_space(const Sequences& s, const HybridBuildOptions& options,
                       HybridBuildReport* report) {
  BlendSpace space = space_of(s);
  *report = build_hybrid_references(options, s.rest.positions, s.rest.triangles, &space);
  return space;
}

class HybridBuild : public ::testing::TestWithParam<int> {};  // number of inputs

TEST_P(HybridBuild, EqualsNonlinearAtEveryReferenceAndMeetsEpsilon) {
  const int n = GetParam();
  const Sequences s = elbow_sequences(n);
  HybridBuildOptions options;
  options.epsilon = 0.005;
  HybridBuildReport report;
  const BlendSpace space = built_space(s, options, &report);
  ASSERT_NO_THROW(space.check());
  EXPECT_TRUE(report.converged);
  EXPECT_GT(report.references_added, 0);
  EXPECT_LE(report.max_error, options.epsilon);
  EXPECT_GT(report.linear_max_error, options.epsilon);  // the test is not trivial
  EXPECT_EQ(space.num_references(), n + report.references_added);
  EXPECT_EQ(static_cast<int>(space.cells.size()), report.cells);

  const NonlinearOracle oracle(s);
  // Exact at every reference (the inputs included), every frame, but for the fp16 rounding of
  // the references' displacements (runtime/blend.h).
  for (int j = 0; j < space.num_references(); ++j) {
    const std::span<const double> w(space.reference_weights.data() + j * n, n);
    for (int f = 0; f < kFrames; ++f) {
      EXPECT_LT(test::max_vertex_distance(evaluate(space, f, w, true), oracle.blend(f, w)),
                j < n ? 1e-5 : 2.5e-4)
          << "reference " << j << " frame " << f;
    }
  }
  // Below epsilon at the test weights of every cell, through the runtime's own cell lookup;
  // and no worse than linear blending anywhere tested.
  const std::vector<std::array<double, 3>> points =
      n == 2 ? std::vector<std::array<double, 3>>{{0.75, 0.25, 0}, {0.5, 0.5, 0}, {0.25, 0.75, 0}}
             : std::vector<std::array<double, 3>>{{0, 0.5, 0.5},
                                                  {0.5, 0, 0.5},
                                                  {0.5, 0.5, 0},
                                                  {1.0 / 3, 1.0 / 3, 1.0 / 3},
                                                  {0.6, 0.2, 0.2}};
  double worst_hybrid = 0, worst_linear = 0;
  for (const auto& cell : space.cells) {
    for (const auto& g : points) {
      const std::vector<double> w = mix(space, cell, g);
      for (int f = 0; f < kFrames; ++f) {
        const Eigen::Matrix3Xd nl = oracle.blend(f, w);
        worst_hybrid =
            std::max(worst_hybrid, test::max_vertex_distance(evaluate(space, f, w, true), nl));
        worst_linear =
            std::max(worst_linear, test::max_vertex_distance(evaluate(space, f, w, false), nl));
      }
    }
  }
  EXPECT_LT(worst_hybrid, options.epsilon);
  EXPECT_LT(worst_hybrid, 0.5 * worst_linear);
}

TEST_P(HybridBuild, SmallerEpsilonAddsReferences) {
  const int n = GetParam();
  const Sequences s = elbow_sequences(n);
  std::vector<int> added;
  std::vector<double> errors;
  for (double eps : {0.05, 0.01, n == 2 ? 0.0005 : 0.002}) {
    BlendSpace space = space_of(s);
    HybridBuildOptions options;
    options.epsilon = eps;
    const HybridBuildReport report =
        build_hybrid_references(options, s.rest.positions, s.rest.triangles, &space);
    EXPECT_TRUE(report.converged) << "epsilon " << eps;
    EXPECT_LE(report.max_error, eps);
    added.push_back(report.references_added);
    errors.push_back(report.max_error);
  }
  EXPECT_LE(added[0], added[1]);
  EXPECT_LT(added[1], added[2]);
  EXPECT_GT(errors[0], errors[2]);
}

// The runtime reads the references as fp16 displacements from the linear blend of the inputs
// (runtime/blend.h). Its blend must equal Eq. 1 evaluated on float reference meshes (the
// non-linear blends at the nodes' weights, which the build stored) to within 0.5 mm, inside
// every cell of a deep build (arc segments included for 2 inputs), at every frame.
TEST_P(HybridBuild, HalfDisplacementsMatchFloatReferences) {
  const int n = GetParam();
  const Sequences s = elbow_sequences(n);
  HybridBuildOptions options;
  options.epsilon = 0.001;
  options.max_references = 100;
  HybridBuildReport report;
  const BlendSpace space = built_space(s, options, &report);
  ASSERT_GT(space.cells.size(), 2u);
  const NonlinearOracle oracle(s);
  auto node_mesh = [&](int r, int f) {
    if (r < n) return s.frames[r][f];
    return oracle.blend(f, std::span<const double>(space.reference_weights.data() + r * n, n));
  };
  const std::vector<std::array<double, 3>> points =
      n == 2 ? std::vector<std::array<double, 3>>{{0.9, 0.1, 0}, {0.6, 0.4, 0}, {0.25, 0.75, 0}}
             : std::vector<std::array<double, 3>>{
                   {0.6, 0.2, 0.2}, {1.0 / 3, 1.0 / 3, 1.0 / 3}, {0.1, 0.3, 0.6}};
  double worst = 0, largest_displacement = 0;
  int arcs = 0;
  for (std::size_t c = 0; c < space.cells.size(); ++c) {
    const std::array<int, 3>& cell = space.cells[c];
    arcs += space.cell_arc_angle(static_cast<int>(c)) > 0;
    for (const auto& g : points) {
      CellNodes nodes;
      cell_shape_functions(space, cell, cell_midpoints(space, cell), g,
                           space.cell_arc_angle(static_cast<int>(c)), &nodes);
      const std::vector<double> w = mix(space, cell, g);
      for (int f = 0; f < kFrames; ++f) {
        Eigen::Matrix3Xd expected = Eigen::Matrix3Xd::Zero(3, space.num_vertices);
        for (int k = 0; k < nodes.count; ++k) {
          const Eigen::Matrix3Xd m = node_mesh(nodes.references[k], f);
          expected += nodes.g[k] * m;
          if (nodes.references[k] >= n) {
            Eigen::Matrix3Xd linear = Eigen::Matrix3Xd::Zero(3, space.num_vertices);
            for (int i = 0; i < n; ++i) {
              linear += space.reference_weights[nodes.references[k] * n + i] * s.frames[i][f];
            }
            largest_displacement =
                std::max(largest_displacement, (m - linear).cwiseAbs().maxCoeff());
          }
        }
        worst = std::max(worst, test::max_vertex_distance(evaluate(space, f, w, true), expected));
      }
    }
  }
  std::printf(
      "%d inputs, %zu cells (%d arc): largest displacement %.1f mm; fp16 blend vs float "
      "references: max %.4f mm\n",
      n, space.cells.size(), arcs, 1000 * largest_displacement, 1000 * worst);
  if (n == 2) {
    EXPECT_GT(arcs, 0);
  }
  EXPECT_GT(largest_displacement, 0.05);  // displacements of a real bend: centimetres
  EXPECT_LT(worst, 5e-4);
}

INSTANTIATE_TEST_SUITE_P(Inputs, HybridBuild, ::testing::Values(2, 3));

// Newest-vertex bisection keeps the weight triangles edge to edge: every cell edge is either
// on the simplex boundary or shared by exactly two cells, every edge has its midpoint node (the
// cells are quadratic), and no other reference lies inside an edge.
TEST(HybridBuild, TriangleCellsAreConformingAndQuadratic) {
  const Sequences s = elbow_sequences(3);
  BlendSpace space = space_of(s);
  HybridBuildOptions options;
  options.epsilon = 0.0002;
  options.max_references = 100;
  build_hybrid_references(options, s.rest.positions, s.rest.triangles, &space);
  ASSERT_GT(space.cells.size(), 4u);
  std::map<std::pair<int, int>, int> edge_count;
  for (const auto& c : space.cells) {
    for (int k = 0; k < 3; ++k) ++edge_count[std::minmax(c[k], c[(k + 1) % 3])];
    for (int m : cell_midpoints(space, c)) EXPECT_GE(m, 0);
  }
  auto w = [&](int r) { return Eigen::Vector3d(space.reference_weights.data() + 3 * r); };
  for (const auto& [edge, count] : edge_count) {
    const Eigen::Vector3d a = w(edge.first), b = w(edge.second);
    const bool on_boundary = ((a + b).array() == 0).any();  // both on one side of the simplex
    EXPECT_EQ(count, on_boundary ? 1 : 2) << edge.first << "-" << edge.second;
    int midpoints = 0;
    for (int r = 0; r < space.num_references(); ++r) {
      if (r == edge.first || r == edge.second) continue;
      const Eigen::Vector3d p = w(r);
      const double along = (p - a).dot(b - a) / (b - a).squaredNorm();
      const bool inside =
          along > 1e-9 && along < 1 - 1e-9 && (a + along * (b - a) - p).norm() < 1e-12;
      if (inside && std::abs(along - 0.5) < 1e-12) {
        ++midpoints;
      } else {
        EXPECT_FALSE(inside) << "reference " << r << " hangs on edge " << edge.first << "-"
                             << edge.second;
      }
    }
    EXPECT_EQ(midpoints, 1) << edge.first << "-" << edge.second;
  }
}

TEST(HybridBuild, ResultDoesNotDependOnTheNumberOfThreads) {
  const Sequences s = elbow_sequences(3);
  BlendSpace parallel = space_of(s), serial = space_of(s);
  HybridBuildOptions options;
  build_hybrid_references(options, s.rest.positions, s.rest.triangles, &parallel);
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    build_hybrid_references(options, s.rest.positions, s.rest.triangles, &serial);
  }
  EXPECT_EQ(parallel.reference_weights, serial.reference_weights);
  EXPECT_EQ(parallel.cells, serial.cells);
  EXPECT_TRUE(parallel.frames == serial.frames);
  EXPECT_TRUE(parallel.displacements == serial.displacements);
}

TEST(HybridBuild, LimitsStopTheBisection) {
  const Sequences s = elbow_sequences(2);
  BlendSpace space = space_of(s);
  HybridBuildOptions options;
  options.epsilon = 1e-6;
  // The root segment's midpoint (1) and one bisection's two new midpoints (2) fit; the next
  // bisection (2 more) does not.
  options.max_references = 4;
  const HybridBuildReport report =
      build_hybrid_references(options, s.rest.positions, s.rest.triangles, &space);
  EXPECT_FALSE(report.converged);
  EXPECT_EQ(report.references_added, 3);
  EXPECT_GT(report.max_error, options.epsilon);

  BlendSpace shallow = space_of(s);
  options.max_references = 100;
  options.max_depth = 1;
  const HybridBuildReport r1 =
      build_hybrid_references(options, s.rest.positions, s.rest.triangles, &shallow);
  EXPECT_EQ(r1.references_added, 3);
  EXPECT_EQ(r1.max_depth, 1);

  // Depth 0: the one quadratic segment, with its midpoint w = 1/2.
  BlendSpace root = space_of(s);
  options.max_depth = 0;
  const HybridBuildReport r0 =
      build_hybrid_references(options, s.rest.positions, s.rest.triangles, &root);
  EXPECT_EQ(r0.references_added, 1);
  ASSERT_EQ(root.cells.size(), 1u);
  EXPECT_EQ(cell_midpoints(root, root.cells[0])[0], 2);

  // No budget for the midpoint: the blend stays linear (one linear cell, no reference).
  BlendSpace none = space_of(s);
  options.max_depth = 8;
  options.max_references = 0;
  const HybridBuildReport rn =
      build_hybrid_references(options, s.rest.positions, s.rest.triangles, &none);
  EXPECT_EQ(rn.references_added, 0);
  EXPECT_FALSE(rn.converged);
  EXPECT_NEAR(rn.max_error, rn.linear_max_error, 1e-4);
}

// Table 1's fixed references: s = {1/2} is one quadratic segment, s = {1/4, 1/2, 3/4} two;
// references that are not midpoints bound linear segments.
TEST(HybridBuild, LineReferencesMakeQuadraticSegments) {
  const Sequences s = elbow_sequences(2);
  BlendSpace one = space_of(s);
  add_line_references(s.rest.positions, s.rest.triangles, std::vector<double>{0.5}, &one);
  EXPECT_EQ(one.cells, (std::vector<std::array<int, 3>>{{0, 1, -1}}));
  EXPECT_EQ(cell_midpoints(one, one.cells[0])[0], 2);
  BlendSpace three = space_of(s);
  add_line_references(s.rest.positions, s.rest.triangles, std::vector<double>{0.25, 0.5, 0.75},
                      &three);
  EXPECT_EQ(three.cells, (std::vector<std::array<int, 3>>{{0, 3, -1}, {3, 1, -1}}));
  EXPECT_EQ(cell_midpoints(three, three.cells[0])[0], 2);
  EXPECT_EQ(cell_midpoints(three, three.cells[1])[0], 4);
  BlendSpace odd = space_of(s);
  add_line_references(s.rest.positions, s.rest.triangles, std::vector<double>{0.3}, &odd);
  EXPECT_EQ(odd.cells, (std::vector<std::array<int, 3>>{{0, 2, -1}, {2, 1, -1}}));
  EXPECT_EQ(cell_midpoints(odd, odd.cells[0])[0], -1);
}

// A rigidly rotating pair: the non-linear blend turns the shape by s x angle, so the
// displacement from the linear blend is the arc against its chord. One quadratic segment with
// the reference at w = 1/2 follows the arc's sagitta; linear blending cuts the chord, and linear
// interpolation inside the two cells [0, 1/2] and [1/2, 1] (the paper's g) still cuts the two
// half-chords. The arc basis with the angle the nodes draw (what add_line_references sets)
// also follows the pace along the arc: it is exact for a rigid rotation.
TEST(HybridBuild, QuadraticCellFollowsARigidRotation) {
  Sequences s;
  s.rest = test::make_tube(17, 12);
  s.frames.resize(2);
  for (int f = 0; f < kFrames; ++f) {
    const Eigen::Matrix3Xd bent = test::bend_tube(s.rest.positions, (30.0 + 5 * f) * kDeg);
    s.frames[0].push_back(bent);
    s.frames[1].push_back(
        test::rotate_about_centroid(bent, (40.0 + 5 * f) * kDeg, Eigen::Vector3d(1, 0.3, 0.2)));
  }
  BlendSpace arc = space_of(s);
  add_line_references(s.rest.positions, s.rest.triangles, std::vector<double>{0.5}, &arc);
  ASSERT_EQ(arc.cell_arc_angles.size(), 1u);
  // The angle the nodes draw: the rotation (40 to 50 degrees over the frames).
  EXPECT_GT(arc.cell_arc_angles[0], 40 * kDeg);
  EXPECT_LT(arc.cell_arc_angles[0], 50 * kDeg);
  BlendSpace quadratic = arc;  // the same reference, the quadratic basis
  quadratic.cell_arc_angles.clear();
  BlendSpace linear_cells = quadratic;  // the same reference, interpolated linearly per half
  linear_cells.cells = {{0, 2, -1}, {2, 1, -1}};
  ASSERT_NO_THROW(linear_cells.check());

  const NonlinearOracle oracle(s);
  double worst_arc = 0, worst_quadratic = 0, worst_cells = 0, worst_linear = 0;
  for (int j = 1; j < 20; ++j) {
    const std::vector<double> w{1 - j / 20.0, j / 20.0};
    for (int f = 0; f < kFrames; ++f) {
      const Eigen::Matrix3Xd nl = oracle.blend(f, w);
      worst_arc = std::max(worst_arc, test::max_vertex_distance(evaluate(arc, f, w, true), nl));
      worst_quadratic = std::max(
          worst_quadratic, test::max_vertex_distance(evaluate(quadratic, f, w, true), nl));
      worst_cells =
          std::max(worst_cells, test::max_vertex_distance(evaluate(linear_cells, f, w, true), nl));
      worst_linear =
          std::max(worst_linear, test::max_vertex_distance(evaluate(quadratic, f, w, false), nl));
    }
  }
  std::printf(
      "rigid rotation: max error linear %.2f mm, linear in 2 cells %.2f mm, quadratic %.2f mm, "
      "arc %.3f mm\n",
      1000 * worst_linear, 1000 * worst_cells, 1000 * worst_quadratic, 1000 * worst_arc);
  EXPECT_GT(worst_linear, 0.02);  // a real rotation: centimetres off
  EXPECT_LT(worst_quadratic, 0.1 * worst_linear);   // measured: 0.056
  EXPECT_LT(worst_quadratic, 0.35 * worst_cells);   // measured: 0.22
  EXPECT_LT(worst_arc, 0.2 * worst_quadratic);
}

TEST(HybridBuild, RejectsNonPositiveEpsilonAndUsedSpaces) {
  const Sequences s = elbow_sequences(2);
  BlendSpace space = space_of(s);
  for (double eps : {0.0, -0.005}) {
    HybridBuildOptions options;
    options.epsilon = eps;
    EXPECT_THROW(options.check(), ConfigError);
    EXPECT_THROW(build_hybrid_references(options, s.rest.positions, s.rest.triangles, &space),
                 ConfigError);
  }
  HybridBuildOptions options;
  build_hybrid_references(options, s.rest.positions, s.rest.triangles, &space);
  // A space that already has references cannot be built again.
  EXPECT_THROW(build_hybrid_references(options, s.rest.positions, s.rest.triangles, &space),
               InputError);
}

}  // namespace
}  // namespace fourd
