// The quadruped's gaits: walk (four-beat, lateral sequence), trot (diagonal pairs) and gallop
// (transverse, with a suspension phase). Each is periodic with a cycle of exactly T seconds,
// not a whole number of frames in general, along a straight line at exactly the spec's speed.
// A hoof in stance stays where it landed, flat on the floor; in swing it follows a smooth curve
// to its next foothold, flexing, and lifted so that no part of it goes below the floor. The
// trunk is rigid: the heights of its hind and front ends (over the hips and the shoulders) are
// smooth periodic curves, the highest at which all four legs reach their hooves, so the body
// bobs and pitches with the footfalls. The legs follow by IK: the cannon's angle from the leg's,
// the upper two bones by two-bone IK, the elbow pointing back, the stifle forward.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "pipeline/core/error.h"
#include "stages/synth/motion_generators.h"
#include "stages/synth/quadruped.h"

namespace fourd::synth::detail {
namespace {

constexpr double kGravity = 9.81;
constexpr double kReach = 0.985;  // legs never straighten completely above the cannon
constexpr int kHarmonics = 8;     // of the trunk's height curves

// Legs in the order front left, front right, hind left, hind right.
constexpr int kLegs = 4;
bool is_front(int leg) { return leg < 2; }

struct Leg {
  std::array<int, 4> joint{};  // top (upper_arm, thigh), middle, cannon, hoof (at the fetlock)
  std::array<Vector3d, 4> rest;  // the joints' rest world positions
  double upper = 0, lower = 0, cannon = 0;  // bone lengths
  double cannon_rest_angle = 0;  // the cannon's rest angle from vertical, + = its bottom ahead
  double leg_rest_angle = 0;     // the same for the line from the top to the fetlock
  double bend = 1;               // the middle joint points ahead (+1, stifle) or behind (-1, elbow)
  HoofShape hoof;
};

struct QuadrupedRig {
  explicit QuadrupedRig(const Skeleton& sk) : skeleton(sk) {
    auto require = [&](const std::string& name) {
      const int j = sk.find(name);
      if (j < 0) throw InputError(fmt::format("quadruped gait: the skeleton has no joint '{}'", name));
      return j;
    };
    pelvis = require("pelvis");
    spine = require("spine");
    chest = require("chest");
    neck = require("neck");
    head = require("head");
    for (int k = 0; k < 3; ++k) tail[static_cast<std::size_t>(k)] = require(fmt::format("tail_{}", k));
    const auto world = forward_kinematics(sk, rest_pose(sk));
    for (const auto& w : world) rest.push_back(w.translation());
    const char* names[2][4] = {{"upper_arm", "forearm", "front_cannon", "front_hoof"},
                               {"thigh", "shin", "hind_cannon", "hind_hoof"}};
    for (int l = 0; l < kLegs; ++l) {
      Leg& leg = legs[static_cast<std::size_t>(l)];
      for (std::size_t k = 0; k < 4; ++k) {
        leg.joint[k] = require(std::string(names[is_front(l) ? 0 : 1][k]) + (l % 2 == 0 ? "_l" : "_r"));
        leg.rest[k] = rest[static_cast<std::size_t>(leg.joint[k])];
      }
      leg.upper = (leg.rest[1] - leg.rest[0]).norm();
      leg.lower = (leg.rest[2] - leg.rest[1]).norm();
      leg.cannon = (leg.rest[3] - leg.rest[2]).norm();
      leg.cannon_rest_angle = std::atan2(leg.rest[3].x() - leg.rest[2].x(), leg.rest[2].z() - leg.rest[3].z());
      leg.leg_rest_angle = std::atan2(leg.rest[3].x() - leg.rest[0].x(), leg.rest[0].z() - leg.rest[3].z());
      leg.bend = is_front(l) ? -1 : 1;
      leg.hoof = hoof_shape(leg.rest[3].z());
    }
    hip_height = legs[2].rest[0].z();
  }

