#include "stages/synth/body_model.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

namespace fourd::synth::detail {
namespace {

using Eigen::Vector3d;

// Proportions of an average adult of this height, standing (x forward, y left, z up).
constexpr double kNominalHeight = 1.75;
constexpr double kArmDropDeg = 45;  // rest arms: lowered this much from a T-pose

struct JointSpec {
  const char* name;
  const char* parent;
};

// Topological order: every parent before its children.
constexpr JointSpec kJoints[] = {
    {"pelvis", nullptr},       {"spine", "pelvis"},        {"chest", "spine"},
    {"neck", "chest"},         {"head", "neck"},           {"clavicle_l", "chest"},
    {"upper_arm_l", "clavicle_l"}, {"forearm_l", "upper_arm_l"}, {"hand_l", "forearm_l"},
    {"clavicle_r", "chest"},   {"upper_arm_r", "clavicle_r"}, {"forearm_r", "upper_arm_r"},
    {"hand_r", "forearm_r"},   {"thigh_l", "pelvis"},      {"shin_l", "thigh_l"},
    {"foot_l", "shin_l"},      {"toe_l", "foot_l"},        {"thigh_r", "pelvis"},
    {"shin_r", "thigh_r"},     {"foot_r", "shin_r"},       {"toe_r", "foot_r"},
};

double sign(double x) { return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0); }

// Exact signed distance to a round cone (Inigo Quilez, "distance functions").
double round_cone_distance(const Vector3d& p, const Vector3d& a, const Vector3d& b, double r1,
                           double r2) {
  const Vector3d ba = b - a;
  const double l2 = ba.squaredNorm();
  const double rr = r1 - r2;
  const double a2 = l2 - rr * rr;
  const double il2 = 1.0 / l2;
  const Vector3d pa = p - a;
  const double y = pa.dot(ba);
  const double z = y - l2;
  const double x2 = (pa * l2 - ba * y).squaredNorm();
  const double y2 = y * y * l2;
  const double z2 = z * z * l2;
  const double k = sign(rr) * rr * rr * x2;
  if (sign(z) * a2 * z2 > k) return std::sqrt(x2 + z2) * il2 - r2;
  if (sign(y) * a2 * y2 < k) return std::sqrt(x2 + y2) * il2 - r1;
  return (std::sqrt(x2 * a2 * il2) + y * rr) * il2 - r1;
}

// Ellipsoid distance bound (Quilez): exact on the surface, a good estimate near it.
double ellipsoid_distance(const Vector3d& p, const BodyPrimitive& e) {
  const Vector3d q = e.axes.transpose() * (p - e.a);
  const double k0 = q.cwiseQuotient(e.radii).norm();
  const double k1 = q.cwiseQuotient(e.radii.cwiseProduct(e.radii)).norm();
  if (k1 < 1e-12) return -e.radii.minCoeff();
  return k0 * (k0 - 1.0) / k1;
}

}  // namespace

double primitive_distance(const BodyPrimitive& prim, const Vector3d& p) {
  if (prim.kind == BodyPrimitive::kEllipsoid) return ellipsoid_distance(p, prim);
  if (prim.scale == Vector3d::Ones()) return round_cone_distance(p, prim.a, prim.b, prim.ra, prim.rb);
  // Distance in the unstretched space, scaled back: a lower bound, exact on the surface.
  const Vector3d q = prim.a + (p - prim.a).cwiseQuotient(prim.scale);
  const Vector3d b = prim.a + (prim.b - prim.a).cwiseQuotient(prim.scale);
  return round_cone_distance(q, prim.a, b, prim.ra, prim.rb) * prim.scale.minCoeff();
}

BodyPrimitive ellipsoid(int joint, const Vector3d& centre, const Vector3d& radii,
                        const Eigen::Matrix3d& axes) {
  BodyPrimitive e;
  e.kind = BodyPrimitive::kEllipsoid;
  e.joint = joint;
  e.a = centre;
  e.radii = radii;
  e.axes = axes;
  return e;
}

BodyPrimitive round_cone(int joint, const Vector3d& a, double ra, const Vector3d& b, double rb,
                         const Vector3d& scale) {
  BodyPrimitive c;
  c.scale = scale;
  c.kind = BodyPrimitive::kRoundCone;
  c.joint = joint;
  c.a = a;
  c.b = b;
  c.ra = ra;
  c.rb = rb;
  return c;
}

