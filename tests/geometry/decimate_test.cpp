// Quadric decimation (OpenMesh) of a fine isosurface down to a vertex count keeps the surface
// closed and on the shape.
#include "pipeline/geometry/decimate.h"

#include <gtest/gtest.h>

#include <thread>

#include "pipeline/geometry/measures.h"
#include "tests/test_shapes.h"

namespace fourd {
namespace {

constexpr double kRadius = 0.3;

TEST(Decimate, ReachesTheTargetAndStaysOnTheSphere) {
  const Mesh fine = test::fine_sphere(kRadius);
  ASSERT_GT(fine.positions.size(), 10000u);
  const Mesh coarse = decimate(fine, 3000);
  EXPECT_LE(coarse.positions.size(), 3000u);
  EXPECT_GE(coarse.positions.size(), 2900u);
  const ManifoldReport report = check_manifold(coarse);
  EXPECT_TRUE(report.manifold());
  EXPECT_EQ(report.boundary_edges, 0);
  EXPECT_EQ(report.components, 1);
  EXPECT_EQ(report.handles, 0);
  EXPECT_LT(test::max_radial_error(coarse, kRadius), 0.002);
}

// The first, multiple-choice stage of decimation draws from rand(): a mesh decimated while
// another one is decimated on another thread (frames run in parallel) comes out the same as
// when decimated alone.
TEST(Decimate, GivesTheSameMeshBesideAnotherDecimation) {
  const Mesh fine = test::make_icosphere(5, 0.3f);  // 10,242 vertices: > 3 x the target
  const Mesh alone = decimate(fine, 1000);
  Mesh other_input = fine;
  for (Vec3f& p : other_input.positions) p *= 1.5f;
  Mesh beside, other;
  std::thread t([&] { other = decimate(other_input, 800); });
  beside = decimate(fine, 1000);
  t.join();
  ASSERT_EQ(beside.positions.size(), alone.positions.size());
  ASSERT_EQ(beside.triangles.size(), alone.triangles.size());
  for (std::size_t i = 0; i < alone.positions.size(); ++i) {
    ASSERT_EQ(beside.positions[i], alone.positions[i]) << "vertex " << i;
  }
  EXPECT_FALSE(other.triangles.empty());
}

TEST(Decimate, LeavesASmallMeshAlone) {
  const Mesh fine = test::fine_sphere(kRadius);
  const Mesh same = decimate(fine, static_cast<int>(fine.positions.size()) + 10);
  EXPECT_EQ(same.positions.size(), fine.positions.size());
  EXPECT_EQ(same.triangles.size(), fine.triangles.size());
}

TEST(Decimate, DropsTrianglesItCannotHoldAndTheVerticesLeftAlone) {
  Mesh mesh = test::make_icosphere(4, 0.3f);  // 2,562 vertices
  const int stray = static_cast<int>(mesh.positions.size());
  mesh.positions.push_back(Vec3f(1, 1, 1));
  mesh.positions.push_back(Vec3f(1, 1, 2));
  mesh.triangles.push_back({stray, stray, stray + 1});  // repeats a vertex
  const Mesh coarse = decimate(mesh, 500);
  EXPECT_LE(coarse.positions.size(), 500u);
  for (const Vec3f& p : coarse.positions) EXPECT_LT(p.norm(), 0.31f);
  EXPECT_EQ(check_manifold(coarse).handles, 0);
}

}  // namespace
}  // namespace fourd
