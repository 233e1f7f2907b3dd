#pragma once
// The viewer's geometry without OpenGL: cameras (orbit and follow), picking points on the
// ground plane, and the Bezier path built from points clicked on the ground. World frame as the
// runtime's: x forward, y left, z up, the ground at z = 0.
#include <Eigen/Core>
#include <span>
#include <vector>

#include "runtime/controller.h"

namespace fourd::viewer {

using Mat4f = Eigen::Matrix4f;

// Right-handed view matrix (OpenGL convention: the camera looks down its -z).
Mat4f look_at(const Eigen::Vector3f& eye, const Eigen::Vector3f& target, const Eigen::Vector3f& up);
// OpenGL clip space (depth -1..1). fov_y in radians.
Mat4f perspective(float fov_y, float aspect, float near_plane, float far_plane);

enum class CameraMode { kFollow, kOrbit };

// A camera on a sphere around a target: yaw about z (0: looking along +x from behind), pitch
// above the ground. Follow mode keeps the target on the character's root and swings behind it
// (yaw is then an offset from the character's heading); orbit mode leaves the target where it is.
struct OrbitCamera {
  CameraMode mode = CameraMode::kFollow;
  Eigen::Vector3f target{0, 0, 0.9f};  // [m] point looked at
  float yaw = -0.6f;                   // [rad] (follow: relative to the smoothed heading)
  float pitch = 0.3f;                  // [rad] above the horizon
  float distance = 4.5f;               // [m]
  float fov_y = 0.8f;                  // [rad]
  float follow_heading = 0;            // [rad] the character's heading, smoothed
  float follow_rate = 2.0f;            // [1/s] how fast the follow camera swings behind
  float target_height = 0.9f;          // [m] follow: the target above the root

  // Follow mode: the target goes to the root, the heading is chased at follow_rate (exact
  // exponential smoothing, so it does not depend on how dt is cut).
  void follow(double root_x, double root_y, double heading, double dt);
  // Mouse: drag in pixels (dx right, dy down), wheel steps (positive: closer).
  void rotate(float dx_pixels, float dy_pixels);
  void zoom(float wheel_steps);

  float world_yaw() const;  // yaw in the world frame
  Eigen::Vector3f eye() const;
  Mat4f view() const;
  Mat4f projection(float aspect) const;
};

// The point of the ground plane z = 0 under a pixel (x right, y down, in a viewport of
// width x height), for the camera matrices given. False when the ray misses the ground (points at
// or above the horizon) or hits it further than max_distance from the eye.
bool pick_ground(const Mat4f& view, const Mat4f& projection, float x, float y, int width,
                 int height, Point2* out, float max_distance = 200);

// A smooth path through the points (at least 2): contiguous cubic Bezier curves, one per pair of
// consecutive points, with Catmull-Rom tangents (the end tangents point at the neighbour). Points
// closer than 1 cm to the previous one are dropped. Empty when fewer than 2 points remain.
std::vector<BezierCurve> bezier_through(std::span<const Point2> points);

// A point of a cubic Bezier curve at u in [0, 1].
Point2 bezier_point(const BezierCurve& curve, double u);

}  // namespace fourd::viewer