  const Skeleton& skeleton;
  int pelvis, spine, chest, neck, head;
  std::array<int, 3> tail{};
  std::vector<Vector3d> rest;
  std::array<Leg, kLegs> legs;
  double hip_height = 0;  // the hips' rest height: the leg length of the gaits' scaling
};

struct QuadrupedGait {
  double speed = 0;
  double cycle = 1;  // [s]
  std::array<double, kLegs> touch_down{};  // phase of each leg's touch-down
  double duty = 0.6;                        // stance fraction of the cycle
  double lift = 0;                          // hoof clearance at mid-swing [m] (the front's; hind 0.85x)
  double lift_peak = 0.4;                   // swing fraction at the highest point
  double hoof_flex = 0;                     // the hoof's flexion at mid-swing [rad]
  std::array<double, 2> cannon_flex{};      // the knee's and the hock's flexion in swing [rad]
  double crouch = 0;                        // trunk lowered from its rest height [m]
  double bob = 0;                           // height oscillation [m], + = highest at mid-stance
  int bob_harmonic = 2;                     // oscillations per cycle
  double nod = 0;                           // neck nod amplitude [rad]
  double tail_lift = 0, tail_sway = 0;      // [rad]
};

// Each gait's footfalls and style. Lengths are fractions of the hip height, angles degrees.
struct GaitStyle {
  const char* kind;
  double froude_lo, froude_hi;  // the speeds it is performed at, as Froude numbers v^2 / (g h)
  std::array<double, kLegs> touch_down;
  double duty, duty_per_froude, duty_lo;  // duty = clamp(duty - duty_per_froude x Froude, duty_lo, duty)
  double lift, lift_peak, hoof_flex;
  std::array<double, 2> cannon_flex;
  double crouch, bob;
  int bob_harmonic;
  double nod, tail_lift, tail_sway;
};
// Walk: the lateral sequence LH, LF, RH, RF. Trot: LF with RH, RF with LH. Gallop: transverse,
// right lead: LH, RH, LF, RF, then all four in the air.
constexpr GaitStyle kStyles[] = {
    {"walk", 0.02, 0.35, {0.25, 0.75, 0.0, 0.5}, 0.72, 0.3, 0.6, 0.09, 0.4, 55, {35, 15}, 0.015, 0.006, 2, 4, 0, 6},
    {"trot", 0.15, 1.5, {0.0, 0.5, 0.5, 0.0}, 0.48, 0.06, 0.38, 0.14, 0.4, 75, {55, 25}, 0.03, -0.02, 2, 2, 10, 4},
    {"gallop", 0.8, 6, {0.38, 0.5, 0.0, 0.1}, 0.3, 0.02, 0.18, 0.2, 0.45, 90, {75, 35}, 0.04, -0.03, 1, 8, 25, 3}};

// The gait of a take. Stride length follows Alexander's relation for mammals (stride / leg
// length = 2.3 Froude^0.3), and the cycle the stride and the speed.
QuadrupedGait make_gait(const QuadrupedRig& rig, const MotionSpec& spec) {
  const double h = rig.hip_height, v = spec.speed;
  const double froude = v * v / (kGravity * h);
  const GaitStyle* style = nullptr;
  for (const GaitStyle& s : kStyles) {
    if (spec.kind == s.kind) style = &s;
  }
  if (style == nullptr) throw ConfigError(fmt::format("take {}: '{}' is not a quadruped's gait", spec.take, spec.kind));
  if (froude < style->froude_lo || froude > style->froude_hi) {
    throw ConfigError(fmt::format(
        "take {}: a quadruped {} needs a speed in [{:.2f}, {:.2f}] m/s for its {:.2f} m legs (Froude number {} to "
        "{}), not {}", spec.take, spec.kind, std::sqrt(style->froude_lo * kGravity * h),
        std::sqrt(style->froude_hi * kGravity * h), h, style->froude_lo, style->froude_hi, v));
  }
  QuadrupedGait g;
  g.speed = v;
  g.cycle = 2.3 * h * std::pow(froude, 0.3) / v;
  g.touch_down = style->touch_down;
  g.duty = std::clamp(style->duty - style->duty_per_froude * froude, style->duty_lo, style->duty);
  g.lift = style->lift * h;
  g.lift_peak = style->lift_peak;
  g.hoof_flex = style->hoof_flex * kDeg;
  g.cannon_flex = {style->cannon_flex[0] * kDeg, style->cannon_flex[1] * kDeg};
  g.crouch = style->crouch * h;
  g.bob = style->bob * h;
  g.bob_harmonic = style->bob_harmonic;
  g.nod = style->nod * kDeg;
  g.tail_lift = style->tail_lift * kDeg;
  g.tail_sway = style->tail_sway * kDeg;
  return g;
}

class Generator {
 public:
  Generator(const Skeleton& skeleton, const MotionSpec& spec, double fps)
      : rig_(skeleton), spec_(spec), fps_(fps), gait_(make_gait(rig_, spec)) {
    start_ = start_state(spec);
    heading_ = rot_z(start_.heading);
    fit_heights();
  }

