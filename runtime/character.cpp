#include "runtime/character.h"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <limits>

#include "pipeline/core/error.h"
#include "pipeline/core/se2.h"
#include "runtime/transition_jump.h"

namespace fourd {

namespace {

constexpr int kMaxSpaces = 64;
// Normalised-time tolerance for reaching a path's exit or end.
constexpr double kSpanTolerance = 1e-9;
// A frame time within this many ticks of a tick counts as that tick (rounding of summed dt).
constexpr double kTickTolerance = 1e-6;

double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3 - 2 * x);
}

// Root motion of `space` from t over dn of normalised time at weights w (a cyclic space may
// run past t = 1; a one-shot clamps at 1), in the root frame at t.
RootPose root_delta(const MotionSpace& space, double t, double dn, std::span<const float> w) {
  if (dn <= 0) return {};
  const RootPose a = space_root(space, t, w);
  const RootPose b = space_root(space, space.cyclic ? t + dn : std::min(1.0, t + dn), w);
  return root_relative(a, b);
}

// The same sources read from the normals array.
void to_normals(const GraphSpace& space, const BlendSources& positions, BlendSources* normals) {
  *normals = positions;
  for (int k = 0; k < positions.count; ++k) normals->sources[k] = space.normals_for(positions.sources[k]);
  for (int k = 0; k < positions.displacement_count; ++k) {
    normals->displacement_sources[k] = space.normals_for(positions.displacement_sources[k]);
    normals->displacement_floats[k] =
        space.normal_displacement_float(positions.displacement_floats[k]);
  }
}

void scale(BlendSources* s, float f) {
  for (int k = 0; k < s->count; ++k) s->coefficients[k] *= f;
  for (int k = 0; k < s->displacement_count; ++k) s->displacement_coefficients[k] *= f;
}

void normalize_planes(BlendedFrame* f) {
  float* __restrict x = f->data.data();
  float* __restrict y = x + f->plane_stride;
  float* __restrict z = y + f->plane_stride;
  const int n = f->num_vertices;
#pragma GCC ivdep
  for (int v = 0; v < n; ++v) {
    const float len2 = x[v] * x[v] + y[v] * y[v] + z[v] * z[v];
    // Branch-free so the loop vectorises; a zero normal stays zero.
    const float inv = 1.0f / std::sqrt(len2 + 1e-30f);
    x[v] *= inv;
    y[v] *= inv;
    z[v] *= inv;
  }
}

std::span<const float> weights_span(const GraphSpace& space, const std::array<float, 3>& w) {
  return {w.data(), static_cast<std::size_t>(space.num_inputs())};
}

}  // namespace

const char* request_result_name(RequestResult r) {
  switch (r) {
    case RequestResult::kAccepted:
      return "accepted";
    case RequestResult::kRouted:
      return "routed";
    case RequestResult::kNoRoute:
      return "no_route";
    case RequestResult::kUnknownSpace:
      return "unknown_space";
  }
  return "?";
}

const char* play_phase_name(PlayPhase p) {
  switch (p) {
    case PlayPhase::kFree:
      return "free";
    case PlayPhase::kSource:
      return "source";
    case PlayPhase::kTarget:
      return "target";
  }
  return "?";
}

void CharacterOptions::check() const {
  if (!(tick_seconds > 0 && tick_seconds <= 0.1)) {
    throw ConfigError(fmt::format("tick_seconds {} must lie in (0, 0.1]", tick_seconds));
  }
  if (!(crossfade_seconds >= 0 && crossfade_seconds <= 5)) {
    throw ConfigError(fmt::format("crossfade_seconds {} must lie in [0, 5]", crossfade_seconds));
  }
  if (!(crossfade_max_seconds >= 0 && crossfade_max_seconds <= 5)) {
    throw ConfigError(
        fmt::format("crossfade_max_seconds {} must lie in [0, 5]", crossfade_max_seconds));
  }
  if (!(crossfade_speed_share > 0 && crossfade_speed_share <= 100)) {
    throw ConfigError(
        fmt::format("crossfade_speed_share {} must lie in (0, 100]", crossfade_speed_share));
  }
  if (!(one_shot_exit_t >= 0 && one_shot_exit_t <= 1)) {
    throw ConfigError(fmt::format("one_shot_exit_t {} must lie in [0, 1]", one_shot_exit_t));
  }
  if (!(max_turn_rate >= 0 && std::isfinite(max_turn_rate))) {
    throw ConfigError(fmt::format("max_turn_rate {} must be finite and >= 0", max_turn_rate));
  }
}

