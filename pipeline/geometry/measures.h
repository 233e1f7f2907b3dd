#pragma once
// Measures and neighbourhoods of a triangle mesh: area, enclosed volume, the vertices next to
// each vertex, and how far the mesh is from a closed manifold surface.
#include <Eigen/Geometry>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

// Area of one triangle of `mesh` [m^2], in double precision.
inline double triangle_area(const Mesh& mesh, const Tri& t) {
  const Eigen::Vector3d a = mesh.positions[t[0]].cast<double>();
  const Eigen::Vector3d b = mesh.positions[t[1]].cast<double>();
  const Eigen::Vector3d c = mesh.positions[t[2]].cast<double>();
  return 0.5 * (b - a).cross(c - a).norm();
}

// Strain of every edge of a deformed mesh: calls f(v, w, change) once per edge {v, w} of
// `rings` (one-rings of `rest`; by its lower-numbered end v), change = |p_v - p_w| / |r_v - r_w|
// - 1 for the deformed `positions` p and the rest positions r; edges of zero rest length are
// skipped.
template <class F>
void for_each_edge_strain(const Mesh& rest, const std::vector<std::vector<int>>& rings,
                          const std::vector<Vec3f>& positions, F&& f) {
  for (std::size_t v = 0; v < rings.size(); ++v) {
    for (int w : rings[v]) {
      if (static_cast<std::size_t>(w) <= v) continue;
      const double length = (rest.positions[v] - rest.positions[w]).norm();
      if (length <= 0) continue;
      f(v, w, (positions[v] - positions[w]).norm() / length - 1);
    }
  }
}

// Total triangle area [m^2].
double surface_area(const Mesh& mesh);

// Volume enclosed by a closed, outward-oriented mesh [m^3] (divergence theorem).
double enclosed_volume(const Mesh& mesh);

// Neighbours of every vertex through the triangles' edges (#V lists), sorted; no manifold
// requirement.
std::vector<std::vector<int>> edge_neighbours(const Mesh& mesh);

// Neighbours of every vertex (#V lists): its one-ring in circulation order (OpenMesh's). Throws
// InputError if the mesh is not manifold.
std::vector<std::vector<int>> vertex_neighbours(const Mesh& mesh);

// Edges used by exactly one triangle (the borders of holes).
int count_boundary_edges(const Mesh& mesh);

struct ManifoldReport {
  int non_manifold_edges = 0;  // edges shared by more than two triangles
  int rejected_faces = 0;      // triangles a halfedge mesh cannot hold (non-manifold vertex or
                               // edge, duplicated or degenerate triangle)
  int boundary_edges = 0;      // edges with one triangle (holes)
  int components = 0;          // connected components of the triangles
  // Handles (genus) summed over the components of a closed manifold mesh: 0 for a surface
  // like a sphere, 1 more for every tunnel, e.g. where an arm touching the body has merged
  // with it. -1 when the mesh has holes or is not manifold.
  int handles = -1;
  bool manifold() const { return non_manifold_edges == 0 && rejected_faces == 0; }
};

ManifoldReport check_manifold(const Mesh& mesh);

}  // namespace fourd