  MotionClip run() const {
    return sample_cyclic(rig_.skeleton, spec_, fps_, gait_.cycle * fps_, [&](double t) { return root(t); },
                         [&](double t) { return phase(t); }, [&](double t) { return pose(t); });
  }

 private:
  // One end of the trunk: its height and the state of the legs that carry it.
  struct Trunk {
    Matrix3d rotation;
    Vector3d root;  // the pelvis joint
  };
  struct Hoof {
    Vector3d fetlock;
    double flex = 0;     // [rad], + = the sole turns back (rot_y)
    double swing = -1;   // swing fraction, or -1 in stance
  };

  double phase(double t) const { return spec_.start_phase + t / gait_.cycle; }
  double time_of(double phi) const { return (phi - spec_.start_phase) * gait_.cycle; }

  RootState root(double t) const {
    RootState r;
    r.heading = start_.heading;
    r.position = start_.position + gait_.speed * t * Vector2d(std::cos(start_.heading), std::sin(start_.heading));
    return r;
  }

  // A rest point relative to the pelvis, carried along the path (no pitch, rest height).
  Vector3d carried(const Vector3d& rest_point, double t) const {
    const Vector2d xy = root(t).position;
    const Vector3d offset = heading_ * (rest_point - rig_.rest[static_cast<std::size_t>(rig_.pelvis)]);
    return Vector3d(xy.x() + offset.x(), xy.y() + offset.y(), rest_point.z());
  }

  // The fetlock of stance n: where the hoof is at rest relative to the body at mid-stance.
  Vector3d foothold(int leg, long n) const {
    const double mid = static_cast<double>(n) + gait_.touch_down[static_cast<std::size_t>(leg)] + gait_.duty / 2;
    return carried(rig_.legs[static_cast<std::size_t>(leg)].rest[3], time_of(mid));
  }

  // How far along its swing a hoof has travelled at swing fraction s, 0 to 1: from rest (the
// hoof leaves the floor without sliding) it speeds up over the first kRamp of the swing, keeps
// its pace, and slows down to rest over the last kRamp. A slower start (smoothstep, minimum
// jerk) leaves the hoof so far behind the moving body in a gallop that the leg cannot reach it.
static double swing_travel(double s) {
  constexpr double kRamp = 0.12;
  const double pace = 1 / (1 - kRamp);
  auto ramp = [&](double x) {  // distance covered after x of a ramp, its speed rising as smoothstep
    const double u = std::clamp(x / kRamp, 0.0, 1.0);
    return pace * kRamp * (u * u * u - 0.5 * u * u * u * u);
  };
  if (s < kRamp) return ramp(s);
  if (s > 1 - kRamp) return 1 - ramp(1 - s);
  return pace * (0.5 * kRamp + (s - kRamp));
}

// The lowest point of the hoof under a flexion, relative to its fetlock.
  static double hoof_bottom(const HoofShape& hoof, double flex) {
    const Matrix3d r = rot_y(flex);
    const Vector3d c = r * hoof.centre;
    double extent = 0;
    for (int i = 0; i < 3; ++i) extent += std::pow(r(2, i) * hoof.radii[i], 2);
    return c.z() - std::sqrt(extent);
  }

