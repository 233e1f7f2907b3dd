#pragma once
// Remeshing a closed surface into well-shaped triangles: towards an edge length or a vertex
// count with CGAL (remesh.cpp), to an exact vertex count with OpenMesh (remesh_vertex_count.cpp).
#include "pipeline/core/mesh.h"

namespace fourd {

// Isotropic remeshing of a closed manifold mesh towards edges of `edge_length` [m]: splits,
// collapses, flips and tangential smoothing (3 steps per iteration) with projection back onto
// the input surface (Botsch & Kobbelt 2004). Keeps it closed and manifold; deterministic.
// Positions and triangles. Throws InputError when the mesh is not a manifold surface.
Mesh remesh_isotropic(const Mesh& mesh, double edge_length, int iterations);

enum class RemeshMode {
  kRelax,      // quadric decimation to the target (its vertices gather where the surface
               // curves), then tangential relaxation into better-shaped triangles
  kIsotropic,  // decimation to decimate_factor x the target, then isotropic remeshing to
               // edges of one length
};

// Remeshing to about `target_vertices` vertices: quadric decimation (decimate.h) down to the
// target (kRelax, or iterations = 0) or decimate_factor x target (kIsotropic), then
// `iterations` rounds of [one isotropic remeshing pass at the edge length that gives the
// target count on the mesh's area (kIsotropic)] and one tangential relaxation step, each
// round ending with every vertex put back on the input surface. The decimated surface is
// repaired first (degenerate faces, pinched vertices). With target_vertices <= 0 or no
// triangles, the mesh itself. Throws SolverError when the decimated surface is not a valid
// polygon mesh, InputError when it is not a manifold surface.
Mesh remesh_to_target(const Mesh& mesh, int target_vertices, RemeshMode mode, int iterations,
                      double decimate_factor);

// A closed manifold mesh of exactly `target_vertices` vertices with near-equilateral
// triangles approximating `mesh` (its largest component): isotropic remeshing (split, collapse,
// valence-equalising flips, tangential relaxation with projection back onto the input; Botsch
// & Kobbelt 2004), then quadric decimation or longest-edge splits for the last few vertices.
// Throws InputError if the input is empty or not manifold where it matters.
Mesh remesh_to_vertex_count(const Mesh& mesh, int target_vertices, int iterations = 10);

}  // namespace fourd