Character::Character(const MotionGraph& graph, const TransitionOptions& transitions,
                     const CharacterOptions& options)
    : graph_(graph), transitions_(transitions), options_(options) {
  options_.check();
  transitions_.check();
  num_spaces_ = static_cast<int>(graph_.spaces.size());
  if (num_spaces_ < 1 || num_spaces_ > kMaxSpaces) {
    throw InputError(
        fmt::format("character: {} motion spaces (1 to {} supported)", num_spaces_, kMaxSpaces));
  }
  // Shortest routes once, so requests allocate nothing.
  next_hop_.fill(-1);
  for (int a = 0; a < num_spaces_; ++a) {
    for (int b = 0; b < num_spaces_; ++b) {
      const std::vector<int> route = shortest_route(graph_, a, b);
      if (!route.empty()) next_hop_[a * kMaxSpaces + b] = route.front();
    }
  }
  const BlendSpace& blend = graph_.spaces.front().motion.blend;
  frame_.positions = make_blended_frame(blend);
  frame_.normals = make_blended_frame(blend);
  scratch_a_ = make_blended_frame(blend);
  scratch_b_ = make_blended_frame(blend);
  // The motions' own vertex speeds, for the cross-fade's length.
  for (int k = 0; k < num_spaces_; ++k) {
    const GraphSpace& sp = graph_.spaces[k];
    for (int i = 0; i < kSpeedSamples; ++i) {
      const double p = sp.parameter_min() +
                       (sp.parameter_max() - sp.parameter_min()) * i / (kSpeedSamples - 1);
      speeds_[k][i] = static_cast<float>(
          motion_displacement_p99(graph_, k, p, graph_.frame_time()) / graph_.frame_time());
    }
  }
  reset(0, graph_.spaces.front().parameter_min());
}

double Character::clamp_p(int space, double p, bool* clamped) const {
  const GraphSpace& s = graph_.spaces[space];
  const double lo = s.parameter_min(), hi = s.parameter_max();
  *clamped = !(p >= lo && p <= hi);
  return std::isfinite(p) ? std::clamp(p, lo, hi) : lo;
}

RequestStatus Character::reset(int space, double p, double t, const RootTransform& root) {
  RequestStatus status;
  if (space < 0 || space >= num_spaces_) {
    status.result = RequestResult::kUnknownSpace;
    return status;
  }
  state_ = CharacterState{};
  state_.space = space;
  state_.t = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0);
  state_.p = state_.p_target = status.applied = clamp_p(space, p, &status.clamped);
  state_.root = root;
  tick_ = 0;
  prepared_tick_ = -1;
  hook_tick_ = -1;
  time_ = 0;
  request_ = parameter_ = turn_ = Request{};
  events_ = StepEvents{};
  record_ = TransitionRecord{};
  clamps_ = status.clamped ? 1 : 0;
  shown_ = state_;
  evaluate(shown_);
  return status;
}

std::int64_t Character::due_tick_now() const {
  if (hook_tick_ >= 0) return hook_tick_;
  return static_cast<std::int64_t>(std::ceil(time_ / options_.tick_seconds - kTickTolerance));
}

RequestStatus Character::set_parameters(double p) {
  // The space the parameter refers to: the one a pending or running transition goes to.
  int space = state_.space;
  if (request_.pending) {
    space = request_.space;
  } else if (state_.phase == PlayPhase::kSource) {
    space = state_.path.end.space;
  }
  RequestStatus status;
  status.applied = clamp_p(space, p, &status.clamped);
  if (status.clamped) ++clamps_;
  parameter_ = {true, space, status.applied, -1, due_tick_now()};
  return status;
}