  Hoof hoof(int leg, double t) const {
    const Leg& l = rig_.legs[static_cast<std::size_t>(leg)];
    const double lambda = phase(t) - gait_.touch_down[static_cast<std::size_t>(leg)];
    const long n = static_cast<long>(std::floor(lambda));
    const double tau = lambda - static_cast<double>(n);
    Hoof h;
    if (tau < gait_.duty) {
      h.fetlock = foothold(leg, n);
      return h;
    }
    const double s = (tau - gait_.duty) / (1 - gait_.duty);
    const Vector3d a = foothold(leg, n), b = foothold(leg, n + 1);
    h.swing = s;
    h.fetlock = a + (b - a) * swing_travel(s);
    // The clearance rises and falls steeply at the ends: the hoof leaves and meets the floor
    // moving up and down, not gliding along it.
    const double p = gait_.lift_peak;
    const double bump = std::sin(M_PI * (s < p ? 0.5 * s / p : 0.5 + 0.5 * (s - p) / (1 - p)));
    h.flex = gait_.hoof_flex * std::pow(std::sin(M_PI * std::pow(s, std::log(0.5) / std::log(0.35))), 2);
    // Lifted by the clearance, and by as much as the flexion lowers the hoof's bottom.
    const double clearance = (is_front(leg) ? 1.0 : 0.85) * gait_.lift * bump;
    h.fetlock.z() += clearance + std::max(0.0, hoof_bottom(l.hoof, 0) - hoof_bottom(l.hoof, h.flex));
    return h;
  }

  // The cannon's direction (top to fetlock) in the body's vertical plane: its rest angle
  // following the leg's, flexed back in swing.
  Vector3d cannon_direction(int leg, const Vector3d& top, const Hoof& h) const {
    const Leg& l = rig_.legs[static_cast<std::size_t>(leg)];
    const Vector3d d = heading_.transpose() * (h.fetlock - top);
    const double leg_angle = std::atan2(d.x(), -d.z());
    double angle = l.cannon_rest_angle + 0.5 * (leg_angle - l.leg_rest_angle);
    if (h.swing >= 0) {
      angle -= gait_.cannon_flex[is_front(leg) ? 0 : 1] * std::pow(std::sin(M_PI * h.swing), 2);
    }
    return heading_ * Vector3d(std::sin(angle), 0, -std::cos(angle));
  }

  // ---- The trunk ----
  // The trunk from the heights of the hips' and the shoulders' midpoints at time t.
  Trunk trunk(double t, double hind_z, double front_z) const {
    const Vector3d pelvis_rest = rig_.rest[static_cast<std::size_t>(rig_.pelvis)];
    const Vector3d hind = 0.5 * (rig_.legs[2].rest[0] + rig_.legs[3].rest[0]) - pelvis_rest;
    const Vector3d front = 0.5 * (rig_.legs[0].rest[0] + rig_.legs[1].rest[0]) - pelvis_rest;
    const Vector3d r = front - hind;  // in the body's plane: r.y() == 0
    const double length = std::hypot(r.x(), r.z());
    const double pitch = std::atan2(r.z(), r.x()) - std::asin(std::clamp((front_z - hind_z) / length, -1.0, 1.0));
    Trunk out;
    out.rotation = heading_ * rot_y(pitch);
    Vector3d hind_world = carried(hind + pelvis_rest, t);
    hind_world.z() = hind_z;
    out.root = hind_world - out.rotation * hind;
    return out;
  }

  Vector3d top(const Trunk& trunk, int leg) const {
    return trunk.root + trunk.rotation * (rig_.legs[static_cast<std::size_t>(leg)].rest[0] -
                                          rig_.rest[static_cast<std::size_t>(rig_.pelvis)]);
  }

  double nominal_height(int end, double phi) const {
    // end 0: front, 1: hind. Highest (walk) or lowest (trot, gallop) when the end's legs are
    // at mid-stance.
    const int leg = end == 0 ? 0 : 2;
    // Once a cycle: the middle of the pair's stances; twice: the pair's legs step half a cycle
    // apart, either one's mid-stance.
    const double touch_down = gait_.bob_harmonic == 1
                                  ? 0.5 * (gait_.touch_down[static_cast<std::size_t>(leg)] +
                                           gait_.touch_down[static_cast<std::size_t>(leg + 1)])
                                  : gait_.touch_down[static_cast<std::size_t>(leg)];
    const double mid = touch_down + gait_.duty / 2;
    const double rest_z = rig_.legs[static_cast<std::size_t>(leg)].rest[0].z();
    return rest_z - gait_.crouch + gait_.bob * std::cos(2 * M_PI * gait_.bob_harmonic * (phi - mid));
  }

