// Solids: thin handles removed by morphology on the voxelised solid, and a surface re-meshed on
// a fresh grid.
#include "pipeline/geometry/solid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "pipeline/geometry/measures.h"
#include "pipeline/geometry/surface_query.h"
#include "tests/test_shapes.h"

namespace fourd {
namespace {

TEST(Solid, SmallHandlesAreRemovedAndLargeOnesKept) {
  // A ball with a thin loop (a tube of 8 mm radius) attached to it at two places: one handle.
  auto ball_with_loop = [](const Eigen::Vector3d& p) {
    const double ball = p.norm() - 0.2;
    const Eigen::Vector3d q = p - Eigen::Vector3d(0.21, 0, 0);
    const double loop = std::hypot(std::hypot(q.x(), q.z()) - 0.04, q.y()) - 0.008;
    return std::min(ball, loop);
  };
  const Mesh mesh = test::isosurface_of(ball_with_loop, {-0.25, -0.25, -0.25}, {0.3, 0.25, 0.25}, 0.005);
  ASSERT_EQ(check_manifold(mesh).handles, 1);
  const Mesh cleaned = remove_small_handles(mesh, 0.005, 3);
  EXPECT_EQ(check_manifold(cleaned).handles, 0);
  EXPECT_EQ(check_manifold(cleaned).components, 1);
  // The ball itself is the input's surface, to within a fraction of the voxel.
  const SurfaceQuery input(mesh);
  int far = 0;
  for (const Vec3f& p : cleaned.positions) far += input.closest(p, 1.0f).distance > 0.002f;
  EXPECT_LT(far, static_cast<int>(cleaned.num_vertices() / 50));
  // Closed and opened by one voxel at most, only a handle a few voxels thin goes: the 16 mm
  // tube goes at 5 mm voxels (three across) and stays at 2 mm (eight).
  EXPECT_EQ(check_manifold(remove_small_handles(mesh, 0.002, 1)).handles, 1);
  EXPECT_EQ(check_manifold(remove_small_handles(mesh, 0.005, 1)).handles, 0);

  // A torus's hole is far wider than the clean-up: the torus is returned as it is.
  auto torus = [](const Eigen::Vector3d& p) {
    return std::hypot(std::hypot(p.x(), p.y()) - 0.3, p.z()) - 0.1;
  };
  const Mesh ring = test::isosurface_of(torus, {-0.5, -0.5, -0.2}, {0.5, 0.5, 0.2}, 0.02);
  const Mesh kept = remove_small_handles(ring, 0.005, 3);
  EXPECT_EQ(kept.positions, ring.positions);
  EXPECT_EQ(check_manifold(kept).handles, 1);
}

// A garment over a body: a thin shell (a bowl 10 mm thick, like a skirt's cloth) perforated by
// small holes, as an 8 mm re-meshing or a reconstruction leaves it. The opening that cuts thin
// bridges erases the sheet; closing alone fills the holes and keeps it.
TEST(Solid, HolesThroughAThinSheetAreFilledAndTheSheetKept) {
  const std::vector<Eigen::Vector3d> holes = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0},
                                              {0, 0, 1}, {0.6, 0.6, 0.53}};  // where, from the centre
  auto bowl = [&](const Eigen::Vector3d& p) {
    double d = std::max(std::fabs(p.norm() - 0.15) - 0.005, -(p.z() + 0.05));
    for (const Eigen::Vector3d& h : holes) {  // a tunnel of 3 mm radius through the sheet
      const Eigen::Vector3d axis = h.normalized();
      if (p.dot(axis) > 0) d = std::max(d, 0.003 - (p - p.dot(axis) * axis).norm());
    }
    return d;
  };
  const Mesh mesh = test::isosurface_of(bowl, {-0.17, -0.17, -0.07}, {0.17, 0.17, 0.17}, 0.002);
  ASSERT_EQ(check_manifold(mesh).components, 1);
  ASSERT_EQ(check_manifold(mesh).handles, static_cast<int>(holes.size()));  // a handle a hole
  const Mesh cleaned = remove_small_handles(mesh, 0.005, 1);
  EXPECT_EQ(check_manifold(cleaned).handles, 0);
  EXPECT_NEAR(enclosed_volume(cleaned), enclosed_volume(mesh), 0.1 * enclosed_volume(mesh));
  const SurfaceQuery input(mesh);
  int far = 0;
  for (const Vec3f& p : cleaned.positions) far += input.closest(p, 1.0f).distance > 0.003f;
  EXPECT_LT(far, static_cast<int>(cleaned.num_vertices() / 20));
}