RequestStatus Character::request_motion(int space, double p, double t) {
  RequestStatus status;
  if (space < 0 || space >= num_spaces_) {
    status.result = RequestResult::kUnknownSpace;
    return status;
  }
  status.applied = clamp_p(space, p, &status.clamped);
  if (status.clamped) ++clamps_;
  const int from = state_.phase == PlayPhase::kSource ? state_.path.end.space : state_.space;
  if (space != from || t >= 0) {
    if (graph_.find_edge(from, space) >= 0) {
      status.hops = 1;
    } else {
      // Count the hops of the shortest route.
      int at = from;
      while (at != space && at >= 0 && status.hops <= kMaxSpaces) {
        at = next_hop_[at * kMaxSpaces + space];
        ++status.hops;
      }
      if (at != space) {
        status.result = RequestResult::kNoRoute;
        status.hops = 0;
        return status;
      }
      status.result = RequestResult::kRouted;
    }
  }
  request_ = {true, space, status.applied, std::isfinite(t) && t >= 0 ? std::min(t, 1.0) : -1.0,
              due_tick_now()};
  return status;
}

RequestStatus Character::request_motion(std::string_view space, double p, double t) {
  for (int k = 0; k < num_spaces_; ++k) {
    if (graph_.spaces[k].name() == space) return request_motion(k, p, t);
  }
  RequestStatus status;
  status.result = RequestResult::kUnknownSpace;
  return status;
}

void Character::set_turn_rate(double rad_per_second) {
  const double m = options_.max_turn_rate;
  const double r = std::isfinite(rad_per_second) ? std::clamp(rad_per_second, -m, m) : 0.0;
  turn_ = {true, -1, r, -1, due_tick_now()};
}

bool Character::start_transition(int target, double p, double t) {
  CharacterState& s = state_;
  if (target == s.space && t < 0) {
    // A parameter change in the current space; a path not yet switched is abandoned.
    if (s.phase == PlayPhase::kSource) s.phase = PlayPhase::kFree;
    s.p_target = p;
    s.goal_space = -1;
    return true;
  }
  int edge = graph_.find_edge(s.space, target);
  int hop = target;
  double hop_p = p, hop_t = t;
  if (edge < 0) {
    hop = next_hop_[s.space * kMaxSpaces + target];
    if (hop < 0) return false;
    edge = graph_.find_edge(s.space, hop);
    if (edge < 0) return false;
    const GraphSpace& h = graph_.spaces[hop];
    hop_p = 0.5 * (h.parameter_min() + h.parameter_max());
    hop_t = -1;
    s.goal_space = target;
    s.goal_p = p;
    s.goal_t = t;
  } else {
    s.goal_space = -1;
  }
  const MotionState from{s.space, s.t, s.p};
  const TransitionTarget to{hop, hop_p, hop_t};
  const auto start = std::chrono::steady_clock::now();
  const TransitionPath path = search_.search(graph_, edge, from, to, transitions_);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ++events_.searches;
  events_.search_seconds += seconds;
  if (!path.found) {
    ++events_.refused;
    s.goal_space = -1;
    return false;
  }
  // Leaving a cyclic space for a one-shot one: come back to it afterwards, at the parameter
  // it was asked to play (not the one the path ramps through).
  if (graph_.spaces[s.space].cyclic() && !graph_.spaces[hop].cyclic()) {
    s.return_space = s.space;
    s.return_p = s.phase == PlayPhase::kSource ? s.return_p : s.p_target;
  }
  s.phase = PlayPhase::kSource;
  s.path = path;
  s.played = 0;
  s.p_target = path.end.p;
  s.holding = false;
  record_ = TransitionRecord{};
  record_.from = s.space;
  record_.to = hop;
  record_.request_time = s.time;
  record_.search_seconds = seconds;
  record_.path = path;
  return true;
}

