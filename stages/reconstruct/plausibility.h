#pragma once
// Checks of a frame's result against what its capture implies, so that a reconstruction that
// went wrong (options for another size of subject, silhouettes that disagree, a calibration
// that is off) is flagged instead of passing silently. Each check that fails is a warning
// naming the camera where one applies; none fails the frame.
//
//   - the hull's outline in a camera covers less than min_hull_coverage of its silhouette:
//     the silhouettes disagree across cameras (or the calibration does), the other cameras
//     carved away what this one saw;
//   - the mesh's outline covers less than min_mesh_coverage of a camera's silhouette, or more
//     than max_mesh_spill of it lies outside the silhouette;
//   - the mesh's volume or largest extent is below min_size_ratio of the hull's;
//   - the hull spans fewer than min_voxels voxels: the voxel size is too coarse for the subject.
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"
#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"

namespace fourd::reconstruct {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/reconstruct.md, "Advanced").
struct PlausibilityOptions {
  bool enabled = true;
  double min_hull_coverage = 0.5;  // warn when the hull's outline covers less of a camera's
                                   // silhouette
  double min_mesh_coverage = 0.8;  // ... or the mesh's outline
  double max_mesh_spill = 0.2;     // warn when more of the mesh's outline lies outside it
  double min_size_ratio = 0.25;    // warn when the mesh's volume or extent is below this
                                   // fraction of the hull's
  int min_voxels = 40;             // warn when the hull spans fewer voxels
  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "check every frame's result against its silhouettes and warn");
  }
};

// How a surface's outline in one camera compares with the camera's silhouette.
struct OutlineOverlap {
  double coverage = 0;  // fraction of the silhouette's pixels the outline covers
  double spill = 0;     // fraction of the outline's pixels outside the silhouette
};

// The outline of `mesh` seen by `camera` (its triangles filled, lens distortion at the
// vertices) against `silhouette` (CV_8UC1, nonzero = subject, the camera's image size).
OutlineOverlap outline_overlap(const Camera& camera, const Mesh& mesh, const cv::Mat& silhouette);

struct PlausibilityReport {
  std::vector<std::string> warnings;
  std::vector<OutlineOverlap> hull, mesh;  // per camera (mesh: empty when no mesh)
  double volume_ratio = 0, extent_ratio = 0;
};

// The checks above for one frame: `cameras[i]` saw `silhouettes[i]`; `mesh` may be empty (the
// frame failed). `voxel` is the hull's fine voxel size [m].
PlausibilityReport check_plausibility(const std::vector<Camera>& cameras,
                                      const std::vector<cv::Mat>& silhouettes,
                                      const Mesh& hull, const Mesh& mesh, double voxel,
                                      const PlausibilityOptions& options);

}  // namespace fourd::reconstruct