// Closed surfaces that overlap, as a garment's shell and the body it presses into, re-mesh as
// their union: by the parity of crossings their overlap would be outside, a hollow inside.
TEST(Solid, RemeshFreshOfOverlappingPartsIsTheirUnion) {
  Mesh both = test::make_icosphere(4, 0.2f);
  const Mesh other = test::make_icosphere(4, 0.2f);
  const int first = static_cast<int>(both.num_vertices());
  for (const Vec3f& p : other.positions) both.positions.push_back(p + Vec3f(0.2f, 0, 0));
  for (const Tri& t : other.triangles) both.triangles.push_back({t[0] + first, t[1] + first, t[2] + first});
  const Mesh fresh = remesh_fresh(both, 0.01, {0.0031, 0.0017, 0.0043});
  EXPECT_EQ(check_manifold(fresh).components, 1);
  EXPECT_EQ(check_manifold(fresh).handles, 0);
  // No vertex inside either ball (the grid rounds the crease where they meet by a voxel): by
  // parity the lens they share would be hollow, its walls deep inside one ball or the other.
  int buried = 0;
  for (const Vec3f& p : fresh.positions) {
    buried += std::min(p.norm(), (p - Vec3f(0.2f, 0, 0)).norm()) < 0.18f;
  }
  EXPECT_EQ(buried, 0);
}

TEST(Solid, RemeshFreshKeepsTheSurfaceAndChangesTheConnectivity) {
  const Mesh sphere = test::make_icosphere(4, 0.3f);
  const Mesh fresh = remesh_fresh(sphere, 0.01, {0.0031, 0.0017, 0.0043});
  ASSERT_FALSE(fresh.triangles.empty());
  EXPECT_NE(fresh.num_vertices(), sphere.num_vertices());
  double worst = 0;
  for (const Vec3f& p : fresh.positions) worst = std::max(worst, std::fabs(p.norm() - 0.3));
  EXPECT_LT(worst, 0.003);  // the icosphere's facets deviate from the sphere by ~1 mm
  // Closed: every edge shared by exactly two triangles (Euler characteristic 2).
  EXPECT_EQ(static_cast<long>(fresh.num_vertices()) - static_cast<long>(fresh.triangles.size()) / 2, 2);

  const Mesh noisy = remesh_fresh(sphere, 0.01, {0.0031, 0.0017, 0.0043}, 0.004, 3);
  double sum = 0;
  for (const Vec3f& p : noisy.positions) sum += std::pow(p.norm() - 0.3, 2);
  EXPECT_GT(std::sqrt(sum / noisy.num_vertices()), 0.002);
}

TEST(Solid, VoxelizedSphereHoldsItsVolume) {
  const Mesh sphere = test::make_icosphere(4, 0.3f);
  const SolidGrid solid = voxelize_solid(sphere, 0.01, 2);
  const double voxels = static_cast<double>(std::count(solid.inside.begin(), solid.inside.end(), 1));
  const double volume = voxels * std::pow(0.01, 3);
  EXPECT_NEAR(volume, enclosed_volume(sphere), 0.02 * enclosed_volume(sphere));
  // The padding leaves the border empty, so the solid's surface is closed.
  const Mesh surface = surface_of_solid(sphere, solid);
  EXPECT_EQ(check_manifold(surface).handles, 0);
  EXPECT_EQ(check_manifold(surface).components, 1);
}

}  // namespace
}  // namespace fourd
