#include "pipeline/geometry/repair.h"

#include <gtest/gtest.h>

#include "pipeline/core/error.h"
#include "pipeline/geometry/measures.h"
#include "tests/test_shapes.h"

namespace fourd {
namespace {

TEST(Repair, FillHolesClosesEveryHoleOnTheSurface) {
  Mesh sphere = test::make_icosphere(3, 0.5f);
  const double area = surface_area(sphere);
  // Two holes far apart: the first triangle and the last one (of other faces of the icosahedron).
  Mesh open = sphere;
  open.triangles.erase(open.triangles.begin());
  open.triangles.pop_back();
  ASSERT_GT(check_manifold(open).boundary_edges, 0);
  Mesh filled = open;
  const int holes = fill_holes(filled);
  EXPECT_EQ(holes, 2);
  const ManifoldReport report = check_manifold(filled);
  EXPECT_EQ(report.boundary_edges, 0);
  EXPECT_EQ(report.handles, 0);
  EXPECT_GT(filled.num_triangles(), open.num_triangles());
  EXPECT_NEAR(surface_area(filled), area, 0.01 * area);
  for (const Vec3f& p : filled.positions) EXPECT_NEAR(p.norm(), 0.5f, 0.02f);
  // A closed mesh is left alone.
  Mesh closed = sphere;
  EXPECT_EQ(fill_holes(closed), 0);
  EXPECT_EQ(closed.positions, sphere.positions);
  EXPECT_EQ(closed.triangles, sphere.triangles);
}

TEST(Repair, SelfIntersectionsOfTwoOverlappingBoxes) {
  EXPECT_FALSE(has_self_intersections(test::make_icosphere(2)));
  Mesh boxes = test::make_box(1.0f);
  const Mesh other = test::make_box(1.0f);
  for (const Vec3f& p : other.positions) boxes.positions.push_back(p + Vec3f(0.5f, 0.3f, 0.2f));
  for (const Tri& t : other.triangles) boxes.triangles.push_back(t + Tri::Constant(8));
  EXPECT_TRUE(has_self_intersections(boxes));
  // Apart, they do not intersect.
  for (int v = 8; v < 16; ++v) boxes.positions[v].x() += 2.0f;
  EXPECT_FALSE(has_self_intersections(boxes));
  Mesh fin = test::make_box();
  fin.positions.push_back(Vec3f(0, 0, 2));
  fin.triangles.push_back({0, 2, 8});
  EXPECT_THROW(has_self_intersections(fin), InputError);
}

}  // namespace
}  // namespace fourd
