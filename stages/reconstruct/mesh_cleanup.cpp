#include "stages/reconstruct/mesh_cleanup.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/manifoldness.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Polygon_mesh_processing/repair.h>
#include <CGAL/Polygon_mesh_processing/repair_degeneracies.h>
#include <CGAL/Polygon_mesh_processing/tangential_relaxation.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Surface_mesh.h>
#include <fmt/format.h>

#include <cmath>
#include <numeric>
#include <optional>

#include "pipeline/core/error.h"
#include "pipeline/geometry/mesh_query.h"
#include "stages/reconstruct/decimate.h"

namespace fourd::reconstruct {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;
namespace PMP = CGAL::Polygon_mesh_processing;

int find_root(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

// Throws InputError naming the first face CGAL refuses (non-manifold edge or vertex).
SurfaceMesh to_surface_mesh(const Mesh& mesh) {
  SurfaceMesh out;
  std::vector<SurfaceMesh::Vertex_index> v;
  v.reserve(mesh.positions.size());
  for (const Vec3f& p : mesh.positions) v.push_back(out.add_vertex(Kernel::Point_3(p.x(), p.y(), p.z())));
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    const Tri& t = mesh.triangles[f];
    if (out.add_face(v[t[0]], v[t[1]], v[t[2]]) == SurfaceMesh::null_face()) {
      throw InputError(fmt::format("remeshing: triangle {} ({}, {}, {}) makes the surface "
                                   "non-manifold", f, t[0], t[1], t[2]));
    }
  }
  return out;
}

Mesh from_surface_mesh(const SurfaceMesh& sm) {
  Mesh out;
  std::vector<int> index(sm.number_of_vertices() + sm.number_of_removed_vertices(), -1);
  for (auto v : sm.vertices()) {
    index[v.idx()] = static_cast<int>(out.positions.size());
    const auto& p = sm.point(v);
    out.positions.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                               static_cast<float>(p.z()));
  }
  for (auto f : sm.faces()) {
    Tri t;
    int k = 0;
    for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) t[k++] = index[v.idx()];
    out.triangles.push_back(t);
  }
  return out;
}

}  // namespace

Mesh keep_largest_component(const Mesh& mesh) {
  const int nv = static_cast<int>(mesh.positions.size());
  std::vector<int> parent(nv);
  std::iota(parent.begin(), parent.end(), 0);
  for (const Tri& t : mesh.triangles) {
    int a = find_root(parent, t[0]);
    for (int k = 1; k < 3; ++k) {
      int b = find_root(parent, t[k]);
      if (a != b) parent[b] = a;
    }
  }
  std::vector<double> area(nv, 0.0);
  for (const Tri& t : mesh.triangles) {
    const Vec3f& a = mesh.positions[t[0]];
    area[find_root(parent, t[0])] +=
        0.5 * (mesh.positions[t[1]] - a).cross(mesh.positions[t[2]] - a).norm();
  }
  if (mesh.triangles.empty()) return {};
  const int keep = static_cast<int>(std::max_element(area.begin(), area.end()) - area.begin());
  Mesh out;
  std::vector<int> index(nv, -1);
  for (const Tri& t : mesh.triangles) {
    if (find_root(parent, t[0]) != keep) continue;
    Tri nt;
    for (int k = 0; k < 3; ++k) {
      int& i = index[t[k]];
      if (i < 0) {
        i = static_cast<int>(out.positions.size());
        out.positions.push_back(mesh.positions[t[k]]);
      }
      nt[k] = i;
    }
    out.triangles.push_back(nt);
  }
  return out;
}

int fill_holes(Mesh& mesh) {
  SurfaceMesh sm = to_surface_mesh(mesh);
  std::vector<SurfaceMesh::Halfedge_index> cycles;
  PMP::extract_boundary_cycles(sm, std::back_inserter(cycles));
  if (cycles.empty()) return 0;
  for (auto h : cycles) {
    std::vector<SurfaceMesh::Face_index> faces;
    std::vector<SurfaceMesh::Vertex_index> vertices;
    PMP::triangulate_and_refine_hole(sm, h, std::back_inserter(faces), std::back_inserter(vertices));
  }
  sm.collect_garbage();
  mesh = from_surface_mesh(sm);
  return static_cast<int>(cycles.size());
}

Mesh remesh(const Mesh& mesh, const RemeshOptions& options) {
  if (options.target_vertices <= 0 || mesh.triangles.empty()) return mesh;
  const double target = options.target_vertices;
  const bool isotropic = options.mode == "isotropic";
  // Fast quadric decimation first (OpenMesh): CGAL's edge collapse and isotropic remeshing
  // cost seconds on a fine isosurface.
  const int decimated_vertices = static_cast<int>(
      std::lround(isotropic && options.iterations > 0 ? options.decimate_factor * target : target));
  Mesh coarse = decimate(mesh, decimated_vertices);
  if (options.iterations <= 0) return coarse;
  SurfaceMesh sm = to_surface_mesh(coarse);
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
  for (int i = 0; i < options.iterations; ++i) {
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
  sm.collect_garbage();
  return from_surface_mesh(sm);
}

}  // namespace fourd::reconstruct
