#include "pipeline/geometry/components.h"

#include <gtest/gtest.h>

#include "pipeline/geometry/measures.h"
#include "tests/test_shapes.h"

namespace fourd {
namespace {

// `b` appended to `a`, moved by `offset`.
Mesh joined(const Mesh& a, const Mesh& b, const Vec3f& offset) {
  Mesh out = a;
  const int n = static_cast<int>(a.num_vertices());
  for (const Vec3f& p : b.positions) out.positions.push_back(p + offset);
  for (const Tri& t : b.triangles) out.triangles.push_back(t + Tri::Constant(n));
  return out;
}

TEST(Components, TwoDisjointBoxesAreTwoComponentsNumberedInTriangleOrder) {
  Mesh mesh = joined(test::make_box(0.5f), test::make_box(2.0f), Vec3f(5, 0, 0));
  mesh.positions.push_back(Vec3f(9, 9, 9));  // no triangle uses it
  int count = 0;
  const std::vector<int> component = vertex_components(mesh, &count);
  EXPECT_EQ(count, 2);
  ASSERT_EQ(component.size(), 17u);
  for (int v = 0; v < 8; ++v) EXPECT_EQ(component[v], 0) << v;
  for (int v = 8; v < 16; ++v) EXPECT_EQ(component[v], 1) << v;
  EXPECT_EQ(component[16], -1);
  EXPECT_EQ(count_components(mesh), 2);
  EXPECT_EQ(count_components(test::make_icosphere(2)), 1);
  EXPECT_EQ(count_components(Mesh{}), 0);
}

TEST(Components, LargestIsByAreaNotByTriangleCount) {
  // A small sphere of 1,280 triangles (area 0.13 m^2) before a box of 12 (area 24 m^2).
  const Mesh sphere = test::make_icosphere(3, 0.1f);
  const Mesh mesh = joined(sphere, test::make_box(2.0f), Vec3f(5, 0, 0));
  const Mesh largest = largest_component(mesh);
  ASSERT_EQ(largest.num_vertices(), 8u);
  ASSERT_EQ(largest.num_triangles(), 12u);
  EXPECT_NEAR(surface_area(largest), 24.0, 1e-9);
  // Renumbered in order of first use: the box's first triangle's corners come first.
  const int n = static_cast<int>(sphere.num_vertices());
  const Tri first = test::make_box(2.0f).triangles[0];
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(largest.triangles[0][k], k);
    EXPECT_EQ(largest.positions[k], mesh.positions[first[k] + n]);
  }
}

TEST(Components, LargestOfEqualOnesIsTheFirst) {
  const Mesh mesh = joined(test::make_box(1.0f), test::make_box(1.0f), Vec3f(3, 0, 0));
  const Mesh largest = largest_component(mesh);
  ASSERT_EQ(largest.num_vertices(), 8u);
  for (const Vec3f& p : largest.positions) EXPECT_LT(p.x(), 1.0f);
}

TEST(Components, LargestKeepsAClosedMeshWholeAndDropsUnusedVertices) {
  Mesh torus = test::isosurface_of(
      [](const Eigen::Vector3d& p) { return std::hypot(std::hypot(p.x(), p.y()) - 0.3, p.z()) - 0.1; },
      {-0.5, -0.5, -0.2}, {0.5, 0.5, 0.2}, 0.02);
  const std::size_t nv = torus.num_vertices(), nf = torus.num_triangles();
  torus.positions.push_back(Vec3f(1, 1, 1));
  const Mesh largest = largest_component(torus);
  EXPECT_EQ(largest.num_vertices(), nv);
  EXPECT_EQ(largest.num_triangles(), nf);
  EXPECT_TRUE(largest_component(Mesh{}).empty());
}

}  // namespace
}  // namespace fourd