void set_skeleton(BodyModel& body, const std::vector<std::pair<std::string, std::string>>& joints,
                  const std::vector<Vector3d>& positions) {
  Skeleton& sk = body.skeleton;
  sk = Skeleton();
  for (const auto& [name, parent] : joints) {
    sk.names.push_back(name);
    sk.parents.push_back(parent.empty() ? -1 : sk.find(parent));
  }
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const int parent = sk.parents[i];
    sk.rest_offsets.push_back(parent < 0 ? positions[i]
                                         : Vector3d(positions[i] - positions[static_cast<std::size_t>(parent)]));
  }
  body.rest_positions = positions;
}

BodyModel scaled_body(double scale, double build, Girth* girth) {
  BodyModel body;
  body.scale = scale;
  body.blend_radius = 0.012 * scale;
  girth->trunk = scale * build;
  girth->extremities = scale * std::pow(build, 0.3);
  return body;
}

BodyModel make_body_model(double height, double build) {
  const double s = height / kNominalHeight;
  // Girth: torso and limbs follow the build fully, head, hands and feet barely.
  Girth girth;
  BodyModel body = scaled_body(s, build, &girth);
  const double g = girth.trunk, g_ext = girth.extremities;

  const double drop = kArmDropDeg * M_PI / 180.0;
  // Arm directions at rest, left (+y) and right (-y).
  const std::array<Vector3d, 2> arm_dir = {Vector3d(0, std::cos(drop), -std::sin(drop)),
                                           Vector3d(0, -std::cos(drop), -std::sin(drop))};
  const std::array<double, 2> side = {1.0, -1.0};

  // Joint rest positions (world).
  std::vector<Vector3d> pos(std::size(kJoints), Vector3d::Zero());
  auto set = [&](const char* name, const Vector3d& p) {
    for (std::size_t i = 0; i < std::size(kJoints); ++i) {
      if (std::string(kJoints[i].name) == name) pos[i] = p * s;
    }
  };
  set("pelvis", {0, 0, 0.97});
  set("spine", {0, 0, 1.08});
  set("chest", {0, 0, 1.26});
  set("neck", {0, 0, 1.47});
  set("head", {0, 0, 1.57});
  const char* suffix[2] = {"_l", "_r"};
  const double upper_arm = 0.29, forearm = 0.25, hand = 0.185;
  // A heavier build has broader shoulders: the shoulder moves out by as much as the chest's
  // and the upper arm's radii grow, so the hanging arm keeps its clearance from the trunk
  // (with the average build's shoulders a build of 1.3 walked with its upper arms 1-2 cm
  // inside its waist). Nominal metres; 0 at the average build.
  const double broader = (0.16 + 0.05) * (build - 1.0);
  // Likewise the legs stand and step wider by as much as the thigh's radius grows, so the
  // thighs and knees keep their clearance in a stride (at 1.3 they passed through each other
  // in a fast walk).
  const double leg_y = 0.09 + 0.088 * (build - 1.0);
  for (int i = 0; i < 2; ++i) {
    const std::string sfx = suffix[i];
    const double y = side[i];
    const Vector3d shoulder(0, (0.175 + broader) * y, 1.43);
    set(("clavicle" + sfx).c_str(), {0, 0.025 * y, 1.43});
    set(("upper_arm" + sfx).c_str(), shoulder);
    set(("forearm" + sfx).c_str(), shoulder + upper_arm * arm_dir[i]);
    set(("hand" + sfx).c_str(), shoulder + (upper_arm + forearm) * arm_dir[i]);
    set(("thigh" + sfx).c_str(), {0, leg_y * y, 0.92});
    set(("shin" + sfx).c_str(), {0, leg_y * y, 0.50});
    set(("foot" + sfx).c_str(), {0, leg_y * y, 0.085});
    set(("toe" + sfx).c_str(), {0.13, leg_y * y, 0.03});
  }

  std::vector<std::pair<std::string, std::string>> joints;
  for (const JointSpec& j : kJoints) joints.emplace_back(j.name, j.parent ? j.parent : "");
  set_skeleton(body, joints, pos);
  const Skeleton& sk = body.skeleton;

  // Primitives, in nominal metres (scaled below): torso, head, arms, legs.
  auto J = [&](const std::string& name) { return sk.find(name); };
  std::vector<BodyPrimitive>& prims = body.primitives;
  auto P = [&](double x, double y, double z) { return Vector3d(x * s, y * s, z * s); };
  prims.push_back(ellipsoid(J("pelvis"), P(-0.01, 0, 0.93), Vector3d(0.11, 0.162, 0.12) * g));
  for (int i = 0; i < 2; ++i) {
    prims.push_back(ellipsoid(J("pelvis"), P(-0.055, 0.07 * side[i], 0.89), Vector3d(0.075, 0.08, 0.09) * g));
  }
  // The trunk: elliptic round cones, narrowest at the waist, tapering to the neck.
  prims.push_back(round_cone(J("spine"), P(0, 0, 0.98), 0.15 * g, P(0, 0, 1.12), 0.135 * g, Vector3d(0.72, 1, 1)));
  prims.push_back(round_cone(J("chest"), P(0, 0, 1.12), 0.135 * g, P(0, 0, 1.30), 0.16 * g, Vector3d(0.74, 1, 1)));
  prims.push_back(round_cone(J("chest"), P(0, 0, 1.30), 0.16 * g, P(0, 0, 1.395), 0.125 * g, Vector3d(0.72, 1, 1)));
  prims.push_back(round_cone(J("neck"), P(0, 0, 1.43), 0.056 * g_ext, P(0.008, 0, 1.585), 0.05 * g_ext));
  prims.push_back(ellipsoid(J("head"), P(0.012, 0, 1.648), Vector3d(0.098, 0.079, 0.107) * s));
  prims.push_back(ellipsoid(J("head"), P(0.045, 0, 1.59), Vector3d(0.065, 0.058, 0.05) * s));
  prims.push_back(ellipsoid(J("head"), P(0.105, 0, 1.635), Vector3d(0.02, 0.012, 0.025) * s));
  for (int i = 0; i < 2; ++i) {
    const std::string sfx = suffix[i];
    const double y = side[i];
    const Vector3d& shoulder = pos[static_cast<std::size_t>(J("upper_arm" + sfx))];
    const Vector3d& elbow = pos[static_cast<std::size_t>(J("forearm" + sfx))];
    const Vector3d& wrist = pos[static_cast<std::size_t>(J("hand" + sfx))];
    const Vector3d& d = arm_dir[i];
    prims.push_back(round_cone(J("clavicle" + sfx), P(-0.01, 0.03 * y, 1.405), 0.055 * g,
                               P(-0.01, (0.165 + broader) * y, 1.42), 0.053 * g));
    prims.push_back(round_cone(J("upper_arm" + sfx), shoulder, 0.05 * g, elbow, 0.04 * g));
    prims.push_back(round_cone(J("forearm" + sfx), elbow, 0.04 * g, wrist, 0.027 * g));
    // The hand: flat, its width along x (palm towards the thigh), its thickness across.
    Eigen::Matrix3d hand_axes;
    hand_axes.col(0) = d;
    hand_axes.col(1) = Vector3d::UnitX();
    hand_axes.col(2) = d.cross(Vector3d::UnitX());
    prims.push_back(ellipsoid(J("hand" + sfx), wrist + 0.085 * s * d,
                              Vector3d(0.5 * hand, 0.045, 0.02) * g_ext, hand_axes));
    body.arms[static_cast<std::size_t>(i)] = {shoulder, wrist + hand * s * d};

    const Vector3d hip = pos[static_cast<std::size_t>(J("thigh" + sfx))];
    const Vector3d knee = pos[static_cast<std::size_t>(J("shin" + sfx))];
    const Vector3d ankle = pos[static_cast<std::size_t>(J("foot" + sfx))];
    prims.push_back(round_cone(J("thigh" + sfx), P(0, leg_y * y, 0.95), 0.088 * g, knee, 0.056 * g));
    prims.push_back(round_cone(J("shin" + sfx), knee, 0.053 * g, ankle, 0.035 * g));
    prims.push_back(ellipsoid(J("shin" + sfx), P(-0.025, leg_y * y, 0.37), Vector3d(0.048, 0.045, 0.11) * g));
    // Feet rest on the floor: every sphere touches z = 0.
    const double rh = 0.045 * g_ext, rbf = 0.036 * g_ext, rt = 0.025 * g_ext;
    prims.push_back(round_cone(J("foot" + sfx), Vector3d(-0.045 * s, leg_y * y * s, rh), rh,
                               Vector3d(0.125 * s, leg_y * y * s, rbf), rbf));
    prims.push_back(round_cone(J("toe" + sfx), Vector3d(0.125 * s, leg_y * y * s, 0.033 * g_ext),
                               0.033 * g_ext, Vector3d(0.2 * s, leg_y * y * s, rt), rt));
    body.legs[static_cast<std::size_t>(i)] = {hip, ankle};
    body.feet[static_cast<std::size_t>(i)] = {Vector3d(-0.09 * s, leg_y * y * s, 0.04 * s),
                                              Vector3d(0.225 * s, leg_y * y * s, 0.04 * s)};
  }
  return body;
}