void Character::plan_next() {
  CharacterState& s = state_;
  if (s.phase != PlayPhase::kFree || s.fading) return;
  const GraphSpace& space = graph_.spaces[s.space];
  const bool ready = space.cyclic() || s.t >= options_.one_shot_exit_t;
  if (!ready) return;
  if (s.goal_space >= 0) {
    if (s.goal_space == s.space && s.goal_t < 0) {
      s.p_target = s.goal_p;
      s.goal_space = -1;
      return;
    }
    const int goal = s.goal_space;
    if (!start_transition(goal, s.goal_p, s.goal_t)) s.goal_space = -1;
    return;
  }
  if (!space.cyclic() && s.return_space >= 0) {
    const int back = s.return_space;
    s.return_space = -1;
    start_transition(back, s.return_p, -1);
    return;
  }
  // Nothing comes next: the default successor, rather than freezing on the last frame.
  if (!space.cyclic() && !s.holding) {
    const int next = graph_.default_successor(s.space);
    if (next < 0) {
      s.holding = true;
      return;
    }
    const GraphSpace& n = graph_.spaces[next];
    if (!start_transition(next, 0.5 * (n.parameter_min() + n.parameter_max()), -1)) s.holding = true;
  }
}

void Character::prepare_tick() {
  if (prepared_tick_ == tick_) return;
  prepared_tick_ = tick_;
  if (hook_) {
    hook_tick_ = tick_;
    hook_->on_tick(*this, state_);
    hook_tick_ = -1;
  }
  if (turn_.pending && turn_.due_tick <= tick_) {
    state_.turn_rate = turn_.p;
    turn_.pending = false;
  }
  if (request_.pending && request_.due_tick <= tick_ && !state_.fading) {
    request_.pending = false;
    if (!start_transition(request_.space, request_.p, request_.t)) ++events_.refused;
  }
  if (parameter_.pending && parameter_.due_tick <= tick_ && !request_.pending) {
    parameter_.pending = false;
    // p_target belongs to the space being played, or to the one a path goes to.
    const int refers =
        state_.phase == PlayPhase::kSource ? state_.path.end.space : state_.space;
    if (parameter_.space == refers) state_.p_target = parameter_.p;
    if (state_.goal_space == parameter_.space) state_.goal_p = parameter_.p;
  }
  if (!request_.pending) plan_next();
}

double Character::motion_speed(int space, double p) const {
  const GraphSpace& sp = graph_.spaces[space];
  const double range = sp.parameter_max() - sp.parameter_min();
  const double x = range > 0 ? std::clamp((p - sp.parameter_min()) / range, 0.0, 1.0) * (kSpeedSamples - 1)
                             : 0.0;
  const int i = std::min(static_cast<int>(x), kSpeedSamples - 2);
  const double a = x - i;
  return (1 - a) * speeds_[space][i] + a * speeds_[space][i + 1];
}

