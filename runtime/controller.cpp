#include "runtime/controller.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "pipeline/core/error.h"
#include "pipeline/core/se2.h"

namespace fourd {

namespace {

Point2 bezier(const std::array<Point2, 4>& c, double u) {
  const double v = 1 - u;
  const double b0 = v * v * v, b1 = 3 * v * v * u, b2 = 3 * v * u * u, b3 = u * u * u;
  return {b0 * c[0].x + b1 * c[1].x + b2 * c[2].x + b3 * c[3].x,
          b0 * c[0].y + b1 * c[1].y + b2 * c[2].y + b3 * c[3].y};
}

double distance(const Point2& a, const Point2& b) { return std::hypot(a.x - b.x, a.y - b.y); }

// Predictions play the path in steps of this many ticks, for at most this many steps.
constexpr int kPreviewTicks = 4;
constexpr int kMaxPreviewSteps = 4000;

}  // namespace

// Samples of one curve at most (1.25 km at the default 5 mm spacing): bounds the memory a
// control script can ask for.
constexpr double kMaxSamplesPerCurve = 1e6;

GroundPath::GroundPath(std::vector<BezierCurve> curves, double sample_spacing)
    : curves_(std::move(curves)) {
  if (curves_.empty()) throw InputError("path: no curves");
  if (!(sample_spacing > 0)) throw InputError("path: sample spacing must be positive");
  for (std::size_t c = 0; c < curves_.size(); ++c) {
    for (const Point2& p : curves_[c].control) {
      if (!std::isfinite(p.x) || !std::isfinite(p.y)) {
        throw InputError(fmt::format("path: curve {} has a point that is not finite", c + 1));
      }
    }
    if (c > 0 && distance(curves_[c].control[0], curves_[c - 1].control[3]) > 1e-3) {
      throw InputError(fmt::format("path: curve {} does not start where curve {} ends", c + 1, c));
    }
  }
  points_.push_back(curves_.front().control[0]);
  s_.push_back(0);
  curve_of_.push_back(0);
  curve_start_.push_back(0);
  for (std::size_t c = 0; c < curves_.size(); ++c) {
    const auto& k = curves_[c].control;
    const double hull = distance(k[0], k[1]) + distance(k[1], k[2]) + distance(k[2], k[3]);
    // Dense parameter sampling, then arc length by chords.
    const double samples = std::ceil(4 * hull / sample_spacing);
    if (!(samples <= kMaxSamplesPerCurve)) {
      throw InputError(fmt::format(
          "path: curve {} is too long: its control points span {:.0f} m, at most {:.0f} m", c + 1,
          hull, kMaxSamplesPerCurve * sample_spacing / 4));
    }
    const int n = std::max(8, static_cast<int>(samples));
    for (int i = 1; i <= n; ++i) {
      const Point2 p = bezier(k, static_cast<double>(i) / n);
      s_.push_back(s_.back() + distance(p, points_.back()));
      points_.push_back(p);
      curve_of_.push_back(static_cast<int>(c));
    }
    curve_start_.push_back(s_.back());
  }
  length_ = s_.back();
}

Point2 GroundPath::point_at(double s) const {
  s = std::clamp(s, 0.0, length_);
  const auto it = std::upper_bound(s_.begin(), s_.end(), s);
  const std::size_t b = std::clamp<std::size_t>(it - s_.begin(), 1, s_.size() - 1), a = b - 1;
  const double len = s_[b] - s_[a];
  const double f = len > 0 ? (s - s_[a]) / len : 0.0;
  return {points_[a].x + f * (points_[b].x - points_[a].x),
          points_[a].y + f * (points_[b].y - points_[a].y)};
}

double GroundPath::heading_at(double s) const {
  const double h = 0.02;
  const Point2 a = point_at(std::max(0.0, s - h)), b = point_at(std::min(length_, s + h));
  return std::atan2(b.y - a.y, b.x - a.x);
}

int GroundPath::curve_at(double s) const {
  const auto it = std::upper_bound(curve_start_.begin(), curve_start_.end(), s);
  const int c = static_cast<int>(it - curve_start_.begin()) - 1;
  return std::clamp(c, 0, static_cast<int>(curves_.size()) - 1);
}

double GroundPath::closest(const Point2& p, double s_from, double s_to) const {
  const auto lo = std::lower_bound(s_.begin(), s_.end(), std::max(0.0, s_from)) - s_.begin();
  const auto hi = std::upper_bound(s_.begin(), s_.end(), std::min(length_, s_to)) - s_.begin();
  const std::size_t a0 = lo > 0 ? lo - 1 : 0;
  const std::size_t a1 = std::min<std::size_t>(hi, s_.size() - 1);
  double best = 1e300, best_s = std::clamp(s_from, 0.0, length_);
  for (std::size_t a = a0; a < a1; ++a) {
    const Point2& u = points_[a];
    const Point2& v = points_[a + 1];
    const double ex = v.x - u.x, ey = v.y - u.y, len2 = ex * ex + ey * ey;
    double f = len2 > 0 ? ((p.x - u.x) * ex + (p.y - u.y) * ey) / len2 : 0.0;
    f = std::clamp(f, 0.0, 1.0);
    const double dx = u.x + f * ex - p.x, dy = u.y + f * ey - p.y;
    const double d2 = dx * dx + dy * dy;
    if (d2 < best) {
      best = d2;
      best_s = s_[a] + f * (s_[a + 1] - s_[a]);
    }
  }
  return best_s;
}

void ControllerOptions::check() const {
  if (!(lookahead > 0)) throw ConfigError(fmt::format("lookahead {} must be > 0", lookahead));
  if (!(heading_gain >= 0) || !(lateral_gain >= 0)) {
    throw ConfigError(fmt::format("heading_gain {} and lateral_gain {} must be >= 0", heading_gain,
                                  lateral_gain));
  }
  if (!(jump_search_distance >= 0)) {
    throw ConfigError(fmt::format("jump_search_distance {} must be >= 0", jump_search_distance));
  }
  if (!(arrive_distance > 0)) {
    throw ConfigError(fmt::format("arrive_distance {} must be > 0", arrive_distance));
  }
  if (!(turn_exit_rate >= 0 && turn_enter_rate >= turn_exit_rate)) {
    throw ConfigError(fmt::format("turn_exit_rate {} must be >= 0 and <= turn_enter_rate {}",
                                  turn_exit_rate, turn_enter_rate));
  }
  if (!(turn_preview > 0)) {
    throw ConfigError(fmt::format("turn_preview {} must be > 0", turn_preview));
  }
}

Controller::Controller(Character& character, const ControllerOptions& options)
    : character_(character), options_(options) {
  options_.check();
  const MotionGraph& g = character_.graph();
  locomotion_ = g.find_space(options_.locomotion_space);
  jump_ = g.find_space(options_.jump_space);
  turning_ = g.find_space(options_.turning_space);
  reach_ = g.find_space(options_.reach_space);
  // Each placed motion must be one-shot and reachable from locomotion; turning cyclic.
  auto usable = [&](int space, bool cyclic) {
    return space >= 0 && locomotion_ >= 0 && g.spaces[space].cyclic() == cyclic &&
           g.find_edge(locomotion_, space) >= 0 && g.find_edge(space, locomotion_) >= 0;
  };
  if (!usable(turning_, true)) turning_ = -1;
  if (!usable(reach_, false)) reach_ = -1;
  if (locomotion_ >= 0) {
    const GraphSpace& loco = g.spaces[locomotion_];
    const double a = cycle_travel(loco.parameter_min()), b = cycle_travel(loco.parameter_max());
    cycle_range_ = {std::min(a, b), std::max(a, b)};
  }
  if (reach_ >= 0) {
    scratch_ = make_blended_frame(g.spaces[reach_].motion.blend);
    scratch0_ = make_blended_frame(g.spaces[reach_].motion.blend);
  }
  character_.set_tick_hook(this);
}

Controller::~Controller() { character_.set_tick_hook(nullptr); }

RequestStatus Controller::walk(double speed, double heading) {
  path_ = nullptr;
  status_.active = false;
  reach_status_.active = false;
  if (locomotion_ < 0) {
    RequestStatus refused;
    refused.result = RequestResult::kUnknownSpace;
    return refused;
  }
  steer_heading_ = std::isfinite(heading);
  heading_goal_ = heading;
  return character_.request_motion(locomotion_, speed);
}

RequestStatus Controller::jump(double length) {
  if (jump_ < 0) {
    RequestStatus refused;
    refused.result = RequestResult::kUnknownSpace;
    return refused;
  }
  return character_.request_motion(jump_, length);
}

RequestStatus Controller::reach(double x, double y, double z) {
  RequestStatus status;
  if (reach_ < 0) {
    status.result = RequestResult::kUnknownSpace;
    return status;
  }
  stop_following();
  steer_heading_ = false;
  const GraphSpace& space = character_.graph().spaces[reach_];
  const double lo = space.parameter_min(), hi = space.parameter_max();
  status.clamped = !(z >= lo && z <= hi);
  status.applied = std::isfinite(z) ? std::clamp(z, lo, hi) : lo;
  status.hops = 1;
  reach_status_ = ReachStatus{};
  reach_status_.active = true;
  reach_status_.target[0] = x, reach_status_.target[1] = y, reach_status_.target[2] = z;
  reach_status_.parameter = status.applied;
  // The hand: the vertex that moves furthest from its place at t = 0 (the rule the parameter
  // is measured with), and the time it is furthest.
  std::array<float, 3> w{};
  space_weights(space, status.applied, &w);
  const std::span<const float> ws(w.data(), space.num_inputs());
  const BlendSpace& blend = space.motion.blend;
  BlendSources sources;
  hybrid_blend_sources(blend, 0.0, ws, &sources);
  weighted_sum(sources, blend.frame_stride(), scratch0_.data.data());
  double furthest = -1;
  const int samples = space.num_samples();
  for (int u = 1; u < samples; ++u) {
    const double t = static_cast<double>(u) / (samples - 1);
    hybrid_blend_sources(blend, t, ws, &sources);
    weighted_sum(sources, blend.frame_stride(), scratch_.data.data());
    for (int v = 0; v < blend.num_vertices; ++v) {
      const double d = (scratch_.position(v) - scratch0_.position(v)).squaredNorm();
      if (d > furthest) {
        furthest = d;
        reach_status_.hand_vertex = v;
        reach_status_.apex_t = t;
        hand_offset_ = {scratch_.x()[v], scratch_.y()[v]};
      }
    }
  }
  return status;
}

void Controller::follow(const GroundPath* path) {
  path_ = path;
  steer_heading_ = false;
  reach_status_.active = false;
  status_ = FollowStatus{};
  status_.active = path != nullptr;
  current_curve_ = -1;
  jumped_curve_ = -1;
  approaching_ = false;
  last_jump_t_ = 1;
  if (!path) return;
  const CharacterState& s = character_.state();
  last_x_ = s.root.x;
  last_y_ = s.root.y;
  last_heading_ = s.root.heading;
  status_.s = status_.s_start = path->closest({s.root.x, s.root.y}, 0.0, path->length());
}

Controller::Placement Controller::predict(const CharacterState& state, int space, double p,
                                          double key_t, const Point2& offset) {
  Placement out;
  const MotionGraph& g = character_.graph();
  const int edge = g.find_edge(locomotion_, space);
  if (edge < 0) return out;
  const TransitionPath path = search_.search(g, edge, {locomotion_, state.t, state.p},
                                             {space, p, -1}, character_.transition_options());
  if (!path.found) return out;
  // Play the path on a copy of the state, as the character will (parameter ramps, cross-fade),
  // without the steering, up to the key time in the target.
  CharacterState s = state;
  s.phase = PlayPhase::kSource;
  s.path = path;
  s.played = 0;
  s.p_target = path.end.p;
  s.turn_rate = 0;
  s.goal_space = -1;
  s.return_space = -1;
  const double dt = kPreviewTicks * character_.options().tick_seconds;
  for (int i = 0; i < kMaxPreviewSteps; ++i) {
    if (s.space == space && s.phase != PlayPhase::kSource && s.t >= key_t - 1e-9) break;
    character_.preview(&s, dt);
  }
  const double c = std::cos(s.root.heading), sn = std::sin(s.root.heading);
  const double kx = s.root.x + c * offset.x - sn * offset.y - state.root.x;
  const double ky = s.root.y + sn * offset.x + c * offset.y - state.root.y;
  const double c0 = std::cos(state.root.heading), s0 = std::sin(state.root.heading);
  const GraphSpace& loco = g.spaces[locomotion_];
  std::array<float, 3> wl{};
  space_weights(loco, state.p, &wl);
  const RootPose cycle =
      space_root(loco.motion, 1.0, std::span<const float>(wl.data(), loco.num_inputs()));
  out.found = true;
  out.forward = c0 * kx + s0 * ky;
  out.left = -s0 * kx + c0 * ky;
  out.cycle = std::hypot(cycle.x, cycle.y);
  return out;
}
double Controller::cycle_travel(double speed) const {
  const GraphSpace& loco = character_.graph().spaces[locomotion_];
  std::array<float, 3> w{};
  space_weights(loco, speed, &w);
  const RootPose r =
      space_root(loco.motion, 1.0, std::span<const float>(w.data(), loco.num_inputs()));
  return std::hypot(r.x, r.y);
}

double Controller::speed_for_cycle(double travel) const {
  const GraphSpace& loco = character_.graph().spaces[locomotion_];
  double lo = loco.parameter_min(), hi = loco.parameter_max();
  const bool increasing = cycle_travel(hi) >= cycle_travel(lo);
  for (int k = 0; k < 30; ++k) {
    const double mid = 0.5 * (lo + hi);
    if ((cycle_travel(mid) < travel) == increasing) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return 0.5 * (lo + hi);
}

bool Controller::approach(Character& character, const CharacterState& state,
                          const Placement& placement, double goal_forward) {
  const double error = goal_forward - placement.forward;
  const double cycle = placement.cycle;
  if (!(cycle > 1e-6)) return true;
  // The staircase's step: measured when the prediction steps (the error drops by a plausible
  // amount), else half a cycle (a walk offers a take-off from either foot).
  if (!approaching_) {
    step_ = 0.5 * cycle;
  } else if (last_error_ - error > 0.2 * cycle && last_error_ - error < 0.7 * cycle) {
    step_ = 0.5 * (step_ + (last_error_ - error));
  }
  last_error_ = error;
  approaching_ = true;
  if (error < 0.5 * step_) return true;
  // The k-th next step lands on the goal if the steps are error / k long; they scale with the
  // cycle's travel. Of the k around error / step, the one whose cycle the speed range allows
  // and that changes the speed least.
  const double k0 = std::max(1.0, std::floor(error / step_));
  double best = cycle, best_cost = 1e300;
  for (double k = k0; k <= k0 + 1; ++k) {
    const double wanted = cycle * error / (k * step_);
    const double feasible = std::clamp(wanted, cycle_range_[0], cycle_range_[1]);
    const double cost = 10 * std::abs(wanted - feasible) + std::abs(feasible - cycle);
    if (cost < best_cost) best_cost = cost, best = feasible;
  }
  const double speed = speed_for_cycle(best);
  const GraphSpace& loco = character.graph().spaces[locomotion_];
  if (std::abs(state.p_target - speed) > 0.01 * (loco.parameter_max() - loco.parameter_min())) {
    character.set_parameters(speed);
  }
  return false;
}

void Controller::on_tick(Character& character, const CharacterState& state) {
  if (path_ && status_.active) {
    follow_tick(character, state);
    return;
  }
  if (reach_status_.active) {
    reach_tick(character, state);
    return;
  }
  if (steer_heading_) {
    character.set_turn_rate(options_.heading_gain *
                            wrap_heading(heading_goal_ - state.root.heading));
  }
}

void Controller::reach_tick(Character& character, const CharacterState& state) {
  ReachStatus& r = reach_status_;
  const double c = std::cos(state.root.heading), sn = std::sin(state.root.heading);
  if (r.requested) {
    if (state.space == reach_ && state.phase != PlayPhase::kSource && state.t >= r.apex_t) {
      // The hand at its furthest point, in the world.
      const GraphSpace& space = character.graph().spaces[reach_];
      std::array<float, 3> w{};
      space_weights(space, state.p, &w);
      BlendSources sources;
      hybrid_blend_sources(space.motion.blend, state.t,
                           std::span<const float>(w.data(), space.num_inputs()), &sources);
      weighted_sum(sources, space.motion.blend.frame_stride(), scratch_.data.data());
      const Vec3f h = scratch_.position(r.hand_vertex);
      r.hand[0] = state.root.x + c * h.x() - sn * h.y();
      r.hand[1] = state.root.y + sn * h.x() + c * h.y();
      r.hand[2] = h.z();
      r.hand_error =
          std::sqrt(std::pow(r.hand[0] - r.target[0], 2) + std::pow(r.hand[1] - r.target[1], 2) +
                    std::pow(r.hand[2] - r.target[2], 2));
      r.done = true;
      r.active = false;
      character.set_turn_rate(0);
    }
    return;
  }
  if (state.space != locomotion_ || state.phase != PlayPhase::kFree || state.fading) {
    if (state.space != locomotion_ && state.phase == PlayPhase::kFree && !state.fading &&
        character.graph().spaces[state.space].cyclic()) {
      character.request_motion(locomotion_, state.p_target);  // reach from locomotion
    }
    return;
  }
  // The target in the current root frame; steer so that the hand's sideways offset at the
  // furthest point lines up with it.
  const double dx = r.target[0] - state.root.x, dy = r.target[1] - state.root.y;
  const double forward = c * dx + sn * dy;
  const double aim_x = dx + sn * hand_offset_.y, aim_y = dy - c * hand_offset_.y;
  const double desired = std::atan2(aim_y, aim_x);
  character.set_turn_rate(options_.heading_gain * wrap_heading(desired - state.root.heading));
  const Placement placement = predict(state, reach_, r.parameter, r.apex_t, hand_offset_);
  if (!placement.found) return;
  if (approach(character, state, placement, forward)) {
    character.request_motion(reach_, r.parameter);
    character.set_turn_rate(0);
    r.requested = true;
    approaching_ = false;
  }
}

void Controller::follow_tick(Character& character, const CharacterState& state) {
  const GroundPath& path = *path_;
  const Point2 root{state.root.x, state.root.y};
  status_.travelled += std::hypot(root.x - last_x_, root.y - last_y_);
  last_x_ = root.x;
  last_y_ = root.y;
  status_.total_turn += std::abs(state.root.heading - last_heading_);
  status_.root_turn += std::abs(state.turn_rate) * character.options().tick_seconds;
  last_heading_ = state.root.heading;
  status_.s = path.closest(root, status_.s - 0.5, status_.s + 1.0);
  const Point2 q = path.point_at(status_.s);
  const double tangent = path.heading_at(status_.s);
  status_.lateral_error = std::cos(tangent) * (root.y - q.y) - std::sin(tangent) * (root.x - q.x);
  status_.max_abs_error = std::max(status_.max_abs_error, std::abs(status_.lateral_error));
  // Where the jump happened: its middle against the gap's.
  if (jump_ >= 0 && jumped_curve_ >= 0 && state.space == jump_ &&
      state.phase != PlayPhase::kSource) {
    if (last_jump_t_ < 0.5 && state.t >= 0.5) {
      const double middle = 0.5 * (path.curve_start(jumped_curve_) + path.curve_end(jumped_curve_));
      status_.jump_offset = status_.s - middle;
      if (std::abs(status_.jump_offset) > std::abs(status_.max_abs_jump_offset)) {
        status_.max_abs_jump_offset = status_.jump_offset;
      }
    }
    last_jump_t_ = state.t;
  } else {
    last_jump_t_ = state.space == jump_ ? state.t : 0.0;
  }
  if (status_.s >= path.length() - options_.arrive_distance) {
    status_.done = true;
    status_.active = false;
    character.set_turn_rate(0);
    return;
  }
  const bool free = state.phase == PlayPhase::kFree && !state.fading;
  // Speed of the curve being walked.
  const int curve = path.curve_at(status_.s);
  current_curve_ = curve;
  double speed = -1;
  for (int c = curve; c >= 0 && speed < 0; --c) speed = path.curves()[c].speed;
  // The next gap within reach of the jump prediction.
  int gap = -1;
  if (jump_ >= 0) {
    for (int c = curve; c < static_cast<int>(path.curves().size()); ++c) {
      if (!path.curves()[c].gap || c == jumped_curve_) continue;
      const double middle = 0.5 * (path.curve_start(c) + path.curve_end(c));
      if (middle - status_.s <= options_.jump_search_distance) gap = c;
      break;
    }
  }
  if (gap < 0) approaching_ = false;
  if (speed >= 0 && state.space == locomotion_ && state.phase == PlayPhase::kFree &&
      !approaching_) {
    const GraphSpace& loco = character.graph().spaces[locomotion_];
    const double v = std::clamp(speed, loco.parameter_min(), loco.parameter_max());
    if (std::abs(state.p_target - v) > 1e-9) character.set_parameters(v);
  }
  // Curves: the turning space when the turn rate the path needs is large enough.
  if (turning_ >= 0 && free) {
    const GraphSpace& loco = character.graph().spaces[locomotion_];
    const double v = state.space == locomotion_ ? state.p
                     : speed >= 0               ? speed
                                  : 0.5 * (loco.parameter_min() + loco.parameter_max());
    const double a = status_.s + options_.lookahead;
    const double b = std::min(path.length(), a + options_.turn_preview);
    const double rate = b > a ? wrap_heading(path.heading_at(b) - path.heading_at(a)) / (b - a) *
                                    v * 180 / std::numbers::pi
                              : 0.0;
    const GraphSpace& turning = character.graph().spaces[turning_];
    const double applied = std::clamp(rate, turning.parameter_min(), turning.parameter_max());
    if (state.space == locomotion_ && gap < 0 && std::abs(rate) >= options_.turn_enter_rate) {
      character.request_motion(turning_, applied);
      ++status_.turning_requests;
    } else if (state.space == turning_) {
      if (gap >= 0 || std::abs(rate) < options_.turn_exit_rate) {
        character.request_motion(locomotion_, v);
      } else if (std::abs(state.p_target - applied) > 0.5) {
        character.set_parameters(applied);
      }
    }
  }
  // The gap: place the jump's middle on the gap's middle.
  if (gap >= 0 && state.space == locomotion_ && free) {
    const auto& k = path.curves()[gap].control;
    const double length = std::hypot(k[3].x - k[0].x, k[3].y - k[0].y);
    const double middle = 0.5 * (path.curve_start(gap) + path.curve_end(gap));
    const Placement placement = predict(state, jump_, length, 0.5, {0, 0});
    if (placement.found && approach(character, state, placement, middle - status_.s)) {
      character.request_motion(jump_, length);
      jumped_curve_ = gap;
      approaching_ = false;
      ++status_.jumps;
      status_.predicted_jump_middle = status_.s + placement.forward;
    }
  }
  // Pure pursuit on the look-ahead point, plus a lateral term.
  const Point2 aim = path.point_at(status_.s + options_.lookahead);
  const double desired = std::atan2(aim.y - root.y, aim.x - root.x);
  const double error = wrap_heading(desired - state.root.heading);
  character.set_turn_rate(options_.heading_gain * error -
                          options_.lateral_gain * status_.lateral_error);
}

}  // namespace fourd
