// Remeshing a fine isosurface down to a vertex count: quadric decimation (OpenMesh) and the
// relaxation or isotropic remeshing after it keep the surface closed and on the shape.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <thread>

#include "pipeline/core/isosurface.h"
#include "pipeline/core/mesh_io.h"
#include "stages/reconstruct/decimate.h"
#include "stages/reconstruct/mesh_cleanup.h"
#include "tests/test_shapes.h"

namespace fourd::reconstruct {
namespace {

constexpr double kRadius = 0.3;

// A sphere of radius kRadius as the isosurface of its distance field on an 8 mm grid
// (over 10k vertices, a fine isosurface to bring down to a few thousand).
Mesh fine_sphere() {
  ScalarGrid g;
  g.voxel = 0.008;
  g.nx = g.ny = g.nz = 86;
  g.origin = Eigen::Vector3d::Constant(-0.34);
  g.values.resize(static_cast<std::size_t>(g.nx) * g.ny * g.nz);
  for (int z = 0; z < g.nz; ++z)
    for (int y = 0; y < g.ny; ++y)
      for (int x = 0; x < g.nx; ++x)
        g.values[g.index(x, y, z)] = static_cast<float>(g.point(x, y, z).norm() - kRadius);
  return extract_isosurface(g, 0.0f);
}

std::size_t boundary_edges(const Mesh& mesh) {
  std::map<std::pair<int, int>, int> edges;
  for (const Tri& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      int a = t[k], b = t[(k + 1) % 3];
      edges[{std::min(a, b), std::max(a, b)}] += 1;
    }
  }
  std::size_t n = 0;
  for (const auto& [e, count] : edges) n += count != 2;
  return n;
}

double max_radial_error(const Mesh& mesh) {
  double worst = 0;
  for (const Vec3f& p : mesh.positions) worst = std::max(worst, std::abs(p.cast<double>().norm() - kRadius));
  return worst;
}

// Fraction of the triangles whose smallest angle is below `degrees`.
double share_of_thin_triangles(const Mesh& mesh, double degrees) {
  std::size_t thin = 0;
  for (const Tri& t : mesh.triangles) {
    double smallest = 180;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = mesh.positions[t[k]].cast<double>();
      const Eigen::Vector3d u = mesh.positions[t[(k + 1) % 3]].cast<double>() - p;
      const Eigen::Vector3d w = mesh.positions[t[(k + 2) % 3]].cast<double>() - p;
      smallest = std::min(smallest, std::atan2(u.cross(w).norm(), u.dot(w)) * 180 / M_PI);
    }
    thin += smallest < degrees;
  }
  return mesh.triangles.empty() ? 0.0 : double(thin) / mesh.triangles.size();
}

// Closed mesh: V - E + F = 2 for a sphere.
int euler(const Mesh& mesh) {
  std::map<std::pair<int, int>, int> edges;
  for (const Tri& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) edges[{std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])}];
  return static_cast<int>(mesh.positions.size()) - static_cast<int>(edges.size()) +
         static_cast<int>(mesh.triangles.size());
}

TEST(MeshCleanup, DecimateReachesTheTargetAndStaysOnTheSphere) {
  const Mesh fine = fine_sphere();
  ASSERT_GT(fine.positions.size(), 10000u);
  const Mesh coarse = decimate(fine, 3000);
  EXPECT_LE(coarse.positions.size(), 3000u);
  EXPECT_GE(coarse.positions.size(), 2900u);
  EXPECT_EQ(boundary_edges(coarse), 0u);
  EXPECT_EQ(euler(coarse), 2);
  EXPECT_LT(max_radial_error(coarse), 0.002);
}