void Character::plan_fade(CharacterState* s) {
  s->fade_align = RootPose{};
  s->fade_seconds = options_.crossfade_seconds;
  // The frames on both sides of the switch, each in its own root frame (the root is the same).
  const GraphSpace& src = graph_.spaces[s->fade_space];
  const GraphSpace& dst = graph_.spaces[s->space];
  std::array<float, 3> w{};
  BlendSources sources;
  space_weights(src, s->fade_p, &w);
  hybrid_blend_sources(src.motion.blend, s->fade_t, weights_span(src, w), &sources);
  weighted_sum(sources, src.motion.blend.frame_stride(), scratch_a_.data.data());
  space_weights(dst, s->p, &w);
  hybrid_blend_sources(dst.motion.blend, s->t, weights_span(dst, w), &sources);
  weighted_sum(sources, dst.motion.blend.frame_stride(), scratch_b_.data.data());
  const int n = scratch_a_.num_vertices;
  const float *px = scratch_a_.x(), *py = scratch_a_.y(), *pz = scratch_a_.z();
  const float *qx = scratch_b_.x(), *qy = scratch_b_.y(), *qz = scratch_b_.z();
  // The ground-plane rigid motion A that best fits the target's points q onto the source's p
  // (least squares: centroids, then the rotation of the 2 x 2 cross-covariance).
  RootPose a;
  if (options_.align_at_switch && n > 0) {
    double cpx = 0, cpy = 0, cqx = 0, cqy = 0;
    for (int v = 0; v < n; ++v) cpx += px[v], cpy += py[v], cqx += qx[v], cqy += qy[v];
    cpx /= n, cpy /= n, cqx /= n, cqy /= n;
    double sxx = 0, sxy = 0, syx = 0, syy = 0;  // sum (q - cq) (p - cp)^T
    for (int v = 0; v < n; ++v) {
      const double ax = qx[v] - cqx, ay = qy[v] - cqy, bx = px[v] - cpx, by = py[v] - cpy;
      sxx += ax * bx, sxy += ax * by, syx += ay * bx, syy += ay * by;
    }
    const double theta = std::atan2(sxy - syx, sxx + syy);
    const double c = std::cos(theta), sn = std::sin(theta);
    a = {static_cast<float>(cpx - (c * cqx - sn * cqy)), static_cast<float>(cpy - (sn * cqx + c * cqy)),
         static_cast<float>(theta)};
  }
  // The largest gap left between the two frames.
  const float c = std::cos(a.heading), sn = std::sin(a.heading);
  double gap2 = 0;
  for (int v = 0; v < n; ++v) {
    const double dx = a.x + c * qx[v] - sn * qy[v] - px[v];
    const double dy = a.y + sn * qx[v] + c * qy[v] - py[v];
    const double dz = qz[v] - pz[v];
    gap2 = std::max(gap2, dx * dx + dy * dy + dz * dz);
  }
  // The root takes the alignment on: the target drawn in the new root frame lands on the
  // source; the source, still fading, is drawn in it through A^-1.
  s->root = root_compose(s->root, a);
  s->fade_align = root_inverse(a);
  const double speed =
      std::max(motion_speed(s->fade_space, s->fade_p), motion_speed(s->space, s->p));
  if (speed > 0) {
    const double wanted = 1.5 * std::sqrt(gap2) / (options_.crossfade_speed_share * speed);
    s->fade_seconds = std::max(options_.crossfade_seconds,
                               std::min(wanted, options_.crossfade_max_seconds));
  }
}

