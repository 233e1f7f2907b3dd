#pragma once
// A synthetic performer for the timewarp and motion-space tests: a torso tube on two leg tubes
// (three closed components, z up, facing +x, standing on z = 0), moved by procedural motions
// whose phase, root motion and parameters are known exactly.
//  - walk: legs swing about the hips by +-amplitude with phase phi, the torso bobs and twists a
//    little; the root moves forward at `speed` and turns at `turn_rate`.
//  - jump: a crouch, a flight of `height` over `length` and a landing, in normalised time u,
//    which the take may run through non-uniformly (u = tau^time_power).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <vector>

#include "pipeline/core/mesh.h"
#include "pipeline/exchange/root_motion.h"
#include "tests/motionspace/test_meshes.h"

namespace fourd::test {

inline constexpr double kTwoPi = 2 * std::numbers::pi;

struct Walker {
  TestMesh mesh;        // the template: standing, facing +x
  int torso_end = 0;    // vertices [0, torso_end) are the torso
  int left_end = 0;     // [torso_end, left_end) the left leg, then the right leg
};

inline Walker make_walker(int rings = 9, int segments = 10) {
  Walker w;
  TubeShape torso{0.15, 0.4, 0.1, 1.3};
  TubeShape leg{0.06, 0.4, 0.1, 1.0};
  TestMesh t = make_tube(rings, segments, torso);
  TestMesh l = make_tube(rings, segments, leg);
  const Eigen::Index nt = t.positions.cols(), nl = l.positions.cols();
  w.mesh.positions.resize(3, nt + 2 * nl);
  w.mesh.positions.leftCols(nt) = t.positions.colwise() + Eigen::Vector3d(0, 0, 1.25);
  w.mesh.positions.middleCols(nt, nl) = l.positions.colwise() + Eigen::Vector3d(0, 0.1, 0.4);
  w.mesh.positions.rightCols(nl) = l.positions.colwise() + Eigen::Vector3d(0, -0.1, 0.4);
  w.mesh.triangles = t.triangles;
  for (int k = 0; k < 2; ++k) {
    const int base = static_cast<int>(nt + k * nl);
    for (const Tri& tri : l.triangles) w.mesh.triangles.push_back(tri + Tri::Constant(base));
  }
  w.torso_end = static_cast<int>(nt);
  w.left_end = static_cast<int>(nt + nl);
  return w;
}

// The walker's template as a mesh (the timewarp stage's input type).
inline Mesh walker_mesh(const Walker& w) {
  Mesh m;
  m.positions = to_vec3f(w.mesh.positions);
  m.triangles = w.mesh.triangles;
  return m;
}

// Legs rotated about the hips (pitch, + swings the foot forward), torso raised and twisted.
inline Eigen::Matrix3Xd pose_walker(const Walker& w, double left_pitch, double right_pitch,
                                    double torso_lift, double torso_twist) {
  Eigen::Matrix3Xd x = w.mesh.positions;
  const Eigen::Matrix3d twist =
      Eigen::AngleAxisd(torso_twist, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (int v = 0; v < w.torso_end; ++v) {
    x.col(v) = twist * x.col(v) + Eigen::Vector3d(0, 0, torso_lift);
  }
  for (int side = 0; side < 2; ++side) {
    const int first = side == 0 ? w.torso_end : w.left_end;
    const int last = side == 0 ? w.left_end : static_cast<int>(x.cols());
    const double pitch = side == 0 ? left_pitch : right_pitch;
    const Eigen::Vector3d hip(0, side == 0 ? 0.1 : -0.1, 0.8);
    // A forward swing turns the leg's lower end towards +x: rotation about -y.
    const Eigen::Matrix3d r = Eigen::AngleAxisd(pitch, -Eigen::Vector3d::UnitY()).toRotationMatrix();
    for (int v = first; v < last; ++v) {
      x.col(v) = r * (x.col(v) - hip) + hip + Eigen::Vector3d(0, 0, torso_lift);
    }
  }
  return x;
}

struct WalkSpec {
  double amplitude = 0.35;      // leg swing [rad]
  double cycle_frames = 15;     // frames per cycle (fractional allowed)
  double start_phase = 0;       // phase at frame 0
  double speed = 1.0;           // [m/s]
  double turn_rate = 0;         // [rad/s]
  double fps = 25;
  int frames = 20;
  double start_heading = 0;     // [rad]
  Eigen::Vector2d start_position{0, 0};
};

inline double walk_phase(const WalkSpec& s, int f) { return s.start_phase + f / s.cycle_frames; }

inline Eigen::Matrix3Xd walk_shape(const Walker& w, const WalkSpec& s, double phase) {
  const double a = s.amplitude * std::sin(kTwoPi * phase);
  return pose_walker(w, a, -a, 0.02 * std::cos(2 * kTwoPi * phase),
                     0.05 * std::sin(kTwoPi * phase));
}

// A root's ground position, and the root as a vector (x, y, heading), for comparisons.
inline Eigen::Vector2d xy(const RootTransform& r) { return {r.x, r.y}; }
inline Eigen::Vector3d xyh(const RootTransform& r) { return {r.x, r.y, r.heading}; }

// World root of a walk at frame f: (x, y, heading) integrated along a circular arc.
inline RootTransform walk_root(const WalkSpec& s, double f) {
  const double time = f / s.fps;
  const double heading = s.start_heading + s.turn_rate * time;
  Eigen::Vector2d p = s.start_position;
  if (std::abs(s.turn_rate) < 1e-12) {
    p += s.speed * time * Eigen::Vector2d(std::cos(s.start_heading), std::sin(s.start_heading));
  } else {
    const double r = s.speed / s.turn_rate;
    p += r * Eigen::Vector2d(std::sin(heading) - std::sin(s.start_heading),
                             -std::cos(heading) + std::cos(s.start_heading));
  }
  return {p.x(), p.y(), heading};
}

inline std::vector<Eigen::Matrix3Xd> walk_frames(const Walker& w, const WalkSpec& s) {
  std::vector<Eigen::Matrix3Xd> frames;
  for (int f = 0; f < s.frames; ++f) {
    frames.push_back(apply_root(walk_shape(w, s, walk_phase(s, f)), walk_root(s, f)));
  }
  return frames;
}

struct JumpSpec {
  double length = 0.6;      // [m]
  double height = 0.15;     // torso rise at the top [m]
  int frames = 24;
  double time_power = 1.0;  // u = tau^time_power, tau = f / (frames - 1)
  double fps = 25;
};

inline double jump_time(const JumpSpec& s, int f) {
  return std::pow(static_cast<double>(f) / (s.frames - 1), s.time_power);
}

// Crouch (u < 0.3), flight (0.3 to 0.7), landing; legs tuck in flight.
inline Eigen::Matrix3Xd jump_shape(const Walker& w, const JumpSpec& s, double u) {
  const double crouch = -0.08 * std::pow(std::sin(std::numbers::pi * std::min(u / 0.3, 1.0)), 2) -
                        0.08 * std::pow(std::sin(std::numbers::pi * std::max((u - 0.7) / 0.3, 0.0)), 2);
  const double flight = u > 0.3 && u < 0.7 ? std::sin(std::numbers::pi * (u - 0.3) / 0.4) : 0.0;
  const double tuck = 0.5 * flight;
  return pose_walker(w, tuck, tuck, crouch + s.height * flight, 0.0);
}

inline std::vector<Eigen::Matrix3Xd> jump_frames(const Walker& w, const JumpSpec& s) {
  std::vector<Eigen::Matrix3Xd> frames;
  for (int f = 0; f < s.frames; ++f) {
    const double u = jump_time(s, f);
    const double x = s.length * (u < 0.3 ? 0.0 : u > 0.7 ? 1.0 : (u - 0.3) / 0.4);
    frames.push_back(apply_root(jump_shape(w, s, u), {x, 0.0, 0.0}));
  }
  return frames;
}

}  // namespace fourd::test
