#pragma once
// Ground-plane rigid motions (SE(2)) of the character's root (x, y, heading), as RootPose of
// runtime/motion_space.h (float, within a motion space) or RootTransform of
// runtime/character.h (double, in the world): p -> R(heading) p + (x, y); and the wrapping of
// headings and of cyclic normalised time. Header-only; the one home of this maths for the
// runtime and for the stages that build its assets (the graph stage's similarity), which link
// the runtime; pipeline/ has no use for it.
#include <cmath>
#include <numbers>

#include "runtime/motion_space.h"

namespace fourd {

// a * b: apply b, then a. In a's precision: a RootPose (float) or a RootTransform (double)
// composed with a RootPose delta.
template <class A, class B>
A root_compose(const A& a, const B& b) {
  using Scalar = decltype(a.heading);
  const Scalar c = std::cos(a.heading), s = std::sin(a.heading);
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

// Cyclic normalised time wrapped to [0, 1).
inline double wrap01(double t) {
  const double w = t - std::floor(t);
  return w >= 1.0 ? 0.0 : w;
}

// Heading wrapped to (-pi, pi].
inline double wrap_heading(double a) {
  const double two_pi = 2 * std::numbers::pi;
  a = std::fmod(a + std::numbers::pi, two_pi);
  if (a <= 0) a += two_pi;
  return a - std::numbers::pi;
}

}  // namespace fourd