void Character::advance(CharacterState* s, double seconds, bool commit) {
  for (int iteration = 0; iteration < 64; ++iteration) {
    // Boundaries first: a path's exit (switch) and end (arrival) may need no time at all.
    if (s->phase == PlayPhase::kSource && s->played >= s->path.source_span - kSpanTolerance) {
      const TransitionPath& path = s->path;
      if (options_.crossfade_seconds > 0) {
        s->fading = true;
        s->fade_space = s->space;
        s->fade_t = s->t;
        s->fade_p = s->p;
        s->fade_elapsed = 0;
      }
      s->space = path.entry.space;
      s->t = path.entry.t;
      s->p = path.entry.p;
      s->phase = PlayPhase::kTarget;
      s->played = 0;
      if (s->fading) plan_fade(s);
      if (commit) {
        ++events_.switches;
        record_.switch_time = s->time;
      }
      continue;
    }
    if (s->phase == PlayPhase::kTarget && s->played >= s->path.target_span - kSpanTolerance) {
      s->phase = PlayPhase::kFree;
      s->p = s->path.end.p;
      if (commit) {
        ++events_.arrivals;
        record_.arrive_time = s->time;
      }
      continue;
    }
    if (!(seconds > 1e-12)) break;

    const GraphSpace& space = graph_.spaces[s->space];
    const MotionSpace& motion = space.motion;
    std::array<float, 3> w{};
    space_weights(space, s->p, &w);
    const std::span<const float> ws = weights_span(space, w);
    const double pace = blended_seconds_per_t(motion, s->t, ws);  // [s per unit t]
    double limit = std::numeric_limits<double>::infinity();
    if (s->phase == PlayPhase::kSource) limit = s->path.source_span - s->played;
    if (s->phase == PlayPhase::kTarget) limit = s->path.target_span - s->played;
    bool idle_rest = false;  // a one-shot space that has ended: the rest of the time is still
    if (!space.cyclic() && 1 - s->t < limit) {
      limit = 1 - s->t;
      idle_rest = s->phase == PlayPhase::kFree;
    }
    limit = std::max(0.0, limit);
    double dn = pace > 0 ? seconds / pace : limit;
    double used = seconds;
    if (dn > limit) {
      dn = limit;
      if (!idle_rest) used = std::min(seconds, dn * pace);
    }

    // Root motion of this segment (weights at its start), the parameter at its end.
    RootPose delta = root_delta(motion, s->t, dn, ws);
    if (s->phase == PlayPhase::kSource || s->phase == PlayPhase::kTarget) {
      const bool src = s->phase == PlayPhase::kSource;
      const double span = src ? s->path.source_span : s->path.target_span;
      const double a = src ? s->path.start.p : s->path.entry.p;
      const double b = src ? s->path.exit.p : s->path.end.p;
      const double f = span > 0 ? std::clamp((s->played + dn) / span, 0.0, 1.0) : 1.0;
      s->p = a + f * (b - a);
    } else {
      const double rate = space.parameter_max() - space.parameter_min();  // per unit t
      const double step = rate * dn;
      s->p = s->p_target > s->p ? std::min(s->p_target, s->p + step)
                                : std::max(s->p_target, s->p - step);
    }

    if (s->fading) {
      const GraphSpace& fs = graph_.spaces[s->fade_space];
      std::array<float, 3> wf{};
      space_weights(fs, s->fade_p, &wf);
      const std::span<const float> wfs = weights_span(fs, wf);
      const double pace_f = blended_seconds_per_t(fs.motion, s->fade_t, wfs);
      double dnf = pace_f > 0 ? used / pace_f : 0.0;
      if (!fs.cyclic()) dnf = std::min(dnf, 1 - s->fade_t);
      // The faded space's root motion, seen in the current root frame.
      const RootPose delta_f = root_compose(
          root_compose(s->fade_align, root_delta(fs.motion, s->fade_t, dnf, wfs)),
          root_inverse(s->fade_align));
      s->fade_t = fs.cyclic() ? wrap01(s->fade_t + dnf) : std::min(1.0, s->fade_t + dnf);
      const double beta = smoothstep((s->fade_elapsed + 0.5 * used) / s->fade_seconds);
      delta = root_lerp(delta_f, delta, static_cast<float>(beta));
      s->fade_elapsed += used;
      if (s->fade_elapsed >= s->fade_seconds) s->fading = false;
    }

    // Steering: half the turn before the segment's translation, half after (midpoint rule).
    const double turn = s->turn_rate * used;
    s->root.heading += 0.5 * turn;
    s->root = root_compose(s->root, delta);
    s->root.heading += 0.5 * turn;

    s->t = space.cyclic() ? wrap01(s->t + dn) : std::min(1.0, s->t + dn);
    s->played += dn;
    s->time += used;
    seconds -= used;
  }
}

const CharacterFrame& Character::step(double dt) {
  events_ = StepEvents{};
  if (std::isfinite(dt) && dt > 0) time_ += dt;
  const double h = options_.tick_seconds;
  const auto target_tick = static_cast<std::int64_t>(std::floor(time_ / h + kTickTolerance));
  while (tick_ < target_tick) {
    prepare_tick();
    advance(&state_, h, true);
    ++tick_;
    // Pin the committed clock to the tick grid (no drift from summing h).
    state_.time = static_cast<double>(tick_) * h;
  }
  shown_ = state_;
  const double rest = time_ - static_cast<double>(tick_) * h;
  if (rest > kTickTolerance * h) {
    prepare_tick();
    shown_ = state_;
    advance(&shown_, rest, false);
  }
  evaluate(shown_);
  return frame_;
}

