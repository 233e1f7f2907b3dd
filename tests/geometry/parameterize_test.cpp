#include "pipeline/geometry/parameterize.h"

#include <gtest/gtest.h>

#include "tests/test_shapes.h"

namespace fourd {
namespace {

// The chart of `mesh`'s triangles whose centroid lies above z = 0 (a disc on a sphere), as
// its own small mesh.
void upper_half(const Mesh& mesh, std::vector<Eigen::Vector3d>* positions, std::vector<Tri>* triangles) {
  std::vector<int> local(mesh.num_vertices(), -1);
  for (const Tri& t : mesh.triangles) {
    const Vec3f c = mesh.positions[t[0]] + mesh.positions[t[1]] + mesh.positions[t[2]];
    if (c.z() <= 0) continue;
    Tri lt;
    for (int k = 0; k < 3; ++k) {
      int& i = local[t[k]];
      if (i < 0) {
        i = static_cast<int>(positions->size());
        positions->push_back(mesh.positions[t[k]].cast<double>());
      }
      lt[k] = i;
    }
    triangles->push_back(lt);
  }
}

double signed_uv_area(const std::vector<Eigen::Vector2d>& uv, const Tri& t) {
  const Eigen::Vector2d a = uv[t[1]] - uv[t[0]], b = uv[t[2]] - uv[t[0]];
  return 0.5 * (a.x() * b.y() - a.y() * b.x());
}

TEST(Parameterize, AHemisphereFlattensWithoutFoldsByBothMethods) {
  std::vector<Eigen::Vector3d> positions;
  std::vector<Tri> triangles;
  upper_half(test::make_icosphere(3), &positions, &triangles);
  ASSERT_GT(triangles.size(), 500u);
  for (const FlattenMethod method : {FlattenMethod::kLscm, FlattenMethod::kArap}) {
    SCOPED_TRACE(static_cast<int>(method));
    std::vector<Eigen::Vector2d> uv;
    ASSERT_TRUE(flatten_chart(positions, triangles, method, &uv));
    ASSERT_EQ(uv.size(), positions.size());
    // Every triangle keeps its orientation in the plane (all the same sign): no fold.
    const double first = signed_uv_area(uv, triangles[0]);
    int folded = 0;
    for (const Tri& t : triangles) folded += signed_uv_area(uv, t) * first <= 0;
    EXPECT_EQ(folded, 0);
  }
}

TEST(Parameterize, AClosedSurfaceOrANonManifoldChartIsRefused) {
  const Mesh sphere = test::make_icosphere(1);
  std::vector<Eigen::Vector3d> positions;
  for (const Vec3f& p : sphere.positions) positions.push_back(p.cast<double>());
  std::vector<Eigen::Vector2d> uv(3, Eigen::Vector2d(7, 7));
  EXPECT_FALSE(flatten_chart(positions, sphere.triangles, FlattenMethod::kLscm, &uv));
  EXPECT_EQ(uv.size(), 3u);  // untouched
  std::vector<Tri> fin = {{0, 1, 2}, {0, 1, 3}, {1, 0, 4}};  // three triangles on edge (0, 1)
  EXPECT_FALSE(flatten_chart(positions, fin, FlattenMethod::kLscm, &uv));
  EXPECT_FALSE(flatten_chart(positions, {}, FlattenMethod::kLscm, &uv));
}

}  // namespace
}  // namespace fourd
