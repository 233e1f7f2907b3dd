#include "runtime/parameter_map.h"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <cmath>

#include "pipeline/core/error.h"

namespace fourd {

namespace {

bool increasing(const ParameterMap& map) { return map.values.back() >= map.values.front(); }

}  // namespace

double ParameterMap::min_value() const {
  return values.empty() ? 0.0 : std::min(values.front(), values.back());
}

double ParameterMap::max_value() const {
  return values.empty() ? 0.0 : std::max(values.front(), values.back());
}

void ParameterMap::check() const {
  if (num_inputs < 1 || num_inputs > 3) {
    throw InputError(fmt::format("parameter map '{}': {} inputs (1 to 3 supported)", parameter,
                                 num_inputs));
  }
  if (path.empty() || path.size() != values.size()) {
    throw InputError(fmt::format("parameter map '{}': {} path positions for {} values", parameter,
                                 path.size(), values.size()));
  }
  if (path.front() != 0.0 || path.back() != num_inputs - 1.0) {
    throw InputError(fmt::format("parameter map '{}': the path runs from {} to {}, expected 0 to {}",
                                 parameter, path.front(), path.back(), num_inputs - 1));
  }
  for (std::size_t k = 0; k < values.size(); ++k) {
    if (!std::isfinite(values[k]) || !std::isfinite(path[k])) {
      throw InputError(fmt::format("parameter map '{}': sample {} is not finite", parameter, k));
    }
  }
  if (num_inputs > 1 && values.size() < 2) {
    throw InputError(fmt::format("parameter map '{}': one sample for {} inputs", parameter,
                                 num_inputs));
  }
  const double sign = increasing(*this) ? 1.0 : -1.0;
  for (std::size_t k = 1; k < values.size(); ++k) {
    if (!(path[k] > path[k - 1]) || !(sign * (values[k] - values[k - 1]) > 0)) {
      throw InputError(fmt::format(
          "parameter map '{}': samples {} and {} are not strictly monotone (s {} -> {}, {} {} -> {})",
          parameter, k - 1, k, path[k - 1], path[k], parameter, values[k - 1], values[k]));
    }
  }
}

void path_weights(int num_inputs, double s, std::span<float> w) {
  assert(static_cast<int>(w.size()) >= num_inputs && num_inputs >= 1);
  for (int i = 0; i < num_inputs; ++i) w[i] = 0.f;
  if (num_inputs == 1) {
    w[0] = 1.f;
    return;
  }
  const double c = std::clamp(s, 0.0, num_inputs - 1.0);
  const int i = std::min(static_cast<int>(std::floor(c)), num_inputs - 2);
  const double a = c - i;
  w[i] = static_cast<float>(1 - a);
  w[i + 1] = static_cast<float>(a);
}

ParameterLookup weights_for_parameter(const ParameterMap& map, double p, std::span<float> w) {
  ParameterLookup out;
  out.requested = p;
  const std::size_t k = map.values.size();
  assert(k >= 1);
  const double lo = map.min_value(), hi = map.max_value();
  out.clamped = !(p >= lo && p <= hi);
  out.applied = std::isfinite(p) ? std::clamp(p, lo, hi) : lo;
  if (k == 1) {
    out.path_position = 0;
  } else {
    // Search in increasing order of value whichever way the samples run.
    const bool up = increasing(map);
    auto value_at = [&](std::size_t i) { return up ? map.values[i] : map.values[k - 1 - i]; };
    std::size_t a = 0, b = k - 1;  // value_at(a) <= applied <= value_at(b)
    while (b - a > 1) {
      const std::size_t m = (a + b) / 2;
      (value_at(m) <= out.applied ? a : b) = m;
    }
    const double va = value_at(a), vb = value_at(b);
    const double f = vb > va ? (out.applied - va) / (vb - va) : 0.0;
    const std::size_t ia = up ? a : k - 1 - a, ib = up ? b : k - 1 - b;
    out.path_position = map.path[ia] + f * (map.path[ib] - map.path[ia]);
  }
  path_weights(map.num_inputs, out.path_position, w);
  return out;
}

double parameter_at_path(const ParameterMap& map, double s) {
  const std::size_t k = map.values.size();
  assert(k >= 1);
  if (k == 1) return map.values[0];
  const double c = std::clamp(s, map.path.front(), map.path.back());
  const auto it = std::upper_bound(map.path.begin(), map.path.end(), c);
  const std::size_t b = std::clamp<std::size_t>(it - map.path.begin(), 1, k - 1), a = b - 1;
  const double f = (c - map.path[a]) / (map.path[b] - map.path[a]);
  return map.values[a] + f * (map.values[b] - map.values[a]);
}

}  // namespace fourd
