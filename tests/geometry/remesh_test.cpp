// Remeshing: CGAL's isotropic remesher of a closed surface, remeshing to a vertex target
// (decimation, then relaxation or isotropic remeshing) and OpenMesh's remeshing to an exact
// vertex count keep the surface closed and on the shape.
#include "pipeline/geometry/remesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "pipeline/core/error.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/geometry/measures.h"
#include "tests/test_shapes.h"

namespace fourd {
namespace {

constexpr double kRadius = 0.3;

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

// A closed surface of one component without handles: a sphere's topology.
void expect_sphere_topology(const Mesh& mesh) {
  const ManifoldReport report = check_manifold(mesh);
  EXPECT_TRUE(report.manifold());
  EXPECT_EQ(report.boundary_edges, 0);
  EXPECT_EQ(report.components, 1);
  EXPECT_EQ(report.handles, 0);
}

TEST(Remesh, IsotropicReachesTheEdgeLengthOnAClosedSurface) {
  const Mesh sphere = test::make_icosphere(4, static_cast<float>(kRadius));  // 2,562 vertices
  // Towards edges of L = 30 mm: CGAL splits edges over 4/3 L and collapses those under 4/5 L,
  // so on the sphere's 1.13 m^2 (2 A / (sqrt(3) l^2) vertices for edges of l) there are more
  // vertices than at 4/3 L (816) and fewer than at 4/5 L (2,266).
  const double edge = 0.03;
  const Mesh out = remesh_isotropic(sphere, edge, 3);
  EXPECT_GT(out.num_vertices(), 816u);
  EXPECT_LT(out.num_vertices(), 2266u);
  double longest = 0;
  for (const Tri& t : out.triangles) {
    for (int k = 0; k < 3; ++k) {
      longest = std::max(longest, static_cast<double>((out.positions[t[k]] - out.positions[t[(k + 1) % 3]]).norm()));
    }
  }
  EXPECT_LT(longest, 1.1 * 4.0 / 3.0 * edge);
  expect_sphere_topology(out);
  EXPECT_LT(test::max_radial_error(out, kRadius), 0.002);
  EXPECT_LT(share_of_thin_triangles(out, 20.0), 0.02);
  Mesh open = sphere;
  open.positions.push_back(Vec3f(0, 0, 2));
  open.triangles.push_back({open.triangles[0][0], open.triangles[0][1], 2562});  // a fin
  EXPECT_THROW(remesh_isotropic(open, 0.03, 1), InputError);
}

TEST(Remesh, RelaxedKeepsTheCountAndShapesTheTriangles) {
  const Mesh fine = test::fine_sphere(kRadius);
  const Mesh quick = remesh_to_target(fine, 2000, RemeshMode::kRelax, 0, 1.5);  // decimation only
  EXPECT_LE(quick.positions.size(), 2000u);
  EXPECT_GE(quick.positions.size(), 1900u);
  EXPECT_LT(test::max_radial_error(quick, kRadius), 0.002);

  const Mesh relaxed = remesh_to_target(fine, 2000, RemeshMode::kRelax, 3, 1.5);
  EXPECT_EQ(relaxed.positions.size(), quick.positions.size());
  expect_sphere_topology(relaxed);
  // Relaxed along the surface, then put back onto it: as close to the sphere as the input.
  EXPECT_LT(test::max_radial_error(relaxed, kRadius), 0.001);
  const double thin_before = share_of_thin_triangles(quick, 20.0);
  const double thin_after = share_of_thin_triangles(relaxed, 20.0);
  EXPECT_LT(thin_after, 0.5 * thin_before) << thin_before << " -> " << thin_after;
  EXPECT_EQ(remesh_to_target(fine, 0, RemeshMode::kRelax, 3, 1.5).positions, fine.positions);
}

TEST(Remesh, IsotropicToTargetGivesAboutTheCountOnTheShape) {
  const Mesh fine = test::fine_sphere(kRadius);
  const Mesh out = remesh_to_target(fine, 2000, RemeshMode::kIsotropic, 2, 1.5);
  // Isotropic remeshing splits and collapses around the target edge length: about the count.
  EXPECT_NEAR(static_cast<double>(out.positions.size()), 2000.0, 600.0);
  expect_sphere_topology(out);
  EXPECT_LT(test::max_radial_error(out, kRadius), 0.001);
  EXPECT_LT(share_of_thin_triangles(out, 20.0), 0.01);
}

TEST(Remesh, ToVertexCountIsExactClosedAndOnTheShape) {
  // The alignment template's remesher (OpenMesh): exactly the budget, whatever the input's.
  const Mesh fine = test::fine_sphere(kRadius);
  for (int target : {500, 2001}) {
    const Mesh out = remesh_to_vertex_count(fine, target);
    EXPECT_EQ(static_cast<int>(out.positions.size()), target);
    expect_sphere_topology(out);
    EXPECT_LT(test::max_radial_error(out, kRadius), 0.003);
    EXPECT_LT(share_of_thin_triangles(out, 20.0), 0.02);
  }
  EXPECT_THROW(remesh_to_vertex_count(Mesh{}, 100), InputError);
}

// Two spheres pinched together at one shared vertex, plus a stray vertex and a zero-area
// triangle: what a fused surface can look like where two limbs touch. Remeshing must return a
// valid mesh (or refuse with an Error), never crash.
TEST(Remesh, ToTargetSurvivesPinchedAndDegenerateInput) {
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
  for (const RemeshMode mode : {RemeshMode::kRelax, RemeshMode::kIsotropic}) {
    SCOPED_TRACE(static_cast<int>(mode));
    Mesh out;
    try {
      out = remesh_to_target(m, 1500, mode, 1, 1.5);
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
TEST(Remesh, ToTargetSurvivesAVertexLeftWithOnlyDegenerateFaces) {
  const Mesh m = read_ply(std::filesystem::path(FOURD_SOURCE_DIR) / "tests/geometry/data/remesh_crash.ply");
  const Mesh out = remesh_to_target(m, 5000, RemeshMode::kIsotropic, 1, 1.5);
  EXPECT_NEAR(static_cast<double>(out.positions.size()), 5000.0, 1000.0);
  EXPECT_EQ(check_manifold(out).boundary_edges, 0);
}

}  // namespace
}  // namespace fourd
