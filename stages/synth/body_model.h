#pragma once
// The procedural performer's body before meshing: a skeleton and an implicit body, the smooth
// union of ellipsoids and round cones ("capsules" with two radii), each carried by one joint.
// Internal to the synth stage.
#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "stages/synth/character.h"

namespace fourd::synth::detail {

struct BodyPrimitive {
  enum Kind { kEllipsoid, kRoundCone };
  Kind kind = kEllipsoid;
  int joint = 0;  // the joint that carries it (skinning)
  // Ellipsoid: centre a, semi-axes radii along the columns of axes (a rotation).
  // Round cone: sphere of radius ra at a swept to a sphere of radius rb at b, then stretched
  // about a by `scale` along the world axes (elliptic cross-sections for the torso).
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  double ra = 0, rb = 0;
  Eigen::Vector3d radii = Eigen::Vector3d::Ones();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
};

// A limb as a straight axis, for texture charts: start -> end.
struct LimbAxis {
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  Eigen::Vector3d end = Eigen::Vector3d::Zero();
};

inline constexpr std::size_t kMaxPrimitives = 64;

// Where the quadruped's texture charts lie (quadruped.h), in the model's coordinates.
struct QuadrupedLayout {
  LimbAxis trunk;  // rump -> chest along the trunk's centre line
  LimbAxis head;   // neck base -> muzzle tip
  LimbAxis tail;   // tail root -> tip
  // Per leg (front left, front right, hind left, hind right): its joints top to fetlock, then
  // the hoof's centre.
  std::array<std::vector<Eigen::Vector3d>, 4> legs;
  double hoof_top = 0;                   // height of the hooves' tops above the floor [m]
  std::array<Eigen::Vector3d, 2> eyes;  // left, right
};

struct BodyModel {
  Skeleton skeleton;
  std::vector<Eigen::Vector3d> rest_positions;  // world position of every joint at rest
  std::vector<BodyPrimitive> primitives;  // at most kMaxPrimitives
  double blend_radius = 0.012;  // smooth-union radius [m]
  double scale = 1;             // height / nominal height: landmark heights scale with it
  // Texture-chart axes, index 0 = left, 1 = right.
  std::array<LimbAxis, 2> arms;   // shoulder -> finger tips
  std::array<LimbAxis, 2> legs;   // hip -> ankle
  std::array<LimbAxis, 2> feet;   // heel end -> toe end, at mid-foot height
  // The quadruped's charts (make_quadruped_model); unset for the human, whose charts are the
  // axes above.
  std::optional<QuadrupedLayout> quadruped;
};

// The body for the given height and build (no randomness: the shape depends on the options).
BodyModel make_body_model(double height, double build);

// A body at `scale` times its nominal size, yet without joints or primitives: its scale and
// smooth-union radius. `girth`: the factor of the trunk's and the limbs' radii (the build fully)
// and of the head's and the extremities' (the build barely).
struct Girth {
  double trunk = 1, extremities = 1;
};
BodyModel scaled_body(double scale, double build, Girth* girth);

// Primitives carried by `joint`: an ellipsoid (semi-axes `radii` along the columns of `axes`),
// and a round cone from a sphere of radius ra at a to one of radius rb at b, stretched about a by
// `scale` along the world axes.
BodyPrimitive ellipsoid(int joint, const Eigen::Vector3d& centre, const Eigen::Vector3d& radii,
                        const Eigen::Matrix3d& axes = Eigen::Matrix3d::Identity());
BodyPrimitive round_cone(int joint, const Eigen::Vector3d& a, double ra, const Eigen::Vector3d& b, double rb,
                         const Eigen::Vector3d& scale = Eigen::Vector3d::Ones());
// body.skeleton and body.rest_positions from joints in topological order (name, parent's name;
// "" for the root) and their rest world positions.
void set_skeleton(BodyModel& body, const std::vector<std::pair<std::string, std::string>>& joints,
                  const std::vector<Eigen::Vector3d>& positions);

// Signed distance (approximate for ellipsoids) from p to one primitive; negative inside.
double primitive_distance(const BodyPrimitive& primitive, const Eigen::Vector3d& p);
// The same for every primitive.
void primitive_distances(const BodyModel& body, const Eigen::Vector3d& p, double* out);
// The implicit body: smooth minimum of the primitive distances; negative inside.
double body_field(const BodyModel& body, const Eigen::Vector3d& p);
// The body moved by `shift`, then scaled by `factor` about the origin: its primitives, blend
// radius, joints' rest positions and limb axes (body.skeleton is left as it was). The character's final mesh is its model's surface
// shifted onto the floor and scaled to the exact height (make_procedural_character).
BodyModel moved_body(BodyModel body, const Eigen::Vector3d& shift, double factor);
// Axis-aligned bounds of the body with `margin` around it.
void body_bounds(const BodyModel& body, double margin, Eigen::Vector3d* lo, Eigen::Vector3d* hi);

}  // namespace fourd::synth::detail
