#pragma once
// Ground-plane rigid motions of the character's root (x, y, heading), as RootPose of
// runtime/motion_space.h: p -> R(heading) p + (x, y). Header-only; used by the motion graph,
// the transition search and the runtime's root integration.
#include <cmath>
#include <numbers>

#include "runtime/motion_space.h"

namespace fourd {

// a * b: apply b, then a.
inline RootPose root_compose(const RootPose& a, const RootPose& b) {
  const float c = std::cos(a.heading), s = std::sin(a.heading);
  return {a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, a.heading + b.heading};
}

inline RootPose root_inverse(const RootPose& a) {
  const float c = std::cos(a.heading), s = std::sin(a.heading);
  return {-(c * a.x + s * a.y), -(-s * a.x + c * a.y), -a.heading};
}

// b seen from a: a^-1 * b. Maps points of b's frame into a's frame.
inline RootPose root_relative(const RootPose& a, const RootPose& b) {
  return root_compose(root_inverse(a), b);
}

// Linear blend of two root poses (headings blended as angles, not wrapped: both come from the
// same continuous curve or from deltas of a few degrees).
inline RootPose root_lerp(const RootPose& a, const RootPose& b, float f) {
  return {a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), a.heading + f * (b.heading - a.heading)};
}

// Heading wrapped to (-pi, pi].
inline double wrap_heading(double a) {
  const double two_pi = 2 * std::numbers::pi;
  a = std::fmod(a + std::numbers::pi, two_pi);
  if (a <= 0) a += two_pi;
  return a - std::numbers::pi;
}

}  // namespace fourd
