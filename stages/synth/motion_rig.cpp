#include "stages/synth/motion_rig.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "pipeline/core/error.h"

namespace fourd::synth::detail {
namespace {

constexpr double kHangDeg = 80;  // hanging arms: this far below horizontal

int require(const Skeleton& skeleton, const std::string& name) {
  const int j = skeleton.find(name);
  if (j < 0) {
    throw InputError(fmt::format("motion: the skeleton has no joint '{}' (procedural motions need the "
                                 "joints of the procedural performer)", name));
  }
  return j;
}

// Any unit vector perpendicular to u.
Vector3d perpendicular(const Vector3d& u) {
  const Vector3d other = std::abs(u.x()) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY();
  return u.cross(other).normalized();
}

// The ankle's range of motion from its neutral (foot perpendicular to the shin), human:
// dorsiflexion (toes towards the shin) up to 25 deg, plantarflexion up to 50 deg.
constexpr double kMaxDorsiflexionDeg = 25, kMaxPlantarflexionDeg = 50;

// The turn that brings a foot pointing along `forward` within that range of a shin pointing
// along `up` (ankle towards knee), about the axis perpendicular to both; identity when it is
// within (or the two are parallel).
Matrix3d ankle_range_turn(const Vector3d& up, const Vector3d& forward) {
  const Vector3d axis = up.cross(forward);
  if (axis.norm() < 1e-9) return Matrix3d::Identity();
  const double angle = std::atan2(axis.norm(), up.dot(forward));  // 90 deg: neutral
  const double within =
      std::clamp(angle, (90 - kMaxDorsiflexionDeg) * kDeg, (90 + kMaxPlantarflexionDeg) * kDeg);
  return Eigen::AngleAxisd(within - angle, axis.normalized()).toRotationMatrix();
}

}  // namespace

Matrix3d frame_rotation(const Vector3d& a, const Vector3d& b, const Vector3d& c, const Vector3d& d) {
  Matrix3d from, to;
  from << a, b, a.cross(b);
  to << c, d, c.cross(d);
  return to * from.transpose();
}

Matrix3d rot_x(double a) { return Eigen::AngleAxisd(a, Vector3d::UnitX()).toRotationMatrix(); }
Matrix3d rot_y(double a) { return Eigen::AngleAxisd(a, Vector3d::UnitY()).toRotationMatrix(); }
Matrix3d rot_z(double a) { return Eigen::AngleAxisd(a, Vector3d::UnitZ()).toRotationMatrix(); }

double smoothstep01(double t) {
  t = std::clamp(t, 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

double minimum_jerk(double t) {
  t = std::clamp(t, 0.0, 1.0);
  return t * t * t * (10 + t * (-15 + 6 * t));
}

Rig::Rig(const Skeleton& sk)
    : skeleton(sk),
      pelvis(require(sk, "pelvis")),
      spine(require(sk, "spine")),
      chest(require(sk, "chest")),
      neck(require(sk, "neck")),
      head(require(sk, "head")) {
  const char* sfx[2] = {"_l", "_r"};
  for (std::size_t i = 0; i < 2; ++i) {
    const std::string s = sfx[i];
    clavicle[i] = require(sk, "clavicle" + s);
    upper_arm[i] = require(sk, "upper_arm" + s);
    forearm[i] = require(sk, "forearm" + s);
    hand[i] = require(sk, "hand" + s);
    thigh[i] = require(sk, "thigh" + s);
    shin[i] = require(sk, "shin" + s);
    foot[i] = require(sk, "foot" + s);
    toe[i] = require(sk, "toe" + s);
  }
  const auto world = forward_kinematics(sk, rest_pose(sk));
  for (const auto& w : world) rest.push_back(w.translation());
  auto at = [&](int j) { return rest[static_cast<std::size_t>(j)]; };
  pelvis_height = at(pelvis).z();
  thigh_length = (at(shin[0]) - at(thigh[0])).norm();
  shin_length = (at(foot[0]) - at(shin[0])).norm();
  upper_arm_length = (at(forearm[0]) - at(upper_arm[0])).norm();
  forearm_length = (at(hand[0]) - at(forearm[0])).norm();
  palm_offset = 0.33 * forearm_length;
  ankle_height = at(foot[0]).z();
  toe_from_ankle = at(toe[0]) - at(foot[0]);
  heel_x = -0.35 * toe_from_ankle.x();
  for (std::size_t i = 0; i < 2; ++i) {
    hip_offset[i] = at(thigh[i]) - at(pelvis);
    arm_direction[i] = (at(hand[i]) - at(upper_arm[i])).normalized();
    foot_ground[i] = (at(foot[i]) - at(pelvis)).head<2>();
  }
}

void WorldPose::set_local(const Skeleton& skeleton, int j, const Matrix3d& local) {
  const int parent = skeleton.parents[static_cast<std::size_t>(j)];
  rotation[static_cast<std::size_t>(j)] = parent < 0 ? local : Matrix3d(rotation[static_cast<std::size_t>(parent)] * local);
}

Vector3d WorldPose::position(const Skeleton& skeleton, int j) const {
  const int parent = skeleton.parents[static_cast<std::size_t>(j)];
  if (parent < 0) return root;
  return position(skeleton, parent) + rotation[static_cast<std::size_t>(parent)] * skeleton.rest_offsets[static_cast<std::size_t>(j)];
}

Pose WorldPose::to_pose(const Skeleton& skeleton) const {
  Pose pose;
  pose.root_position = root;
  pose.local_rotations.resize(skeleton.size());
  for (std::size_t j = 0; j < skeleton.size(); ++j) {
    const int parent = skeleton.parents[j];
    const Matrix3d local = parent < 0 ? rotation[j] : Matrix3d(rotation[static_cast<std::size_t>(parent)].transpose() * rotation[j]);
    pose.local_rotations[j] = Eigen::Quaterniond(local).normalized();
  }
  return pose;
}

TwoBone solve_two_bone(const Vector3d& root, const Vector3d& target, double l1, double l2, const Vector3d& pole,
                       const Vector3d& axis0, const Vector3d& forward0) {
  TwoBone out;
  Vector3d to_target = target - root;
  double d = to_target.norm();
  const Vector3d u = d > 1e-12 ? Vector3d(to_target / d) : Vector3d(axis0);
  Vector3d v = pole - pole.dot(u) * u;
  v = v.norm() > 1e-9 ? Vector3d(v.normalized()) : perpendicular(u);
  const double lo = std::abs(l1 - l2) + 1e-9, hi = l1 + l2;
  if (d > hi) out.reached = d <= hi * (1 + 1e-9);
  if (d < lo) out.reached = false;
  d = std::clamp(d, lo, hi);
  const double a = (l1 * l1 - l2 * l2 + d * d) / (2 * d);
  const double h = std::sqrt(std::max(0.0, l1 * l1 - a * a));
  out.middle = root + a * u + h * v;
  const Vector3d end = root + d * u;
  const Vector3d n = u.cross(v).normalized();  // the hinge axis
  const Vector3d n0 = axis0.cross(forward0).normalized();
  const Vector3d a1 = (out.middle - root).normalized();
  const Vector3d a2 = (end - out.middle).normalized();
  out.upper = frame_rotation(axis0, n0, a1, n);
  out.lower = frame_rotation(axis0, n0, a2, n);
  return out;
}

FootState planted_foot(const Rig& rig, const Vector2d& ground, double yaw, double pitch) {
  const Matrix3d heading = rot_z(yaw);
  const Vector3d base(ground.x(), ground.y(), 0);
  const Vector3d ankle_rel(0, 0, rig.ankle_height);
  FootState s;
  s.rotation = heading * rot_y(-pitch);
  if (pitch > 0) {
    // Rolling on the heel: the heel's contact point stays put.
    const Vector3d heel(rig.heel_x, 0, 0);
    s.ankle = base + heading * heel + s.rotation * (ankle_rel - heel);
    s.toe_rotation = s.rotation;
  } else if (pitch < 0) {
    // Rolling on the ball of the foot: the toe joint stays put, the toes stay flat.
    const Vector3d ball = ankle_rel + rig.toe_from_ankle;
    s.ankle = base + heading * ball + s.rotation * (ankle_rel - ball);
    s.toe_rotation = heading;
  } else {
    s.ankle = base + heading * ankle_rel;
    s.toe_rotation = heading;
  }
  return s;
}

FootState free_foot(const Vector3d& ankle, double yaw, double pitch, double toe_bend) {
  FootState s;
  s.ankle = ankle;
  s.rotation = rot_z(yaw) * rot_y(-pitch);
  s.toe_rotation = s.rotation * rot_y(-toe_bend);
  s.in_air = true;
  return s;
}

double max_pelvis_height(const Rig& rig, const Vector2d& pelvis_xy, const Matrix3d& pelvis_rotation,
                         const std::array<Vector3d, 2>& ankles, double fraction) {
  double best = std::numeric_limits<double>::infinity();
  const double reach = fraction * rig.leg_length();
  for (std::size_t i = 0; i < 2; ++i) {
    const Vector3d hip = pelvis_rotation * rig.hip_offset[i];
    const Vector2d horizontal = pelvis_xy + hip.head<2>() - ankles[i].head<2>();
    const double h2 = reach * reach - horizontal.squaredNorm();
    if (h2 < 0) return -std::numeric_limits<double>::infinity();
    best = std::min(best, ankles[i].z() - hip.z() + std::sqrt(h2));
  }
  return best;
}

void solve_legs(const Rig& rig, const std::array<FootState, 2>& feet, WorldPose& pose) {
  const Skeleton& sk = rig.skeleton;
  for (std::size_t i = 0; i < 2; ++i) {
    const Vector3d hip = pose.position(sk, rig.thigh[i]);
    // The knee points over the toes.
    const Vector3d pole = feet[i].rotation * Vector3d::UnitX();
    const TwoBone leg = solve_two_bone(hip, feet[i].ankle, rig.thigh_length, rig.shin_length, pole,
                                       -Vector3d::UnitZ(), Vector3d::UnitX());
    pose.rotation[static_cast<std::size_t>(rig.thigh[i])] = leg.upper;
    pose.rotation[static_cast<std::size_t>(rig.shin[i])] = leg.lower;
    // A foot in the air turns no further than the ankle allows (a heel kicked up behind in a
    // run with the foot kept level would fold the foot under the shin).
    const Matrix3d turn = feet[i].in_air ? ankle_range_turn(leg.lower * Vector3d::UnitZ(),
                                                            feet[i].rotation * Vector3d::UnitX())
                                         : Matrix3d::Identity();
    pose.rotation[static_cast<std::size_t>(rig.foot[i])] = turn * feet[i].rotation;
    pose.rotation[static_cast<std::size_t>(rig.toe[i])] = turn * feet[i].toe_rotation;
  }
}

void set_trunk(const Rig& rig, const Matrix3d& pelvis, const Matrix3d& chest, const Matrix3d& head, WorldPose& pose) {
  auto between = [](const Matrix3d& a, const Matrix3d& b) {
    return Eigen::Quaterniond(a).slerp(0.5, Eigen::Quaterniond(b)).toRotationMatrix();
  };
  pose.rotation[static_cast<std::size_t>(rig.pelvis)] = pelvis;
  pose.rotation[static_cast<std::size_t>(rig.spine)] = between(pelvis, chest);
  pose.rotation[static_cast<std::size_t>(rig.chest)] = chest;
  pose.rotation[static_cast<std::size_t>(rig.neck)] = between(chest, head);
  pose.rotation[static_cast<std::size_t>(rig.head)] = head;
}

void hang_arm(const Rig& rig, int side, double swing, double elbow, WorldPose& pose, double shrug) {
  hold_arm(rig, side, kHangDeg * M_PI / 180, swing, elbow, pose, shrug);
}

void hold_arm(const Rig& rig, int side, double drop, double swing, double elbow, WorldPose& pose, double shrug,
              double sweep) {
  const Skeleton& sk = rig.skeleton;
  const std::size_t i = static_cast<std::size_t>(side);
  const Vector3d& d0 = rig.arm_direction[i];
  // Lower (or raise) the arm from its rest angle, in its own vertical plane.
  const double rest_drop = std::atan2(-d0.z(), std::abs(d0.y()));
  const double lower = drop - rest_drop;
  const Matrix3d hang = rot_x(side == 0 ? -lower : lower);
  pose.set_local(sk, rig.clavicle[i], rot_x(side == 0 ? shrug : -shrug));
  const Matrix3d raised = rot_y(-swing) * hang;
  pose.set_local(sk, rig.upper_arm[i], sweep == 0 ? raised : Matrix3d(rot_z(side == 0 ? -sweep : sweep) * raised));
  // The elbow flexes the forearm forward: about d0 x (+x) in the upper arm's frame.
  const Vector3d hinge = d0.cross(Vector3d::UnitX()).normalized();
  pose.set_local(sk, rig.forearm[i], Eigen::AngleAxisd(elbow, hinge).toRotationMatrix());
  pose.set_local(sk, rig.hand[i], Matrix3d::Identity());
}

double keyframes(const std::vector<std::pair<double, double>>& keys, double t) {
  if (t <= keys.front().first) return keys.front().second;
  for (std::size_t i = 1; i < keys.size(); ++i) {
    if (t <= keys[i].first) {
      const double span = keys[i].first - keys[i - 1].first;
      const double s = span > 0 ? smoothstep01((t - keys[i - 1].first) / span) : 1.0;
      return keys[i - 1].second + (keys[i].second - keys[i - 1].second) * s;
    }
  }
  return keys.back().second;
}

Vector3d palm_position(const Rig& rig, int side, const WorldPose& pose) {
  const std::size_t i = static_cast<std::size_t>(side);
  return pose.position(rig.skeleton, rig.hand[i]) +
         pose.rotation[static_cast<std::size_t>(rig.hand[i])] * rig.arm_direction[i] * rig.palm_offset;
}

}  // namespace fourd::synth::detail
