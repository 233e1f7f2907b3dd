#include "pipeline/geometry/openmesh_adapter.h"

#include <gtest/gtest.h>

#include "tests/test_shapes.h"

namespace fourd {
namespace {

// Equal up to a rotation of the corners (OpenMesh starts a face at a corner of its choice).
bool same_triangle(const Tri& a, const Tri& b) {
  for (int r = 0; r < 3; ++r) {
    if (a[0] == b[r] && a[1] == b[(r + 1) % 3] && a[2] == b[(r + 2) % 3]) return true;
  }
  return false;
}

TEST(OpenMeshAdapter, ABoxGoesThereAndBackUnchanged) {
  const Mesh box = test::make_box(Vec3f(1, 2, 3));
  int rejected = -1;
  OpenMeshF om = to_openmesh<OpenMeshF>(box, &rejected);
  EXPECT_EQ(rejected, 0);
  EXPECT_EQ(om.n_vertices(), 8u);
  EXPECT_EQ(om.n_faces(), 12u);
  EXPECT_EQ(om.n_edges(), 18u);
  const Mesh back = from_openmesh(om);
  EXPECT_EQ(back.positions, box.positions);
  ASSERT_EQ(back.triangles.size(), box.triangles.size());
  for (std::size_t f = 0; f < box.triangles.size(); ++f) {
    EXPECT_TRUE(same_triangle(back.triangles[f], box.triangles[f])) << f;
  }
}

TEST(OpenMeshAdapter, TrianglesAHalfedgeMeshCannotHoldAreCounted) {
  Mesh mesh = test::make_box();
  mesh.triangles.push_back({1, 1, 2});  // repeats a vertex
  mesh.triangles.push_back(mesh.triangles[0]);  // twice
  mesh.positions.push_back(Vec3f(0, 0, 2));
  mesh.triangles.push_back({0, 2, 8});  // a third triangle on the edge (0, 2)
  int rejected = 0;
  const OpenMeshF om = to_openmesh<OpenMeshF>(mesh, &rejected);
  EXPECT_EQ(rejected, 3);
  EXPECT_EQ(om.n_faces(), 12u);
}

TEST(OpenMeshAdapter, IsolatedVerticesAreKeptOrDropped) {
  Mesh mesh = test::make_box();
  // A vertex no triangle uses, between the box's corners.
  mesh.positions.insert(mesh.positions.begin() + 4, Vec3f(7, 7, 7));
  for (Tri& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) t[k] += t[k] >= 4 ? 1 : 0;
  }
  OpenMeshF om = to_openmesh<OpenMeshF>(mesh);
  EXPECT_EQ(from_openmesh(om, IsolatedVertices::kKeep).num_vertices(), 9u);
  const Mesh dropped = from_openmesh(om, IsolatedVertices::kDrop);
  ASSERT_EQ(dropped.num_vertices(), 8u);
  ASSERT_EQ(dropped.num_triangles(), 12u);
  EXPECT_EQ(dropped.positions, test::make_box().positions);
  for (std::size_t f = 0; f < dropped.triangles.size(); ++f) {
    EXPECT_TRUE(same_triangle(dropped.triangles[f], test::make_box().triangles[f])) << f;
  }
}

}  // namespace
}  // namespace fourd
