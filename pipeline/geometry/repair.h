#pragma once
// Repairs and checks of a closed surface with CGAL (kept in repair.cpp).
#include "pipeline/core/mesh.h"

namespace fourd {

// Closes every hole (boundary loop) of a manifold mesh with a triangulated, refined and faired
// patch. Returns the number of holes filled (the mesh is untouched when there is none). Throws
// InputError when the mesh is not a manifold surface.
int fill_holes(Mesh& mesh);

// True if two non-adjacent triangles intersect. Throws InputError when the mesh is not a
// manifold surface.
bool has_self_intersections(const Mesh& mesh);

}  // namespace fourd
