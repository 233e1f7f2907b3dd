#pragma once
// Building blocks of the procedural motions: the performer's joints and dimensions, poses as
// world rotations, analytic two-bone IK and planted feet. Internal to the synth stage.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <vector>

#include "stages/synth/character.h"

namespace fourd::synth::detail {

using Eigen::Matrix3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kDeg = M_PI / 180;  // one degree [rad]

Matrix3d rot_x(double angle);
Matrix3d rot_y(double angle);  // positive tilts +z towards +x (a forward lean / the toes down)
Matrix3d rot_z(double angle);  // heading: positive turns left

// Rotation taking the orthonormal frame (a, b, a x b) to (c, d, c x d).
Matrix3d frame_rotation(const Vector3d& a, const Vector3d& b, const Vector3d& c, const Vector3d& d);

double smoothstep01(double t);  // 3t^2 - 2t^3 on [0, 1], clamped
double minimum_jerk(double t);  // 10t^3 - 15t^4 + 6t^5 on [0, 1], clamped

// Joint indices and rest dimensions of the procedural skeleton (index 0 = left, 1 = right).
struct Rig {
  explicit Rig(const Skeleton& skeleton);  // throws InputError when a joint is missing

  const Skeleton& skeleton;
  int pelvis, spine, chest, neck, head;
  std::array<int, 2> clavicle, upper_arm, forearm, hand, thigh, shin, foot, toe;

  std::vector<Vector3d> rest;  // world joint positions at rest
  double pelvis_height = 0;    // standing pelvis height
  std::array<Vector3d, 2> hip_offset;  // hip relative to the pelvis at rest
  double thigh_length = 0, shin_length = 0;
  double upper_arm_length = 0, forearm_length = 0;
  double palm_offset = 0;    // palm centre beyond the wrist, along the hand
  double ankle_height = 0;   // rest ankle height above the floor
  Vector3d toe_from_ankle;   // rest ball-of-foot joint relative to the ankle (x forward, z up)
  double heel_x = 0;         // heel contact point, x relative to the ankle at rest
  std::array<Vector3d, 2> arm_direction;  // rest direction shoulder -> wrist
  std::array<Vector2d, 2> foot_ground;    // rest ankle ground position relative to the pelvis

  double leg_length() const { return thigh_length + shin_length; }
  double reach_length() const { return upper_arm_length + forearm_length + palm_offset; }
};

// A pose as the world position of the root and a world rotation per joint.
struct WorldPose {
  Vector3d root = Vector3d::Zero();
  std::vector<Matrix3d> rotation;  // per joint

  explicit WorldPose(std::size_t joints) : rotation(joints, Matrix3d::Identity()) {}
  // Sets joint j's rotation relative to its parent.
  void set_local(const Skeleton& skeleton, int j, const Matrix3d& local);
  Vector3d position(const Skeleton& skeleton, int j) const;  // world position of joint j
  Pose to_pose(const Skeleton& skeleton) const;
};

// Two-bone IK (hip-knee-ankle, shoulder-elbow-wrist). The middle joint bends in the plane of
// root, target and `pole` (the direction the middle joint points to); `forward0` is the
// direction it points to at rest, perpendicular to the straight rest limb along `axis0`.
// Returns the world rotations of both bones; `reached` is false when the target is beyond the
// limb's length (the limb then points straight at it).
struct TwoBone {
  Matrix3d upper, lower;
  Vector3d middle;
  bool reached = true;
};
TwoBone solve_two_bone(const Vector3d& root, const Vector3d& target, double upper_length,
                       double lower_length, const Vector3d& pole, const Vector3d& axis0,
                       const Vector3d& forward0);

// A foot on the floor: the ground point under the ankle when the foot is flat, its heading,
// and its pitch (positive: toes up, rolling on the heel; negative: heel up, rolling on the ball
// of the foot with the toes flat on the floor).
struct FootState {
  Vector3d ankle;
  Matrix3d rotation;        // world rotation of the foot joint
  Matrix3d toe_rotation;    // world rotation of the toe joint
  bool in_air = false;      // free to turn within the ankle's range (solve_legs)
};
FootState planted_foot(const Rig& rig, const Vector2d& ground, double yaw, double pitch);
// A foot in the air at `ankle`, pitch about its own heading, toes bent up by toe_bend (the
// pitch is the world's; solve_legs keeps it within the ankle's range relative to the shin).
FootState free_foot(const Vector3d& ankle, double yaw, double pitch, double toe_bend);

// The highest pelvis height at which both hips reach their ankles with legs at most
// `fraction` of their full length. -infinity if a foot is out of reach at any height.
double max_pelvis_height(const Rig& rig, const Vector2d& pelvis_xy, const Matrix3d& pelvis_rotation,
                         const std::array<Vector3d, 2>& ankles, double fraction);

// Legs by IK (knees towards the feet's headings) and feet from their states. The pelvis's
// world rotation and the root must be set.
void solve_legs(const Rig& rig, const std::array<FootState, 2>& feet, WorldPose& pose);

// The trunk and head from world rotations of the pelvis, chest and head: the spine halfway
// between the pelvis and the chest, the neck halfway between the chest and the head.
void set_trunk(const Rig& rig, const Matrix3d& pelvis, const Matrix3d& chest, const Matrix3d& head, WorldPose& pose);

// Arms hanging with a forward swing (radians, + = hand forward) and elbow flexion, the
// shoulder raised by `shrug` (radians of clavicle elevation). The chest must be set.
void hang_arm(const Rig& rig, int side, double swing, double elbow, WorldPose& pose, double shrug = 0);
// The same with the arm raised sideways to `drop` below horizontal (hang_arm's: 80 degrees; 0
// holds it out level, negative raises it above the shoulder), then swept about the vertical by
// `sweep` (radians, + = hand forward): a raised arm swings forward and back that way.
void hold_arm(const Rig& rig, int side, double drop, double swing, double elbow, WorldPose& pose,
              double shrug = 0, double sweep = 0);

// Piecewise smooth curve through (time, value) keys, eased between neighbours (smoothstep).
double keyframes(const std::vector<std::pair<double, double>>& keys, double t);

// The palm centre of the right hand (side 1) or left hand (side 0).
Vector3d palm_position(const Rig& rig, int side, const WorldPose& pose);

}  // namespace fourd::synth::detail
