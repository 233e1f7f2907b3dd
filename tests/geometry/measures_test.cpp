#include "pipeline/geometry/measures.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numbers>

#include "pipeline/core/error.h"
#include "tests/test_shapes.h"

namespace fourd {
namespace {

Mesh torus() {
  return test::isosurface_of(
      [](const Eigen::Vector3d& p) { return std::hypot(std::hypot(p.x(), p.y()) - 0.3, p.z()) - 0.1; },
      {-0.5, -0.5, -0.2}, {0.5, 0.5, 0.2}, 0.02);
}

TEST(Measures, AreaAndVolumeOfABoxAndASphere) {
  const Mesh box = test::make_box(Vec3f(1, 2, 3));
  EXPECT_NEAR(surface_area(box), 22.0, 1e-9);
  EXPECT_NEAR(enclosed_volume(box), 6.0, 1e-9);
  EXPECT_NEAR(triangle_area(box, box.triangles[0]), 1.0, 1e-9);  // half of the 1 x 2 face
  // An inscribed polyhedron: a little less than the sphere's area and volume.
  const Mesh sphere = test::make_icosphere(4);
  const double pi = std::numbers::pi;
  EXPECT_LT(surface_area(sphere), 4 * pi);
  EXPECT_GT(surface_area(sphere), 0.99 * 4 * pi);
  EXPECT_LT(enclosed_volume(sphere), 4.0 / 3 * pi);
  EXPECT_GT(enclosed_volume(sphere), 0.99 * 4.0 / 3 * pi);
  // Inside out: the volume changes sign.
  Mesh flipped = sphere;
  for (Tri& t : flipped.triangles) std::swap(t[1], t[2]);
  EXPECT_NEAR(enclosed_volume(flipped), -enclosed_volume(sphere), 1e-9);
}

TEST(Measures, EdgeNeighboursAreSortedAndUnique) {
  const std::vector<std::vector<int>> rings = edge_neighbours(test::make_box());
  ASSERT_EQ(rings.size(), 8u);
  EXPECT_EQ(rings[0], (std::vector<int>{1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(rings[7], (std::vector<int>{1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(rings[1], (std::vector<int>{0, 3, 5, 7}));
}

TEST(Measures, VertexNeighboursAreTheOneRingsInCirculationOrder) {
  const Mesh sphere = test::make_icosphere(1);
  const std::vector<std::vector<int>> rings = vertex_neighbours(sphere);
  const std::vector<std::vector<int>> edges = edge_neighbours(sphere);
  ASSERT_EQ(rings.size(), 42u);
  for (std::size_t v = 0; v < rings.size(); ++v) {
    EXPECT_EQ(rings[v].size(), v < 12 ? 5u : 6u) << v;  // the icosahedron's corners: valence 5
    std::vector<int> sorted = rings[v];
    std::sort(sorted.begin(), sorted.end());
    EXPECT_EQ(sorted, edges[v]) << v;
    // Consecutive ring vertices are neighbours of each other (a fan around v).
    for (std::size_t k = 0; k < rings[v].size(); ++k) {
      const std::vector<int>& next = edges[rings[v][k]];
      EXPECT_TRUE(std::binary_search(next.begin(), next.end(), rings[v][(k + 1) % rings[v].size()]));
    }
  }
  Mesh fin = test::make_box();
  fin.positions.push_back(Vec3f(0, 0, 2));
  fin.triangles.push_back({0, 2, 8});  // a third triangle on the edge (0, 2)
  EXPECT_THROW(vertex_neighbours(fin), InputError);
}

TEST(Measures, BoundaryEdgesAreThoseOfOneTriangle) {
  Mesh box = test::make_box();
  EXPECT_EQ(count_boundary_edges(box), 0);
  box.triangles.pop_back();
  EXPECT_EQ(count_boundary_edges(box), 3);
  box.triangles.pop_back();  // its neighbour on the +x face: a square hole
  EXPECT_EQ(count_boundary_edges(box), 4);
}

TEST(Measures, HandlesCountTheGenusOfAClosedMesh) {
  EXPECT_EQ(check_manifold(test::make_icosphere(2)).handles, 0);

  // A torus (one handle), and beside it a sphere: the genus is summed over components.
  Mesh mesh = torus();
  ManifoldReport report = check_manifold(mesh);
  EXPECT_TRUE(report.manifold());
  EXPECT_EQ(report.components, 1);
  EXPECT_EQ(report.handles, 1);
  const Mesh sphere = test::make_icosphere(1, 0.1f);
  const int offset = static_cast<int>(mesh.num_vertices());
  for (const Vec3f& p : sphere.positions) mesh.positions.push_back(p + Vec3f(2, 0, 0));
  for (const Tri& t : sphere.triangles) mesh.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  report = check_manifold(mesh);
  EXPECT_EQ(report.components, 2);
  EXPECT_EQ(report.handles, 1);

  // With a hole the genus is unknown.
  Mesh open = test::make_icosphere(2);
  open.triangles.pop_back();
  report = check_manifold(open);
  EXPECT_EQ(report.boundary_edges, 3);
  EXPECT_EQ(report.handles, -1);
}

TEST(Measures, NonManifoldEdgesAndRefusedTrianglesAreCounted) {
  Mesh fin = test::make_box();
  fin.positions.push_back(Vec3f(0, 0, 2));
  fin.triangles.push_back({0, 2, 8});  // a third triangle on the edge (0, 2)
  const ManifoldReport report = check_manifold(fin);
  EXPECT_EQ(report.non_manifold_edges, 1);
  EXPECT_EQ(report.rejected_faces, 1);
  EXPECT_EQ(report.boundary_edges, 2);  // (0, 8) and (2, 8)
  EXPECT_FALSE(report.manifold());
  EXPECT_EQ(report.components, 1);
  EXPECT_EQ(report.handles, -1);
}

}  // namespace
}  // namespace fourd
