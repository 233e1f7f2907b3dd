#pragma once
// Surface remeshing and checks backed by CGAL (kept in one translation unit: CGAL is slow to
// compile). Internal to the synth stage.
#include "pipeline/core/mesh.h"

namespace fourd::synth::detail {

// Isotropic remeshing of a closed manifold mesh towards edges of `edge_length`: splits,
// collapses, flips and tangential smoothing with projection back onto the input surface
// (Botsch & Kobbelt 2004). Keeps it closed and manifold; deterministic. Positions only.
Mesh remesh_isotropic(const Mesh& mesh, double edge_length, int iterations);

// True if two non-adjacent triangles intersect.
bool has_self_intersections(const Mesh& mesh);

}  // namespace fourd::synth::detail
