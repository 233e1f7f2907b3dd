#include "stages/reconstruct/pinhole.h"

#include <opencv2/imgproc.hpp>

namespace fourd::reconstruct {

PinholeCamera PinholeCamera::from(const Camera& camera) {
  PinholeCamera p;
  p.name = camera.name;
  p.width = camera.intrinsics.width;
  p.height = camera.intrinsics.height;
  p.K << camera.intrinsics.fx, 0, camera.intrinsics.cx,  //
      0, camera.intrinsics.fy, camera.intrinsics.cy,     //
      0, 0, 1;
  p.R = camera.camera_from_world.linear();
  p.t = camera.camera_from_world.translation();
  return p;
}

Eigen::Vector3d PinholeCamera::unproject(double x, double y, double z) const {
  Eigen::Vector3d cam((x - K(0, 2)) / K(0, 0) * z, (y - K(1, 2)) / K(1, 1) * z, z);
  return R.transpose() * (cam - t);
}

Undistorter::Undistorter(const Camera& camera) {
  identity_ = !camera.intrinsics.has_distortion();
  if (identity_) return;
  const Intrinsics& in = camera.intrinsics;
  map_x_.create(in.height, in.width, CV_32F);
  map_y_.create(in.height, in.width, CV_32F);
  for (int r = 0; r < in.height; ++r) {
    float* mx = map_x_.ptr<float>(r);
    float* my = map_y_.ptr<float>(r);
    for (int c = 0; c < in.width; ++c) {
      // Where the lens put the ray of the ideal pixel centre (c + 0.5, r + 0.5); OpenCV's remap
      // puts pixel centres at integers, hence the -0.5.
      Eigen::Vector2d u((c + 0.5 - in.cx) / in.fx, (r + 0.5 - in.cy) / in.fy);
      Eigen::Vector2d d = camera.distort(u);
      mx[c] = static_cast<float>(in.fx * d.x() + in.cx - 0.5);
      my[c] = static_cast<float>(in.fy * d.y() + in.cy - 0.5);
    }
  }
}

cv::Mat Undistorter::apply(const cv::Mat& image, int interpolation) const {
  if (identity_) return image;
  cv::Mat out;
  cv::remap(image, out, map_x_, map_y_, interpolation, cv::BORDER_REPLICATE);
  return out;
}

}  // namespace fourd::reconstruct
