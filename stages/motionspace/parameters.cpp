#include "stages/motionspace/parameters.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "pipeline/core/error.h"
#include "pipeline/exchange/root_motion.h"

namespace fourd {

namespace {

constexpr double kRadToDeg = 180 / std::numbers::pi;

double torso_height(const ParameterProbe& probe, const BlendedFrame& shape) {
  double z = 0;
  const float* pz = shape.z();
  for (int v = 0; v < shape.num_vertices; ++v) z += probe.torso[v] * pz[v];
  return z;
}

std::string unit_of(const std::string& parameter) {
  if (parameter == "speed") return "m/s";
  if (parameter == "direction") return "deg/s";
  return "m";
}

// The vertex that moves furthest from its place at t = 0, summed over the inputs.
int most_moving_vertex(const MotionSpace& space) {
  const BlendSpace& b = space.blend;
  std::vector<double> travel(b.num_vertices, 0.0);
  const std::size_t stride = b.plane_stride;
  for (int k = 0; k < b.num_inputs; ++k) {
    std::vector<double> furthest(b.num_vertices, 0.0);
    const float* p0 = b.frame(k, 0);
    for (int f = 1; f < b.num_frames; ++f) {
      const float* p = b.frame(k, f);
      for (int v = 0; v < b.num_vertices; ++v) {
        const double dx = p[v] - p0[v], dy = p[stride + v] - p0[stride + v],
                     dz = p[2 * stride + v] - p0[2 * stride + v];
        furthest[v] = std::max(furthest[v], dx * dx + dy * dy + dz * dz);
      }
    }
    for (int v = 0; v < b.num_vertices; ++v) travel[v] += std::sqrt(furthest[v]);
  }
  return static_cast<int>(std::max_element(travel.begin(), travel.end()) - travel.begin());
}

}  // namespace

ParameterProbe make_parameter_probe(const std::string& motion_class, const std::string& parameter,
                                    const Eigen::Matrix3Xd& template_positions,
                                    const MotionSpace& space) {
  static const char* kKnown[] = {"speed", "direction", "length", "height", "reach"};
  if (std::find(std::begin(kKnown), std::end(kKnown), parameter) == std::end(kKnown)) {
    throw ConfigError(fmt::format("motion class {}: unknown parameter '{}' (known: speed, "
                                  "direction, length, height, reach)",
                                  motion_class, parameter));
  }
  ParameterProbe probe;
  probe.parameter = parameter;
  probe.unit = unit_of(parameter);
  probe.torso = torso_weights(template_positions);
  if (parameter == "reach") probe.hand_vertex = most_moving_vertex(space);
  return probe;
}

double measure_parameter(const ParameterProbe& probe, const MotionSpace& space,
                         std::span<const float> w, MotionSample* scratch) {
  const std::string& p = probe.parameter;
  if (p == "speed" || p == "length" || p == "direction") {
    const RootPose end = blended_root(space, 1.0, w);
    const double duration = blended_duration(space, w);
    if (p == "length") return std::hypot(end.x, end.y);
    if (p == "speed") return std::hypot(end.x, end.y) / duration;
    return end.heading * kRadToDeg / duration;
  }
  const int f = space.num_samples();
  if (p == "height") {
    double start = 0, top = -1e300;
    for (int i = 0; i < f; ++i) {
      evaluate_motion_space_weights(space, static_cast<double>(i) / (f - 1), w, scratch);
      const double z = torso_height(probe, scratch->shape);
      if (i == 0) start = z;
      top = std::max(top, z);
    }
    return top - start;
  }
  // reach
  Vec3f start = Vec3f::Zero();
  double furthest = -1, height = 0;
  for (int i = 0; i < f; ++i) {
    evaluate_motion_space_weights(space, static_cast<double>(i) / (f - 1), w, scratch);
    const Vec3f hand = scratch->shape.position(probe.hand_vertex);
    if (i == 0) start = hand;
    const double d = (hand - start).norm();
    if (d > furthest) furthest = d, height = hand.z();
  }
  return height;
}

ParameterMap build_parameter_map(const ParameterProbe& probe, const MotionSpace& space,
                                 int samples_per_segment, ParameterMapReport* report) {
  const int n = space.num_inputs();
  const int per = std::max(1, samples_per_segment);
  const int count = n == 1 ? 1 : (n - 1) * per + 1;
  MotionSample scratch = make_motion_sample(space);
  std::vector<double> s(count), p(count);
  std::array<float, 3> w{};
  for (int j = 0; j < count; ++j) {
    s[j] = n == 1 ? 0.0 : static_cast<double>(j) / per;
    path_weights(n, s[j], std::span<float>(w.data(), n));
    p[j] = measure_parameter(probe, space, std::span<const float>(w.data(), n), &scratch);
  }
  report->input_values.clear();
  for (int k = 0; k < n; ++k) report->input_values.push_back(p[k * per]);

  ParameterMap map;
  map.parameter = probe.parameter;
  map.unit = probe.unit;
  map.num_inputs = n;
  if (n == 1) {
    map.path = {0.0};
    map.values = {p[0]};
    return map;
  }
  // The inputs must be in parameter order, so that h is monotone along the path.
  const double sign = p.back() >= p.front() ? 1.0 : -1.0;
  for (int k = 1; k < n; ++k) {
    if (!(sign * (report->input_values[k] - report->input_values[k - 1]) > 0)) {
      std::string values;
      for (int i = 0; i < n; ++i) {
        values += fmt::format("{}{} {:.4g} {}", i ? ", " : "", space.takes[i],
                              report->input_values[i], probe.unit);
      }
      throw InputError(fmt::format(
          "motion class {}: the takes are not in {} order ({}); list them in session.yaml from "
          "the lowest to the highest value, with distinct values",
          space.name, probe.parameter, values));
    }
  }
  // A strictly monotone subset: drop samples that do not move towards the last one.
  std::vector<int> kept{0};
  for (int j = 1; j < count; ++j) {
    const bool last = j == count - 1;
    const bool ahead = sign * (p[j] - p[kept.back()]) > 0;
    const bool before_end = last || sign * (p.back() - p[j]) > 0;
    if (ahead && before_end) {
      kept.push_back(j);
    } else if (last) {  // the end must stay: drop what it does not exceed
      while (kept.size() > 1 && !(sign * (p[j] - p[kept.back()]) > 0)) kept.pop_back();
      kept.push_back(j);
    }
  }
  report->dropped_samples = count - static_cast<int>(kept.size());
  for (int j : kept) {
    map.path.push_back(s[j]);
    map.values.push_back(p[j]);
  }
  map.check();
  return map;
}

ParameterAccuracy check_parameter_accuracy(const ParameterProbe& probe, const MotionSpace& space,
                                           int count) {
  ParameterAccuracy acc;
  const ParameterMap& map = space.parameter_map;
  const double lo = map.min_value(), hi = map.max_value();
  const double range = hi - lo;
  if (!(range > 0) || count < 1) return acc;
  MotionSample sample = make_motion_sample(space);
  const int n = space.num_inputs();
  double sum = 0;
  for (int j = 0; j < count; ++j) {
    const double request = lo + (j + 0.5) / count * range;
    std::array<float, 3> w{};
    weights_for_parameter(map, request, std::span<float>(w.data(), n));
    const double measured =
        measure_parameter(probe, space, std::span<const float>(w.data(), n), &sample);
    const double error = 100 * std::abs(measured - request) / range;
    acc.requested.push_back(request);
    acc.measured.push_back(measured);
    acc.max_error_pct = std::max(acc.max_error_pct, error);
    sum += error;
  }
  acc.mean_error_pct = sum / count;
  return acc;
}

}  // namespace fourd
