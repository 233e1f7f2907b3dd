#include "stages/motionspace/nonlinear_blend.h"

#include <gtest/gtest.h>

#include <numbers>
#include <vector>

#include "pipeline/core/error.h"
#include "tests/motionspace/test_meshes.h"

namespace fourd {
namespace {

using test::TubeShape;

constexpr double kDeg = std::numbers::pi / 180;

// An asymmetric closed shape: an elliptic tube bent by 40 degrees.
test::TestMesh asymmetric_shape() {
  TubeShape shape;
  shape.ellipticity = 1.6;
  test::TestMesh m = test::make_tube(21, 16, shape);
  m.positions = test::bend_tube(m.positions, 40 * kDeg, shape);
  return m;
}

// Direction of the tube's upper end: from the centroid of its first ring above the bend
// zone to the centroid of its top ring.
Eigen::Vector3d end_axis(const Eigen::Matrix3Xd& x, int rings, int segments, int first_ring) {
  const Eigen::Vector3d a = x.middleCols(first_ring * segments, segments).rowwise().mean();
  const Eigen::Vector3d b = x.middleCols((rings - 1) * segments, segments).rowwise().mean();
  return (b - a).normalized();
}

TEST(NonlinearBlend, TubeIsClosedAndOutwardOriented) {
  const test::TestMesh m = test::make_tube(21, 16);
  const double expected = std::numbers::pi * 0.08 * 0.08 * 1.0;  // cylinder r = 0.08, length 1
  EXPECT_NEAR(test::volume(m.positions, m.triangles), expected, 0.03 * expected);
}

TEST(NonlinearBlend, IdenticalInputsWithEqualWeightsAreExact) {
  const test::TestMesh m = asymmetric_shape();
  for (int n : {2, 3}) {
    const std::vector<Eigen::Matrix3Xd> inputs(n, m.positions);
    const std::vector<double> w(n, 1.0 / n);
    // Reference = the straight tube, so the inputs really are deformed relative to it.
    const test::TestMesh straight = test::make_tube(21, 16, TubeShape{.ellipticity = 1.6});
    const Eigen::Matrix3Xd nl = nonlinear_blend(straight.positions, m.triangles, inputs, w);
    EXPECT_LT(test::max_vertex_distance(nl, m.positions), 1e-9) << n << " inputs";
    EXPECT_LT(test::max_vertex_distance(linear_blend(inputs, w), m.positions), 1e-12);
  }
}

TEST(NonlinearBlend, ReproducesEachInputAtItsUnitWeight) {
  const TubeShape shape;
  const test::TestMesh m = test::make_tube(21, 16, shape);
  const std::vector<Eigen::Matrix3Xd> inputs{test::bend_tube(m.positions, 0, shape),
                                             test::bend_tube(m.positions, 120 * kDeg, shape),
                                             test::bend_tube(m.positions, -70 * kDeg, shape)};
  NonlinearBlendData data;
  nonlinear_blend_precompute(m.positions, m.triangles, &data);
  NonlinearBlendInputs prepared;
  nonlinear_blend_prepare(data, inputs, &prepared);
  Eigen::Matrix3Xd out;
  for (int k = 0; k < 3; ++k) {
    std::vector<double> w(3, 0.0);
    w[k] = 1;
    nonlinear_blend_solve(data, prepared, w, &out);
    EXPECT_LT(test::max_vertex_distance(out, inputs[k]), 1e-9) << "input " << k;
  }
}

class RigidRotation : public ::testing::TestWithParam<double> {};

// A mesh and its copy rotated by a large angle blend at w = 0.5 to the rotation by half the
// angle: shape, volume and edge lengths kept; the linear blend shrinks.
TEST_P(RigidRotation, BlendsToHalfTheRotation) {
  const double angle = GetParam() * kDeg;
  const Eigen::Vector3d axis(0.3, -1.0, 0.4);
  const test::TestMesh m = asymmetric_shape();
  const std::vector<Eigen::Matrix3Xd> inputs{m.positions,
                                             test::rotate_about_centroid(m.positions, angle, axis)};
  const std::vector<double> w{0.5, 0.5};
  const Eigen::Matrix3Xd nl = nonlinear_blend(m.positions, m.triangles, inputs, w);
  const Eigen::Matrix3Xd expected = test::rotate_about_centroid(m.positions, angle / 2, axis);
  const double size = (m.positions.rowwise().maxCoeff() - m.positions.rowwise().minCoeff()).norm();
  EXPECT_LT(test::max_vertex_distance(nl, expected), 1e-3 * size);

  const double v0 = test::volume(m.positions, m.triangles);
  EXPECT_NEAR(test::volume(nl, m.triangles) / v0, 1.0, 1e-3);
  EXPECT_LT(test::max_edge_length_change(m.positions, nl, m.triangles), 1e-3);

  const Eigen::Matrix3Xd linear = linear_blend(inputs, w);
  // Linear blending scales the components across the axis by cos(angle / 2).
  EXPECT_LT(test::volume(linear, m.triangles) / v0, 0.6);
  EXPECT_GT(test::max_edge_length_change(m.positions, linear, m.triangles), 0.2);
}

INSTANTIATE_TEST_SUITE_P(NonlinearBlend, RigidRotation, ::testing::Values(90.0, 150.0, 175.0));

// The gradient operator's reference only defines where gradients are measured: blending rigid
// copies gives the same result from a differently shaped reference.
TEST(NonlinearBlend, ReferencePoseDoesNotChangeRigidBlend) {
  const test::TestMesh m = asymmetric_shape();
  const Eigen::Vector3d axis(1, 1, 0);
  const std::vector<Eigen::Matrix3Xd> inputs{
      m.positions, test::rotate_about_centroid(m.positions, 150 * kDeg, axis)};
  const std::vector<double> w{0.3, 0.7};
  const Eigen::Matrix3Xd from_input = nonlinear_blend(m.positions, m.triangles, inputs, w);
  const test::TestMesh straight = test::make_tube(21, 16, TubeShape{.ellipticity = 1.6});
  const Eigen::Matrix3Xd from_template =
      nonlinear_blend(straight.positions, m.triangles, inputs, w);
  EXPECT_LT(test::max_vertex_distance(from_input, from_template), 1e-6);
  EXPECT_LT(test::max_vertex_distance(
                from_input, test::rotate_about_centroid(m.positions, 0.7 * 150 * kDeg, axis)),
            1e-6);
}

// The elbow blended half way between straight and bent by 120 degrees is the elbow bent by 60:
// per-triangle rotations halve and the arc's compression/stretch interpolates linearly.
TEST(NonlinearBlend, BentTubeBlendsToHalfTheBend) {
  const TubeShape shape;
  const int rings = 41, segments = 24;
  const test::TestMesh m = test::make_tube(rings, segments, shape);
  const std::vector<Eigen::Matrix3Xd> inputs{m.positions,
                                             test::bend_tube(m.positions, 120 * kDeg, shape)};
  const std::vector<double> w{0.5, 0.5};
  const Eigen::Matrix3Xd nl = nonlinear_blend(m.positions, m.triangles, inputs, w);
  const Eigen::Matrix3Xd linear = linear_blend(inputs, w);
  Eigen::Matrix3Xd expected = test::bend_tube(m.positions, 60 * kDeg, shape);
  // Compare shapes, not placement: the blend keeps the linear blend's centroid.
  expected.colwise() += nl.rowwise().mean() - expected.rowwise().mean();

  const double length = 2 * shape.half_length;
  const double nl_error = test::max_vertex_distance(nl, expected);
  EXPECT_LT(nl_error, 1e-3 * length);  // measured 0.07 mm on this 1 m tube
  EXPECT_GT(test::max_vertex_distance(linear, expected), 0.1 * length);  // measured 17 cm

  // First ring fully above the bend zone (z > 0.2 at rest).
  const int first_ring = static_cast<int>(std::ceil((shape.bend_half_zone + shape.half_length) /
                                                    length * (rings - 1))) +
                         1;
  const Eigen::Vector3d axis_nl = end_axis(nl, rings, segments, first_ring);
  const double bend_nl = std::acos(std::clamp(axis_nl.z(), -1.0, 1.0)) / kDeg;
  EXPECT_NEAR(bend_nl, 60.0, 0.2);
  EXPECT_NEAR(test::volume(nl, m.triangles) / test::volume(m.positions, m.triangles), 1.0, 2e-3);
}

// Two separate pieces: each keeps its own centroid from the linear blend.
TEST(NonlinearBlend, EachConnectedComponentIsPlacedOnItsOwn) {
  const test::TestMesh a = asymmetric_shape();
  test::TestMesh both;
  both.positions.resize(3, 2 * a.positions.cols());
  both.positions << a.positions, (a.positions.colwise() + Eigen::Vector3d(2, 0, 0));
  both.triangles = a.triangles;
  const int offset = static_cast<int>(a.positions.cols());
  for (const Tri& t : a.triangles) both.triangles.push_back(t + Tri::Constant(offset));
  Eigen::Matrix3Xd rotated = both.positions;
  const Eigen::Vector3d axis(0, 0, 1);
  rotated.leftCols(offset) =
      test::rotate_about_centroid(both.positions.leftCols(offset), 100 * kDeg, axis);
  rotated.rightCols(offset) =
      test::rotate_about_centroid(both.positions.rightCols(offset), -60 * kDeg, axis);
  const std::vector<Eigen::Matrix3Xd> inputs{both.positions, rotated};
  const Eigen::Matrix3Xd nl =
      nonlinear_blend(both.positions, both.triangles, inputs, std::vector<double>{0.5, 0.5});
  EXPECT_LT(test::max_vertex_distance(
                nl.leftCols(offset),
                test::rotate_about_centroid(both.positions.leftCols(offset), 50 * kDeg, axis)),
            1e-6);
  EXPECT_LT(test::max_vertex_distance(
                nl.rightCols(offset),
                test::rotate_about_centroid(both.positions.rightCols(offset), -30 * kDeg, axis)),
            1e-6);
}

TEST(NonlinearBlend, RejectsBadInput) {
  const test::TestMesh m = test::make_tube(5, 8);
  NonlinearBlendData data;
  std::vector<Tri> degenerate = m.triangles;
  degenerate[3] = Tri(0, 1, 1);
  EXPECT_THROW(nonlinear_blend_precompute(m.positions, degenerate, &data), InputError);
  std::vector<Tri> out_of_range = m.triangles;
  out_of_range[0] = Tri(0, 1, static_cast<int>(m.positions.cols()));
  EXPECT_THROW(nonlinear_blend_precompute(m.positions, out_of_range, &data), InputError);

  nonlinear_blend_precompute(m.positions, m.triangles, &data);
  NonlinearBlendInputs prepared;
  const std::vector<Eigen::Matrix3Xd> wrong_size{m.positions, m.positions.leftCols(10)};
  EXPECT_THROW(nonlinear_blend_prepare(data, wrong_size, &prepared), InputError);
  const std::vector<Eigen::Matrix3Xd> inputs{m.positions, m.positions};
  nonlinear_blend_prepare(data, inputs, &prepared);
  Eigen::Matrix3Xd out;
  EXPECT_THROW(nonlinear_blend_solve(data, prepared, std::vector<double>{1.0}, &out), InputError);
  EXPECT_THROW(nonlinear_blend_solve(data, prepared, std::vector<double>{0.0, 0.0}, &out),
               InputError);
  EXPECT_THROW(nonlinear_blend_solve(data, prepared, std::vector<double>{1.5, -0.5}, &out),
               InputError);
}

}  // namespace
}  // namespace fourd
