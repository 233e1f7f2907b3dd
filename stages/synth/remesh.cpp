#include "stages/synth/remesh.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <vector>

#include "pipeline/core/error.h"

namespace fourd::synth::detail {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;
namespace PMP = CGAL::Polygon_mesh_processing;

SurfaceMesh to_surface_mesh(const Mesh& mesh) {
  SurfaceMesh out;
  std::vector<SurfaceMesh::Vertex_index> vertex;
  vertex.reserve(mesh.positions.size());
  for (const Vec3f& p : mesh.positions) vertex.push_back(out.add_vertex(Kernel::Point_3(p.x(), p.y(), p.z())));
  for (const Tri& t : mesh.triangles) {
    if (out.add_face(vertex[static_cast<std::size_t>(t[0])], vertex[static_cast<std::size_t>(t[1])],
                     vertex[static_cast<std::size_t>(t[2])]) == SurfaceMesh::null_face()) {
      throw InputError("remeshing: the input mesh is not an oriented 2-manifold");
    }
  }
  return out;
}

Mesh from_surface_mesh(SurfaceMesh& sm) {
  sm.collect_garbage();  // indices become contiguous
  Mesh out;
  out.positions.reserve(sm.number_of_vertices());
  for (SurfaceMesh::Vertex_index v : sm.vertices()) {
    const Kernel::Point_3& p = sm.point(v);
    out.positions.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
  }
  out.triangles.reserve(sm.number_of_faces());
  for (SurfaceMesh::Face_index f : sm.faces()) {
    Tri t;
    int c = 0;
    for (SurfaceMesh::Vertex_index v : vertices_around_face(sm.halfedge(f), sm)) t[c++] = static_cast<int>(v.idx());
    out.triangles.push_back(t);
  }
  return out;
}

}  // namespace

Mesh remesh_isotropic(const Mesh& mesh, double edge_length, int iterations) {
  SurfaceMesh sm = to_surface_mesh(mesh);
  PMP::isotropic_remeshing(faces(sm), edge_length, sm,
                           PMP::parameters::number_of_iterations(static_cast<unsigned>(iterations))
                               .number_of_relaxation_steps(3));
  return from_surface_mesh(sm);
}

bool has_self_intersections(const Mesh& mesh) {
  SurfaceMesh sm = to_surface_mesh(mesh);
  return PMP::does_self_intersect(sm);
}

}  // namespace fourd::synth::detail
