#pragma once
// Fast mesh simplification (OpenMesh's quadric-error decimater): the first, cheap step of
// remeshing a fine isosurface down to a few thousand vertices.
#include "pipeline/core/mesh.h"

namespace fourd {

// Collapses edges by increasing quadric error (Garland & Heckbert; down to 3 x the target by
// the best of a few random candidates at a time, which is faster), refusing collapses that
// flip a face normal by more than `max_normal_deviation_deg` (<= 0: no such check), until at
// most `target_vertices` remain (or no legal collapse is left). The surface's topology is kept
// (closed stays closed). Triangles a halfedge mesh cannot hold (non-manifold, repeating a
// vertex) are dropped, and so are the vertices left without a triangle. A mesh already at or
// below the target is returned unchanged.
Mesh decimate(const Mesh& mesh, int target_vertices, double max_normal_deviation_deg = 60);

}  // namespace fourd
