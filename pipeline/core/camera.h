#pragma once
// Pinhole camera with OpenCV-style radial/tangential distortion (COLMAP model "OPENCV":
// fx, fy, cx, cy, k1, k2, p1, p2).
//
// Pixel convention (COLMAP's): the image spans [0,W]x[0,H], the centre of pixel (col,row)
// is (col+0.5, row+0.5). OpenCV functions use pixel centres at integers: subtract 0.5 when
// handing our pixel coordinates to them.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>

namespace fourd {

struct Intrinsics {
  int width = 0;   // pixels
  int height = 0;  // pixels
  double fx = 0, fy = 0;  // focal length, pixels
  double cx = 0, cy = 0;  // principal point, pixels (COLMAP convention)
  double k1 = 0, k2 = 0;  // radial distortion
  double p1 = 0, p2 = 0;  // tangential distortion
  bool has_distortion() const { return k1 != 0 || k2 != 0 || p1 != 0 || p2 != 0; }
  // Camera matrix for OpenCV functions (cv::projectPoints, cv::initUndistortRectifyMap...):
  // the principal point moves by -0.5 because OpenCV puts pixel centres at integers.
  Eigen::Matrix3d opencv_camera_matrix() const;
  // Distortion coefficients in OpenCV's order (k1, k2, p1, p2).
  Eigen::Vector4d opencv_distortion() const { return {k1, k2, p1, p2}; }
};

// A ray in world space; direction is unit length.
struct Ray {
  Eigen::Vector3d origin;
  Eigen::Vector3d direction;
};

struct Camera {
  std::string name;  // e.g. "cam00": also the folder name under capture/<take>/
  Intrinsics intrinsics;
  // World-to-camera rigid transform: x_cam = camera_from_world * x_world. The camera looks
  // down +z, x to the right, y down (COLMAP/OpenCV convention).
  Eigen::Isometry3d camera_from_world = Eigen::Isometry3d::Identity();

  Eigen::Vector3d center() const;  // camera centre in world coordinates

  // Normalised (z=1) image coordinates <-> distorted normalised coordinates.
  Eigen::Vector2d distort(const Eigen::Vector2d& undistorted) const;
  // Inverse of distort() by fixed-point/Newton iteration; exact to ~1e-12 for sane lenses.
  Eigen::Vector2d undistort(const Eigen::Vector2d& distorted) const;

  // World point -> pixel. Returns false (and leaves `pixel` untouched) when the point is
  // behind the camera.
  bool project(const Eigen::Vector3d& world, Eigen::Vector2d* pixel) const;
  // Pixel -> world ray through it (distortion removed).
  Ray unproject(const Eigen::Vector2d& pixel) const;
  // Depth of a world point along the optical axis (z in camera coordinates).
  double depth(const Eigen::Vector3d& world) const;

  bool in_image(const Eigen::Vector2d& pixel) const {
    return pixel.x() >= 0 && pixel.y() >= 0 && pixel.x() < intrinsics.width &&
           pixel.y() < intrinsics.height;
  }
};

// A camera at `eye` looking at `target` with `up` roughly up in the image.
Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                          const Eigen::Vector3d& up);

}  // namespace fourd
