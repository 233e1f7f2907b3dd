#pragma once
// Mesh work particular to alignment: the template's isotropic remeshing to a vertex budget
// (OpenMesh, with projection by align's surface query), the removal of thin handles, and
// geodesic distances. The general mesh algorithms are in pipeline/geometry/.
#include <vector>

#include "pipeline/core/mesh.h"
#include "stages/align/shape_descriptor.h"

namespace fourd::align {

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

// Dijkstra along mesh edges (`rings`: neighbours of every vertex) from `source`, lowering
// `dist` where it finds shorter paths (so repeated calls give the distance to the nearest
// source) and recording `source_id` in `owner` there. Vertices farther than `radius` are not
// expanded. Returns the vertices it reached.
std::vector<int> geodesic_update(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                                 int source, int source_id, double radius,
                                 std::vector<double>& dist, std::vector<int>& owner);

}  // namespace fourd::align
