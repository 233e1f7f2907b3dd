#include "pipeline/core/isosurface.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>

namespace fourd {
namespace {

ScalarGrid sphere_grid(double radius, double voxel, Eigen::Vector3d center) {
  ScalarGrid g;
  g.voxel = voxel;
  g.nx = g.ny = g.nz = static_cast<int>(std::ceil(2.6 * radius / voxel));
  g.origin = center - Eigen::Vector3d::Constant(1.3 * radius);
  g.values.resize(static_cast<std::size_t>(g.nx) * g.ny * g.nz);
  for (int z = 0; z < g.nz; ++z)
    for (int y = 0; y < g.ny; ++y)
      for (int x = 0; x < g.nx; ++x)
        g.values[g.index(x, y, z)] = static_cast<float>((g.point(x, y, z) - center).norm() - radius);
  return g;
}

// Every undirected edge is used by exactly two triangles, once in each direction.
void expect_closed_oriented(const Mesh& m) {
  std::map<std::pair<int, int>, int> directed;
  for (const Tri& t : m.triangles)
    for (int k = 0; k < 3; ++k) directed[{t[k], t[(k + 1) % 3]}]++;
  for (const auto& [e, n] : directed) {
    ASSERT_EQ(n, 1) << "edge used twice in one direction";
    ASSERT_EQ(directed.count({e.second, e.first}), 1u) << "open edge " << e.first << "-" << e.second;
  }
  long v = static_cast<long>(m.positions.size()), f = static_cast<long>(m.triangles.size());
  long e = static_cast<long>(directed.size()) / 2;
  EXPECT_EQ(v - e + f, 2) << "Euler characteristic of a sphere";
}

TEST(Isosurface, SphereIsClosedAccurateAndOutward) {
  const Eigen::Vector3d c(0.1, -0.2, 0.3);
  Mesh m = extract_isosurface(sphere_grid(0.5, 0.05, c));
  ASSERT_GT(m.triangles.size(), 500u);
  expect_closed_oriented(m);
  double volume = 0;
  for (const Tri& t : m.triangles) {
    Eigen::Vector3d a = m.positions[t[0]].cast<double>() - c, b = m.positions[t[1]].cast<double>() - c,
                    d = m.positions[t[2]].cast<double>() - c;
    volume += a.dot(b.cross(d)) / 6.0;
  }
  EXPECT_NEAR(volume, 4.0 / 3.0 * M_PI * 0.125, 0.03 * 4.0 / 3.0 * M_PI * 0.125);
  for (const Vec3f& p : m.positions) EXPECT_NEAR((p.cast<double>() - c).norm(), 0.5, 0.01);
}

TEST(Isosurface, SurfaceTouchingTheBorderIsClosed) {
  // Inside everywhere: the border closes the surface as a box.
  ScalarGrid g;
  g.nx = g.ny = g.nz = 4;
  g.values.assign(64, -1.0f);
  Mesh m = extract_isosurface(g);
  expect_closed_oriented(m);
}

TEST(Isosurface, EmptyWhenAllOutside) {
  ScalarGrid g;
  g.nx = g.ny = g.nz = 3;
  g.values.assign(27, 1.0f);
  EXPECT_TRUE(extract_isosurface(g).triangles.empty());
}

TEST(Isosurface, ProjectionPutsACoarseSurfaceOnTheFineLevelSet) {
  // The isosurface of every 4th sample (a coarse, faceted sphere) put back on the full grid's
  // zero level: within half a millimetre of the true sphere (2 cm voxels), from up to 5 mm.
  const Eigen::Vector3d c(0.1, -0.2, 0.3);
  const ScalarGrid fine = sphere_grid(0.5, 0.02, c);
  const ScalarGrid coarse = subsample(fine, 4);
  Mesh m = extract_isosurface(coarse);
  double worst_before = 0;
  for (const Vec3f& p : m.positions) {
    worst_before = std::max(worst_before, std::fabs((p.cast<double>() - c).norm() - 0.5));
  }
  ASSERT_GT(worst_before, 0.003);
  const int moved = project_to_isosurface(m, fine, 0.0f, 4 * fine.voxel);
  EXPECT_GT(moved, static_cast<int>(0.9 * m.positions.size()));  // the rest already lie on it
  for (const Vec3f& p : m.positions) EXPECT_NEAR((p.cast<double>() - c).norm(), 0.5, 0.0005);
  expect_closed_oriented(m);
}

TEST(Isosurface, ProjectionLeavesVerticesItCannotPlace) {
  const Eigen::Vector3d c(0, 0, 0);
  const ScalarGrid grid = sphere_grid(0.5, 0.05, c);
  Mesh m;
  m.positions = {Vec3f(0.52f, 0, 0),     // 2 cm outside: moved
                 Vec3f(0, 0.62f, 0),     // 12 cm outside, farther than the 4 cm allowed
                 Vec3f(0, 0, 5.0f),      // beyond the grid
                 Vec3f(NAN, 0, 0), Vec3f(1e30f, -1e30f, 0)};
  ScalarGrid with_nan = grid;
  EXPECT_EQ(project_to_isosurface(m, grid, 0.0f, 0.04), 1);
  EXPECT_NEAR(m.positions[0].x(), 0.5f, 0.002f);
  EXPECT_EQ(m.positions[1], Vec3f(0, 0.62f, 0));
  EXPECT_EQ(m.positions[2], Vec3f(0, 0, 5.0f));
  EXPECT_TRUE(std::isnan(m.positions[3].x()));
  EXPECT_EQ(m.positions[4], Vec3f(1e30f, -1e30f, 0));
  // A NaN sample next to the vertex: left where it is.
  const Eigen::Vector3d g = (Eigen::Vector3d(0.52, 0, 0) - grid.origin) / grid.voxel;
  with_nan.values[with_nan.index(static_cast<int>(g.x()), static_cast<int>(g.y()),
                                 static_cast<int>(g.z()))] = NAN;
  Mesh n;
  n.positions = {Vec3f(0.52f, 0, 0)};
  EXPECT_EQ(project_to_isosurface(n, with_nan, 0.0f, 0.04), 0);
}

TEST(Isosurface, ProjectionDoesNotFoldATriangleOver) {
  // A ridge, z = -2|x|, and a small triangle above its crest facing up: projected on their own,
  // its two lower vertices cross the crest and swap sides, which would turn the triangle over.
  ScalarGrid ridge;
  ridge.voxel = 0.005;
  ridge.origin = Eigen::Vector3d::Constant(-0.05);
  ridge.nx = ridge.ny = ridge.nz = 21;
  ridge.values.resize(21 * 21 * 21);
  for (int z = 0; z < 21; ++z)
    for (int y = 0; y < 21; ++y)
      for (int x = 0; x < 21; ++x) {
        const Eigen::Vector3d p = ridge.point(x, y, z);
        ridge.values[ridge.index(x, y, z)] = static_cast<float>(p.z() + 2 * std::fabs(p.x()));
      }
  const Vec3f a(-0.005f, 0.0012f, 0.012f), b(0.005f, 0.0012f, 0.012f), c(0, 0.0112f, 0.012f);
  Mesh points;
  points.positions = {a, b, c};
  ASSERT_EQ(project_to_isosurface(points, ridge, 0.0f, 0.05), 3);
  ASSERT_GT(points.positions[0].x(), points.positions[1].x()) << "the vertices did not swap";

  Mesh triangle = points;
  triangle.positions = {a, b, c};
  triangle.triangles = {Tri(0, 1, 2)};
  const Vec3f before = (b - a).cross(c - a);
  const int moved = project_to_isosurface(triangle, ridge, 0.0f, 0.05);
  EXPECT_LT(moved, 3);
  const std::vector<Vec3f>& p = triangle.positions;
  EXPECT_GE(before.dot((p[1] - p[0]).cross(p[2] - p[0])), 0.0f);
}

}  // namespace
}  // namespace fourd
