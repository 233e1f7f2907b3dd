#pragma once
// Visual hull from calibrated silhouettes, as a signed distance-like field on a voxel grid:
// for every voxel, the largest over cameras of the silhouette's signed distance at its
// projection (pixels, negative inside), scaled to metres by depth / focal length. Its zero
// level set is the hull surface, located to sub-voxel precision.
#include <opencv2/core.hpp>
#include <vector>

#include "pipeline/core/camera.h"
#include "pipeline/core/config.h"
#include "pipeline/core/isosurface.h"
#include "pipeline/core/mesh.h"

namespace fourd::reconstruct {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/reconstruct.md, "Advanced"); internal_lengths() lists the tuned lengths
// scaled to the subject.
struct VisualHullOptions {
  double voxel_size = 0.006;
  double coarse_voxel = 0.08;   // first pass over the whole volume [m]
  double margin = 0.03;         // added around the coarse bounding box [m]
  int block = 8;                // fine voxels per block edge; blocks far from the surface are skipped
  std::vector<double> volume_min = {-3.0, -3.0, -0.05};
  std::vector<double> volume_max = {3.0, 3.0, 2.4};
  int min_views = 2;            // a point seen by fewer cameras cannot be carved and counts as outside
  double min_view_fraction = 0.75;

  template <class V>
  void visit(V& v) {
    v("voxel_size", voxel_size, "fine voxel size [m]", Length{1e-5, 0.1});
    v("volume_min", volume_min,
      "capture volume searched, lower corner [m] (unset: the volume the cameras share, "
      "subject.h)");
    v("volume_max", volume_max,
      "capture volume searched, upper corner [m] (unset: the volume the cameras share)");
    v("min_view_fraction", min_view_fraction,
      "fraction of the cameras that must see a point (and at least 2): the performer is seen by "
      "every camera, while a point near the volume's border seen by only two opposite cameras, in "
      "line with the performer, would be a phantom part of the hull (with 4 cameras it can "
      "outgrow the body)",
      Range{0, 1});
  }
  template <class V>
  void internal_lengths(V& v) {
    v("coarse_voxel", coarse_voxel, "", Length{1e-4, 0.5});
    v("margin", margin, "", Length{0, 1});
  }
  void check() const;
};

// Signed distance of every pixel centre to the silhouette boundary [px], negative inside:
// the boundary lies half-way between a foreground and a background pixel centre.
cv::Mat silhouette_signed_distance(const cv::Mat& silhouette);

class VisualHull {
 public:
  // `silhouettes[i]` (CV_8UC1, nonzero = foreground) belongs to `cameras[i]`.
  VisualHull(const std::vector<Camera>& cameras, const std::vector<cv::Mat>& silhouettes,
             const VisualHullOptions& options);

  // Hull field at a world point [m], negative inside, NaN-free.
  float value(const Eigen::Vector3d& point) const;
  // The field on the fine grid around the hull (blocks far from the surface hold a
  // conservative constant of the right sign). Empty grid (nx == 0) when nothing is inside.
  ScalarGrid grid() const;
  Mesh mesh() const;

 private:
  const std::vector<Camera>& cameras_;
  std::vector<cv::Mat> distance_;  // per camera, CV_32F
  VisualHullOptions options_;
  int min_views_ = 1;  // max(min_views, ceil(min_view_fraction x cameras))
};

}  // namespace fourd::reconstruct
