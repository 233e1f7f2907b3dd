#pragma once
// Small procedural motion spaces and graphs for the graph and runtime tests: a bending tube
// that "walks" (cyclic, root moving forward at the input's speed), "turns" (cyclic, 3 inputs,
// heading changing at the input's rate) and "jumps" (one-shot, lifted and carried forward by
// the input's length), each with the parameter map of its inputs and, for 2-input spaces, one
// hybrid reference at the middle of the weight segment.
#include <Eigen/Core>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "runtime/motion_graph.h"
#include "runtime/motion_space.h"
#include "stages/graph/graph.h"
#include "tests/motionspace/test_meshes.h"

namespace fourd::test {

inline constexpr double kTestDeg = std::numbers::pi / 180;

struct SpaceRecipe {
  std::string name;
  bool cyclic = true;
  int samples = 17;
  std::vector<double> parameter;  // one value per input (the map is linear between them)
  std::string parameter_name = "speed";
  std::vector<double> amplitude;  // bend amplitude per input [deg]
  std::vector<double> duration;   // seconds per pass per input
  std::vector<double> forward;    // root displacement per pass [m] (cyclic: per cycle)
  std::vector<double> turn;       // heading change per pass [deg]
  double lift = 0;                // one-shot: vertical lift at mid-motion [m] (times input index + 1)
  double direction = 0;           // bend plane [deg]
  bool hybrid_reference = true;   // add the mid-segment reference (2 inputs)
};

inline const TestMesh& test_tube() {
  static const TestMesh m = [] {
    TestMesh t = make_tube(9, 8);
    t.positions.row(2).array() += 0.5;  // stand on the floor (z >= 0)
    return t;
  }();
  return m;
}

// The shape of input k at time t in [0, 1].
inline Eigen::Matrix3Xd recipe_shape(const SpaceRecipe& r, int k, double t) {
  const TestMesh& m = test_tube();
  Eigen::Matrix3Xd centred = m.positions;
  centred.row(2).array() -= 0.5;
  const double phase = r.cyclic ? std::sin(2 * std::numbers::pi * t)
                                : std::pow(std::sin(std::numbers::pi * t), 2);
  Eigen::Matrix3Xd x =
      bend_tube(centred, (r.amplitude[k] * phase + 3.0 * k) * kTestDeg, {}, r.direction * kTestDeg);
  x.row(2).array() += 0.5;
  if (!r.cyclic) x.row(2).array() += r.lift * (k + 1) * std::sin(std::numbers::pi * t);
  return x;
}

inline MotionSpace make_test_space(const SpaceRecipe& r) {
  const int n = static_cast<int>(r.parameter.size());
  const int f = r.samples;
  const TestMesh& m = test_tube();
  MotionSpace s;
  s.name = r.name;
  s.cyclic = r.cyclic;
  for (int k = 0; k < n; ++k) s.takes.push_back(r.name + "_" + std::to_string(k));
  s.character_height = 1.0;
  s.triangles = m.triangles;
  s.blend = make_blend_space(n, static_cast<int>(m.positions.cols()), f);
  for (int k = 0; k < n; ++k) {
    for (int u = 0; u < f; ++u) {
      set_frame(&s.blend, k, u, to_vec3f(recipe_shape(r, k, static_cast<double>(u) / (f - 1))));
    }
  }
  if (n == 2 && r.hybrid_reference) {
    const std::vector<double> mid{0.5, 0.5};
    const int ref = add_reference(&s.blend, mid);
    for (int u = 0; u < f; ++u) {
      const double t = static_cast<double>(u) / (f - 1);
      Eigen::Matrix3Xd x = 0.5 * (recipe_shape(r, 0, t) + recipe_shape(r, 1, t));
      x.row(0).array() += 0.01;  // a small "non-linear" correction
      set_frame(&s.blend, ref, u, to_vec3f(x));
    }
    s.blend.cells = {{0, ref, -1}, {ref, 1, -1}};
  }
  for (int k = 0; k < n; ++k) {
    for (int u = 0; u < f; ++u) {
      const double t = static_cast<double>(u) / (f - 1);
      const double progress = r.cyclic ? t : t * t * (3 - 2 * t);
      const double heading = r.turn.empty() ? 0.0 : r.turn[k] * kTestDeg * t;
      // Forward along the turning heading: integrate the arc exactly for a constant rate.
      const double dist = r.forward[k] * progress;
      RootPose p;
      if (std::abs(heading) < 1e-12) {
        p = {static_cast<float>(dist), 0.f, 0.f};
      } else {
        const double radius = dist / heading;
        p = {static_cast<float>(radius * std::sin(heading)),
             static_cast<float>(radius * (1 - std::cos(heading))), static_cast<float>(heading)};
      }
      s.roots.push_back(p);
      s.seconds.push_back(static_cast<float>(r.duration[k] * t));
    }
  }
  ParameterMap& pm = s.parameter_map;
  pm.parameter = r.parameter_name;
  pm.unit = "";
  pm.num_inputs = n;
  for (int k = 0; k < n; ++k) {
    pm.path.push_back(k);
    pm.values.push_back(r.parameter[k]);
  }
  s.check();
  return s;
}

inline SpaceRecipe walk_recipe() {
  SpaceRecipe r;
  r.name = "locomotion";
  r.cyclic = true;
  r.samples = 17;
  r.parameter = {1.0, 1.6};
  r.amplitude = {30, 50};
  r.duration = {1.0, 0.8};
  r.forward = {1.0, 1.28};
  return r;
}

inline SpaceRecipe jump_recipe() {
  SpaceRecipe r;
  r.name = "jump_length";
  r.cyclic = false;
  r.samples = 21;
  r.parameter = {0.6, 1.2};
  r.parameter_name = "length";
  r.amplitude = {60, 80};
  r.duration = {1.2, 1.4};
  r.forward = {0.6, 1.2};
  r.lift = 0.1;
  r.direction = 90;
  return r;
}

inline SpaceRecipe turn_recipe() {
  SpaceRecipe r;
  r.name = "turning";
  r.cyclic = true;
  r.samples = 13;
  r.parameter = {-45, 0, 45};
  r.parameter_name = "direction";
  r.amplitude = {35, 40, 45};
  r.duration = {1.0, 1.0, 1.0};
  r.forward = {1.3, 1.3, 1.3};
  r.turn = {-45, 0, 45};
  r.direction = 30;
  return r;
}

// A one-shot "reach": the tube bends forward and comes back, more for the second input.
inline SpaceRecipe reach_recipe() {
  SpaceRecipe r;
  r.name = "reach";
  r.cyclic = false;
  r.samples = 21;
  r.parameter = {0, 1};  // replaced by the measured hand heights (make_reach_space)
  r.parameter_name = "reach";
  r.amplitude = {40, 80};
  r.duration = {1.5, 1.5};
  r.forward = {0.1, 0.1};
  r.direction = 0;
  return r;
}

// The reach space, its parameter measured as the motion spaces stage measures it: the height
// of the vertex that moves furthest (the "hand") at its furthest point, per input.
inline MotionSpace make_reach_space() {
  MotionSpace s = make_test_space(reach_recipe());
  const BlendSpace& b = s.blend;
  for (int k = 0; k < s.num_inputs(); ++k) {
    double furthest = -1, height = 0;
    for (int u = 1; u < b.num_frames; ++u) {
      const float* f = b.frame(k, u);
      const float* f0 = b.frame(k, 0);
      for (int v = 0; v < b.num_vertices; ++v) {
        double d = 0;
        for (int c = 0; c < 3; ++c) {
          const double e = f[c * b.plane_stride + v] - f0[c * b.plane_stride + v];
          d += e * e;
        }
        if (d > furthest) furthest = d, height = f[2 * b.plane_stride + v];
      }
    }
    s.parameter_map.values[k] = height;
  }
  s.check();
  return s;
}

// locomotion <-> jump_length (+ locomotion <-> turning when `with_turning`, + locomotion <->
// reach when `with_reach`), self-loops on.
inline MotionGraph make_test_graph(bool with_turning = false, double fps = 25,
                                   bool with_reach = false) {
  std::vector<MotionSpace> spaces{make_test_space(walk_recipe()), make_test_space(jump_recipe())};
  std::vector<TransitionConfig> transitions{{"locomotion", "jump_length"},
                                            {"jump_length", "locomotion"}};
  if (with_turning) {
    spaces.push_back(make_test_space(turn_recipe()));
    transitions.push_back({"locomotion", "turning"});
    transitions.push_back({"turning", "locomotion"});
  }
  if (with_reach) {
    spaces.push_back(make_reach_space());
    transitions.push_back({"locomotion", "reach"});
    transitions.push_back({"reach", "locomotion"});
  }
  graph::GraphOptions options;
  options.precomputed.parameter_samples = 5;
  return graph::build_motion_graph("test", fps, std::move(spaces), transitions, options, nullptr);
}

// Synthetic key textures for `graph` (runtime/textures.h): `keys` phases per input, `size`
// texels square, every image a distinct pattern (so a blend can be traced to its images), UVs
// spread over the texture.
inline void add_test_textures(MotionGraph* graph, int keys = 4, int size = 32) {
  AssetTextures& t = graph->textures;
  t = AssetTextures{};
  t.width = t.height = size;
  const std::size_t faces = graph->spaces.front().motion.triangles.size();
  for (std::size_t f = 0; f < faces; ++f) {
    const float u = (static_cast<float>(f % 16) + 0.5f) / 16, v = (static_cast<float>(f / 16 % 16) + 0.5f) / 16;
    t.corner_uvs.push_back(Vec2f(u, v));
    t.corner_uvs.push_back(Vec2f(u + 0.02f, v));
    t.corner_uvs.push_back(Vec2f(u, v + 0.02f));
  }
  for (const GraphSpace& s : graph->spaces) {
    t.spaces.push_back({keys, static_cast<int>(t.images.size())});
    for (int k = 0; k < keys * s.num_inputs(); ++k) {
      const int id = static_cast<int>(t.images.size());
      cv::Mat image(size, size, CV_8UC3);
      for (int y = 0; y < size; ++y) {
        for (int x = 0; x < size; ++x) {
          // Smooth (as JPEG keeps them well) and distinct: a red level of its own per image.
          const double a = 2 * std::numbers::pi * (static_cast<double>(x) / size + 0.13 * id);
          const double b = 2 * std::numbers::pi * (static_cast<double>(y) / size + 0.29 * id);
          image.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<std::uint8_t>(128 + 90 * std::sin(a)),
                                                static_cast<std::uint8_t>(128 + 90 * std::cos(b)),
                                                static_cast<std::uint8_t>(20 + (47 * id) % 216));
        }
      }
      t.images.push_back(image);
    }
  }
  graph->check();
}

// The test graph (locomotion <-> jump_length) with 4 key textures of 32 x 32 texels per input.
inline const MotionGraph& textured_test_graph() {
  static const MotionGraph g = [] {
    MotionGraph graph = make_test_graph();
    add_test_textures(&graph, 4, 32);
    return graph;
  }();
  return g;
}

}  // namespace fourd::test
