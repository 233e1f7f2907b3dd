#pragma once
// Test-only: a textured UV sphere seen by a ring of known cameras, its images rendered from
// the true texture — the input the texture stage must turn back into that texture.
#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"
#include "pipeline/render/textured_render.h"
#include "tests/synth/uv_sphere.h"

namespace fourd::test {

// A smooth colour pattern (BGR, 8 bits): bands in u and v of a few cycles, so the cameras
// resolve it and a faithful texture reproduces it closely.
inline cv::Mat smooth_texture(int size = 256) {
  cv::Mat t(size, size, CV_8UC3);
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const double u = (x + 0.5) / size, v = (y + 0.5) / size;
      const double a = std::sin(2 * std::numbers::pi * 4 * u), b = std::cos(2 * std::numbers::pi * 3 * v);
      t.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<std::uint8_t>(128 + 90 * a),
                                        static_cast<std::uint8_t>(128 + 90 * b),
                                        static_cast<std::uint8_t>(128 + 60 * a * b));
    }
  }
  return t;
}

// `count` cameras on a circle of `radius` around the origin at height `height`, looking at
// the origin; 320x240, 300 px focal length.
inline std::vector<Camera> camera_ring(int count, double radius, double height,
                                       const std::string& prefix = "cam", double phase = 0) {
  std::vector<Camera> cameras;
  for (int i = 0; i < count; ++i) {
    const double a = phase + 2 * std::numbers::pi * i / count;
    Camera c;
    c.name = prefix + std::to_string(i);
    c.intrinsics.width = 320;
    c.intrinsics.height = 240;
    c.intrinsics.fx = c.intrinsics.fy = 300;
    c.intrinsics.cx = 160;
    c.intrinsics.cy = 120;
    c.camera_from_world = look_at(Eigen::Vector3d(radius * std::cos(a), radius * std::sin(a), height),
                                  Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ());
    cameras.push_back(c);
  }
  return cameras;
}

// What `camera` records of `mesh` textured by `texture` (unlit, 8-bit BGR, black backdrop).
inline cv::Mat record(const MeshRenderer& renderer, const Camera& camera) {
  cv::Mat image;
  renderer.render(camera).image.convertTo(image, CV_8UC3, 255.0);
  return image;
}

}  // namespace fourd::test
