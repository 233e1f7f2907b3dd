// Dance: steps on the spot with wide arm swings, a spin, and back to standing; material for a
// loose skirt to swing and flare. Over the take's duration T:
//
//   0 .. 0.12 T       standing; the arms sweep out from hanging to almost level
//   0.12 .. 0.92 T    steps on the spot, the feet in turn, the hips swaying over the standing
//                     foot; before and after the spin the raised arms swing forward and back
//   0.2 .. 0.85 T     the spin: the heading turns by turn_rate x T, its rate rising and falling
//                     smoothly; the dancer rises onto the balls of the feet, arms held out, the
//                     upper body leading the turn; a standing foot pivots with it
//   0.92 .. T         back to standing, the arms lowered
//
// A spin's steps come often enough that a standing foot pivots at most about 70 degrees.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "pipeline/core/error.h"
#include "stages/synth/motion_generators.h"

namespace fourd::synth::detail {
namespace {

constexpr double kNominalLeg = 0.835;  // hip-to-ankle length of the 1.75 m performer [m]
constexpr double kStepsFrom = 0.12, kStepsTo = 0.92;  // fractions of the take
constexpr double kSpinFrom = 0.2, kSpinTo = 0.85;
constexpr double kSpinRamp = 0.3;   // fraction of the spin over which its rate rises (and falls)
constexpr double kDuty = 0.55;      // fraction of a foot's step cycle on the floor
constexpr double kMaxPivotDeg = 70;  // a standing foot turns at most this much, about
constexpr double kReleveDeg = 25;    // heels up (on the balls of the feet) at the spin's peak

// The angle from a to b, in (-pi, pi].
double angle_difference(double a, double b) { return std::remainder(b - a, 2 * M_PI); }

class DanceGenerator {
 public:
  DanceGenerator(const Rig& rig, const MotionSpec& spec, double fps) : rig_(rig), spec_(spec), fps_(fps) {
    require_frames(spec, 1.5, fps);
    start_ = start_state(spec);
    duration_ = (spec.frames - 1) / fps;
    k_ = rig.leg_length() / kNominalLeg;
    spin_ = spec.turn_rate * kDeg * duration_;
    peak_rate_ = std::abs(spin_) / ((kSpinTo - kSpinFrom) * duration_ * (1 - kSpinRamp));
    cycle_ = std::clamp(kMaxPivotDeg * kDeg / std::max(peak_rate_ * kDuty, 1e-9), 0.32, 0.6);
    plan_steps();
  }

  MotionClip run() const {
    MotionClip clip = sample_one_shot(
        rig_, spec_, fps_, [&](double t) { return RootState{start_.position, heading(t)}; },
        [&](double t) { return pose(t); });
    const double turned = clip.root.back().heading - clip.root.front().heading;
    clip.parameters = {{"direction_deg_per_s", turned / kDeg / duration_},
                       {"spin_deg", spin_ / kDeg},
                       {"spin_peak_deg_per_s", std::copysign(peak_rate_, spin_) / kDeg}};
    return clip;
  }

 private:
  struct Foothold {
    Vector2d ground;
    double yaw = 0;
  };

  // The spin's progress in [0, 1] at `u` of its time: the integral of a rate that rises as a
  // smoothstep over kSpinRamp, holds, and falls the same way, normalised.
  static double spin_progress(double u) {
    const double a = kSpinRamp;
    auto rise = [&](double x) { return a * (x * x * x - 0.5 * x * x * x * x); };  // a * integral of smoothstep
    double area;
    if (u <= 0) return 0;
    if (u >= 1) return 1;
    if (u < a) {
      area = rise(u / a);
    } else if (u <= 1 - a) {
      area = 0.5 * a + (u - a);
    } else {
      area = (1 - a) - rise((1 - u) / a);
    }
    return area / (1 - a);
  }

  // The spin's rate relative to its peak, in [0, 1].
  double spin_intensity(double t) const {
    const double u = (t / duration_ - kSpinFrom) / (kSpinTo - kSpinFrom);
    if (u <= 0 || u >= 1) return 0;
    return smoothstep01(u / kSpinRamp) * smoothstep01((1 - u) / kSpinRamp);
  }

  double heading(double t) const {
    return start_.heading + spin_ * spin_progress((t / duration_ - kSpinFrom) / (kSpinTo - kSpinFrom));
  }

  // Rises from 0 to 1 and falls back over the stepping, eased over a step cycle at each end.
  double stepping(double t) const {
    const double t0 = kStepsFrom * duration_, t1 = kStepsTo * duration_;
    return smoothstep01((t - t0) / cycle_) * smoothstep01((t1 - t) / cycle_);
  }

  Foothold foothold_at(int side, double t) const {
    const double h = heading(t);
    return {start_.position + Eigen::Rotation2Dd(h) * rig_.foot_ground[static_cast<std::size_t>(side)], h};
  }

  // Each foot's swings (start times) and the footholds between them: footholds_[side][m] is
  // where the foot stands before swing m (m = 0: the rest stance), each placed beside the spot
  // at the heading of the middle of its stance; the last at the final heading.
  void plan_steps() {
    const double t0 = kStepsFrom * duration_, t1 = kStepsTo * duration_;
    const double swing = (1 - kDuty) * cycle_;
    for (int side = 0; side < 2; ++side) {
      auto& starts = swings_[static_cast<std::size_t>(side)];
      auto& holds = footholds_[static_cast<std::size_t>(side)];
      holds.push_back(foothold_at(side, 0));
      for (int m = 0;; ++m) {
        const double s = t0 + (m + 0.5 * side) * cycle_;
        if (s + swing > t1) break;
        starts.push_back(s);
        holds.push_back(foothold_at(side, std::min(duration_, s + swing + 0.5 * kDuty * cycle_)));
      }
      holds.back() = foothold_at(side, duration_);
    }
  }

