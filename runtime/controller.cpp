#include "runtime/controller.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "pipeline/core/error.h"
#include "runtime/root_math.h"

namespace fourd {

namespace {

Point2 bezier(const std::array<Point2, 4>& c, double u) {
  const double v = 1 - u;
  const double b0 = v * v * v, b1 = 3 * v * v * u, b2 = 3 * v * u * u, b3 = u * u * u;
  return {b0 * c[0].x + b1 * c[1].x + b2 * c[2].x + b3 * c[3].x,
          b0 * c[0].y + b1 * c[1].y + b2 * c[2].y + b3 * c[3].y};
}

double distance(const Point2& a, const Point2& b) { return std::hypot(a.x - b.x, a.y - b.y); }

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
}

Controller::Controller(Character& character, const ControllerOptions& options)
    : character_(character), options_(options) {
  options_.check();
  locomotion_ = character_.graph().find_space(options_.locomotion_space);
  jump_ = character_.graph().find_space(options_.jump_space);
  character_.set_tick_hook(this);
}

Controller::~Controller() { character_.set_tick_hook(nullptr); }

RequestStatus Controller::walk(double speed, double heading) {
  path_ = nullptr;
  status_.active = false;
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

void Controller::follow(const GroundPath* path) {
  path_ = path;
  steer_heading_ = false;
  status_ = FollowStatus{};
  status_.active = path != nullptr;
  current_curve_ = -1;
  jumped_curve_ = -1;
  if (!path) return;
  const CharacterState& s = character_.state();
  last_x_ = s.root.x;
  last_y_ = s.root.y;
  status_.s = path->closest({s.root.x, s.root.y}, 0.0, path->length());
}

void Controller::on_tick(Character& character, const CharacterState& state) {
  if (path_ && status_.active) {
    const GroundPath& path = *path_;
    const Point2 root{state.root.x, state.root.y};
    status_.travelled += std::hypot(root.x - last_x_, root.y - last_y_);
    last_x_ = root.x;
    last_y_ = root.y;
    status_.s = path.closest(root, status_.s - 0.5, status_.s + 1.0);
    const Point2 q = path.point_at(status_.s);
    const double tangent = path.heading_at(status_.s);
    status_.lateral_error =
        std::cos(tangent) * (root.y - q.y) - std::sin(tangent) * (root.x - q.x);
    status_.max_abs_error = std::max(status_.max_abs_error, std::abs(status_.lateral_error));
    if (status_.s >= path.length() - options_.arrive_distance) {
      status_.done = true;
      status_.active = false;
      character.set_turn_rate(0);
      return;
    }
    // Speed of the curve being walked, applied whenever the character is in locomotion.
    const int curve = path.curve_at(status_.s);
    current_curve_ = curve;
    double speed = -1;
    for (int c = curve; c >= 0 && speed < 0; --c) speed = path.curves()[c].speed;
    if (speed >= 0 && state.space == locomotion_ && state.phase == PlayPhase::kFree) {
      const GraphSpace& loco = character.graph().spaces[locomotion_];
      const double v = std::clamp(speed, loco.parameter_min(), loco.parameter_max());
      if (std::abs(state.p_target - v) > 1e-9) character.set_parameters(v);
    }
    // The next gap: predict where a jump requested now would peak; request it once that
    // reaches the middle of the gap.
    if (jump_ >= 0 && state.space == locomotion_ && state.phase == PlayPhase::kFree &&
        !state.fading) {
      for (int c = curve; c < static_cast<int>(path.curves().size()); ++c) {
        if (!path.curves()[c].gap || c == jumped_curve_) continue;
        const double middle = 0.5 * (path.curve_start(c) + path.curve_end(c));
        if (middle - status_.s > options_.jump_search_distance) break;
        const auto& k = path.curves()[c].control;
        const double length = std::hypot(k[3].x - k[0].x, k[3].y - k[0].y);
        const MotionGraph& g = character.graph();
        const int edge = g.find_edge(locomotion_, jump_);
        if (edge < 0) break;
        const TransitionPath p = search_.search(g, edge, {locomotion_, state.t, state.p},
                                                {jump_, length, -1}, character.transition_options());
        if (!p.found) break;
        const GraphSpace& loco = g.spaces[locomotion_];
        const GraphSpace& jump = g.spaces[jump_];
        std::array<float, 3> wl{}, wj{};
        space_weights(loco, state.p, &wl);
        space_weights(jump, p.entry.p, &wj);
        const std::span<const float> wls(wl.data(), loco.num_inputs());
        const std::span<const float> wjs(wj.data(), jump.num_inputs());
        const RootPose run_up = root_relative(space_root(loco.motion, state.t, wls),
                                              space_root(loco.motion, state.t + p.source_span, wls));
        const double flight = space_root(jump.motion, 0.5, wjs).x -
                              space_root(jump.motion, std::min(0.5, p.entry.t), wjs).x;
        const double predicted = status_.s + run_up.x + flight;
        // The search exits at a favoured phase of the cycle, so the prediction is a staircase
        // that steps by one cycle's travel: request on the step nearest to the gap's middle.
        const double cycle = space_root(loco.motion, 1.0, wls).x;
        if (predicted >= middle - 0.5 * cycle) {
          character.request_motion(jump_, length);
          jumped_curve_ = c;
          ++status_.jumps;
          status_.predicted_jump_middle = predicted;
        }
        break;
      }
    }
    // Pure pursuit on the look-ahead point, plus a lateral term.
    const Point2 aim = path.point_at(status_.s + options_.lookahead);
    const double desired = std::atan2(aim.y - root.y, aim.x - root.x);
    const double error = wrap_heading(desired - state.root.heading);
    character.set_turn_rate(options_.heading_gain * error -
                            options_.lateral_gain * status_.lateral_error);
    return;
  }
  if (steer_heading_) {
    character.set_turn_rate(options_.heading_gain * wrap_heading(heading_goal_ - state.root.heading));
  }
}

}  // namespace fourd
