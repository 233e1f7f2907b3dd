#include "pipeline/geometry/remesh.h"

#include <CGAL/Polygon_mesh_processing/manifoldness.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Polygon_mesh_processing/repair.h>
#include <CGAL/Polygon_mesh_processing/repair_degeneracies.h>
#include <CGAL/Polygon_mesh_processing/tangential_relaxation.h>

#include <cmath>
#include <optional>

#include "pipeline/core/error.h"
#include "pipeline/geometry/cgal_adapter.h"
#include "pipeline/geometry/decimate.h"
#include "pipeline/geometry/mesh_query.h"

namespace fourd {
namespace {

using cgal::Kernel;
using cgal::SurfaceMesh;
namespace PMP = CGAL::Polygon_mesh_processing;

}  // namespace

Mesh remesh_isotropic(const Mesh& mesh, double edge_length, int iterations) {
  SurfaceMesh sm = cgal::to_surface_mesh(mesh, "remeshing");
  PMP::isotropic_remeshing(faces(sm), edge_length, sm,
                           PMP::parameters::number_of_iterations(static_cast<unsigned>(iterations))
                               .number_of_relaxation_steps(3));
  return cgal::from_surface_mesh(sm);
}

Mesh remesh_to_target(const Mesh& mesh, int target_vertices, RemeshMode mode, int iterations,
                      double decimate_factor) {
  if (target_vertices <= 0 || mesh.triangles.empty()) return mesh;
  const double target = target_vertices;
  const bool isotropic = mode == RemeshMode::kIsotropic;
  // Fast quadric decimation first (OpenMesh): CGAL's edge collapse and isotropic remeshing
  // cost seconds on a fine isosurface.
  const int decimated_vertices = static_cast<int>(
      std::lround(isotropic && iterations > 0 ? decimate_factor * target : target));
  Mesh coarse = decimate(mesh, decimated_vertices);
  if (iterations <= 0) return coarse;
  SurfaceMesh sm = cgal::to_surface_mesh(coarse, "remeshing");
  // Decimation can leave pinched vertices, needles and caps; CGAL's tangential relaxation
  // dereferences the fan of every vertex and crashes on such a mesh, so repair it first.
  PMP::remove_degenerate_faces(sm);
  PMP::duplicate_non_manifold_vertices(sm);
  PMP::remove_isolated_vertices(sm);
  sm.collect_garbage();
  if (!CGAL::is_valid_polygon_mesh(sm) || sm.number_of_faces() == 0) {
    throw SolverError("remeshing: the decimated surface is not a valid polygon mesh");
  }
  // The input surface (as a triangle soup: it need not be a valid polygon mesh), to put the
  // vertices back on after each step: relaxation moves them along the tangent planes, off a
  // curved surface, and the remeshing's own projection is onto the decimated mesh.
  std::optional<MeshQuery> input;
  try {
    input.emplace(mesh);
  } catch (const InputError&) {
    // No non-degenerate input triangle: nothing to put the vertices back on.
  }
  auto project = [&] {
    if (!input) return;
    for (auto v : vertices(sm)) {
      const Kernel::Point_3& p = sm.point(v);
      const Vec3f q = input->closest(Vec3f(p.x(), p.y(), p.z())).point;
      sm.point(v) = Kernel::Point_3(q.x(), q.y(), q.z());
    }
  };
  // Equilateral triangles of side L cover the area A with 2V faces: A = 2V (sqrt(3)/4) L^2.
  const double edge = std::sqrt(2.0 * PMP::area(sm) / (std::sqrt(3.0) * target));
  // Isotropic: one remeshing iteration at a time, its tangential relaxation run separately:
  // the split/collapse/flip pass can leave a vertex whose faces are all degenerate, and the
  // relaxation inside CGAL 5.5's isotropic_remeshing then looks up the edge of a null
  // halfedge and crashes. Degenerate faces are removed before each relaxation instead.
  for (int i = 0; i < iterations; ++i) {
    if (isotropic) {
      PMP::isotropic_remeshing(
          faces(sm), edge, sm,
          CGAL::parameters::number_of_iterations(1).number_of_relaxation_steps(0));
      sm.collect_garbage();
      PMP::remove_degenerate_faces(sm);
      sm.collect_garbage();
    }
    PMP::tangential_relaxation(vertices(sm), sm, CGAL::parameters::number_of_iterations(1));
    project();
  }
  return cgal::from_surface_mesh(sm);
}

}  // namespace fourd
