// One-shot motions: a standing jump of exact length and pelvis apex height, and a reach of the
// right palm to an exact target.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "pipeline/core/error.h"
#include "stages/synth/motion_generators.h"

namespace fourd::synth::detail {
namespace {

constexpr double kGravity = 9.81;
constexpr double kNominalLeg = 0.835;

// ------------------------------------------------------------------------------------------
// Jump. Coordinates of the take: x along the starting heading, y to the left, z up; the
// pelvis moves in the x-z plane. Feet stand at x = 0 before and at x = jump_length after.
class JumpGenerator {
 public:
  JumpGenerator(const Rig& rig, const MotionSpec& spec, double fps) : rig_(rig), spec_(spec), fps_(fps) {
    start_ = start_state(spec);
    plan();
  }

  MotionClip run() const {
    return sample_one_shot(
        rig_, spec_, fps_,
        [&](double t) {
          RootState r;
          r.heading = start_.heading;
          r.position = to_world(pelvis(t).x(), 0);
          return r;
        },
        [&](double t) { return pose(t); });
  }

 private:
  Vector2d to_world(double x, double y) const {
    return start_.position + Eigen::Rotation2Dd(start_.heading) * Vector2d(x, y);
  }

  Matrix3d pelvis_rotation(double t) const { return rot_z(start_.heading) * rot_y(0.6 * keyframes(lean_, t)); }

  std::array<Vector3d, 2> ankles(double x, double pitch) const {
    return {planted(0, x, pitch).ankle, planted(1, x, pitch).ankle};
  }

  FootState planted(int side, double x, double pitch) const {
    const Vector2d g = rig_.foot_ground[static_cast<std::size_t>(side)];
    return planted_foot(rig_, to_world(x + g.x(), g.y()), start_.heading, pitch);
  }

  double reachable_height(double pelvis_x, double lean, const std::array<Vector3d, 2>& feet, double fraction) const {
    return max_pelvis_height(rig_, to_world(pelvis_x, 0), rot_z(start_.heading) * rot_y(0.6 * lean), feet, fraction);
  }

  void plan() {
    const double k = rig_.leg_length() / kNominalLeg;
    const double length = spec_.jump_length, height = spec_.jump_height;
    const double stand = rig_.pelvis_height;
    lead_ = std::min(0.22 * k, 0.22 * length);  // pelvis ahead of the feet at take-off
    crouch_ = std::clamp(0.12 + 0.3 * height + 0.05 * length, 0.1, 0.3) * k;
    take_off_pitch_ = -45 * kDeg;

    // Times before the take-off are provisional until the apex is put on a frame.
    double t_stand = 0.2;
    t_crouch_ = t_stand + 0.45;
    const double take_off_lean = 12 * kDeg, landing_lean = 12 * kDeg;
    // Take-off: as high as the legs reach on the balls of the feet, leaving at least 3 cm
    // (scaled) of ballistic rise to the apex.
    const double apex = stand + height;
    take_off_ = {lead_, std::min(reachable_height(lead_, take_off_lean, ankles(0, take_off_pitch_), 0.99) - 1e-3,
                                 apex - 0.03 * k)};
    vz_ = std::sqrt(2 * kGravity * (apex - take_off_.y()));
    // Touch-down: feet flat at x = length, pelvis behind them, legs nearly straight.
    land_ = {length - lead_, 0};
    land_.y() = std::min(reachable_height(land_.x(), landing_lean, ankles(length, 0), 0.98) - 1e-3, apex);
    flight_ = (vz_ + std::sqrt(vz_ * vz_ + 2 * kGravity * (take_off_.y() - land_.y()))) / kGravity;
    vx_ = (land_.x() - take_off_.x()) / flight_;
    // Push-off: uniform acceleration from the crouch (at rest) to the take-off velocity.
    crouch_at_ = {0, stand - crouch_};
    push_ = 2 * (take_off_.y() - crouch_at_.y()) / vz_;
    crouch_at_.x() = take_off_.x() - vx_ * push_ / 2;
    // Put the apex exactly on a frame so that the sampled apex is the true one.
    const double apex_time = t_crouch_ + push_ + vz_ / kGravity;
    const double shift = std::ceil(apex_time * fps_ - 1e-9) / fps_ - apex_time;
    t_stand += shift;
    t_crouch_ += shift;
    t_take_off_ = t_crouch_ + push_;
    t_land_ = t_take_off_ + flight_;
    // Landing: uniform deceleration to rest, then stand up over the feet.
    const double vz_land = vz_ - kGravity * flight_;
    absorb_ = std::clamp(2 * (0.12 * k + 0.3 * height) / std::abs(vz_land), 0.15, 0.4);
    absorbed_ = land_ + Vector2d(vx_, vz_land) * absorb_ / 2;
    recover_ = 0.55;
    t_end_ = t_land_ + absorb_ + recover_;
    t_stand_ = t_stand;
    require_frames(spec_, t_end_, fps_);

    const double t_apex = t_take_off_ + vz_ / kGravity;
    lean_ = {{t_stand, 0},           {t_crouch_, 35 * kDeg},         {t_take_off_, take_off_lean}, {t_apex, 5 * kDeg},
             {t_land_, landing_lean}, {t_land_ + absorb_, 30 * kDeg}, {t_end_, 0}};
    const double arms_back = t_stand + 0.7 * (t_crouch_ - t_stand);
    arms_ = {{t_stand, 0},          {arms_back, -45 * kDeg},         {t_take_off_, 50 * kDeg}, {t_apex, 45 * kDeg},
             {t_land_, 25 * kDeg},  {t_land_ + absorb_, 10 * kDeg},  {t_end_, 0}};
  }

