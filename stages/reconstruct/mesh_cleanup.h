#pragma once
// Turning a raw reconstructed surface into the mesh later stages want: a given number of
// well-shaped triangles (the options of pipeline/geometry/remesh.h's remeshing; its largest
// component and hole filling are pipeline/geometry/components.h's and repair.h's).
#include <string>

#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"

namespace fourd::reconstruct {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/reconstruct.md, "Advanced").
struct RemeshOptions {
  int target_vertices = 5000;
  std::string mode = "relax";
  // Relaxation or remeshing iterations (0: decimation only). Each relaxation evens the
  // triangles out but moves vertices away from where the decimation put them on curved parts:
  // on the default sample (final vertices on the fused field) completeness 0.9509 with none,
  // 0.9503 with one, 0.9495 with three; triangles under 20 degrees 24 %, 9 %, 6 %.
  int iterations = 1;
  double decimate_factor = 1.5; // mode isotropic: first decimate to this many times the target
  template <class V>
  void visit(V& v) {
    v("target_vertices", target_vertices, "vertices of the final mesh (0: no remeshing)",
      Range{0, 10000000});
    v("mode", mode,
      "relax (quadric decimation to the target, its vertices gathering where the surface "
      "curves, then tangential relaxation into better-shaped triangles) | isotropic (decimation "
      "to 1.5 x the target, then isotropic remeshing to edges of one length); both end with "
      "every vertex on the input surface");
  }
};

// Remeshing to about `options.target_vertices` vertices (remesh_to_target of
// pipeline/geometry/remesh.h in the options' mode): quadric decimation (OpenMesh) down to the
// target (relax) or decimate_factor x target (isotropic), then relaxation or isotropic
// remeshing (CGAL) at the edge length that gives the target count on the mesh's area. With
// iterations = 0, quadric decimation straight to the target (well-placed vertices, less
// regular triangles; fast). Throws InputError when the mesh is not a manifold surface.
Mesh remesh(const Mesh& mesh, const RemeshOptions& options);

}  // namespace fourd::reconstruct
