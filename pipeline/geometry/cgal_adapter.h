#pragma once
// Mesh <-> CGAL Surface_mesh (exact predicates, inexact constructions). Includes CGAL, which is
// slow to compile: only pipeline/geometry's .cpp files that run CGAL's algorithms include this
// header; every other header of the library keeps CGAL out.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>

#include <string_view>

#include "pipeline/core/mesh.h"

namespace fourd::cgal {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;

// The surface mesh of `mesh`'s positions (same order) and triangles. Throws InputError
// "<what>: triangle f (a, b, c) makes the surface non-manifold" at the first triangle it
// refuses.
SurfaceMesh to_surface_mesh(const Mesh& mesh, std::string_view what);

// Collects `sm`'s garbage (its indices become contiguous, in CGAL's order), then copies its
// vertices and faces. Positions and triangles.
Mesh from_surface_mesh(SurfaceMesh& sm);

}  // namespace fourd::cgal