  // Pelvis (x, z) in the take's frame.
  Vector2d pelvis(double t) const {
    const Vector2d standing(0, rig_.pelvis_height), finish(spec_.jump_length, rig_.pelvis_height);
    if (t <= t_stand_) return standing;
    if (t <= t_crouch_) return standing + (crouch_at_ - standing) * minimum_jerk((t - t_stand_) / (t_crouch_ - t_stand_));
    if (t <= t_take_off_) {
      const double s = (t - t_crouch_) / push_;
      return crouch_at_ + (take_off_ - crouch_at_) * s * s;
    }
    if (t <= t_land_) {
      const double u = t - t_take_off_;
      return take_off_ + Vector2d(vx_ * u, vz_ * u - 0.5 * kGravity * u * u);
    }
    const Vector2d v_land(vx_, vz_ - kGravity * flight_);
    if (t <= t_land_ + absorb_) {
      const double u = t - t_land_;
      return land_ + v_land * u - 0.5 * (v_land / absorb_) * u * u;
    }
    if (t <= t_end_) return absorbed_ + (finish - absorbed_) * minimum_jerk((t - t_land_ - absorb_) / recover_);
    return finish;
  }

  std::array<FootState, 2> feet(double t, const Vector3d& pelvis_world) const {
    std::array<FootState, 2> out;
    if (t <= t_take_off_) {
      // Heels rise during the push, rolling on the balls of the feet; more if the legs need it.
      const double ramp = take_off_pitch_ * smoothstep01((t - t_crouch_ - 0.3 * push_) / (0.7 * push_));
      for (int side = 0; side < 2; ++side) {
        double pitch = ramp;
        for (; pitch > -70 * kDeg; pitch -= 1 * kDeg) {
          const Vector3d hip = pelvis_world + pelvis_rotation(t) * rig_.hip_offset[static_cast<std::size_t>(side)];
          if ((planted(side, 0, pitch).ankle - hip).norm() <= rig_.leg_length()) break;
        }
        out[static_cast<std::size_t>(side)] = planted(side, 0, pitch);
      }
      return out;
    }
    if (t >= t_land_) {
      for (int side = 0; side < 2; ++side) out[static_cast<std::size_t>(side)] = planted(side, spec_.jump_length, 0);
      return out;
    }
    // In the air: carried from the take-off stance towards the landing stance with the pelvis,
    // knees tucked up in between.
    const double u = (t - t_take_off_) / flight_;
    const double s = smoothstep01(u);
    const Vector2d p = pelvis(t), p0 = pelvis(t_take_off_), p1 = pelvis(t_land_);
    const double k = rig_.leg_length() / kNominalLeg;
    const double tuck = (0.1 * k + 0.25 * spec_.jump_height) * std::pow(std::sin(M_PI * u), 2);
    for (int side = 0; side < 2; ++side) {
      const Vector3d a0 = planted(side, 0, take_off_pitch_).ankle;
      const Vector3d a1 = planted(side, spec_.jump_length, 0).ankle;
      const Vector2d d0 = p - p0, d1 = p - p1;
      Vector3d ankle = (1 - s) * (a0 + Vector3d(0, 0, d0.y())) + s * (a1 + Vector3d(0, 0, d1.y()));
      const Vector2d along = Eigen::Rotation2Dd(start_.heading) * Vector2d((1 - s) * d0.x() + s * d1.x() + 0.3 * tuck, 0);
      ankle.head<2>() += along;
      ankle.z() += tuck;
      out[static_cast<std::size_t>(side)] =
          free_foot(ankle, start_.heading, take_off_pitch_ * (1 - s), -take_off_pitch_ * (1 - smoothstep01(u / 0.3)));
    }
    return out;
  }

