#pragma once
// Connected components of a triangle mesh: triangles that share a vertex are connected.
//
// The largest component is the one of largest surface area, not the one of most triangles:
// area is a property of the surface, the triangle count one of its tessellation, and a small
// finely tessellated piece (a reconstruction's noisy blob of tiny triangles) can outnumber a
// large coarse one. On the uniform isosurfaces the stages cut (reconstruction, the synthetic
// performer's implicit body) the two criteria pick the same component, the body.
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

// The component of every vertex (#V): 0, 1, ... numbered in the order of each component's
// first triangle; -1 for a vertex no triangle uses. `*count` (if given) gets the number of
// components.
std::vector<int> vertex_components(const Mesh& mesh, int* count = nullptr);

// The number of connected components of the triangles.
int count_components(const Mesh& mesh);

// The component of largest surface area (ties: the one numbered first), its vertices
// renumbered in the order its triangles first use them. Positions and triangles only; empty
// for a mesh without triangles.
Mesh largest_component(const Mesh& mesh);

}  // namespace fourd