// The first, multiple-choice stage of decimation draws from rand(): a mesh decimated while
// another one is decimated on another thread (frames run in parallel) comes out the same as
// when decimated alone.
TEST(MeshCleanup, DecimateGivesTheSameMeshBesideAnotherDecimation) {
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

TEST(MeshCleanup, DecimateLeavesASmallMeshAlone) {
  const Mesh fine = fine_sphere();
  const Mesh same = decimate(fine, static_cast<int>(fine.positions.size()) + 10);
  EXPECT_EQ(same.positions.size(), fine.positions.size());
  EXPECT_EQ(same.triangles.size(), fine.triangles.size());
}

TEST(MeshCleanup, RelaxedRemeshKeepsTheCountAndShapesTheTriangles) {
  const Mesh fine = fine_sphere();
  RemeshOptions options;
  options.target_vertices = 2000;
  options.iterations = 0;  // decimation only
  const Mesh quick = remesh(fine, options);
  EXPECT_LE(quick.positions.size(), 2000u);
  EXPECT_GE(quick.positions.size(), 1900u);
  EXPECT_LT(max_radial_error(quick), 0.002);

  options.mode = "relax";
  options.iterations = 3;
  const Mesh relaxed = remesh(fine, options);
  EXPECT_EQ(relaxed.positions.size(), quick.positions.size());
  EXPECT_EQ(boundary_edges(relaxed), 0u);
  EXPECT_EQ(euler(relaxed), 2);
  // Relaxed along the surface, then put back onto it: as close to the sphere as the input.
  EXPECT_LT(max_radial_error(relaxed), 0.001);
  const double thin_before = share_of_thin_triangles(quick, 20.0);
  const double thin_after = share_of_thin_triangles(relaxed, 20.0);
  EXPECT_LT(thin_after, 0.5 * thin_before) << thin_before << " -> " << thin_after;
}

TEST(MeshCleanup, IsotropicRemeshGivesAboutTheTargetCountOnTheShape) {
  const Mesh fine = fine_sphere();
  RemeshOptions options;
  options.mode = "isotropic";
  options.target_vertices = 2000;
  options.iterations = 2;
  const Mesh out = remesh(fine, options);
  // Isotropic remeshing splits and collapses around the target edge length: about the count.
  EXPECT_NEAR(static_cast<double>(out.positions.size()), 2000.0, 600.0);
  EXPECT_EQ(boundary_edges(out), 0u);
  EXPECT_EQ(euler(out), 2);
  EXPECT_LT(max_radial_error(out), 0.001);
  EXPECT_LT(share_of_thin_triangles(out, 20.0), 0.01);
}

// Two spheres pinched together at one shared vertex, plus a stray vertex and a zero-area
// triangle: what a fused surface can look like where two limbs touch. Remeshing must return a
// valid mesh (or refuse with an Error), never crash.
TEST(MeshCleanup, RemeshSurvivesPinchedAndDegenerateInput) {
  Mesh a = test::make_icosphere(4, 0.2f), b = test::make_icosphere(4, 0.2f);
  const int n = static_cast<int>(a.positions.size());
  for (Vec3f& p : b.positions) p += Vec3f(0.4f, 0, 0);
  // b's vertex nearest to a's rightmost vertex becomes that vertex: one pinched vertex.
  int a_right = 0, b_left = 0;
  for (int i = 0; i < n; ++i) {
    if (a.positions[i].x() > a.positions[a_right].x()) a_right = i;
    if (b.positions[i].x() < b.positions[b_left].x()) b_left = i;
  }
  Mesh m = a;
  m.positions.insert(m.positions.end(), b.positions.begin(), b.positions.end());
  for (Tri t : b.triangles) {
    for (int& v : t) v = v == b_left ? a_right : v + n;
    m.triangles.push_back(t);
  }
  m.positions.push_back(Vec3f(5, 5, 5));  // stray
  const int d = static_cast<int>(m.positions.size());
  m.positions.push_back(Vec3f(1, 1, 1));
  m.positions.push_back(Vec3f(1, 1, 1));
  m.positions.push_back(Vec3f(1, 1, 1));
  m.triangles.push_back({d, d + 1, d + 2});  // zero area
  for (const char* mode : {"relax", "isotropic"}) {
    SCOPED_TRACE(mode);
    RemeshOptions options;
    options.mode = mode;
    options.target_vertices = 1500;
    Mesh out;
    try {
      out = remesh(m, options);
    } catch (const Error&) {
      continue;  // refusing with a clear error is acceptable; crashing is not
    }
    ASSERT_FALSE(out.triangles.empty());
    for (const Tri& t : out.triangles) {
      for (int v : t) {
        ASSERT_GE(v, 0);
        ASSERT_LT(v, static_cast<int>(out.positions.size()));
      }
    }
  }
}

// A decimated fused surface (one noisy frame) on which CGAL 5.5's isotropic remeshing left a
// vertex with only degenerate faces and its tangential relaxation crashed. Remeshing it now
// gives a closed mesh of about the target size.
TEST(MeshCleanup, RemeshSurvivesAVertexLeftWithOnlyDegenerateFaces) {
  const Mesh m = read_ply(std::filesystem::path(FOURD_SOURCE_DIR) / "tests/reconstruct/data/remesh_crash.ply");
  RemeshOptions options;
  options.mode = "isotropic";
  const Mesh out = remesh(m, options);
  EXPECT_NEAR(static_cast<double>(out.positions.size()), 5000.0, 1000.0);
  EXPECT_EQ(boundary_edges(out), 0u);
}

}  // namespace
}  // namespace fourd::reconstruct
