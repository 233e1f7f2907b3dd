#include "pipeline/geometry/repair.h"

#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>

#include <iterator>
#include <vector>

#include "pipeline/geometry/cgal_adapter.h"

namespace fourd {
namespace {

using cgal::SurfaceMesh;
namespace PMP = CGAL::Polygon_mesh_processing;

}  // namespace

int fill_holes(Mesh& mesh) {
  SurfaceMesh sm = cgal::to_surface_mesh(mesh, "hole filling");
  std::vector<SurfaceMesh::Halfedge_index> cycles;
  PMP::extract_boundary_cycles(sm, std::back_inserter(cycles));
  if (cycles.empty()) return 0;
  for (auto h : cycles) {
    std::vector<SurfaceMesh::Face_index> faces;
    std::vector<SurfaceMesh::Vertex_index> vertices;
    PMP::triangulate_and_refine_hole(sm, h, std::back_inserter(faces), std::back_inserter(vertices));
  }
  mesh = cgal::from_surface_mesh(sm);
  return static_cast<int>(cycles.size());
}

bool has_self_intersections(const Mesh& mesh) {
  const SurfaceMesh sm = cgal::to_surface_mesh(mesh, "self-intersection check");
  return PMP::does_self_intersect(sm);
}

}  // namespace fourd
