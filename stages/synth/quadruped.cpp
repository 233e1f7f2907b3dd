#include "stages/synth/quadruped.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "stages/synth/paint.h"

namespace fourd::synth::detail {
namespace {

using Eigen::Vector3d;

// The nominal animal's highest point (the ears' tips) [m]; make_quadruped_model scales it to
// the requested height, the mesh is then scaled to it exactly.
constexpr double kNominalHeight = 1.015;

const char* const kSide[2] = {"_l", "_r"};

// ---- Atlas layout (u to the right, v up) ----
// Column u < 0.5: the trunk (top half), the head and neck, the tail (bottom rows); then a column
// for the front legs and one for the hind legs, rows by height above the floor.
constexpr double kU0 = 0.01, kDu = 0.48;
constexpr double kTrunkV0 = 0.51, kTrunkDv = 0.48;
constexpr double kHeadV0 = 0.17, kHeadDv = 0.32;
constexpr double kTailV0 = 0.01, kTailDv = 0.14;
constexpr double kFrontU0 = 0.51, kHindU0 = 0.76, kLegDu = 0.23;
constexpr double kLegV0 = 0.01, kLegDv = 0.98, kLegTopNominal = 0.72;  // rows: 0 .. this height [m]

enum class Part { kTrunk, kHead, kTail, kFrontLeg, kHindLeg };

double leg_top(const BodyModel& body) { return kLegTopNominal * body.scale; }

// Position along `axis` (0 at its start, 1 at its end), and the angle around it from straight
// up, folded to [0, pi] (0 on the back, pi underneath).
void axis_coordinates(const LimbAxis& axis, const Vector3d& p, double* t, double* phi) {
  const Vector3d d = axis.end - axis.start;
  const Vector3d u = d.normalized();
  *t = (p - axis.start).dot(u) / d.norm();
  *phi = folded_angle(p - axis.start, u, (Vector3d::UnitZ() - Vector3d::UnitZ().dot(u) * u).normalized());
}

// Around a leg: the angle of p's horizontal offset from the nearest point of the leg's polyline,
// from straight ahead, folded to [0, pi] (left and right legs mirror each other).
double leg_angle(const std::vector<Vector3d>& leg, const Vector3d& p) {
  double best = std::numeric_limits<double>::max();
  Vector3d nearest = leg.front();
  for (std::size_t k = 0; k + 1 < leg.size(); ++k) {
    const Vector3d a = leg[k], ab = leg[k + 1] - leg[k];
    const double s = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    const Vector3d q = a + s * ab;
    if ((p - q).squaredNorm() < best) {
      best = (p - q).squaredNorm();
      nearest = q;
    }
  }
  const Vector3d d = p - nearest;
  return std::abs(std::atan2(d.y(), d.x()));
}

Vec2f chart_uv(const BodyModel& body, Part part, int side, const Vector3d& p) {
  const QuadrupedLayout& q = *body.quadruped;
  double t = 0, phi = 0;
  auto in = [&](double v0, double dv) {
    return Vec2f(static_cast<float>(kU0 + kDu * phi / M_PI), static_cast<float>(v0 + dv * std::clamp(t, 0.0, 1.0)));
  };
  switch (part) {
    case Part::kTrunk:
      axis_coordinates(q.trunk, p, &t, &phi);
      return in(kTrunkV0, kTrunkDv);
    case Part::kHead:
      axis_coordinates(q.head, p, &t, &phi);
      return in(kHeadV0, kHeadDv);
    case Part::kTail:
      axis_coordinates(q.tail, p, &t, &phi);
      return in(kTailV0, kTailDv);
    case Part::kFrontLeg:
    case Part::kHindLeg: {
      const bool front = part == Part::kFrontLeg;
      phi = leg_angle(q.legs[static_cast<std::size_t>((front ? 0 : 2) + side)], p);
      const double v = std::clamp(p.z() / leg_top(body), 0.0, 1.0);
      return {static_cast<float>((front ? kFrontU0 : kHindU0) + kLegDu * phi / M_PI),
              static_cast<float>(kLegV0 + kLegDv * v)};
    }
  }
  return Vec2f::Zero();
}

// ---- The coat ----
struct Coat {
  Rgb base, mane, belly, hoof, sock_hoof;
  int marking = 0;  // 0 plain, 1 dapples, 2 pinto patches, 3 brindle stripes
  bool dorsal_stripe = false;
  std::array<double, 2> sock{};  // white socks of the front and the hind legs up to this height [m]
  std::uint64_t seed = 0;
};

Coat choose_coat(const BodyModel& body, std::uint64_t seed, const std::optional<Rgb>& key) {
  // Bay, chestnut, dun, grey, black, cream, liver, red: no greens (the default studio is chroma
  // green), and the key's own hue left out.
  const std::array<Rgb, 8> all = {rgb(140, 80, 42),  rgb(165, 82, 38),  rgb(196, 164, 112), rgb(150, 148, 145),
                                  rgb(44, 38, 36),   rgb(222, 205, 170), rgb(105, 60, 40),   rgb(190, 100, 45)};
  std::vector<Rgb> coats = wardrobe(all, key);
  if (coats.empty()) coats = {rgb(150, 148, 145)};
  std::uint64_t state = splitmix64(seed ^ 0xC0A7ull);
  auto pick = [&](std::size_t n) {
    state = splitmix64(state);
    return static_cast<std::size_t>(state % n);
  };
  Coat c;
  c.seed = splitmix64(seed ^ 0x0A11Aull);
  c.base = coats[pick(coats.size())];
  const bool dark = c.base.maxCoeff() < 0.3;
  c.mane = dark ? rgb(20, 18, 18) : (pick(2) ? rgb(30, 24, 22) : Rgb(c.base * 0.45));
  c.belly = dark ? Rgb(c.base * 1.3) : Rgb(0.55 * c.base + 0.45 * rgb(235, 222, 200));
  c.hoof = rgb(48, 42, 40);
  c.sock_hoof = rgb(125, 110, 88);
  c.marking = static_cast<int>(pick(4));
  c.dorsal_stripe = pick(3) == 0;
  for (double& sock : c.sock) sock = pick(3) == 0 ? (0.12 + 0.04 * static_cast<double>(pick(4))) * body.scale : 0.0;
  return c;
}

// Hair: the base colour with its markings, streaks along the hair (sv) and fine noise.
Rgb hair(const Coat& c, const Rgb& base, double su, double sv, bool markings) {
  Rgb col = base;
  if (markings) {
    switch (c.marking) {
      case 1: {  // dapples: light rings on a grid, jittered by noise
        const double p = 0.05, x = su / p + 0.3 * fbm(su, sv, 0.1, c.seed + 31), y = sv / p;
        const double d = std::hypot(x - std::floor(x) - 0.5, y - std::floor(y) - 0.5);
        col = base + (Rgb::Constant(0.85) - base) * 0.35 * smoothstep(0.18, 0.3, d) * (1 - smoothstep(0.38, 0.48, d));
        break;
      }
      case 2:  // pinto: large white patches
        col = base + (rgb(238, 234, 226) - base) * smoothstep(0.28, 0.34, fbm(su, sv, 0.35, c.seed + 32));
        break;
      case 3:  // brindle: dark irregular stripes
        col = base * (1 - 0.45 * smoothstep(0.55, 0.8, std::sin(2 * M_PI * (sv / 0.045 + 0.8 * fbm(su, sv, 0.12, c.seed + 33)))));
        break;
      default:
        break;
    }
  }
  return vary(col, 0.18 * fbm(su, sv, 0.04, c.seed + 1) + 0.12 * value_noise(su / 0.003, sv / 0.02, c.seed + 2) +
                       0.06 * value_noise(su / 0.004, sv / 0.004, c.seed + 3));
}

Rgb paint_trunk(const BodyModel& body, const Coat& c, double t, double phi) {
  const QuadrupedLayout& q = *body.quadruped;
  const double radius = 0.12 * body.scale;
  const double su = phi * radius, sv = t * (q.trunk.end - q.trunk.start).norm();
  if (c.dorsal_stripe && phi < 0.05 * M_PI) return hair(c, c.mane, su, sv, false);
  const Rgb base = c.base + (c.belly - c.base) * smoothstep(0.62 * M_PI, 0.92 * M_PI, phi);
  return hair(c, base, su, sv, true);
}

Rgb paint_head(const BodyModel& body, const Coat& c, double t, double phi) {
  const QuadrupedLayout& q = *body.quadruped;
  const double length = (q.head.end - q.head.start).norm(), radius = 0.06 * body.scale;
  const double su = phi * radius, sv = t * length;
  for (const Vector3d& eye : q.eyes) {
    double te = 0, pe = 0;
    axis_coordinates(q.head, eye, &te, &pe);
    const double d = std::hypot((phi - pe) * radius, (t - te) * length) / (0.013 * body.scale);
    if (d < 1) return d < 0.35 ? rgb(230, 225, 215) * (1 - smoothstep(0.2, 0.35, d)) + rgb(18, 14, 12) * smoothstep(0.2, 0.35, d)
                               : rgb(18, 14, 12);
  }
  // The mane along the top of the neck, the muzzle darker towards the nose.
  if (t < 0.45 && phi < 0.1 * M_PI) return hair(c, c.mane, su, sv, false);
  const Rgb muzzle = c.base * 0.55 + rgb(30, 24, 22) * 0.45;
  const Rgb base = c.base + (muzzle - c.base) * smoothstep(0.82, 0.95, t);
  return hair(c, base, su, sv, t < 0.5);
}

Rgb paint_tail(const BodyModel& body, const Coat& c, double t, double phi) {
  const QuadrupedLayout& q = *body.quadruped;
  const double su = phi * 0.025 * body.scale, sv = t * (q.tail.end - q.tail.start).norm();
  return hair(c, c.base + (c.mane - c.base) * smoothstep(0.15, 0.4, t), su, sv, false);
}

Rgb paint_leg(const BodyModel& body, const Coat& c, bool front, double z, double phi) {
  const QuadrupedLayout& q = *body.quadruped;
  const double su = phi * 0.035 * body.scale, sv = z;
  const double sock = c.sock[front ? 0 : 1];
  if (z < q.hoof_top) {
    // The hoof: horn with growth rings, a coronet band at its top.
    const Rgb horn = sock > 0 ? c.sock_hoof : c.hoof;
    if (z > q.hoof_top - 0.006 * body.scale) return vary(horn * 1.4, 0.1 * value_noise(su / 0.004, sv / 0.004, c.seed + 40));
    return vary(horn, 0.15 * std::sin(2 * M_PI * z / (0.004 * body.scale)) + 0.1 * fbm(su, sv, 0.01, c.seed + 41));
  }
  if (z < sock) return hair(c, rgb(236, 232, 224), su, sv, false);
  // Lower legs darken towards the hoof (points), the upper legs carry the trunk's markings.
  const Rgb lower = c.base + (c.mane - c.base) * 0.5;
  return hair(c, c.base + (lower - c.base) * (1 - smoothstep(0.18, 0.32, z / body.scale)), su, sv, z > 0.4 * body.scale);
}

}  // namespace

HoofShape hoof_shape(double fetlock_height) {
  // Nominal: the fetlock 65 mm up, the hoof 80 mm long, 60 wide and 60 high, 25 mm ahead.
  const double k = fetlock_height / 0.065;
  return {Vector3d(0.025, 0, -0.035) * k, Vector3d(0.04, 0.03, 0.03) * k};
}

BodyModel make_quadruped_model(double height, double build) {
  const double s = height / kNominalHeight;
  // Girth: trunk and limbs follow the build fully, head, tail and hooves barely.
  Girth girth;
  BodyModel body = scaled_body(s, build, &girth);
  const double g = girth.trunk, g_ext = girth.extremities;
  auto P = [&](double x, double y, double z) { return Vector3d(x * s, y * s, z * s); };

  // Joints and their rest positions, nominal metres.
  std::vector<std::pair<std::string, std::string>> joints = {
      {"pelvis", ""}, {"spine", "pelvis"}, {"chest", "spine"}, {"neck", "chest"}, {"head", "neck"},
      {"tail_0", "pelvis"}, {"tail_1", "tail_0"}, {"tail_2", "tail_1"}};
  std::vector<Vector3d> pos = {P(-0.30, 0, 0.62), P(-0.05, 0, 0.62), P(0.18, 0, 0.63), P(0.28, 0, 0.70),
                               P(0.42, 0, 0.88),  P(-0.44, 0, 0.68), P(-0.52, 0, 0.64), P(-0.59, 0, 0.57)};
  const Vector3d tail_tip = P(-0.64, 0, 0.49);
  // Legs: top, second, third joint, fetlock; the hoof (hoof_shape) below the fetlock.
  struct LegSpec {
    const char* names[4];
    const char* parent;
    double y;
    std::array<Vector3d, 4> at;
  };
  const LegSpec legs[2] = {
      {{"upper_arm", "forearm", "front_cannon", "front_hoof"}, "chest", 0.085,
       {Vector3d(0.22, 0, 0.56), Vector3d(0.12, 0, 0.42), Vector3d(0.18, 0, 0.22), Vector3d(0.19, 0, 0.065)}},
      {{"thigh", "shin", "hind_cannon", "hind_hoof"}, "pelvis", 0.075,
       {Vector3d(-0.30, 0, 0.58), Vector3d(-0.20, 0, 0.40), Vector3d(-0.34, 0, 0.22), Vector3d(-0.32, 0, 0.065)}}};
  const HoofShape hoof = hoof_shape(0.065 * s);
  QuadrupedLayout layout;
  for (int front_hind = 0; front_hind < 2; ++front_hind) {
    const LegSpec& leg = legs[front_hind];
    for (int i = 0; i < 2; ++i) {
      const double y = (i == 0 ? 1 : -1) * leg.y;
      std::string parent = leg.parent;
      std::vector<Vector3d>& chart = layout.legs[static_cast<std::size_t>(2 * front_hind + i)];
      for (int k = 0; k < 4; ++k) {
        const std::string name = std::string(leg.names[k]) + kSide[i];
        joints.emplace_back(name, parent);
        pos.push_back(P(leg.at[static_cast<std::size_t>(k)].x(), y, leg.at[static_cast<std::size_t>(k)].z()));
        chart.push_back(pos.back());
        parent = name;
      }
      chart.push_back(pos.back() + hoof.centre);
    }
  }
  set_skeleton(body, joints, pos);
  const Skeleton& sk = body.skeleton;
  auto J = [&](const std::string& name) { return sk.find(name); };
  auto at = [&](const std::string& name) { return pos[static_cast<std::size_t>(J(name))]; };

  std::vector<BodyPrimitive>& prims = body.primitives;
  // The trunk: rump, barrel (elliptic, taller than wide), chest and withers.
  prims.push_back(ellipsoid(J("pelvis"), P(-0.33, 0, 0.63), Vector3d(0.14, 0.105, 0.13) * g));
  prims.push_back(round_cone(J("spine"), P(-0.28, 0, 0.615), 0.125 * g, P(0.02, 0, 0.61), 0.14 * g, Vector3d(1, 0.8, 1)));
  prims.push_back(round_cone(J("chest"), P(0.02, 0, 0.61), 0.14 * g, P(0.20, 0, 0.62), 0.13 * g, Vector3d(1, 0.78, 1)));
  prims.push_back(ellipsoid(J("chest"), P(0.16, 0, 0.70), Vector3d(0.12, 0.07, 0.07) * g));
  // Neck, head (cranium, muzzle) and ears, tilted out.
  prims.push_back(round_cone(J("neck"), P(0.24, 0, 0.68), 0.085 * g, P(0.42, 0, 0.88), 0.055 * g, Vector3d(1, 0.8, 1)));
  prims.push_back(ellipsoid(J("head"), P(0.45, 0, 0.905), Vector3d(0.075, 0.055, 0.06) * g_ext));
  prims.push_back(round_cone(J("head"), P(0.47, 0, 0.89), 0.048 * g_ext, P(0.60, 0, 0.83), 0.03 * g_ext));
  for (int i = 0; i < 2; ++i) {
    const double y = i == 0 ? 1 : -1;
    const Eigen::Matrix3d tilt = Eigen::AngleAxisd(y * 20 * M_PI / 180, Vector3d::UnitX()).toRotationMatrix();
    prims.push_back(ellipsoid(J("head"), P(0.425, 0.045 * y, 0.975), Vector3d(0.016, 0.013, 0.04) * s, tilt));
    layout.eyes[static_cast<std::size_t>(i)] = P(0.488, 0.043 * y, 0.915);
  }
  // The tail, held out behind the hind legs.
  const Vector3d tail[4] = {at("tail_0"), at("tail_1"), at("tail_2"), tail_tip};
  const double tail_r[4] = {0.035, 0.03, 0.026, 0.018};
  for (int k = 0; k < 3; ++k) {
    prims.push_back(round_cone(J("tail_" + std::to_string(k)), tail[k], tail_r[k] * g_ext, tail[k + 1], tail_r[k + 1] * g_ext));
  }
  // Legs: upper and lower leg, cannon, pastern and hoof. The hoof's bottom is on the floor.
  const double radii[2][4][2] = {{{0.065, 0.05}, {0.048, 0.03}, {0.03, 0.022}, {0.024, 0.026}},
                                 {{0.075, 0.05}, {0.045, 0.03}, {0.03, 0.022}, {0.024, 0.026}}};
  for (int front_hind = 0; front_hind < 2; ++front_hind) {
    for (int i = 0; i < 2; ++i) {
      const std::vector<Vector3d>& chain = layout.legs[static_cast<std::size_t>(2 * front_hind + i)];
      for (int k = 0; k < 4; ++k) {
        const int joint = J(std::string(legs[front_hind].names[k]) + kSide[i]);
        Vector3d a = chain[static_cast<std::size_t>(k)], b = chain[static_cast<std::size_t>(k + 1)];
        if (k == 0) a.z() += 0.02 * s;  // the top reaches into the trunk
        if (k == 3) b = a + 0.6 * (b - a) + Vector3d(0, 0, 0.005 * s);  // the pastern
        const double r = radii[front_hind][k][0] * (k == 3 ? g_ext : g), rb = radii[front_hind][k][1] * (k == 3 ? g_ext : g);
        prims.push_back(round_cone(joint, a, r, b, rb));
      }
      prims.push_back(ellipsoid(J(std::string(legs[front_hind].names[3]) + kSide[i]), chain[4], hoof.radii));
    }
  }
  layout.trunk = {P(-0.47, 0, 0.62), P(0.33, 0, 0.63)};
  layout.head = {P(0.24, 0, 0.66), P(0.64, 0, 0.82)};
  layout.tail = {at("tail_0"), tail_tip};
  layout.hoof_top = 0.058 * s;
  body.quadruped = layout;
  return body;
}

std::vector<Vec2f> quadruped_uvs(const BodyModel& body, const Mesh& mesh, const Eigen::MatrixXd& dense) {
  const Skeleton& sk = body.skeleton;
  // The part of each joint: 0 trunk, 1 head and neck, 2 tail, 3 + leg (front l, r, hind l, r).
  std::vector<int> part_of_joint(sk.size(), 0);
  for (std::size_t j = 0; j < sk.size(); ++j) {
    const std::string& n = sk.names[j];
    const int side = n.size() > 2 && n.substr(n.size() - 2) == "_r" ? 1 : 0;
    if (n == "neck" || n == "head") {
      part_of_joint[j] = 1;
    } else if (n.rfind("tail", 0) == 0) {
      part_of_joint[j] = 2;
    } else if (n.rfind("upper_arm", 0) == 0 || n.rfind("forearm", 0) == 0 || n.rfind("front_", 0) == 0) {
      part_of_joint[j] = 3 + side;
    } else if (n.rfind("thigh", 0) == 0 || n.rfind("shin", 0) == 0 || n.rfind("hind_", 0) == 0) {
      part_of_joint[j] = 5 + side;
    }
  }
  std::vector<Vec2f> uvs(mesh.num_vertices());
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    double weight[7] = {0};
    for (std::size_t j = 0; j < sk.size(); ++j) weight[part_of_joint[j]] += dense(static_cast<Eigen::Index>(v), static_cast<Eigen::Index>(j));
    const int best = static_cast<int>(std::max_element(weight, weight + 7) - weight);
    const Part part = best == 0 ? Part::kTrunk : best == 1 ? Part::kHead : best == 2 ? Part::kTail
                    : best < 5 ? Part::kFrontLeg : Part::kHindLeg;
    uvs[v] = chart_uv(body, part, best >= 3 ? (best - 3) % 2 : 0, mesh.positions[v].cast<double>());
  }
  return uvs;
}

cv::Mat paint_coat(const BodyModel& body, int size, std::uint64_t seed, const std::optional<Eigen::Vector3d>& key) {
  const Coat coat = choose_coat(body, seed, key);
  return paint_image(size, [&](double u, double v) -> Rgb {
    const double phi = std::clamp((u - kU0) / kDu, 0.0, 1.0) * M_PI;
    if (u < 0.5) {
      if (v >= 0.5) return paint_trunk(body, coat, std::clamp((v - kTrunkV0) / kTrunkDv, 0.0, 1.0), phi);
      if (v >= 0.155) return paint_head(body, coat, std::clamp((v - kHeadV0) / kHeadDv, 0.0, 1.0), phi);
      return paint_tail(body, coat, std::clamp((v - kTailV0) / kTailDv, 0.0, 1.0), phi);
    }
    const bool front = u < 0.75;
    const double leg_phi = std::clamp((u - (front ? kFrontU0 : kHindU0)) / kLegDu, 0.0, 1.0) * M_PI;
    const double z = std::clamp((v - kLegV0) / kLegDv, 0.0, 1.0) * leg_top(body);
    return paint_leg(body, coat, front, z, leg_phi);
  });
}

}  // namespace fourd::synth::detail