void primitive_distances(const BodyModel& body, const Vector3d& p, double* out) {
  for (std::size_t i = 0; i < body.primitives.size(); ++i) out[i] = primitive_distance(body.primitives[i], p);
}

double body_field(const BodyModel& body, const Vector3d& p) {
  // Exponential smooth minimum: symmetric in its arguments, so the order of the primitives
  // does not matter, and C-infinity smooth where they blend.
  const double k = body.blend_radius;
  double d[kMaxPrimitives];
  const std::size_t n = body.primitives.size();
  primitive_distances(body, p, d);
  const double dmin = *std::min_element(d, d + n);
  double sum = 0;
  for (std::size_t i = 0; i < n; ++i) sum += std::exp(-(d[i] - dmin) / k);
  return dmin - k * std::log(sum);
}

BodyModel moved_body(BodyModel body, const Vector3d& shift, double factor) {
  for (BodyPrimitive& prim : body.primitives) {
    prim.a = (prim.a + shift) * factor;
    prim.b = (prim.b + shift) * factor;
    prim.ra *= factor;
    prim.rb *= factor;
    prim.radii *= factor;
  }
  for (Vector3d& p : body.rest_positions) p = (p + shift) * factor;
  body.blend_radius *= factor;
  auto move = [&](Vector3d& p) { p = (p + shift) * factor; };
  auto move_axis = [&](LimbAxis& axis) {
    move(axis.start);
    move(axis.end);
  };
  for (auto* axes : {&body.arms, &body.legs, &body.feet}) {
    for (LimbAxis& axis : *axes) move_axis(axis);
  }
  if (body.quadruped) {
    QuadrupedLayout& q = *body.quadruped;
    for (LimbAxis* axis : {&q.trunk, &q.head, &q.tail}) move_axis(*axis);
    for (auto& leg : q.legs) {
      for (Vector3d& p : leg) move(p);
    }
    for (Vector3d& eye : q.eyes) move(eye);
    q.hoof_top = (q.hoof_top + shift.z()) * factor;
  }
  return body;
}

