#pragma once
// Halfedge-mesh work for alignment, backed by OpenMesh: manifold checks of the input frames,
// connected components, the template's isotropic remeshing to a vertex budget, and vertex
// neighbourhoods.
#include <vector>

#include "pipeline/core/mesh.h"
#include "stages/align/shape_descriptor.h"

namespace fourd::align {

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

// The zero set of the signed distance to `mesh`, sampled at the centres of `solid`'s voxels
// and signed by their occupancy (inside negative). Where the solid is the mesh's own the
// surface is the mesh's, to sub-voxel precision; where the solid was edited it follows the
// edit. Closed and manifold (the solid's border voxels must be empty).
Mesh surface_of_solid(const Mesh& mesh, const SolidGrid& solid);

// The mesh's surface without its handles thinner than a few voxels: noise tunnels of a
// reconstruction, or an arm merged with the body where it touched it. Its solid, voxelised at
// `voxel`, is closed then opened by r voxels for r = 1, 2, ... max_radius, and the first result
// whose largest component has no handle, holds all but 0.5 % of the result's volume (opening
// cut nothing off) and keeps at least `min_volume` of the input's volume is returned (its
// largest component); failing that, the one of the fewest handles, or the input itself when
// no result has fewer handles than it.
Mesh remove_small_handles(const Mesh& mesh, double voxel, int max_radius,
                          double min_volume = 0.98);

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