  WorldPose pose(double t) const {
    const Skeleton& sk = rig_.skeleton;
    WorldPose pose(sk.size());
    const Vector2d p = pelvis(t);
    const Vector2d xy = to_world(p.x(), 0);
    pose.root = Vector3d(xy.x(), xy.y(), p.y());
    const double lean = keyframes(lean_, t);
    const Matrix3d heading = rot_z(start_.heading);
    pose.rotation[static_cast<std::size_t>(rig_.pelvis)] = pelvis_rotation(t);
    pose.rotation[static_cast<std::size_t>(rig_.spine)] = heading * rot_y(0.8 * lean);
    pose.rotation[static_cast<std::size_t>(rig_.chest)] = heading * rot_y(lean);
    // Eyes on the landing spot.
    pose.rotation[static_cast<std::size_t>(rig_.neck)] = heading * rot_y(0.5 * lean);
    pose.rotation[static_cast<std::size_t>(rig_.head)] = heading * rot_y(0.15 * lean);
    const double arms = keyframes(arms_, t);
    for (int side = 0; side < 2; ++side) hang_arm(rig_, side, arms, 15 * kDeg + 0.3 * std::abs(arms), pose);
    solve_legs(rig_, feet(t, pose.root), pose);
    return pose;
  }

  const Rig& rig_;
  const MotionSpec& spec_;
  double fps_;
  RootState start_;
  double lead_ = 0, crouch_ = 0, take_off_pitch_ = 0;
  Vector2d take_off_, land_, crouch_at_, absorbed_;
  double vz_ = 0, vx_ = 0, flight_ = 0, push_ = 0, absorb_ = 0, recover_ = 0;
  double t_stand_ = 0, t_crouch_ = 0, t_take_off_ = 0, t_land_ = 0, t_end_ = 0;
  std::vector<std::pair<double, double>> lean_, arms_;
};

// ------------------------------------------------------------------------------------------
// Reach: the body bends and crouches as little as needed, the right palm travels on an arc
// around the shoulder to the target, holds, and comes back.
struct Posture {
  double bend = 0;    // trunk flexion [rad]
  double crouch = 0;  // pelvis lowering [m]
  double twist = 0;   // trunk rotation towards the target [rad]
  double shrug = 0;   // right shoulder raised [rad]
};

class ReachGenerator {
 public:
  ReachGenerator(const Rig& rig, const MotionSpec& spec, double fps) : rig_(rig), spec_(spec), fps_(fps) {
    start_ = start_state(spec);
    const double total = (spec.frames - 1) / fps;
    if (total < 1.5) require_frames(spec, 1.5, fps);
    t_go_ = 0.1 * total;
    t_reached_ = t_go_ + 0.35 * total;
    t_back_ = t_reached_ + 0.15 * total;
    t_home_ = t_back_ + 0.3 * total;
    const Vector2d xy = to_world(spec.reach_target[0], spec.reach_target[1]);
    target_ = Vector3d(xy.x(), xy.y(), spec.reach_target[2]);
    choose_posture();
    // The palm path, in the chest's frame: from the hanging hand to the target.
    const WorldPose p0 = body(0), p1 = body(1);
    const WorldPose& hanging = p0;
    const Vector3d s0 = p0.position(rig_.skeleton, rig_.upper_arm[1]);
    const Vector3d s1 = p1.position(rig_.skeleton, rig_.upper_arm[1]);
    const Matrix3d& c0 = p0.rotation[static_cast<std::size_t>(rig_.chest)];
    const Matrix3d& c1 = p1.rotation[static_cast<std::size_t>(rig_.chest)];
    from_ = c0.transpose() * (palm_position(rig_, 1, hanging) - s0);
    to_ = c1.transpose() * (target_ - s1);
    // Where the hanging elbow points, as the IK pole at the start.
    const Vector3d elbow = hanging.position(rig_.skeleton, rig_.forearm[1]);
    const Vector3d line = (palm_position(rig_, 1, hanging) - s0).normalized();
    const Vector3d off = elbow - s0;
    pole_from_ = c0.transpose() * (off - off.dot(line) * line).normalized();
    pole_to_ = Vector3d(-0.25, -0.7, -0.65).normalized();
  }