void body_bounds(const BodyModel& body, double margin, Vector3d* lo, Vector3d* hi) {
  *lo = Vector3d::Constant(std::numeric_limits<double>::max());
  *hi = Vector3d::Constant(std::numeric_limits<double>::lowest());
  for (const BodyPrimitive& prim : body.primitives) {
    if (prim.kind == BodyPrimitive::kEllipsoid) {
      // Half-extent of a rotated ellipsoid along each world axis.
      const Vector3d half = (prim.axes.cwiseAbs() * prim.radii.asDiagonal()).rowwise().norm();
      *lo = lo->cwiseMin(prim.a - half);
      *hi = hi->cwiseMax(prim.a + half);
    } else {
      // Bounds of the unstretched cone about a, stretched.
      const Vector3d b = (prim.b - prim.a).cwiseQuotient(prim.scale);
      const Vector3d cone_lo = Vector3d::Constant(-prim.ra).cwiseMin((b.array() - prim.rb).matrix());
      const Vector3d cone_hi = Vector3d::Constant(prim.ra).cwiseMax((b.array() + prim.rb).matrix());
      *lo = lo->cwiseMin(prim.a + cone_lo.cwiseProduct(prim.scale));
      *hi = hi->cwiseMax(prim.a + cone_hi.cwiseProduct(prim.scale));
    }
  }
  *lo = (lo->array() - margin).matrix();
  *hi = (hi->array() + margin).matrix();
}

}  // namespace fourd::synth::detail
