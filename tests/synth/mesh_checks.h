#pragma once
// Checks of the synthetic performers' meshes and textures shared by the synth tests.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <limits>
#include <map>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd::synth::test {

inline double signed_volume(const Mesh& mesh) {
  double volume = 0;
  for (const Tri& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.positions[t[0]].cast<double>();
    const Eigen::Vector3d b = mesh.positions[t[1]].cast<double>();
    const Eigen::Vector3d c = mesh.positions[t[2]].cast<double>();
    volume += a.dot(b.cross(c)) / 6.0;
  }
  return volume;
}

// Fraction of a BGR texture's texels of a saturated colour within `window` degrees of hue.
inline double fraction_near_hue(const cv::Mat& bgr, double hue_deg, double window) {
  cv::Mat hsv;
  cv::cvtColor(bgr, hsv, cv::COLOR_BGR2HSV_FULL);
  int near = 0;
  for (int r = 0; r < hsv.rows; ++r) {
    for (int c = 0; c < hsv.cols; ++c) {
      const cv::Vec3b p = hsv.at<cv::Vec3b>(r, c);
      const double dh = std::abs(p[0] * 360.0 / 256.0 - hue_deg);
      if (p[1] > 0.4 * 255 && p[2] > 40 && std::min(dh, 360 - dh) < window) ++near;
    }
  }
  return double(near) / double(hsv.total());
}

// The lowest height of the given vertices of a mesh.
inline float lowest(const Mesh& mesh, const std::vector<int>& vertices) {
  float z = std::numeric_limits<float>::max();
  for (int v : vertices) z = std::min(z, mesh.positions[static_cast<std::size_t>(v)].z());
  return z;
}

// The lowest height of any vertex of the meshes.
inline float lowest_vertex(const std::vector<Mesh>& meshes) {
  float z = std::numeric_limits<float>::max();
  for (const Mesh& m : meshes) {
    for (const Vec3f& p : m.positions) z = std::min(z, p.z());
  }
  return z;
}

// Closed, consistently oriented, manifold (edges and vertices), genus 0.
inline void expect_closed_manifold_sphere(const Mesh& mesh) {
  std::map<std::pair<int, int>, int> directed;
  for (const Tri& t : mesh.triangles) {
    EXPECT_TRUE(t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
    for (int c = 0; c < 3; ++c) ++directed[{t[c], t[(c + 1) % 3]}];
  }
  std::size_t edges = 0;
  for (const auto& [e, count] : directed) {
    ASSERT_EQ(count, 1) << "directed edge used twice: inconsistent orientation";
    ASSERT_EQ(directed.count({e.second, e.first}), 1u) << "boundary edge";
    if (e.first < e.second) ++edges;
  }
  // Each vertex's triangles form a single fan (no pinched vertices).
  std::vector<std::map<int, int>> next(mesh.num_vertices());
  for (const Tri& t : mesh.triangles) {
    for (int c = 0; c < 3; ++c) next[t[c]][t[(c + 1) % 3]] = t[(c + 2) % 3];
  }
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    ASSERT_FALSE(next[v].empty()) << "isolated vertex " << v;
    int start = next[v].begin()->first, cur = start;
    std::size_t steps = 0;
    do {
      cur = next[v].at(cur);
      ++steps;
    } while (cur != start && steps <= next[v].size());
    ASSERT_EQ(steps, next[v].size()) << "vertex " << v << " is not manifold";
  }
  const long euler = static_cast<long>(mesh.num_vertices()) - static_cast<long>(edges) +
                     static_cast<long>(mesh.num_triangles());
  EXPECT_EQ(euler, 2);
}

}  // namespace fourd::synth::test
