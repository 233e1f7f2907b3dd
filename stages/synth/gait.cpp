// Walk, run and turn: a periodic gait whose root follows a straight line or a circular arc at
// exactly the requested speed and turn rate. Feet are planted in the world during stance
// (heel strike, flat foot, heel-off on the ball of the foot) and swing on smooth curves
// between footholds; the legs follow by two-bone IK from a pelvis whose height is the highest
// smooth, periodic curve at which both legs reach their feet.
//
// Pauses (MotionSpec::pauses): the gait's amplitude falls from 1 to 0 over a gait cycle and
// rises again over a cycle after the stand (minimum jerk). The root travels and turns at the
// amplitude times the gait's speed and turn rate, so the footholds (where the root is at
// mid-stance) close up into two feet side by side; the pelvis's bob, sway, roll and twist, the
// lean and the arm swing shrink with it, and the pelvis settles from its bobbing curve to a
// standing height. A step's lift and the feet's roll shrink with the step's length, so a foot
// never slides. The cadence is kept: standing, a "step" goes from a foothold to the same one.
// The root is still from about a cycle before the stand to about a cycle after it, so that no
// step that lands, rolls or lifts off in the stand moves: the last steps close up and the first
// one sets off around it. The body sways a few millimetres over the planted feet.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "pipeline/core/error.h"
#include "stages/synth/motion_generators.h"

