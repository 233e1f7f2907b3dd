#pragma once
// Test-only: a UV sphere (latitude/longitude grid) with per-vertex texture coordinates and a
// checker texture, for the renderer's tests and benchmark.
#include <cmath>
#include <numbers>
#include <opencv2/core.hpp>

#include "pipeline/core/mesh.h"

namespace fourd::test {

// rings x segments quads around `centre`; seam vertices are duplicated so that UVs can be per
// vertex: (rings+1)(segments+1) vertices, with outward unit normals. UVs follow the OBJ
// convention (v up): u runs with longitude, v from the south pole (0) to the north pole (1).
inline Mesh make_uv_sphere(const Eigen::Vector3f& centre, float radius, int rings, int segments) {
  Mesh mesh;
  for (int i = 0; i <= rings; ++i) {
    const float theta = std::numbers::pi_v<float> * i / rings;  // from the north pole
    for (int j = 0; j <= segments; ++j) {
      const float phi = 2 * std::numbers::pi_v<float> * j / segments;
      const Vec3f n(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                    std::cos(theta));
      mesh.positions.push_back(centre + radius * n);
      mesh.normals.push_back(n);
      mesh.uvs.emplace_back(static_cast<float>(j) / segments, 1.0f - static_cast<float>(i) / rings);
    }
  }
  auto index = [&](int i, int j) { return i * (segments + 1) + j; };
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      const int a = index(i, j), b = index(i + 1, j), c = index(i + 1, j + 1), d = index(i, j + 1);
      // Counter-clockwise seen from outside; the pole rows have one triangle per quad.
      if (i != 0) mesh.triangles.emplace_back(a, b, d);
      if (i != rings - 1) mesh.triangles.emplace_back(b, c, d);
    }
  }
  return mesh;
}

// Red / white / blue checker (BGR): nothing green in it, so it never looks like the screen.
inline cv::Mat checker_texture(int size = 256, int squares = 16) {
  cv::Mat t(size, size, CV_8UC3);
  const int cell = size / squares;
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const int k = (x / cell + y / cell) % 3;
      t.at<cv::Vec3b>(y, x) = k == 0   ? cv::Vec3b(40, 40, 200)    // red
                              : k == 1 ? cv::Vec3b(230, 230, 230)  // white
                                       : cv::Vec3b(180, 60, 30);   // blue
    }
  }
  return t;
}

}  // namespace fourd::test