  // A standing foot turns with the body, at most kMaxPivotDeg from where it was put down, and
  // rises onto its ball with the spin.
  FootState standing(const Foothold& hold, double t) const {
    const double pivot = std::clamp(angle_difference(hold.yaw, heading(t)), -kMaxPivotDeg * kDeg, kMaxPivotDeg * kDeg);
    return planted_foot(rig_, hold.ground, hold.yaw + pivot, -kReleveDeg * kDeg * spin_intensity(t));
  }

  FootState foot(int side, double t) const {
    const auto& starts = swings_[static_cast<std::size_t>(side)];
    const auto& holds = footholds_[static_cast<std::size_t>(side)];
    const std::size_t m = static_cast<std::size_t>(std::upper_bound(starts.begin(), starts.end(), t) - starts.begin());
    if (m == 0) return standing(holds[0], t);
    const double s = starts[m - 1], swing = (1 - kDuty) * cycle_;
    if (t >= s + swing) return standing(holds[m], t);
    // In the air: from the last stance's end to the next one's start, lifted in between.
    const FootState from = standing(holds[m - 1], s), to = standing(holds[m], s + swing);
    const double sigma = (t - s) / swing, e = smoothstep01(sigma);
    Vector3d ankle = (1 - e) * from.ankle + e * to.ankle;
    ankle.z() += 0.08 * k_ * std::pow(std::sin(M_PI * sigma), 2);
    const double yaw_from = std::atan2(from.rotation(1, 0), from.rotation(0, 0));
    const double yaw = yaw_from + angle_difference(yaw_from, std::atan2(to.rotation(1, 0), to.rotation(0, 0))) * e;
    // On the balls of the feet the toes stay level, as they were on the floor.
    const double pitch = -kReleveDeg * kDeg * spin_intensity(t);
    return free_foot(ankle, yaw, pitch, -pitch);
  }

  // The step cycle's phase of the left foot: 0 as its swing's middle.
  double step_phase(double t) const {
    return 2 * M_PI * (t - kStepsFrom * duration_ - 0.5 * (1 - kDuty) * cycle_) / cycle_;
  }

  WorldPose pose(double t) const {
    const Skeleton& sk = rig_.skeleton;
    WorldPose pose(sk.size());
    const double h = heading(t), spin = spin_intensity(t), steps = stepping(t);
    const double phase = step_phase(t);
    // The hips over the standing foot (the right one while the left swings), less in the spin.
    const double sway = -0.03 * k_ * steps * (1 - 0.7 * spin) * std::cos(phase);
    const Vector2d xy = start_.position + Eigen::Rotation2Dd(h) * Vector2d(0, sway);
    const Matrix3d pelvis = rot_z(h + 8 * kDeg * steps * std::sin(phase)) * rot_x(-4 * kDeg * steps * std::cos(phase));
    const std::array<FootState, 2> feet = {foot(0, t), foot(1, t)};
    const double wanted = rig_.pelvis_height - 0.03 * k_ + 0.03 * k_ * spin;
    const double reach = max_pelvis_height(rig_, xy, pelvis, {feet[0].ankle, feet[1].ankle}, 0.995);
    pose.root = Vector3d(xy.x(), xy.y(), std::min(wanted, reach - 1e-3));
    // The upper body leads the spin and turns against the hips with the steps.
    const double rate = (heading(t + 1e-3) - heading(t - 1e-3)) / 2e-3;
    const double lead = std::clamp(0.12 * rate, -25 * kDeg, 25 * kDeg);
    const Matrix3d chest = rot_z(h + lead - 10 * kDeg * steps * (1 - spin) * std::sin(phase)) * rot_y(3 * kDeg);
    const Matrix3d head = rot_z(h + 0.5 * lead);
    set_trunk(rig_, pelvis, chest, head, pose);
    // Arms: out from hanging to almost level and back; with the steps, wide swings forward and
    // back (the left arm forward as the left foot swings), none in the spin.
    const double T = duration_;
    const double drop = keyframes({{0, 80 * kDeg}, {0.15 * T, 15 * kDeg}, {kSpinFrom * T, 5 * kDeg},
                                   {kSpinTo * T, 5 * kDeg}, {0.97 * T, 80 * kDeg}},
                                  t);
    const double sweep = 45 * kDeg * steps * (1 - spin) * std::cos(phase);
    hold_arm(rig_, 0, drop, 0, 20 * kDeg, pose, 0, sweep);
    hold_arm(rig_, 1, drop, 0, 20 * kDeg, pose, 0, -sweep);
    solve_legs(rig_, feet, pose);
    return pose;
  }

  const Rig& rig_;
  const MotionSpec& spec_;
  double fps_;
  RootState start_;
  double duration_ = 0, k_ = 1, spin_ = 0, peak_rate_ = 0, cycle_ = 0.5;
  std::array<std::vector<double>, 2> swings_;
  std::array<std::vector<Foothold>, 2> footholds_;
};

}  // namespace

MotionClip generate_dance(const Rig& rig, const MotionSpec& spec, double fps) {
  return DanceGenerator(rig, spec, fps).run();
}

}  // namespace fourd::synth::detail
