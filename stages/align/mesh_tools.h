#pragma once
// Halfedge-mesh work for alignment, backed by OpenMesh: manifold checks of the input frames,
// connected components, the template's isotropic remeshing to a vertex budget, and vertex
// neighbourhoods.
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd::align {

struct ManifoldReport {
  int non_manifold_edges = 0;  // edges shared by more than two triangles
  int rejected_faces = 0;      // triangles a halfedge mesh cannot hold (non-manifold vertex or
                               // edge, duplicated or degenerate triangle)
  int boundary_edges = 0;      // edges with one triangle (holes)
  int components = 0;          // connected components of the triangles
  bool manifold() const { return non_manifold_edges == 0 && rejected_faces == 0; }
};

ManifoldReport check_manifold(const Mesh& mesh);

// The connected component (through shared vertices) with the largest surface area, with
// unused vertices dropped. Positions and triangles only.
Mesh largest_component(const Mesh& mesh);

// Total triangle area [m^2].
double surface_area(const Mesh& mesh);

// A closed manifold mesh of exactly `target_vertices` vertices with near-equilateral
// triangles approximating `mesh` (its largest component): isotropic remeshing (split, collapse,
// valence-equalising flips, tangential relaxation with projection back onto the input; Botsch
// & Kobbelt 2004), then quadric decimation or longest-edge splits for the last few vertices.
// Throws InputError if the input is empty or not manifold where it matters.
Mesh remesh_to_vertex_count(const Mesh& mesh, int target_vertices, int iterations = 10);

// Neighbours of every vertex (its one-ring, in circulation order). Throws InputError if the
// mesh is not manifold.
std::vector<std::vector<int>> vertex_neighbours(const Mesh& mesh);

// Neighbours of every vertex through the triangles' edges, sorted; no manifold requirement.
std::vector<std::vector<int>> edge_neighbours(const Mesh& mesh);

// Dijkstra along mesh edges (`rings`: neighbours of every vertex) from `source`, lowering
// `dist` where it finds shorter paths (so repeated calls give the distance to the nearest
// source) and recording `source_id` in `owner` there. Vertices farther than `radius` are not
// expanded. Returns the vertices it reached.
std::vector<int> geodesic_update(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                                 int source, int source_id, double radius,
                                 std::vector<double>& dist, std::vector<int>& owner);

}  // namespace fourd::align
