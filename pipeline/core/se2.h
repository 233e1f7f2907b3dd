#pragma once
// Ground-plane rigid motions (SE(2)) of a character's root: (x, y, heading), the map
// p -> R(heading) p + (x, y); and the wrapping of headings and of cyclic normalised time.
// Header-only; the one home of this maths: the timewarp stage estimates roots and their mean
// motion per cycle (double), the runtime plays them (float in the asset, double in the world),
// the graph stage compares them.
#include <cmath>
#include <numbers>

namespace fourd {

template <class T>
struct GroundPose {
  using Scalar = T;
  T x = 0;        // [m]
  T y = 0;        // [m]
  T heading = 0;  // [rad] counter-clockwise seen from above; not wrapped
  bool operator==(const GroundPose&) const = default;
  bool finite() const { return std::isfinite(x) && std::isfinite(y) && std::isfinite(heading); }
};

// A root as the asset stores it (float): within a motion space, x forward and y left in the
// root frame at t = 0.
using RootPose = GroundPose<float>;
// A root in the world, or a root motion computed offline (double: long walks integrate
// without drift).
using RootTransform = GroundPose<double>;

// a * b: apply b, then a. In a's precision: a RootPose composed with a RootPose, a
// RootTransform with either.
template <class A, class B>
A root_compose(const A& a, const B& b) {
  using Scalar = decltype(a.heading);
  const Scalar c = std::cos(a.heading), s = std::sin(a.heading);
  return {a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, a.heading + b.heading};
}

template <class A>
A root_inverse(const A& a) {
  using Scalar = decltype(a.heading);
  const Scalar c = std::cos(a.heading), s = std::sin(a.heading);
  return {-(c * a.x + s * a.y), -(-s * a.x + c * a.y), -a.heading};
}

// b seen from a: a^-1 * b. Maps points of b's frame into a's frame.
template <class A>
A root_relative(const A& a, const A& b) {
  return root_compose(root_inverse(a), b);
}

// Linear blend of two root poses (headings blended as angles, not wrapped: both come from the
// same continuous curve or from deltas of a few degrees).
template <class A>
A root_lerp(const A& a, const A& b, typename A::Scalar f) {
  return {a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), a.heading + f * (b.heading - a.heading)};
}

// The fraction `alpha` of the rigid motion `a` along its screw (a rotation about a fixed
// centre, or a translation): root_power(a, 0) is the identity, root_power(a, 1) == a and
// root_power(a, s + t) == root_compose(root_power(a, s), root_power(a, t)). A body moving by
// root_power(a, t) from t = 0 to 1 turns at a constant rate along a circular arc (a straight
// line when a does not turn). |heading| of `a` below 2 pi (less than a full turn).
inline RootTransform root_power(const RootTransform& a, double alpha) {
  // A rigid motion of the plane is exp of a twist (v, w): heading w, translation V(w) v with
  // V(w) = sinc(w / 2) R(w / 2). So root_power(a, alpha) turns by alpha w and translates by
  // V(alpha w) alpha V(w)^-1 t.
  auto sinc = [](double x) { return std::abs(x) < 1e-4 ? 1 - x * x / 6 : std::sin(x) / x; };
  const double w = a.heading;
  const double scale = alpha * sinc(alpha * w / 2) / sinc(w / 2);
  const double turn = (alpha - 1) * w / 2;
  const double c = std::cos(turn), s = std::sin(turn);
  return {scale * (c * a.x - s * a.y), scale * (s * a.x + c * a.y), alpha * w};
}

// Cyclic normalised time wrapped to [0, 1).
inline double wrap01(double t) {
  const double w = t - std::floor(t);
  return w >= 1.0 ? 0.0 : w;
}

// Heading wrapped to (-pi, pi]; a heading already in that range is returned unchanged.
inline double wrap_heading(double a) {
  const double two_pi = 2 * std::numbers::pi;
  a = std::fmod(a, two_pi);
  if (a <= -std::numbers::pi) a += two_pi;
  if (a > std::numbers::pi) a -= two_pi;
  return a;
}

}  // namespace fourd
