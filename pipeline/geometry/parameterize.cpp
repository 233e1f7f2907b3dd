#include "pipeline/geometry/parameterize.h"

#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh_parameterization/ARAP_parameterizer_3.h>
#include <CGAL/Surface_mesh_parameterization/LSCM_parameterizer_3.h>
#include <CGAL/Surface_mesh_parameterization/parameterize.h>

#include "pipeline/geometry/cgal_adapter.h"

namespace fourd {
namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;
using VertexIndex = SurfaceMesh::Vertex_index;
namespace smp = CGAL::Surface_mesh_parameterization;
namespace pmp = CGAL::Polygon_mesh_processing;

}  // namespace

bool flatten_chart(const std::vector<Eigen::Vector3d>& positions, const std::vector<Tri>& triangles,
                   FlattenMethod method, std::vector<Eigen::Vector2d>* uv) {
  if (triangles.empty()) return false;
  SurfaceMesh mesh;
  std::vector<VertexIndex> vertices;
  // A refused triangle would make the chart non-manifold.
  if (cgal::add_triangles(mesh, positions, triangles, &vertices) >= 0) return false;
  // A disc: one border loop, Euler characteristic 1, no isolated vertices.
  std::vector<SurfaceMesh::Halfedge_index> borders;
  pmp::extract_boundary_cycles(mesh, std::back_inserter(borders));
  const long euler = static_cast<long>(mesh.number_of_vertices()) -
                     static_cast<long>(mesh.number_of_edges()) +
                     static_cast<long>(mesh.number_of_faces());
  if (borders.size() != 1 || euler != 1) return false;
  for (VertexIndex v : mesh.vertices()) {
    if (mesh.is_isolated(v)) return false;
  }

  auto uv_map = mesh.add_property_map<VertexIndex, Kernel::Point_2>("v:uv").first;
  const SurfaceMesh::Halfedge_index border = borders.front();
  smp::Error_code status;
  try {
    if (method == FlattenMethod::kLscm) {
      status = smp::parameterize(mesh, smp::LSCM_parameterizer_3<SurfaceMesh>(), border, uv_map);
    } else {
      status = smp::parameterize(mesh, smp::ARAP_parameterizer_3<SurfaceMesh>(), border, uv_map);
    }
  } catch (const std::exception&) {  // CGAL precondition failures on degenerate charts
    return false;
  }
  if (status != smp::OK) return false;
  std::vector<Eigen::Vector2d> out(positions.size());
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const Kernel::Point_2& q = uv_map[vertices[i]];
    out[i] = {q.x(), q.y()};
    if (!out[i].allFinite()) return false;
  }
  *uv = std::move(out);
  return true;
}

}  // namespace fourd