void Character::evaluate(const CharacterState& s) {
  const GraphSpace& space = graph_.spaces[s.space];
  std::array<float, 3> w{};
  space_weights(space, s.p, &w);
  BlendSources a, an;
  hybrid_blend_sources(space.motion.blend, s.t, weights_span(space, w), &a);
  const double beta =
      s.fading && s.fade_seconds > 0 ? smoothstep(s.fade_elapsed / s.fade_seconds) : 1.0;
  const std::size_t n = space.motion.blend.frame_stride();
  if (beta < 1) scale(&a, static_cast<float>(beta));
  to_normals(space, a, &an);
  weighted_sum(a, n, frame_.positions.data.data());
  weighted_sum(an, n, frame_.normals.data.data());
  if (beta < 1) {
    const GraphSpace& fs = graph_.spaces[s.fade_space];
    std::array<float, 3> wf{};
    space_weights(fs, s.fade_p, &wf);
    BlendSources b, bn;
    hybrid_blend_sources(fs.motion.blend, s.fade_t, weights_span(fs, wf), &b);
    scale(&b, static_cast<float>(1 - beta));
    to_normals(fs, b, &bn);
    const RootPose& al = s.fade_align;
    if (al.x == 0 && al.y == 0 && al.heading == 0) {
      accumulate_weighted_sum(b, n, frame_.positions.data.data());
      accumulate_weighted_sum(bn, n, frame_.normals.data.data());
    } else {
      // The faded blend drawn in the current root frame (positions moved, normals turned).
      const float c = std::cos(al.heading), sn = std::sin(al.heading);
      const float shift = static_cast<float>(1 - beta);
      for (int pass = 0; pass < 2; ++pass) {
        weighted_sum(pass == 0 ? b : bn, n, scratch_b_.data.data());
        BlendedFrame& out = pass == 0 ? frame_.positions : frame_.normals;
        const float tx = pass == 0 ? shift * al.x : 0.f, ty = pass == 0 ? shift * al.y : 0.f;
        float* __restrict ox = out.data.data();
        float* __restrict oy = ox + out.plane_stride;
        float* __restrict oz = oy + out.plane_stride;
        const float* x = scratch_b_.x();
        const float* y = scratch_b_.y();
        const float* z = scratch_b_.z();
        for (int v = 0; v < out.num_vertices; ++v) {
          ox[v] += c * x[v] - sn * y[v] + tx;
          oy[v] += sn * x[v] + c * y[v] + ty;
          oz[v] += z[v];
        }
      }
    }
  }
  if (options_.normalize_normals) normalize_planes(&frame_.normals);
  frame_.textures.count = 0;
  if (!graph_.textures.empty()) {
    texture_blend_add(graph_.textures, s.space, space.cyclic(), s.t, weights_span(space, w),
                      static_cast<float>(beta), &frame_.textures);
    if (beta < 1) {
      const GraphSpace& fs = graph_.spaces[s.fade_space];
      std::array<float, 3> wf{};
      space_weights(fs, s.fade_p, &wf);
      texture_blend_add(graph_.textures, s.fade_space, fs.cyclic(), s.fade_t,
                        weights_span(fs, wf), static_cast<float>(1 - beta), &frame_.textures);
    }
  }
  frame_.root = s.root;
  frame_.fade_weight = static_cast<float>(beta);
}

void character_world_positions(const CharacterFrame& frame, std::vector<Vec3f>* out) {
  const BlendedFrame& f = frame.positions;
  out->resize(f.num_vertices);
  const double c = std::cos(frame.root.heading), s = std::sin(frame.root.heading);
  for (int v = 0; v < f.num_vertices; ++v) {
    const double x = f.x()[v], y = f.y()[v];
    (*out)[v] = Vec3f(static_cast<float>(frame.root.x + c * x - s * y),
                      static_cast<float>(frame.root.y + s * x + c * y), f.z()[v]);
  }
}

void character_world_normals(const CharacterFrame& frame, std::vector<Vec3f>* out) {
  const BlendedFrame& f = frame.normals;
  out->resize(f.num_vertices);
  const double c = std::cos(frame.root.heading), s = std::sin(frame.root.heading);
  for (int v = 0; v < f.num_vertices; ++v) {
    const double x = f.x()[v], y = f.y()[v];
    (*out)[v] = Vec3f(static_cast<float>(c * x - s * y), static_cast<float>(s * x + c * y),
                      f.z()[v]);
  }
}

}  // namespace fourd