  double height(int end, double phi) const {
    const auto& cos_terms = height_cos_[static_cast<std::size_t>(end)];
    const auto& sin_terms = height_sin_[static_cast<std::size_t>(end)];
    double z = cos_terms[0];
    for (int m = 1; m <= kHarmonics; ++m) {
      z += cos_terms[static_cast<std::size_t>(m)] * std::cos(2 * M_PI * m * phi) +
           sin_terms[static_cast<std::size_t>(m)] * std::sin(2 * M_PI * m * phi);
    }
    return z;
  }

  // How far the leg's top must come down (> 0) for the leg to reach its cannon's top.
  double overreach(int leg, const Vector3d& top_world, const Hoof& h) const {
    const Leg& l = rig_.legs[static_cast<std::size_t>(leg)];
    const Vector3d cannon_top = h.fetlock - l.cannon * cannon_direction(leg, top_world, h);
    const double reach = kReach * (l.upper + l.lower);
    const double horizontal2 = (top_world - cannon_top).head<2>().squaredNorm();
    if (horizontal2 >= reach * reach) {
      throw ConfigError(fmt::format("take {}: a quadruped {} at {} m/s is beyond its legs (a hoof lands {:.2f} m from "
                                    "under its hip or shoulder)", spec_.take, spec_.kind, spec_.speed,
                                    std::sqrt(horizontal2)));
    }
    return top_world.z() - (cannon_top.z() + std::sqrt(reach * reach - horizontal2));
  }

  // The heights of both ends over one cycle: the nominal curves, cut where the legs would not
  // reach, smoothed to a few harmonics, then lowered until every leg reaches everywhere.
  void fit_heights() {
    const int n = 16 * static_cast<int>(std::ceil(gait_.cycle * fps_)) + 64;
    std::vector<double> phi(n);
    std::array<std::vector<double>, 2> target;
    for (auto& v : target) v.assign(n, 0);
    for (int k = 0; k < n; ++k) {
      const double t = k * gait_.cycle / n;
      phi[k] = phase(t);
      for (int end = 0; end < 2; ++end) {
        double limit = std::numeric_limits<double>::infinity();
        for (int leg = 2 * end; leg < 2 * end + 2; ++leg) {
          // At the nominal height without pitch: the top where the trunk carries it at rest.
          Vector3d nominal_top = carried(rig_.legs[static_cast<std::size_t>(leg)].rest[0], t);
          nominal_top.z() = nominal_height(end, phi[k]);
          limit = std::min(limit, nominal_top.z() - overreach(leg, nominal_top, hoof(leg, t)));
        }
        target[static_cast<std::size_t>(end)][static_cast<std::size_t>(k)] = std::min(nominal_height(end, phi[k]), limit);
      }
    }
    for (int end = 0; end < 2; ++end) {
      auto& c = height_cos_[static_cast<std::size_t>(end)];
      auto& s = height_sin_[static_cast<std::size_t>(end)];
      c.assign(kHarmonics + 1, 0.0);
      s.assign(kHarmonics + 1, 0.0);
      for (int m = 0; m <= kHarmonics; ++m) {
        for (int k = 0; k < n; ++k) {
          const double z = target[static_cast<std::size_t>(end)][static_cast<std::size_t>(k)];
          c[static_cast<std::size_t>(m)] += z * std::cos(2 * M_PI * m * phi[k]);
          s[static_cast<std::size_t>(m)] += z * std::sin(2 * M_PI * m * phi[k]);
        }
        c[static_cast<std::size_t>(m)] *= (m == 0 ? 1.0 : 2.0) / n;
        s[static_cast<std::size_t>(m)] *= (m == 0 ? 0.0 : 2.0) / n;
      }
    }
    // The pitched trunk carries the tops a little off their nominal places: lower each end
    // by its worst overreach until none is left (lowering both by as much keeps the pitch).
    for (int iteration = 0; iteration < 8; ++iteration) {
      std::array<double, 2> worst = {0, 0};
      for (int k = 0; k < n; ++k) {
        const double t = k * gait_.cycle / n;
        const Trunk body = trunk(t, height(1, phi[k]), height(0, phi[k]));
        for (int leg = 0; leg < kLegs; ++leg) {
          double& w = worst[is_front(leg) ? 0 : 1];
          w = std::max(w, overreach(leg, top(body, leg), hoof(leg, t)));
        }
      }
      if (worst[0] <= 1e-9 && worst[1] <= 1e-9) return;
      for (int end = 0; end < 2; ++end) height_cos_[static_cast<std::size_t>(end)][0] -= worst[static_cast<std::size_t>(end)] + 1e-7;
    }
  }

