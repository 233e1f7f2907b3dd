#pragma once
// Mesh <-> CGAL Surface_mesh (exact predicates, inexact constructions). Includes CGAL, which is
// slow to compile: only pipeline/geometry's .cpp files that run CGAL's algorithms include this
// header; every other header of the library keeps CGAL out.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>

#include <string_view>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd::cgal {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;

// Adds `positions` (#V points with x(), y(), z(), in any precision) as vertices of `sm` (their
// handles in `*vertices`, if given), then `triangles` (#F, indices into positions) as faces in
// order, up to the first one `sm` refuses (it would make the surface non-manifold). Returns
// that triangle's index, or -1 when every one is in. For any Surface_mesh point type.
template <class SM, class Position>
long add_triangles(SM& sm, const std::vector<Position>& positions, const std::vector<Tri>& triangles,
                   std::vector<typename SM::Vertex_index>* vertices = nullptr) {
  using Point = typename SM::Point;
  std::vector<typename SM::Vertex_index> v;
  v.reserve(positions.size());
  for (const Position& p : positions) v.push_back(sm.add_vertex(Point(p.x(), p.y(), p.z())));
  long refused = -1;
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    const Tri& t = triangles[f];
    if (sm.add_face(v[t[0]], v[t[1]], v[t[2]]) == SM::null_face()) {
      refused = static_cast<long>(f);
      break;
    }
  }
  if (vertices) *vertices = std::move(v);
  return refused;
}

// The surface mesh of `mesh`'s positions (same order) and triangles. Throws InputError
// "<what>: triangle f (a, b, c) makes the surface non-manifold" at the first triangle it
// refuses.
SurfaceMesh to_surface_mesh(const Mesh& mesh, std::string_view what);

// Collects `sm`'s garbage (its indices become contiguous, in CGAL's order), then copies its
// vertices and faces. Positions and triangles.
Mesh from_surface_mesh(SurfaceMesh& sm);

}  // namespace fourd::cgal
