#include "pipeline/geometry/cgal_adapter.h"

#include <fmt/format.h>

#include "pipeline/core/error.h"

namespace fourd::cgal {

SurfaceMesh to_surface_mesh(const Mesh& mesh, std::string_view what) {
  SurfaceMesh out;
  const long f = add_triangles(out, mesh.positions, mesh.triangles);
  if (f >= 0) {
    const Tri& t = mesh.triangles[f];
    throw InputError(fmt::format("{}: triangle {} ({}, {}, {}) makes the surface non-manifold",
                                 what, f, t[0], t[1], t[2]));
  }
  return out;
}

Mesh from_surface_mesh(SurfaceMesh& sm) {
  sm.collect_garbage();
  Mesh out;
  out.positions.reserve(sm.number_of_vertices());
  for (SurfaceMesh::Vertex_index v : sm.vertices()) {
    const Kernel::Point_3& p = sm.point(v);
    out.positions.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                               static_cast<float>(p.z()));
  }
  out.triangles.reserve(sm.number_of_faces());
  for (SurfaceMesh::Face_index f : sm.faces()) {
    Tri t;
    int k = 0;
    for (SurfaceMesh::Vertex_index v : CGAL::vertices_around_face(sm.halfedge(f), sm)) {
      t[k++] = static_cast<int>(v.idx());
    }
    out.triangles.push_back(t);
  }
  return out;
}

}  // namespace fourd::cgal
