#pragma once
// Ideal pinhole cameras for multi-view stereo. Every calibrated camera is resampled once to a
// pinhole camera with the same K and no lens distortion, so that projections are a 3x4 matrix
// and plane-induced warps are homographies. Pixel convention as Camera's (COLMAP's): pixel
// (col, row) has its centre at (col + 0.5, row + 0.5).
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>

#include "pipeline/core/camera.h"

namespace fourd::reconstruct {

struct PinholeCamera {
  std::string name;
  int width = 0, height = 0;
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();  // COLMAP pixel convention
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // camera_from_world rotation
  Eigen::Vector3d t = Eigen::Vector3d::Zero();      // camera_from_world translation

  // The same camera without its lens distortion.
  static PinholeCamera from(const Camera& camera);

  Eigen::Vector3d center() const { return -R.transpose() * t; }
  // Unit viewing direction (optical axis) in world coordinates.
  Eigen::Vector3d axis() const { return R.row(2).transpose(); }
  Eigen::Vector3d to_camera(const Eigen::Vector3d& world) const { return R * world + t; }
  // Pixel of a point in camera coordinates (z > 0 assumed).
  Eigen::Vector2d pixel(const Eigen::Vector3d& cam) const {
    return {K(0, 0) * cam.x() / cam.z() + K(0, 2), K(1, 1) * cam.y() / cam.z() + K(1, 2)};
  }
  // The world point at depth `z` (along the optical axis) on the ray through pixel (x, y).
  Eigen::Vector3d unproject(double x, double y, double z) const;
  bool in_image(const Eigen::Vector2d& px) const {
    return px.x() >= 0 && px.y() >= 0 && px.x() < width && px.y() < height;
  }
};

// Remaps a captured image (or silhouette, or any per-pixel map) of `camera` to the pixel grid
// of PinholeCamera::from(camera). Built once per camera, applied to every frame.
class Undistorter {
 public:
  Undistorter() = default;
  explicit Undistorter(const Camera& camera);
  // Bilinear for images, nearest for label images (interpolation = cv::INTER_NEAREST).
  // Without distortion the input is returned as is (no copy).
  cv::Mat apply(const cv::Mat& image, int interpolation) const;

 private:
  bool identity_ = true;
  cv::Mat map_x_, map_y_;
};

}  // namespace fourd::reconstruct
