#pragma once
// Rigs and captures the import tests share.
#include <fmt/format.h>

#include <cmath>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"

namespace fourd::test {

// `count` cameras on a circle (like synth's rig: z up, looking at the performer's middle), with
// awkward numbers and distortion on every other camera; `size` scales the images.
inline std::vector<Camera> circle_rig(int count = 8, int width = 640, int height = 480) {
  std::vector<Camera> rig;
  for (int i = 0; i < count; ++i) {
    const double a = 2 * M_PI * i / count + 0.1234;
    Camera c;
    c.name = fmt::format("cam{:02d}", i);
    Intrinsics& in = c.intrinsics;
    in.width = width;
    in.height = height;
    in.fx = 0.88 * width + 3.3 * i + 0.123456789;
    in.fy = in.fx * (1.0 + 0.001 * i);
    in.cx = width / 2.0 + 1.7 * std::sin(a);
    in.cy = height / 2.0 - 2.3 * std::cos(a);
    if (i % 2 == 0) {
      in.k1 = -0.0731 + 0.001 * i;
      in.k2 = 0.0123456;
      in.p1 = 0.000731;
      in.p2 = -0.000417;
    }
    const Eigen::Vector3d eye(3.5 * std::cos(a), 3.5 * std::sin(a), 1.6 + 0.05 * i);
    c.camera_from_world = look_at(eye, Eigen::Vector3d(0.01 * i, -0.02, 1.0), Eigen::Vector3d::UnitZ());
    rig.push_back(c);
  }
  return rig;
}

}  // namespace fourd::test
