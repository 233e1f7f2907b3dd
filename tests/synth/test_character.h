#pragma once
// A small skinned character and a clip for it, for the glTF/BVH tests and the fuzz seeds.
#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <opencv2/core.hpp>
#include <random>
#include <string>
#include <vector>

#include "stages/synth/character.h"
#include "stages/synth/motion.h"

namespace fourd::synth::test {

// A small hand-made character: 5 joints (pelvis root with a leg and a spine carrying a head
// and an arm), a column of square rings with per-vertex UVs, two joints per vertex.
inline Character make_test_character() {
  Character c;
  c.name = "column";
  Skeleton& s = c.skeleton;
  s.names = {"pelvis", "leg", "spine", "head", "arm"};
  s.parents = {-1, 0, 0, 2, 2};
  s.rest_offsets = {{0.02, -0.01, 1.0}, {0, 0.05, -0.45}, {0, 0, 0.25}, {0, 0, 0.3}, {0, 0.2, 0.1}};
  std::vector<Eigen::Vector3d> world(s.size());
  for (std::size_t j = 0; j < s.size(); ++j)
    world[j] = s.parents[j] < 0 ? s.rest_offsets[j] : world[s.parents[j]] + s.rest_offsets[j];
  for (const Eigen::Vector3d& p : world) {
    Eigen::Isometry3d ib = Eigen::Isometry3d::Identity();
    ib.translation() = -p;
    c.skin.inverse_bind.push_back(ib);
  }
  Mesh& m = c.skin.rest;
  const int rings = 7;
  for (int r = 0; r < rings; ++r) {
    const float z = 0.5f + 0.2f * r;
    for (int k = 0; k < 4; ++k) {
      const float a = static_cast<float>(k * std::numbers::pi / 2 + 0.3);
      m.positions.emplace_back(0.1f * std::cos(a) + 0.02f, 0.12f * std::sin(a), z);
      m.uvs.emplace_back(0.1f + 0.2f * k, 0.05f + 0.9f * r / (rings - 1));
      // Two influences per vertex, changing along the column.
      const int lower = r < 2 ? 1 : r < 4 ? 0 : 2;
      const int upper = r < 2 ? 0 : r < 4 ? 2 : (k % 2 ? 3 : 4);
      const float w = 0.3f + 0.1f * k;
      c.skin.joints.emplace_back(lower, upper, 0, 0);
      c.skin.weights.emplace_back(1 - w, w, 0, 0);
    }
  }
  for (int r = 0; r + 1 < rings; ++r)
    for (int k = 0; k < 4; ++k) {
      const int a = r * 4 + k, b = r * 4 + (k + 1) % 4, d = a + 4, e = b + 4;
      m.triangles.emplace_back(a, b, e);
      m.triangles.emplace_back(a, e, d);
    }
  m.triangles.emplace_back(0, 2, 1);
  m.triangles.emplace_back(0, 3, 2);
  const int top = (rings - 1) * 4;
  m.triangles.emplace_back(top, top + 1, top + 2);
  m.triangles.emplace_back(top, top + 2, top + 3);
  c.texture = cv::Mat(16, 24, CV_8UC3);
  cv::randu(c.texture, cv::Scalar::all(0), cv::Scalar::all(255));
  c.height = 1.2;
  return c;
}

inline MotionClip make_test_clip(const Skeleton& s, const std::string& take, int frames, double fps,
                          unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  MotionClip clip;
  clip.spec.take = take;
  clip.fps = fps;
  Eigen::Vector3d axis[5];
  for (auto& a : axis) a = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
  for (int f = 0; f < frames; ++f) {
    Pose pose;
    pose.root_position = Eigen::Vector3d(0.3 * f / fps, 0.1 * std::sin(f), 1.0 + 0.05 * u(rng));
    for (std::size_t j = 0; j < s.size(); ++j)
      pose.local_rotations.push_back(Eigen::Quaterniond(
          Eigen::AngleAxisd(1.2 * std::sin(0.7 * f + j) + 0.4 * u(rng), axis[j])));
    clip.poses.push_back(pose);
  }
  return clip;
}

}  // namespace fourd::synth::test