  MotionClip run() const {
    MotionClip clip = sample_one_shot(
        rig_, spec_, fps_, [&](double) { return start_; }, [&](double t) { return pose(progress(t)); });
    // The palm, measured at the middle of the hold, in the body frame of frame 0.
    const int hold = static_cast<int>(std::lround(0.5 * (t_reached_ + t_back_) * fps_));
    const WorldPose held = pose(progress(hold / fps_));
    const Vector3d palm = palm_position(rig_, 1, held);
    const Vector2d local = Eigen::Rotation2Dd(-start_.heading) * (palm.head<2>() - start_.position);
    clip.parameters = {{"reach_x", local.x()}, {"reach_y", local.y()}, {"reach_z", palm.z()}};
    return clip;
  }

 private:
  static constexpr double kHangElbow = 10 * kDeg;

  Vector2d to_world(double x, double y) const {
    return start_.position + Eigen::Rotation2Dd(start_.heading) * Vector2d(x, y);
  }

  // 0 standing, 1 at the target.
  double progress(double t) const {
    if (t <= t_go_ || t >= t_home_) return 0;
    if (t < t_reached_) return minimum_jerk((t - t_go_) / (t_reached_ - t_go_));
    if (t <= t_back_) return 1;
    return 1 - minimum_jerk((t - t_back_) / (t_home_ - t_back_));
  }

  // Torso and legs at a posture, the head turned `look` of the way to the target; arms hanging.
  WorldPose body(const Posture& posture, double look) const {
    const Skeleton& sk = rig_.skeleton;
    WorldPose pose(sk.size());
    const double k = rig_.leg_length() / kNominalLeg;
    const double h = start_.heading;
    const Matrix3d pelvis = rot_z(h + 0.25 * posture.twist) * rot_y(0.45 * posture.bend);
    // Hips go back to balance a forward bend or a squat.
    const double back = 0.15 * k * std::sin(0.45 * posture.bend) + 0.3 * posture.crouch;
    const Vector2d xy = to_world(-back, 0);
    std::array<FootState, 2> feet;
    for (int side = 0; side < 2; ++side) {
      const Vector2d g = rig_.foot_ground[static_cast<std::size_t>(side)];
      feet[static_cast<std::size_t>(side)] = planted_foot(rig_, to_world(g.x(), g.y()), h, 0);
    }
    const double z = std::min(rig_.pelvis_height - posture.crouch,
                              max_pelvis_height(rig_, xy, pelvis, {feet[0].ankle, feet[1].ankle}, 1.0) - 1e-9);
    pose.root = Vector3d(xy.x(), xy.y(), z);
    pose.rotation[static_cast<std::size_t>(rig_.pelvis)] = pelvis;
    pose.rotation[static_cast<std::size_t>(rig_.spine)] = rot_z(h + 0.6 * posture.twist) * rot_y(0.75 * posture.bend);
    const Matrix3d chest = rot_z(h + posture.twist) * rot_y(posture.bend);
    pose.rotation[static_cast<std::size_t>(rig_.chest)] = chest;
    hang_arm(rig_, 0, 0, kHangElbow, pose);
    hang_arm(rig_, 1, 0, kHangElbow, pose, posture.shrug);
    // Look at the target.
    const Vector3d eye = pose.position(sk, rig_.head);
    const Vector3d to_target = target_ - eye;
    const double yaw = std::atan2(to_target.y(), to_target.x());
    const double pitch = std::atan2(-to_target.z(), to_target.head<2>().norm());
    const Matrix3d head = rot_z(h + look * angle(yaw - h)) * rot_y(look * 0.6 * pitch);
    pose.rotation[static_cast<std::size_t>(rig_.head)] = head;
    pose.rotation[static_cast<std::size_t>(rig_.neck)] =
        Eigen::Quaterniond(chest).slerp(0.5, Eigen::Quaterniond(head)).toRotationMatrix();
    solve_legs(rig_, feet, pose);
    return pose;
  }

