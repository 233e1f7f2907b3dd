#include "pipeline/core/mesh.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "pipeline/core/error.h"
#include "tests/input_error.h"
#include "tests/test_shapes.h"

namespace fourd {
namespace {

using test::input_error;

TEST(Mesh, ShapesHaveExpectedCounts) {
  Mesh sphere = test::make_icosphere(2, 1.5f);
  EXPECT_EQ(sphere.num_vertices(), 162u);
  EXPECT_EQ(sphere.num_triangles(), 320u);
  for (const Vec3f& p : sphere.positions) EXPECT_NEAR(p.norm(), 1.5f, 1e-5f);
  Mesh box = test::make_box(Vec3f(1, 2, 3));
  EXPECT_EQ(box.num_vertices(), 8u);
  EXPECT_EQ(box.num_triangles(), 12u);
  EXPECT_NO_THROW(sphere.check("sphere"));
  EXPECT_NO_THROW(box.check("box"));
}

TEST(Mesh, VertexNormalsPointOutwardOnIcosphere) {
  Mesh sphere = test::make_icosphere(2, 2.0f);
  compute_vertex_normals(sphere);
  ASSERT_EQ(sphere.normals.size(), sphere.num_vertices());
  for (std::size_t i = 0; i < sphere.num_vertices(); ++i) {
    EXPECT_NEAR(sphere.normals[i].norm(), 1.0f, 1e-5f);
    // On a sphere the normal is the radial direction, up to the faceting.
    EXPECT_GT(sphere.normals[i].dot(sphere.positions[i].normalized()), 0.99f) << "vertex " << i;
  }
}

TEST(Mesh, VertexNormalsPointOutwardOnBoxAndFacesAreOutward) {
  Mesh box = test::make_box(Vec3f(2, 4, 6));
  for (const Tri& t : box.triangles) {
    const Vec3f& a = box.positions[t[0]];
    Vec3f face_normal = (box.positions[t[1]] - a).cross(box.positions[t[2]] - a);
    Vec3f centre = (a + box.positions[t[1]] + box.positions[t[2]]) / 3.0f;
    EXPECT_GT(face_normal.dot(centre), 0.0f);
  }
  compute_vertex_normals(box);
  for (std::size_t i = 0; i < box.num_vertices(); ++i) {
    // Each corner's normal leans into its octant: same sign as the corner on every axis.
    for (int k = 0; k < 3; ++k) {
      EXPECT_GT(box.normals[i][k] * box.positions[i][k], 0.0f) << "corner " << i << " axis " << k;
    }
  }
}

TEST(Mesh, IsolatedVertexGetsZeroNormal) {
  Mesh box = test::make_box();
  box.positions.emplace_back(5, 5, 5);
  compute_vertex_normals(box);
  EXPECT_EQ(box.normals.back(), Vec3f::Zero());
}

TEST(Mesh, BoundingBox) {
  Mesh box = test::make_box(Vec3f(2, 4, 6));
  Vec3f lo, hi;
  bounding_box(box, &lo, &hi);
  EXPECT_EQ(lo, Vec3f(-1, -2, -3));
  EXPECT_EQ(hi, Vec3f(1, 2, 3));
  bounding_box(Mesh{}, &lo, &hi);
  EXPECT_GT(lo.x(), hi.x());  // empty
}

TEST(Mesh, CheckRejectsBadMeshes) {
  Mesh bad_index = test::make_box();
  bad_index.triangles[3][1] = 8;
  EXPECT_NE(input_error([&] { bad_index.check("box.ply"); }).find("box.ply"), std::string::npos);

  Mesh negative = test::make_box();
  negative.triangles[0][0] = -1;
  EXPECT_THROW(negative.check("m"), InputError);

  Mesh normals = test::make_box();
  normals.normals.assign(3, Vec3f::UnitZ());
  EXPECT_THROW(normals.check("m"), InputError);

  Mesh colors = test::make_box();
  colors.colors.resize(9);
  EXPECT_THROW(colors.check("m"), InputError);

  Mesh confidence = test::make_box();
  confidence.confidence.assign(8, 1.0f);
  EXPECT_NO_THROW(confidence.check("m"));
  confidence.confidence.resize(7);
  EXPECT_THROW(confidence.check("m"), InputError);
  confidence.confidence.assign(8, 0.0f);
  confidence.confidence[5] = 1.5f;
  EXPECT_NE(input_error([&] { confidence.check("m"); }).find("vertex 5 has confidence 1.5"),
            std::string::npos);
  confidence.confidence[5] = std::nanf("");
  EXPECT_THROW(confidence.check("m"), InputError);

  Mesh uvs = test::make_box();
  uvs.uvs.assign(7, Vec2f::Zero());
  EXPECT_THROW(uvs.check("m"), InputError);

  Mesh corner_uvs = test::make_box();
  corner_uvs.uvs.assign(3, Vec2f::Zero());  // (resize would leave them uninitialised)
  corner_uvs.uv_triangles.assign(12, Tri(0, 1, 2));
  EXPECT_NO_THROW(corner_uvs.check("m"));
  corner_uvs.uv_triangles[5][2] = 3;
  EXPECT_THROW(corner_uvs.check("m"), InputError);
  corner_uvs.uv_triangles.resize(11, Tri(0, 1, 2));
  EXPECT_THROW(corner_uvs.check("m"), InputError);

  Mesh nan = test::make_box();
  nan.positions[2].y() = std::nanf("");
  EXPECT_NE(input_error([&] { nan.check("m"); }).find("not finite"), std::string::npos);
}

}  // namespace
}  // namespace fourd