namespace fourd::synth::detail {
namespace {

constexpr double kGravity = 9.81;
constexpr double kNominalLeg = 0.835;  // hip-to-ankle length of the 1.75 m performer [m]

struct Gait {
  double speed = 0;        // along the path [m/s]
  double omega = 0;        // turn rate [rad/s], + = left
  double cycle = 1;        // gait cycle [s] (a whole number of frames)
  double duty = 0.6;       // stance fraction of the cycle, per foot
  double half_width = 0;   // feet either side of the path [m]
  double plant_offset = 0; // flat foot ahead of the root at mid-stance [m]
  double heel_strike_pitch = 0, toe_off_pitch = 0;  // [rad], + = toes up
  double heel_rocker = 0.15;  // stance fraction rolling on the heel
  double heel_off = 0.55;     // stance fraction at which the heel lifts
  double lift = 0.05;         // swing clearance [m]
  double lift_peak = 0.5;     // swing fraction at the highest point
  double pelvis_drop = 0;     // nominal pelvis height below standing [m]
  double bob = 0;             // vertical oscillation [m], + = highest at mid-stance
  double sway = 0, roll = 0, twist = 0, chest_twist = 0, lean = 0;  // [m], [rad]
  double arm_swing = 0, elbow = 0, elbow_swing = 0;                  // [rad]
};

Gait make_gait(const Rig& rig, const MotionSpec& spec, double fps, int* cycle_frames) {
  const double k = rig.leg_length() / kNominalLeg;  // performer scale
  const double v = spec.speed;
  const bool running = spec.kind == "run";
  Gait g;
  g.speed = v;
  g.omega = spec.kind == "turn" ? spec.turn_rate * kDeg : 0.0;
  // Stride frequency grows with speed (stride length and cadence both increase), slower for
  // longer legs.
  const double frequency = running ? 1.35 * std::pow(std::max(v, 1.0) / 3.0, 0.3) / std::sqrt(k)
                                   : 0.92 * std::sqrt(std::max(v, 0.3) / 1.3) / std::sqrt(k);
  // A whole number of frames per cycle, and at least 4 (fewer cannot show a stride); the
  // stride is the speed times that cycle, so the clamp must not bind at a walk's cadence even
  // at 6 fps (at 8 frames, a 1.7 m/s walk took a 2.3 m stride there).
  *cycle_frames = std::max(4, static_cast<int>(std::lround(fps / frequency)));
  g.cycle = *cycle_frames / fps;
  const double stride = v * g.cycle;
  if (running) {
    g.duty = std::clamp(0.38 - 0.04 * (v - 3), 0.26, 0.45);
    g.half_width = 0.05 * k;
    g.plant_offset = -0.055 * stride;
    g.heel_strike_pitch = 6 * kDeg;
    g.heel_rocker = 0.1;
    g.heel_off = 0.4;
    g.toe_off_pitch = -55 * kDeg;
    g.lift = std::clamp(0.15 + 0.07 * (v - 2), 0.12, 0.35) * k;
    g.lift_peak = 0.35;
    g.pelvis_drop = 0.045 * k;
    // Highest mid-flight, curving down at g there: the flight is close to ballistic.
    g.bob = -std::min(0.04 * k, kGravity / std::pow(4 * M_PI / g.cycle, 2));
    g.sway = 0.01 * k;
    g.roll = 3 * kDeg;
    g.twist = 6 * kDeg;
    g.chest_twist = 8 * kDeg;
    g.lean = (6 + 2 * v) * kDeg;
    g.arm_swing = 35 * kDeg;
    g.elbow = 85 * kDeg;
    g.elbow_swing = 10 * kDeg;
  } else {
    g.duty = std::clamp(0.62 - 0.04 * (v - 1.3), 0.56, 0.68);
    g.half_width = 0.065 * k;
    g.plant_offset = -0.07 * stride;
    g.heel_strike_pitch = std::min(20.0, 10 + 6 * v / 1.3) * kDeg;
    g.toe_off_pitch = -std::clamp(65 + 8 * (v / 1.3 - 1), 58.0, 72.0) * kDeg;
    g.heel_off = 0.42;
    g.lift = 0.05 * k + 0.015 * v;
    g.lift_peak = 0.45;
    g.pelvis_drop = 0.01 * k;
    g.bob = 0.012 * k;
    g.sway = 0.025 * k * std::sqrt(1.3 / std::max(v, 0.8));
    g.roll = 4 * kDeg;
    g.twist = (3 + 2 * v) * kDeg;
    g.chest_twist = (2 + 2 * v) * kDeg;
    g.lean = (2 + 2 * v) * kDeg;
    g.arm_swing = (8 + 10 * v) * kDeg;
    g.elbow = (12 + 8 * v) * kDeg;
    g.elbow_swing = 10 * kDeg;
  }
  return g;
}

// The smallest signed angle from a to b.
double angle_difference(double a, double b) { return std::remainder(b - a, 2 * M_PI); }

Vector3d hermite(const Vector3d& p0, const Vector3d& m0, const Vector3d& p1, const Vector3d& m1, double s) {
  const double s2 = s * s, s3 = s2 * s;
  return (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * m1;
}

// ∫_0^x minimum_jerk: 2.5 x^4 - 3 x^5 + x^6 on [0, 1] (clamped; 0.5 at 1).
double minimum_jerk_integral(double x) {
  x = std::clamp(x, 0.0, 1.0);
  const double x4 = x * x * x * x;
  return x4 * (2.5 - 3 * x + x * x);
}

// How far the gait is under way at each time: 1 walking, 0 in a stand [t0, t1], a minimum-jerk
// ramp of `ramp` seconds down before each stand and up after it.
class PauseTiming {
 public:
  PauseTiming() = default;
  // The root is still over [at - before, last frame + after] of every pause [s].
  PauseTiming(const MotionSpec& spec, double fps, double ramp, double before, double after) : ramp_(ramp) {
    for (const PauseSpec& p : spec.pauses) {
      const double t0 = p.at / fps - before, t1 = (p.at + p.frames - 1) / fps + after;
      if (!stands_.empty() && t0 - ramp < stands_.back().second + ramp) {
        throw ConfigError(fmt::format("take {}: the stand from frame {} comes too soon after the one before: "
                                      "setting off, walking and slowing down again need {:.0f} frames between two stands",
                                      spec.take, p.at, std::ceil((2 * ramp + before + after) * fps)));
      }
      stands_.emplace_back(t0, t1);
    }
  }

  bool empty() const { return stands_.empty(); }

  double amplitude(double t) const {
    double a = 1;
    for (const auto& stand : stands_) {
      if (t < stand.first) {
        a *= 1 - minimum_jerk((t - stand.first + ramp_) / ramp_);
      } else if (t <= stand.second) {
        a = 0;
      } else {
        a *= minimum_jerk((t - stand.second) / ramp_);
      }
    }
    return a;
  }

  // ∫_0^t amplitude: the time the gait would have taken at full pace to get as far [s].
  double walked(double t) const {
    double w = t;
    for (const auto& stand : stands_) {
      const double after = std::clamp((t - stand.second) / ramp_, 0.0, 1.0);
      w -= ramp_ * minimum_jerk_integral((t - stand.first + ramp_) / ramp_) +
           std::clamp(t - stand.first, 0.0, stand.second - stand.first) +
           ramp_ * (after - minimum_jerk_integral(after));
    }
    return w;
  }

 private:
  std::vector<std::pair<double, double>> stands_;  // [first, last] standing time [s]
  double ramp_ = 1;
};

class GaitGenerator {
 public:
  GaitGenerator(const Rig& rig, const MotionSpec& spec, double fps) : rig_(rig), spec_(spec), fps_(fps) {
    gait_ = make_gait(rig, spec, fps, &cycle_frames_);
    start_ = start_state(spec);
    fit_pelvis_height();  // at full pace: before the pauses are set
    if (!spec.pauses.empty()) {
      // A foot that lands before the stand rolls onto it until heel_rocker of its stance; a
      // foot that stands into the stand lifts its heel from heel_off: the footholds of those
      // steps (root at mid-stance) must be where the root stands.
      const double before = (1 - (0.5 - gait_.heel_rocker) * gait_.duty) * gait_.cycle;
      const double after = (1 + (0.5 - gait_.heel_off) * gait_.duty) * gait_.cycle;
      pauses_ = PauseTiming(spec, fps, gait_.cycle, before + 1e-6, after + 1e-6);
      fit_stand_height();
    }
  }

  MotionClip run() const {
    MotionClip clip = sample_cyclic(rig_.skeleton, spec_, fps_, cycle_frames_, [&](double t) { return root(t); },
                                    [&](double t) { return phase(t); }, [&](double t) { return pose(t); });
    if (!pauses_.empty()) {
      for (int f = 0; f < spec_.frames; ++f) clip.amplitude.push_back(pauses_.amplitude(f / fps_));
    }
    return clip;
  }

 private:
  double phase(double t) const { return spec_.start_phase + t / gait_.cycle; }

  // The gait's amplitude at time t: 1 but around a pause.
  double amp(double t) const { return pauses_.empty() ? 1.0 : pauses_.amplitude(t); }

  RootState root(double time) const {
    const double t = pauses_.empty() ? time : pauses_.walked(time);
    RootState r;
    r.heading = start_.heading + gait_.omega * t;
    const double v = gait_.speed;
    if (std::abs(gait_.omega) < 1e-12) {
      r.position = start_.position + v * t * Vector2d(std::cos(start_.heading), std::sin(start_.heading));
    } else {
      // Constant speed along a circle: velocity v (cos h, sin h) with h = h0 + omega t.
      const double radius = v / gait_.omega;
      r.position = start_.position + radius * Vector2d(std::sin(r.heading) - std::sin(start_.heading),
                                                       std::cos(start_.heading) - std::cos(r.heading));
    }
    return r;
  }

  // ---- Feet ----
  static double foot_phase_offset(int side) { return side == 0 ? 0.0 : 0.5; }

  // Foothold of stance number n of a foot: beside the path where the root is at mid-stance.
  void foothold(int side, long n, Vector2d* ground, double* yaw) const {
    const double t_mid = (static_cast<double>(n) + foot_phase_offset(side) + gait_.duty / 2 - spec_.start_phase) * gait_.cycle;
    const RootState r = root(t_mid);
    const double lateral = side == 0 ? gait_.half_width : -gait_.half_width;
    *ground = r.position + Eigen::Rotation2Dd(r.heading) * Vector2d(gait_.plant_offset * amp(t_mid), lateral);
    *yaw = r.heading;
  }

  // How much of a step from stance n of a foot to stance n + 1 is taken: 1 at a quarter of a
  // full stride or more, down to 0 for a step on the spot; the lift and the feet's roll scale
  // with it.
  double step_scale(int side, long n) const {
    if (pauses_.empty()) return 1.0;
    Vector2d g0, g1;
    double yaw0, yaw1;
    foothold(side, n, &g0, &yaw0);
    foothold(side, n + 1, &g1, &yaw1);
    return std::min(1.0, (g1 - g0).norm() / (0.25 * gait_.speed * gait_.cycle));
  }

  double stance_pitch(double sigma) const {
    if (sigma < gait_.heel_rocker) return gait_.heel_strike_pitch * (1 - smoothstep01(sigma / gait_.heel_rocker));
    if (sigma > gait_.heel_off) return gait_.toe_off_pitch * std::pow((sigma - gait_.heel_off) / (1 - gait_.heel_off), 1.5);
    return 0;
  }

  FootState stance(int side, long n, double sigma) const {
    Vector2d ground;
    double yaw;
    foothold(side, n, &ground, &yaw);
    // Rolling off the heel ends the step that landed, lifting the heel starts the next one.
    const double a = sigma < gait_.heel_rocker ? step_scale(side, n - 1) : step_scale(side, n);
    return planted_foot(rig_, ground, yaw, stance_pitch(sigma) * a);
  }

  FootState swing(int side, long n, double s) const {
    const FootState lift_off = stance(side, n, 1), touch_down = stance(side, n + 1, 0);
    // Match the ankle's velocity at both ends of the swing (finite differences of the stance).
    const double eps = 1e-4, stance_time = gait_.duty * gait_.cycle, swing_time = (1 - gait_.duty) * gait_.cycle;
    const Vector3d v0 = (lift_off.ankle - stance(side, n, 1 - eps).ankle) / (eps * stance_time);
    const Vector3d v1 = (stance(side, n + 1, eps).ankle - touch_down.ankle) / (eps * stance_time);
    Vector3d ankle = hermite(lift_off.ankle, v0 * swing_time, touch_down.ankle, v1 * swing_time, s);
    const double a = step_scale(side, n);
    const double bump = std::sin(M_PI * std::pow(s, std::log(0.5) / std::log(gait_.lift_peak)));
    ankle.z() += a * gait_.lift * bump * bump;
    Vector2d g0, g1;
    double yaw0, yaw1;
    foothold(side, n, &g0, &yaw0);
    foothold(side, n + 1, &g1, &yaw1);
    const double yaw = yaw0 + angle_difference(yaw0, yaw1) * smoothstep01(s);
    const double pitch = a * (gait_.toe_off_pitch * (1 - smoothstep01(s / 0.45)) +
                              gait_.heel_strike_pitch * smoothstep01((s - 0.55) / 0.45));
    const double toe_bend = -a * gait_.toe_off_pitch * (1 - smoothstep01(s / 0.3));
    return free_foot(ankle, yaw, pitch, toe_bend);
  }

  FootState foot(int side, double t) const {
    const double lambda = phase(t) - foot_phase_offset(side);
    const long n = static_cast<long>(std::floor(lambda));
    const double tau = lambda - static_cast<double>(n);
    if (tau < gait_.duty) return stance(side, n, tau / gait_.duty);
    return swing(side, n, (tau - gait_.duty) / (1 - gait_.duty));
  }

  // ---- Body ----
  double turn_lean() const { return -std::atan(gait_.speed * gait_.omega / kGravity); }

  Matrix3d pelvis_rotation(double t) const {
    const double phi = phase(t), mid = gait_.duty / 2, a = amp(t);
    const double twist = -a * gait_.twist * std::cos(2 * M_PI * phi);
    const double roll = a * gait_.roll * std::cos(2 * M_PI * (phi - mid));
    return rot_z(root(t).heading + twist) * rot_x(roll + a * a * turn_lean()) * rot_y(0.5 * a * gait_.lean);
  }

  // Standing, the body sways over the feet as a person's does (a few millimetres, slowly).
  Vector2d stand_sway(double t) const {
    const double k = rig_.leg_length() / kNominalLeg;
    return Vector2d(0.004 * k * std::sin(2 * M_PI * 0.17 * t + 1), 0.007 * k * std::sin(2 * M_PI * 0.23 * t));
  }

  Vector2d pelvis_xy(double t) const {
    const RootState r = root(t);
    const double a = amp(t);
    const double sway = a * gait_.sway * std::cos(2 * M_PI * (phase(t) - gait_.duty / 2));
    Vector2d offset(0, sway);
    if (a < 1) offset += (1 - a) * stand_sway(t);
    return r.position + Eigen::Rotation2Dd(r.heading) * offset;
  }

  double nominal_height(double phi) const {
    return rig_.pelvis_height - gait_.pelvis_drop + gait_.bob * std::cos(4 * M_PI * (phi - gait_.duty / 2));
  }

  double pelvis_height(double phi) const {
    double h = height_cos_[0];
    for (std::size_t m = 1; m < height_cos_.size(); ++m) {
      h += height_cos_[m] * std::cos(2 * M_PI * m * phi) + height_sin_[m] * std::sin(2 * M_PI * m * phi);
    }
    return h;
  }

  // The pelvis height over one cycle: the nominal bobbing curve, cut where the legs would not
  // reach, smoothed to a few harmonics, then lowered until it is reachable everywhere.
  void fit_pelvis_height() {
    const int n = 8 * cycle_frames_;
    constexpr int kHarmonics = 4;
    constexpr double kReach = 0.996;  // knees never lock completely
    std::vector<double> phi(n), limit(n), target(n);
    for (int k = 0; k < n; ++k) {
      const double t = k * gait_.cycle / n;
      phi[k] = phase(t);
      limit[k] = max_pelvis_height(rig_, pelvis_xy(t), pelvis_rotation(t), {foot(0, t).ankle, foot(1, t).ankle}, kReach);
      if (!std::isfinite(limit[k]) || limit[k] < 0.5 * rig_.pelvis_height) {
        throw SolverError(fmt::format("take {}: a {} at {} m/s is beyond the performer's legs (no pelvis height "
                                      "reaches both feet)", spec_.take, spec_.kind, spec_.speed));
      }
      target[k] = std::min(nominal_height(phi[k]), limit[k]);
    }
    height_cos_.assign(kHarmonics + 1, 0.0);
    height_sin_.assign(kHarmonics + 1, 0.0);
    for (int m = 0; m <= kHarmonics; ++m) {
      for (int k = 0; k < n; ++k) {
        height_cos_[m] += target[k] * std::cos(2 * M_PI * m * phi[k]);
        height_sin_[m] += target[k] * std::sin(2 * M_PI * m * phi[k]);
      }
      height_cos_[m] *= (m == 0 ? 1.0 : 2.0) / n;
      height_sin_[m] *= (m == 0 ? 0.0 : 2.0) / n;
    }
    double violation = 0;
    for (int k = 0; k < n; ++k) violation = std::max(violation, pelvis_height(phi[k]) - limit[k]);
    height_cos_[0] -= violation;
  }

  // The pelvis's height standing still: the nominal one, lowered until the legs reach the feet
  // side by side wherever the standing sway puts the pelvis.
  void fit_stand_height() {
    constexpr double kReach = 0.996;
    const RootState r = root(0);
    const Matrix3d pelvis = rot_z(r.heading);
    std::array<Vector3d, 2> ankles;
    for (int side = 0; side < 2; ++side) {
      const double lateral = side == 0 ? gait_.half_width : -gait_.half_width;
      ankles[static_cast<std::size_t>(side)] =
          planted_foot(rig_, r.position + Eigen::Rotation2Dd(r.heading) * Vector2d(0, lateral), r.heading, 0).ankle;
    }
    const double k = rig_.leg_length() / kNominalLeg;
    stand_height_ = rig_.pelvis_height - gait_.pelvis_drop;
    for (double dx : {-0.004 * k, 0.004 * k}) {
      for (double dy : {-0.007 * k, 0.007 * k}) {
        const Vector2d xy = r.position + Eigen::Rotation2Dd(r.heading) * Vector2d(dx, dy);
        stand_height_ = std::min(stand_height_, max_pelvis_height(rig_, xy, pelvis, ankles, kReach));
      }
    }
  }

  WorldPose pose(double t) const {
    const Skeleton& sk = rig_.skeleton;
    WorldPose pose(sk.size());
    const double phi = phase(t), a = amp(t);
    const double heading = root(t).heading;
    const Vector2d xy = pelvis_xy(t);
    const Matrix3d pelvis = pelvis_rotation(t);
    const std::array<FootState, 2> feet = {foot(0, t), foot(1, t)};
    double height = pelvis_height(phi);
    if (a < 1) {
      constexpr double kReach = 0.996;
      height = std::min(a * height + (1 - a) * stand_height_,
                        max_pelvis_height(rig_, xy, pelvis, {feet[0].ankle, feet[1].ankle}, kReach));
    }
    pose.root = Vector3d(xy.x(), xy.y(), height);
    const Matrix3d chest = rot_z(heading + a * gait_.chest_twist * std::cos(2 * M_PI * phi)) *
                           rot_x(a * a * turn_lean()) * rot_y(a * gait_.lean);
    // Look a little into the turn.
    const double look = std::clamp(a * 0.3 * gait_.omega, -25 * kDeg, 25 * kDeg);
    const Matrix3d head = rot_z(heading + look) * rot_x(0.5 * a * a * turn_lean());
    set_trunk(rig_, pelvis, chest, head, pose);
    // Arms swing with the opposite leg, slightly late; standing, they hang, elbows a little bent.
    constexpr double kStandElbow = 8 * kDeg;
    const double swing = a * gait_.arm_swing * std::cos(2 * M_PI * (phi - 0.03));
    const double elbow = a < 1 ? a * gait_.elbow + (1 - a) * kStandElbow : gait_.elbow;
    for (int side = 0; side < 2; ++side) {
      const double s = side == 0 ? -swing : swing;
      hang_arm(rig_, side, s, elbow + gait_.elbow_swing * std::max(0.0, s / gait_.arm_swing), pose);
    }
    solve_legs(rig_, feet, pose);
    return pose;
  }

  const Rig& rig_;
  const MotionSpec& spec_;
  double fps_;
  Gait gait_;
  int cycle_frames_ = 0;
  RootState start_;
  std::vector<double> height_cos_, height_sin_;
  PauseTiming pauses_;       // none: walking throughout
  double stand_height_ = 0;  // the pelvis's height standing still [m]
};

}  // namespace

MotionClip generate_gait(const Rig& rig, const MotionSpec& spec, double fps) {
  return GaitGenerator(rig, spec, fps).run();
}

}  // namespace fourd::synth::detail