  void solve_leg(int leg, const Vector3d& top_world, const Hoof& h, WorldPose& pose) const {
    const Leg& l = rig_.legs[static_cast<std::size_t>(leg)];
    const Vector3d down = cannon_direction(leg, top_world, h);
    const Vector3d cannon_top = h.fetlock - l.cannon * down;
    const Vector3d ahead = heading_ * Vector3d::UnitX(), side = heading_ * Vector3d::UnitY();
    const TwoBone ik = solve_two_bone(top_world, cannon_top, l.upper, l.lower, l.bend * ahead, -Vector3d::UnitZ(),
                                      Vector3d::UnitX());
    // Each bone turns in the leg's plane from its rest direction to its posed one.
    const Vector3d points[4] = {top_world, ik.middle, cannon_top, h.fetlock};
    for (std::size_t k = 0; k < 3; ++k) {
      const Vector3d rest_dir = (l.rest[k + 1] - l.rest[k]).normalized();
      const Vector3d posed_dir = (points[k + 1] - points[k]).normalized();
      pose.rotation[static_cast<std::size_t>(l.joint[k])] =
          frame_rotation(rest_dir, Vector3d::UnitY(), posed_dir, side);
    }
    pose.rotation[static_cast<std::size_t>(l.joint[3])] = heading_ * rot_y(h.flex);
  }

  WorldPose pose(double t) const {
    const Skeleton& sk = rig_.skeleton;
    WorldPose pose(sk.size());
    const double phi = phase(t);
    const Trunk body = trunk(t, height(1, phi), height(0, phi));
    pose.root = body.root;
    for (int j : {rig_.pelvis, rig_.spine, rig_.chest}) pose.rotation[static_cast<std::size_t>(j)] = body.rotation;
    // The neck nods with the steps; the head stays nearly level.
    const double nod = gait_.nod * std::cos(2 * M_PI * gait_.bob_harmonic * (phi - gait_.touch_down[0]));
    pose.rotation[static_cast<std::size_t>(rig_.neck)] = body.rotation * rot_y(nod);
    pose.rotation[static_cast<std::size_t>(rig_.head)] = heading_ * rot_y(0.5 * nod);
    // The tail sways once a cycle, raised in the faster gaits.
    for (int k = 0; k < 3; ++k) {
      const double sway = gait_.tail_sway * std::sin(2 * M_PI * (phi - 0.15 * k));
      pose.set_local(sk, rig_.tail[static_cast<std::size_t>(k)], rot_z(sway) * rot_y(-gait_.tail_lift / 3));
    }
    for (int leg = 0; leg < kLegs; ++leg) solve_leg(leg, top(body, leg), hoof(leg, t), pose);
    return pose;
  }

  QuadrupedRig rig_;
  const MotionSpec& spec_;
  double fps_;
  QuadrupedGait gait_;
  RootState start_;
  Matrix3d heading_;
  std::array<std::vector<double>, 2> height_cos_, height_sin_;  // per end: 0 front, 1 hind
};

}  // namespace

MotionClip generate_quadruped_gait(const Skeleton& skeleton, const MotionSpec& spec, double fps) {
  return Generator(skeleton, spec, fps).run();
}

}  // namespace fourd::synth::detail