  static double angle(double a) { return std::remainder(a, 2 * M_PI); }

  WorldPose body(double s) const {
    return body(Posture{s * posture_.bend, s * posture_.crouch, s * posture_.twist, s * posture_.shrug}, s);
  }

  WorldPose pose(double s) const {
    WorldPose pose = body(s);
    if (s <= 0) return pose;  // exactly the hanging arm
    const Skeleton& sk = rig_.skeleton;
    const Matrix3d& chest = pose.rotation[static_cast<std::size_t>(rig_.chest)];
    const Vector3d shoulder = pose.position(sk, rig_.upper_arm[1]);
    // Direction and distance from the shoulder, interpolated: an arc around the shoulder.
    const Eigen::Quaterniond turn = Eigen::Quaterniond::FromTwoVectors(from_, to_);
    const Vector3d direction = Eigen::Quaterniond::Identity().slerp(s, turn) * from_.normalized();
    const double distance = (1 - s) * from_.norm() + s * to_.norm();
    const Vector3d palm = s >= 1 ? target_ : Vector3d(shoulder + chest * (direction * distance));
    const Vector3d pole = chest * ((1 - s) * pole_from_ + s * pole_to_).normalized();
    const TwoBone arm = solve_two_bone(shoulder, palm, rig_.upper_arm_length, rig_.forearm_length + rig_.palm_offset,
                                       pole, rig_.arm_direction[1], -Vector3d::UnitX());
    pose.rotation[static_cast<std::size_t>(rig_.upper_arm[1])] = arm.upper;
    pose.rotation[static_cast<std::size_t>(rig_.forearm[1])] = arm.lower;
    pose.rotation[static_cast<std::size_t>(rig_.hand[1])] = arm.lower;
    return pose;
  }

  // The least bending and crouching that brings the target well within the arm's reach; the
  // shoulder rises for targets above it.
  void choose_posture() {
    const double k = rig_.leg_length() / kNominalLeg;
    const double reach = rig_.reach_length();
    const Vector2d local(spec_.reach_target[0], spec_.reach_target[1]);
    const double twist = std::clamp(0.35 * std::atan2(local.y() - rig_.hip_offset[1].y(), std::max(local.x(), 0.05)),
                                    -30 * kDeg, 30 * kDeg);
    const double above = target_.z() - rig_.rest[static_cast<std::size_t>(rig_.upper_arm[1])].z();
    const double shrug = std::clamp(above / (0.5 * k), 0.0, 1.0) * 25 * kDeg;
    double best = std::numeric_limits<double>::infinity();
    bool found = false;
    for (double bend = 0; bend <= 100 * kDeg + 1e-9; bend += 2.5 * kDeg) {
      for (double crouch = 0; crouch <= 0.5 * k + 1e-9; crouch += 0.015 * k) {
        const Posture p{bend, crouch, twist, shrug};
        const double effort = bend / (90 * kDeg) + 1.5 * crouch / (0.45 * k);
        if (effort >= best) continue;
        const double d = (target_ - body(p, 0).position(rig_.skeleton, rig_.upper_arm[1])).norm();
        if (d <= 0.97 * reach && d >= 0.35 * reach) {
          best = effort;
          posture_ = p;
          found = true;
        }
      }
    }
    if (!found) {
      throw ConfigError(fmt::format("take {}: reach_target ({}, {}, {}) is out of the performer's reach",
                                    spec_.take, spec_.reach_target[0], spec_.reach_target[1], spec_.reach_target[2]));
    }
  }

  const Rig& rig_;
  const MotionSpec& spec_;
  double fps_;
  RootState start_;
  double t_go_ = 0, t_reached_ = 0, t_back_ = 0, t_home_ = 0;
  Vector3d target_;
  Posture posture_;
  Vector3d from_, to_, pole_from_, pole_to_;
};

}  // namespace

MotionClip generate_jump(const Rig& rig, const MotionSpec& spec, double fps) {
  return JumpGenerator(rig, spec, fps).run();
}

MotionClip generate_reach(const Rig& rig, const MotionSpec& spec, double fps) {
  return ReachGenerator(rig, spec, fps).run();
}

}  // namespace fourd::synth::detail
