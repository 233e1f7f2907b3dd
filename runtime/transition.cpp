#include "runtime/transition.h"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include "pipeline/core/error.h"
#include "pipeline/core/se2.h"

namespace fourd {

namespace {

constexpr double kTimeTolerance = 1e-9;

double clamp_parameter(const GraphSpace& space, double p) {
  const double lo = space.parameter_min(), hi = space.parameter_max();
  return std::isfinite(p) ? std::clamp(p, lo, hi) : lo;
}

double parameter_step(const GraphSpace& space, const TransitionOptions& options) {
  return options.alpha * (space.parameter_max() - space.parameter_min());
}

// Trellis steps needed to move the parameter from p0 to q, dp per step.
int steps_between(double p0, double q, double dp) {
  if (!(dp > 0)) return 0;
  return std::max(0, static_cast<int>(std::ceil(std::abs(q - p0) / dp - 1e-9)));
}

// Frames played over `span` of normalised time while the parameter ramps between two values of
// blended durations d0 and d1 (trapezoid).
double latency_frames(double span, double d0, double d1, double frame_time) {
  return span * 0.5 * (d0 + d1) / frame_time;
}

// The parameter values of a trellis rooted at p0 with up to `depth` steps: p0 + k dp inside the
// range, plus the range ends where the trellis runs past them, sorted by steps (then value), so
// that the values reachable in a steps are a prefix.
void fill_values(const GraphSpace& space, double p0, double dp, int depth, TrellisSide* side) {
  const double lo = space.parameter_min(), hi = space.parameter_max();
  const double tol = 1e-9 * std::max(1.0, hi - lo);
  int n = 0;
  auto push = [&](double q) {
    for (int k = 0; k < n; ++k) {
      if (std::abs(side->value[k] - q) <= tol) return;
    }
    side->value[n] = q;
    side->steps[n] = steps_between(p0, q, dp);
    ++n;
  };
  push(p0);
  if (dp > 0) {
    for (int k = 1; k <= depth; ++k) {
      for (const double q : {p0 - k * dp, p0 + k * dp}) {
        if (q >= lo - tol && q <= hi + tol) push(std::clamp(q, lo, hi));
      }
    }
    if (p0 - depth * dp < lo - tol) push(lo);
    if (p0 + depth * dp > hi + tol) push(hi);
  }
  // Insertion sort by (steps, value): at most 67 values.
  for (int i = 1; i < n; ++i) {
    for (int j = i; j > 0; --j) {
      const bool before = side->steps[j] < side->steps[j - 1] ||
                          (side->steps[j] == side->steps[j - 1] &&
                           side->value[j] < side->value[j - 1]);
      if (!before) break;
      std::swap(side->value[j], side->value[j - 1]);
      std::swap(side->steps[j], side->steps[j - 1]);
    }
  }
  side->num_values = n;
  for (int k = 0; k < n; ++k) {
    space_weights(space, side->value[k], &side->weight[k]);
    side->duration[k] = blended_duration(
        space.motion, std::span<const float>(side->weight[k].data(), space.num_inputs()));
  }
}

int values_within(const TrellisSide& side, int steps) {
  int n = 0;
  while (n < side.num_values && side.steps[n] <= steps) ++n;
  return n;
}

// The time levels of one side of the trellis, wrapping for a cyclic space: the source's forward
// from t0 (t0 + a dt), the target's backward from t1 (t1 - b dt). A one-shot space's last level
// sits at its end (t = 1 forward, t = 0 backward: a shorter step) and the trellis stops there.
void time_levels(const GraphSpace& space, double from, double dt, bool forward, int depth,
                 TrellisSide* side) {
  int n = 0;
  for (int a = 0; a <= depth; ++a) {
    double time = forward ? from + a * dt : from - a * dt, span = a * dt;
    bool last = false;
    if (!space.cyclic() && (forward ? time >= 1 - kTimeTolerance : time <= kTimeTolerance)) {
      time = forward ? 1 : 0;
      span = std::max(0.0, forward ? 1 - from : from);
      last = true;
    }
    side->time[n] = space.cyclic() ? wrap01(time) : time;
    side->span[n] = span;
    side->count[n] = values_within(*side, a);
    ++n;
    if (last) break;
  }
  side->num_columns = n;
}

// Free phase: one column per phase m dt; every value usable (its latency is the steps its
// parameter needs to reach the requested one).
void target_phases(double dt, TrellisSide* side) {
  const int m = std::min(kMaxTrellisColumns, static_cast<int>(std::ceil(1.0 / dt - 1e-9)));
  for (int c = 0; c < m; ++c) {
    side->time[c] = c * dt;
    side->span[c] = 0;
    side->count[c] = side->num_values;
  }
  side->num_columns = m;
}

void fill_latencies(TrellisSide* side, double root_duration, double dt, double frame_time) {
  for (int c = 0; c < side->num_columns; ++c) {
    float lowest = std::numeric_limits<float>::infinity();
    for (int k = 0; k < side->count[c]; ++k) {
      const double span = side->free_time ? side->steps[k] * dt : side->span[c];
      const auto l = static_cast<float>(
          latency_frames(span, root_duration, side->duration[k], frame_time));
      side->latency[c * kMaxTrellisValues + k] = l;
      lowest = std::min(lowest, l);
    }
    side->min_latency[c] = lowest;
  }
}

bool valid_request(const MotionGraph& graph, int edge, const MotionState& from,
                   const TransitionTarget& to) {
  if (edge < 0 || edge >= static_cast<int>(graph.edges.size())) return false;
  const GraphEdge& e = graph.edges[edge];
  return e.from == from.space && e.to == to.space;
}

}  // namespace

void TransitionOptions::check() const {
  if (!(alpha >= 0.01 && alpha <= 1)) {
    throw ConfigError(fmt::format("alpha {} must lie in [0.01, 1]", alpha));
  }
  if (depth < 0 || depth > kMaxTrellisDepth) {
    throw ConfigError(fmt::format("depth {} must lie in [0, {}]", depth, kMaxTrellisDepth));
  }
  if (!(lambda >= 0) || !(cost_unit > 0)) {
    throw ConfigError(fmt::format("lambda {} must be >= 0 and cost_unit {} > 0", lambda, cost_unit));
  }
  if (!(one_shot_target_t >= 0 && one_shot_target_t <= 1)) {
    throw ConfigError(fmt::format("one_shot_target_t {} must lie in [0, 1]", one_shot_target_t));
  }
}

double resolved_target_time(const MotionGraph& graph, const TransitionTarget& to,
                            const TransitionOptions& options) {
  if (to.t >= 0) return std::min(to.t, 1.0);
  return graph.spaces[to.space].cyclic() ? -1.0 : options.one_shot_target_t;
}

TransitionPath TransitionSearch::search(const MotionGraph& graph, int edge,
                                        const MotionState& from, const TransitionTarget& to,
                                        const TransitionOptions& options) {
  TransitionPath path;
  if (!valid_request(graph, edge, from, to)) return path;
  const GraphEdge& e = graph.edges[edge];
  const GraphSpace& src = graph.spaces[e.from];
  const GraphSpace& dst = graph.spaces[e.to];
  const EdgeSimilarity& sim = e.similarity;
  const double dt = options.alpha, ft = graph.frame_time();
  const int depth = std::clamp(options.depth, 0, kMaxTrellisDepth);

  const double p0 = clamp_parameter(src, from.p), t0 = std::clamp(from.t, 0.0, 1.0);
  const double p1 = clamp_parameter(dst, to.p);
  const double t1 = resolved_target_time(graph, to, options);

  fill_values(src, p0, parameter_step(src, options), depth, &source_);
  time_levels(src, t0, dt, /*forward=*/true, depth, &source_);
  source_.free_time = false;
  fill_latencies(&source_, source_.duration[0], dt, ft);

  fill_values(dst, p1, parameter_step(dst, options), depth, &target_);
  target_.free_time = t1 < 0;
  if (target_.free_time) {
    target_phases(dt, &target_);
  } else {
    time_levels(dst, t1, dt, /*forward=*/false, depth, &target_);
  }
  fill_latencies(&target_, target_.duration[0], dt, ft);

  const int ns_in = sim.source_inputs, nt_in = sim.target_inputs;
  const auto scale = static_cast<float>(options.cost_unit * sim.max_distance);
  const auto lambda = static_cast<float>(options.lambda);
  float best = std::numeric_limits<float>::infinity();
  int best_a = 0, best_ks = 0, best_c = 0, best_kt = 0;
  int candidates = 0;
  std::array<float, 9> m{};

  for (int a = 0; a < source_.num_columns; ++a) {
    const int ns = source_.count[a];
    const float* ls = source_.latency.data() + a * kMaxTrellisValues;
    for (int c = 0; c < target_.num_columns; ++c) {
      // Cheap bound for the whole block: no weighted similarity exceeds the largest entry of S.
      similarity_matrix_at(sim, source_.time[a], target_.time[c], m.data());
      float max_s = 0;
      for (int k = 0; k < ns_in * nt_in; ++k) max_s = std::max(max_s, m[k]);
      const float bound =
          scale * (1 - max_s) + lambda * (source_.min_latency[a] + target_.min_latency[c]);
      if (bound >= best) continue;

      const int nt = target_.count[c];
      const float* lt = target_.latency.data() + c * kMaxTrellisValues;
      for (int k = 0; k < nt; ++k) {
        const std::array<float, 3>& w = target_.weight[k];
        for (int i = 0; i < 3; ++i) {
          y_[i][k] = i < ns_in ? scale * (m[i * nt_in] * w[0] +
                                          (nt_in > 1 ? m[i * nt_in + 1] * w[1] : 0.f) +
                                          (nt_in > 2 ? m[i * nt_in + 2] * w[2] : 0.f))
                               : 0.f;
        }
        target_cost_[k] = scale + lambda * lt[k];
      }
      for (int ks = 0; ks < ns; ++ks) {
        const float w0 = source_.weight[ks][0], w1 = source_.weight[ks][1],
                    w2 = source_.weight[ks][2];
        const float base = lambda * ls[ks];
        float lowest = std::numeric_limits<float>::infinity();
        for (int k = 0; k < nt; ++k) {
          const float cost = base + target_cost_[k] - (w0 * y_[0][k] + w1 * y_[1][k] + w2 * y_[2][k]);
          pair_cost_[k] = cost;
          lowest = std::min(lowest, cost);
        }
        candidates += nt;
        if (lowest < best) {
          best = lowest;
          best_a = a;
          best_ks = ks;
          best_c = c;
          best_kt = static_cast<int>(std::find(pair_cost_.begin(), pair_cost_.begin() + nt, lowest) -
                                     pair_cost_.begin());
        }
      }
    }
  }

  // The winner's numbers again in double precision.
  const std::span<const float> ws(source_.weight[best_ks].data(), 3);
  const std::span<const float> wt(target_.weight[best_kt].data(), 3);
  path.found = true;
  path.edge = edge;
  path.start = {e.from, t0, p0};
  path.exit = {e.from, source_.time[best_a], source_.value[best_ks]};
  path.source_span = source_.span[best_a];
  path.source_steps = best_a;
  path.entry = {e.to, target_.time[best_c], target_.value[best_kt]};
  if (target_.free_time) {
    path.target_steps = target_.steps[best_kt];
    path.target_span = path.target_steps * dt;
    path.end = {e.to, wrap01(target_.time[best_c] + path.target_span), p1};
  } else {
    path.target_steps = best_c;
    path.target_span = target_.span[best_c];
    path.end = {e.to, t1, p1};
  }
  path.similarity = similarity_lower_bound(sim, path.exit.t, ws, path.entry.t, wt);
  path.similarity_cost = options.cost_unit * sim.max_distance * (1 - path.similarity);
  path.latency_frames =
      latency_frames(path.source_span, source_.duration[0], source_.duration[best_ks], ft) +
      latency_frames(path.target_span, target_.duration[best_kt], target_.duration[0], ft);
  path.cost = path.similarity_cost + options.lambda * path.latency_frames;
  path.candidates = candidates;
  return path;
}

TransitionPath search_transition_brute_force(const MotionGraph& graph, int edge,
                                             const MotionState& from, const TransitionTarget& to,
                                             const TransitionOptions& options) {
  TransitionPath best;
  if (!valid_request(graph, edge, from, to)) return best;
  const GraphEdge& e = graph.edges[edge];
  const GraphSpace& src = graph.spaces[e.from];
  const GraphSpace& dst = graph.spaces[e.to];
  const double dt = options.alpha, ft = graph.frame_time();
  const double dps = parameter_step(src, options), dpt = parameter_step(dst, options);
  const double p0 = clamp_parameter(src, from.p), t0 = std::clamp(from.t, 0.0, 1.0);
  const double p1 = clamp_parameter(dst, to.p);
  const double t1 = resolved_target_time(graph, to, options);
  const double d0 = space_duration(src, p0), d1 = space_duration(dst, p1);

  struct Node {
    double t, span, p;
    int steps;
  };
  // Every source node, duplicates included.
  std::vector<Node> sources;
  for (int a = 0; a <= options.depth; ++a) {
    double t = t0 + a * dt, span = a * dt;
    const bool end = !src.cyclic() && t >= 1 - kTimeTolerance;
    if (end) {
      t = 1;
      span = 1 - t0;
    }
    for (int k = -a; k <= a; ++k) {
      sources.push_back({src.cyclic() ? wrap01(t) : t, span, clamp_parameter(src, p0 + k * dps), a});
    }
    if (end) break;
  }
  std::vector<Node> targets;
  if (t1 < 0) {
    const int phases = static_cast<int>(std::ceil(1.0 / dt - 1e-9));
    for (int c = 0; c < phases; ++c) {
      for (int k = -options.depth; k <= options.depth; ++k) {
        const double q = clamp_parameter(dst, p1 + k * dpt);
        const int steps = steps_between(p1, q, dpt);
        targets.push_back({c * dt, steps * dt, q, steps});
      }
    }
  } else {
    for (int b = 0; b <= options.depth; ++b) {
      double t = t1 - b * dt, span = b * dt;
      const bool end = !dst.cyclic() && t <= kTimeTolerance;
      if (end) {
        t = 0;
        span = t1;
      }
      for (int k = -b; k <= b; ++k) {
        targets.push_back({dst.cyclic() ? wrap01(t) : t, span, clamp_parameter(dst, p1 + k * dpt), b});
      }
      if (end) break;
    }
  }
  best.cost = std::numeric_limits<double>::infinity();
  for (const Node& s : sources) {
    std::array<float, 3> ws{};
    space_weights(src, s.p, &ws);
    const double ls = latency_frames(s.span, d0, space_duration(src, s.p), ft);
    for (const Node& t : targets) {
      std::array<float, 3> wt{};
      space_weights(dst, t.p, &wt);
      const double lb = similarity_lower_bound(e.similarity, s.t, ws, t.t, wt);
      const double es = options.cost_unit * e.similarity.max_distance * (1 - lb);
      const double el = ls + latency_frames(t.span, space_duration(dst, t.p), d1, ft);
      const double cost = es + options.lambda * el;
      ++best.candidates;
      if (cost < best.cost) {
        best.found = true;
        best.edge = edge;
        best.start = {e.from, t0, p0};
        best.exit = {e.from, s.t, s.p};
        best.source_span = s.span;
        best.source_steps = s.steps;
        best.entry = {e.to, t.t, t.p};
        best.target_span = t.span;
        best.target_steps = t.steps;
        best.end = {e.to, t1 < 0 ? wrap01(t.t + t.span) : t1, p1};
        best.similarity = lb;
        best.similarity_cost = es;
        best.latency_frames = el;
        best.cost = cost;
      }
    }
  }
  return best;
}

TransitionPath select_precomputed_transition(const MotionGraph& graph, int edge, int n,
                                             const MotionState& from, const TransitionTarget& to,
                                             const TransitionOptions& options,
                                             bool parameter_rate_limit) {
  TransitionPath best;
  if (!valid_request(graph, edge, from, to)) return best;
  const GraphEdge& e = graph.edges[edge];
  const GraphSpace& src = graph.spaces[e.from];
  const GraphSpace& dst = graph.spaces[e.to];
  const double ft = graph.frame_time();
  const double p0 = clamp_parameter(src, from.p), t0 = std::clamp(from.t, 0.0, 1.0);
  const double p1 = clamp_parameter(dst, to.p);
  const double t1 = resolved_target_time(graph, to, options);
  const double d0 = space_duration(src, p0), d1 = space_duration(dst, p1);
  const double dps = parameter_step(src, options), dpt = parameter_step(dst, options);
  best.cost = std::numeric_limits<double>::infinity();
  const int count = std::min<int>(n, static_cast<int>(e.precomputed.size()));
  for (int k = 0; k < count; ++k) {
    const PrecomputedTransition& c = e.precomputed[k];
    // Source: play forward to the stored exit time.
    double source_span = c.source_t - t0;
    if (src.cyclic()) {
      source_span = wrap01(source_span);
    } else if (source_span < -kTimeTolerance) {
      continue;  // a one-shot motion cannot go back
    }
    source_span = std::max(0.0, source_span);
    // The parameter moves at most dp per step of alpha in time, as in the online trellis: the
    // stored exit's parameter is reached no sooner than that (a cyclic source waits whole
    // cycles; a one-shot source cannot reach it).
    const double min_source_span = steps_between(p0, c.source_p, dps) * options.alpha;
    if (parameter_rate_limit && source_span < min_source_span - kTimeTolerance) {
      if (!src.cyclic()) continue;
      source_span += std::ceil(min_source_span - source_span - kTimeTolerance);
    }
    // Target: play from the stored entry to the requested time.
    double target_span = 0;
    double end_t = t1;
    if (t1 < 0) {
      target_span = steps_between(c.target_p, p1, dpt) * options.alpha;
      end_t = wrap01(c.target_t + target_span);
    } else {
      target_span = t1 - c.target_t;
      if (dst.cyclic()) {
        target_span = wrap01(target_span);
      } else if (target_span < -kTimeTolerance) {
        continue;  // entered after the requested time
      }
      target_span = std::max(0.0, target_span);
      // The same rate limit from the stored entry's parameter to the requested one.
      const double min_target_span = steps_between(c.target_p, p1, dpt) * options.alpha;
      if (parameter_rate_limit && target_span < min_target_span - kTimeTolerance) {
        if (!dst.cyclic()) continue;
        target_span += std::ceil(min_target_span - target_span - kTimeTolerance);
      }
    }
    const double es = options.cost_unit * c.distance;
    const double el = latency_frames(source_span, d0, space_duration(src, c.source_p), ft) +
                      latency_frames(target_span, space_duration(dst, c.target_p), d1, ft);
    const double cost = es + options.lambda * el;
    ++best.candidates;
    if (cost < best.cost) {
      best.found = true;
      best.edge = edge;
      best.start = {e.from, t0, p0};
      best.exit = {e.from, c.source_t, c.source_p};
      best.source_span = source_span;
      best.source_steps = static_cast<int>(std::lround(source_span / options.alpha));
      best.entry = {e.to, c.target_t, c.target_p};
      best.end = {e.to, end_t, p1};
      best.target_span = target_span;
      best.target_steps = static_cast<int>(std::lround(target_span / options.alpha));
      best.similarity = 1 - c.distance / e.similarity.max_distance;
      best.similarity_cost = es;
      best.latency_frames = el;
      best.cost = cost;
    }
  }
  if (!best.found) best.cost = 0;
  return best;
}

}  // namespace fourd
