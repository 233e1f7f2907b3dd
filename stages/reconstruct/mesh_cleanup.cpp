#include "stages/reconstruct/mesh_cleanup.h"

#include "pipeline/geometry/remesh.h"

namespace fourd::reconstruct {

Mesh remesh(const Mesh& mesh, const RemeshOptions& options) {
  return remesh_to_target(mesh, options.target_vertices,
                          options.mode == "isotropic" ? RemeshMode::kIsotropic : RemeshMode::kRelax,
                          options.iterations, options.decimate_factor);
}

}  // namespace fourd::reconstruct
