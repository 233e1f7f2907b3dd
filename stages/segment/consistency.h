#pragma once
// Cross-camera consistency of one frame's silhouettes. A coarse voxel grid over the volume the
// cameras share is carved by every camera's silhouette, a voxel kept when at most one of the
// cameras that see it disagrees (so that one bad camera neither carves nor adds); the hull is
// then splatted back into each camera, and the fraction of that camera's silhouette it covers is
// how well the other cameras explain it. A silhouette with foreground the others do not see
// (a key that took part of the backdrop) is poorly explained.
//
// Unlike reconstruct's VisualHull (a fine signed-distance field for the surface), this is a
// cheap vote on a fixed grid whose projections are computed once per rig.
#include <opencv2/core.hpp>
#include <vector>

#include "pipeline/core/camera.h"

namespace fourd::segment {

class ConsistencyCheck {
 public:
  // The grid (kGrid^3 voxels) spans the points that most cameras see, around the point their
  // optical axes pass nearest.
  explicit ConsistencyCheck(const std::vector<Camera>& cameras);

  // Per camera, the fraction of its silhouette (CV_8UC1, nonzero = foreground) covered by the
  // hull's projection; -1 for an empty silhouette or when fewer than kMinCameras cameras are
  // checked (the hull of one or two views explains everything).
  std::vector<double> explained(const std::vector<cv::Mat>& silhouettes) const;

  // Adds to each silhouette the pixels of `doubtful[c]` (CV_8UC1) that the visual hull of all
  // silhouettes and doubtful pixels explains with voxels that at least kMinConfirming cameras
  // see as surely foreground (their silhouette without doubt): the performer, where one camera
  // took it for background and others did not. A shadow on the floor is doubtful in every camera
  // and stays background. Then cleaned up again by the caller.
  void recover(std::vector<cv::Mat>& silhouettes, const std::vector<cv::Mat>& doubtful) const;

  // The performer where one camera cannot tell it from the background (blue shoes over a blue
  // stripe of the rug, skin over a beige floor, a shoe darker than the floor by a shadow's
  // factor): adds to each silhouette the pixels of `candidates[c]` (CV_8UC1) outside it whose
  // ray passes a point that every other camera seeing it sees inside its silhouette by
  // kHiddenMargin px, at least kMinConfirming of them; a camera whose own pixel there is a
  // candidate too dissents only weakly, and one weak dissent is allowed above a quarter of the
  // coarse hull's height when `above_floor`. Only pixels the coarse hull of silhouettes and
  // candidates covers are tried, along their ray inside the checked volume, above the floor
  // z = 0 when `above_floor`.
  // The test is per pixel, not per voxel: the coarse hull alone fills the shadow between the
  // feet.
  void recover_hidden(std::vector<cv::Mat>& silhouettes, const std::vector<cv::Mat>& candidates,
                      bool above_floor) const;

  bool usable() const { return usable_; }
  // The point the cameras' optical axes pass nearest and the cameras' median distance from it
  // (valid when has_aim(): at least kMinCameras cameras whose axes are not all parallel).
  bool has_aim() const { return reach_ > 0; }
  const Eigen::Vector3d& aim_centre() const { return centre_; }
  double aim_reach() const { return reach_; }

 private:
  // Camera c's image of the `kept` voxels, each a disc of `scale` times its bounding sphere's.
  cv::Mat splat(std::size_t c, const std::vector<std::uint8_t>& kept, float scale) const;
  // The voxels whose sphere meets the silhouette (`distance`: to its foreground) of every
  // camera that sees them but the tolerated one.
  std::vector<std::uint8_t> carve(const std::vector<cv::Mat>& distance) const;

  const std::vector<Camera>& cameras_;
  std::vector<Eigen::Vector3d> centres_;     // voxel centres seen by enough cameras
  std::vector<std::int32_t> pixel_;          // [voxel * cameras + camera]: pixel index or -1
  std::vector<float> radius_px_;             // [voxel * cameras + camera]: projected radius
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero();
  Eigen::AlignedBox3d box_;                  // the checked volume
  double reach_ = 0;
  bool usable_ = false;
};

}  // namespace fourd::segment
