#include "stages/synth/garment.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "pipeline/core/error.h"
#include "pipeline/geometry/mesh_query.h"
#include "stages/synth/clothing.h"

namespace fourd::synth {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector3d;

constexpr double kNominalHeight = 1.75;  // the performer the nominal lengths below are for [m]
constexpr double kGravity = 9.81;        // [m/s^2]

// The skirt, nominal at 1.75 m (scaled with the height). The waistband sits just above the
// trousers' belt. The shell is thicker than cloth so that it is more than one step of the
// oracle's 8 mm grid (validate's remesh_fresh re-meshes ground truth on it), yet that is not
// enough to keep it whole there: re-meshed, the skirt of the rest pose has 149 handles, and 234
// with the body (bridged across the 4 mm gap). A 20 mm shell 12 mm off the body re-meshes with
// 9, but with the simulation's margins that large the shell crossed itself while standing and
// the cloth stretched by up to 47 % (docs/synth.md).
constexpr double kWaistAbovePelvis = 0.06;  // waistband height above the pelvis joint [m]
constexpr double kThickness = 0.010;        // [m]
constexpr double kClearance = 0.004;        // shell's inside to the body [m]
constexpr double kRowSpacing = 0.025;       // particle spacing down the cloth, as cut [m]
constexpr int kColumns = 64;                // particles around a ring

// The simulation: small steps with few passes over the constraints each (Macklin et al.,
// "Small steps in physics simulation", 2019) are stiff, stable and cheap. With one pass a
// ring's links down the cloth stretched by up to 7.7 % in a fast dance, with three by up to
// 5.3 %, 99 % of them by less than 1.7 %.
constexpr double kMaxStep = 1.0 / 600;  // [s]
constexpr int kPasses = 3;              // over the distance constraints, per step
constexpr double kAirDrag = 0.8;        // velocity lost per second to the air [1/s]
constexpr double kGather = 0.3;         // across the cloth, distances shrink to this, no further
// Over two segments, down the cloth and along a ring, a distance is pulled back (softly) to
// its cut length down the cloth and to at least kRingBend of it along a ring: kinks straighten.
constexpr double kBendStiffness = 0.2;
constexpr double kRingBend = 0.5;
// Across the cloth neighbours stay at least kApart shell thicknesses apart, and particles two
// apart along a ring twice that: the shell, thicker than cloth, does not fold through itself
// where the cloth gathers.
constexpr double kApart = 1.2;
// The cloth's contact with itself (real cloth does not pass through itself): a particle keeps
// kSelfContact shell thicknesses from every triangle of the sheet it is over that is not its
// neighbour (the triangle's nearest corner more than kSelfNeighbours particles from it along a
// ring or down the cloth), on the side it was on, so that the shell's two sides, half a
// thickness off the sheet either way, do not cross where the cloth folds onto itself. A pair
// nearer than that is parted at kSelfSeparate, not at once (pushed apart in one step, it would
// fly apart).
constexpr double kSelfContact = 2.0;
constexpr int kSelfNeighbours = 1;
constexpr double kSelfOver = 0.5;     // over a triangle: barycentric coordinates >= -kSelfOver
constexpr double kSelfSeparate = 0.3;  // [m/s]
// Along a ring the cloth turns by at most kRingTurn at a particle (its middle kept within
// tan(kRingTurn / 2) / 2 of its neighbours' distance from their midpoint, kTurnStiffness of the
// way per pass): a gathered skirt is a smooth surface; sharper, the cloth would crease at single
// particles and its cells fold through each other.
constexpr double kRingTurn = 45 * M_PI / 180;
constexpr double kTurnStiffness = 0.5;
// Starting a take: the cloth as cut hangs on the rest pose, then the body moves into the first
// frame's pose and holds it; a strong drag damps the fall.
constexpr double kSettleRest = 1.2, kSettleBlend = 0.6, kSettleHold = 0.6;  // [s]
constexpr double kSettleDrag = 6;  // [1/s]

// Primitives farther than this beyond their bounding sphere add nothing to the smooth union.
constexpr double kCullBlendRadii = 12;

std::size_t at(int i) { return static_cast<std::size_t>(i); }

// The joints' world transforms between two frames: rotations by slerp, positions linearly.
std::vector<Isometry3d> interpolate(const std::vector<Isometry3d>& a, const std::vector<Isometry3d>& b, double s) {
  std::vector<Isometry3d> out(a.size());
  for (std::size_t j = 0; j < a.size(); ++j) {
    const Eigen::Quaterniond qa(a[j].linear()), qb(b[j].linear());
    out[j] = Isometry3d::Identity();
    out[j].linear() = qa.slerp(s, qb).toRotationMatrix();
    out[j].translation() = (1 - s) * a[j].translation() + s * b[j].translation();
  }
  return out;
}

// Joints the cloth does not collide with: the head and neck are never near a skirt.
bool collides(const Skeleton& skeleton, int joint) {
  const std::string& name = skeleton.names[at(joint)];
  return name != "head" && name != "neck";
}

// A bounding sphere of a primitive (centre, radius) in its rest space.
std::pair<Vector3d, double> bounding_sphere(const detail::BodyPrimitive& prim) {
  if (prim.kind == detail::BodyPrimitive::kEllipsoid) return {prim.a, prim.radii.maxCoeff()};
  // The unstretched cone lies in the sphere about its middle; the stretch about a scales it.
  const Vector3d b = (prim.b - prim.a).cwiseQuotient(prim.scale);
  return {0.5 * (prim.a + prim.b), (0.5 * b.norm() + std::max(prim.ra, prim.rb)) * prim.scale.maxCoeff()};
}

}  // namespace

// ---- The simulation ----

struct ClothSimulation::Impl {
  struct Link {
    int a, b;
    double min, max, stiffness;
  };
  struct Collider {
    const detail::BodyPrimitive* primitive;
    int joint;
    Vector3d centre;  // bounding sphere, rest space
    double radius;
  };

  const Character& character;
  const Garment& garment;
  std::vector<Link> links;
  // Three particles along a ring (kRingTurn).
  std::vector<Eigen::Vector3i> bends;
  std::vector<Collider> colliders;
  std::vector<Isometry3d> rest_world;  // world_from_joint at rest
  std::vector<Vector3d> x, previous, velocity;
  std::vector<Eigen::Vector4i> carry_joints;  // per particle: the skin under it (follow_skin)
  std::vector<Eigen::Vector4f> carry_weights;
  std::vector<Vector3d> rest_centres;  // the colliders' bounding spheres' centres, rest pose

  // The cloth's contact with itself: the sheet's triangles; the particle-triangle pairs near
  // each other (found where the particles were at `found`, within `found_within`); per step,
  // those in contact, the side of the triangle the particle is on, and the distance to keep.
  struct Candidate {
    int particle, face;
  };
  struct Contact {
    int particle, face;
    double side;      // +1: on the side the triangle's normal points to; -1: the other
    double distance;  // to keep from the triangle's plane
  };
  std::vector<Eigen::Vector3i> faces;
  std::vector<Candidate> candidates;
  std::vector<Vector3d> found;
  double found_within = 0;
  std::vector<Contact> contacts;
  std::vector<int> bucket_start, bucket_particles;  // a spatial hash of the particles

  // Per step: world_from_rest and rest_from_world per joint, colliders' centres in the world.
  std::vector<Isometry3d> skinning, unskinning;
  std::vector<Vector3d> centres;
  std::vector<Isometry3d> last;  // the last frame's joints

  explicit Impl(const Character& c) : character(c), garment(*c.garment) {
    const TubeGrid& g = garment.grid;
    // A distance between min_fraction and max_fraction of the cut's, and at least `apart`.
    auto link = [&](int a, int b, double min_fraction, double max_fraction, double stiffness, double apart = 0) {
      const double rest = (garment.cut[at(a)] - garment.cut[at(b)]).norm();
      links.push_back({a, b, std::min(rest, std::max(min_fraction * rest, apart)), max_fraction * rest, stiffness});
    };
    const double apart = kApart * garment.thickness;
    for (int r = 0; r < g.rings; ++r) {
      for (int c = 0; c < g.columns; ++c) {
        const int i = g.index(r, c), right = g.index(r, (c + 1) % g.columns);
        link(i, right, kGather, 1, 1, apart);  // along the ring
        if (r + 1 < g.rings) {
          link(i, g.index(r + 1, c), 1, 1, 1);  // down the cloth
          link(i, g.index(r + 1, (c + 1) % g.columns), kGather, 1, 1, apart);  // shear
          link(right, g.index(r + 1, c), kGather, 1, 1, apart);
        }
        if (r + 2 < g.rings) link(i, g.index(r + 2, c), 1, 1, kBendStiffness);
        if (r > 0) link(i, g.index(r, (c + 2) % g.columns), kRingBend, 1, kBendStiffness, 2 * apart);
        if (r > 0) bends.emplace_back(i, right, g.index(r, (c + 2) % g.columns));
      }
    }
    faces = g.sheet_triangles();
    for (const detail::BodyPrimitive& prim : garment.body.primitives) {
      if (!collides(character.skeleton, prim.joint)) continue;
      const auto [centre, radius] = bounding_sphere(prim);
      colliders.push_back({&prim, prim.joint, centre, radius});
      rest_centres.push_back(centre);
    }
    for (const Isometry3d& ib : character.skin.inverse_bind) rest_world.push_back(ib.inverse());
    centres.resize(colliders.size());
  }

  void set_joints(const std::vector<Isometry3d>& world) {
    const std::size_t n = world.size();
    skinning.resize(n);
    unskinning.resize(n);
    for (std::size_t j = 0; j < n; ++j) {
      skinning[j] = world[j] * character.skin.inverse_bind[j];
      unskinning[j] = skinning[j].inverse();
    }
    for (std::size_t k = 0; k < colliders.size(); ++k) {
      centres[k] = skinning[at(colliders[k].joint)] * colliders[k].centre;
    }
  }

  Vector3d waist(int column) const {
    const Eigen::Vector4i& joints = garment.waist_joints[at(column)];
    const Eigen::Vector4f& weights = garment.waist_weights[at(column)];
    const Vector3d& p = garment.cut[at(column)];
    Vector3d out = Vector3d::Zero();
    for (int k = 0; k < 4; ++k) {
      if (weights[k] != 0.0f) out += static_cast<double>(weights[k]) * (skinning[at(joints[k])] * p);
    }
    return out;
  }

  // The smooth union of the colliders near p (the body's field); +infinity when none is. With
  // `rigid`, p is in the world and each primitive moves rigidly with its joint; otherwise p is
  // in the rest pose's space.
  double field(const Vector3d& p, const std::vector<int>& near, bool rigid) const {
    if (near.empty()) return std::numeric_limits<double>::infinity();
    double d[detail::kMaxPrimitives];
    double dmin = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < near.size(); ++k) {
      const Collider& c = colliders[at(near[k])];
      d[k] = detail::primitive_distance(*c.primitive, rigid ? Vector3d(unskinning[at(c.joint)] * p) : p);
      dmin = std::min(dmin, d[k]);
    }
    const double blend = garment.body.blend_radius;
    double sum = 0;
    for (std::size_t k = 0; k < near.size(); ++k) sum += std::exp(-(d[k] - dmin) / blend);
    return dmin - blend * std::log(sum);
  }

  // Moves p out of the body's field to at least `margin` from it (see field());
  // `centres` are the colliders' in p's space; with `carried`, only the primitives of the joints
  // in it count.
  void push_out(Vector3d& p, double margin, bool rigid, const std::vector<Vector3d>& at_centres,
                std::vector<int>& near, const Eigen::Vector4i* carried = nullptr) const {
    const double reach = margin + kCullBlendRadii * garment.body.blend_radius;
    near.clear();
    for (std::size_t k = 0; k < colliders.size(); ++k) {
      if (carried && ((*carried).array() != colliders[k].joint).all()) continue;
      if ((p - at_centres[k]).norm() - colliders[k].radius < reach) near.push_back(static_cast<int>(k));
    }
    const double f = field(p, near, rigid);
    if (!(f < margin)) return;
    const double h = 1e-4 * garment.body.scale;
    Vector3d gradient;
    for (int a = 0; a < 3; ++a) {
      Vector3d e = Vector3d::Zero();
      e[a] = h;
      gradient[a] = (field(p + e, near, rigid) - field(p - e, near, rigid)) / (2 * h);
    }
    if (gradient.norm() < 1e-9) return;
    p += (margin - f) * gradient.normalized();
  }

  // Moves particle i out of the body: of the primitives carried rigidly by their joints, then
  // of the body as the skin under the particle deforms (the field of that skin's joints'
  // primitives in the rest pose's space, mapped by the skin's blend of joint transforms), which
  // follows the skinned surface where joints bend.
  void collide(int i, double margin, std::vector<int>& near) {
    Vector3d& p = x[at(i)];
    push_out(p, margin, true, centres, near);
    Eigen::Matrix<double, 3, 4> blend = Eigen::Matrix<double, 3, 4>::Zero();
    for (int k = 0; k < 4; ++k) {
      const float w = carry_weights[at(i)][k];
      if (w != 0.0f) blend += static_cast<double>(w) * skinning[at(carry_joints[at(i)][k])].matrix().topRows<3>();
    }
    const Eigen::Matrix3d linear = blend.leftCols<3>();
    if (std::abs(linear.determinant()) < 1e-6) return;
    Vector3d rest = linear.inverse() * (p - blend.col(3));
    Eigen::Vector4i carried = carry_joints[at(i)];
    for (int k = 0; k < 4; ++k) {
      if (carry_weights[at(i)][k] == 0.0f) carried[k] = -1;
    }
    push_out(rest, margin, false, rest_centres, near, &carried);
    p = linear * rest + blend.col(3);
  }

  // Each particle's skinning for the skin-following collision: the weights of the skin vertex
  // nearest to it with the joints at `world`.
  void follow_skin(const std::vector<Isometry3d>& world) {
    const Mesh posed = skin_mesh(character.skin, world);
    const MeshQuery query(posed);
    carry_joints.resize(x.size());
    carry_weights.resize(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) {
      const ClosestPoint c = query.closest(x[i].cast<float>());
      int corner = 0;
      c.barycentric.maxCoeff(&corner);
      const int v = posed.triangles[at(c.triangle)][corner];
      carry_joints[i] = character.skin.joints[at(v)];
      carry_weights[i] = character.skin.weights[at(v)];
    }
  }

  // How much particle i moves when a constraint corrects it: 0 for the waistband's (ring 0,
  // sewn to the body), 1 for every other.
  double mobility(int i) const { return i < garment.grid.columns ? 0.0 : 1.0; }

  // Moves particles a and b (the waistband's do not move) to a distance within [min, max], by
  // `stiffness` of the way.
  void pull(int a, int b, double min, double max, double stiffness) {
    const double wa = mobility(a), wb = mobility(b);
    if (wa + wb == 0) return;
    const Vector3d d = x[at(b)] - x[at(a)];
    const double length = d.norm();
    if (length < 1e-12) return;
    const double target = std::clamp(length, min, max);
    if (target == length) return;
    const Vector3d correction = stiffness * (length - target) / length * d;
    x[at(a)] += wa / (wa + wb) * correction;
    x[at(b)] -= wb / (wa + wb) * correction;
  }

  // How far particle i is from face f's nearest corner, in steps across the sheet.
  int apart_in_cloth(int i, const Eigen::Vector3i& f) const {
    const TubeGrid& g = garment.grid;
    return std::min({g.steps(i, f[0]), g.steps(i, f[1]), g.steps(i, f[2])});
  }

  // The cells of a spatial hash.
  static std::size_t bucket(const Eigen::Vector3i& cell, std::size_t buckets) {
    const auto h = static_cast<std::uint64_t>(static_cast<std::int64_t>(cell.x()) * 92837111) ^
                   static_cast<std::uint64_t>(static_cast<std::int64_t>(cell.y()) * 689287499) ^
                   static_cast<std::uint64_t>(static_cast<std::int64_t>(cell.z()) * 283923481);
    return static_cast<std::size_t>(h % buckets);
  }

  // Where p is over the triangle (a, b, c): its barycentric coordinates in `over` and its
  // distance from the triangle's plane along the triangle's normal, returned; NaN when the
  // triangle is degenerate.
  static double over_triangle(const Vector3d& p, const Vector3d& a, const Vector3d& b, const Vector3d& c,
                              Vector3d& normal, double over[3]) {
    normal = (b - a).cross(c - a);
    const double area2 = normal.norm();
    if (area2 < 1e-14) return std::numeric_limits<double>::quiet_NaN();
    normal /= area2;
    const Vector3d q = p - a;
    over[1] = q.cross(c - a).dot(normal) / area2;
    over[2] = (b - a).cross(q).dot(normal) / area2;
    over[0] = 1 - over[1] - over[2];
    return q.dot(normal);
  }

  // The particle-triangle pairs within `within` of each other (a spatial hash of the
  // particles), but the triangles' neighbours (kSelfNeighbours).
  void find_candidates(double within) {
    const double cell = within;
    const std::size_t n = x.size(), buckets = 2 * n;
    auto cell_of = [&](const Vector3d& p) { return Eigen::Vector3i((p / cell).array().floor().cast<int>()); };
    bucket_start.assign(buckets + 1, 0);
    for (std::size_t i = 0; i < n; ++i) ++bucket_start[bucket(cell_of(x[i]), buckets) + 1];
    for (std::size_t b = 0; b < buckets; ++b) bucket_start[b + 1] += bucket_start[b];
    bucket_particles.resize(n);
    std::vector<int> fill(bucket_start.begin(), bucket_start.end() - 1);
    for (std::size_t i = 0; i < n; ++i) bucket_particles[at(fill[bucket(cell_of(x[i]), buckets)]++)] = static_cast<int>(i);
    candidates.clear();
    for (std::size_t f = 0; f < faces.size(); ++f) {
      const Eigen::Vector3i& t = faces[f];
      Eigen::AlignedBox3d box;
      for (int k = 0; k < 3; ++k) box.extend(x[at(t[k])]);
      const Eigen::Vector3i lo = cell_of(box.min() - Vector3d::Constant(within));
      const Eigen::Vector3i hi = cell_of(box.max() + Vector3d::Constant(within));
      const std::size_t first = candidates.size();
      for (int cx = lo.x(); cx <= hi.x(); ++cx) {
        for (int cy = lo.y(); cy <= hi.y(); ++cy) {
          for (int cz = lo.z(); cz <= hi.z(); ++cz) {
            const std::size_t b = bucket({cx, cy, cz}, buckets);
            for (int k = bucket_start[b]; k < bucket_start[b + 1]; ++k) {
              const int i = bucket_particles[at(k)];
              if (box.exteriorDistance(x[at(i)]) > within) continue;
              if (apart_in_cloth(i, t) > kSelfNeighbours) candidates.push_back({i, static_cast<int>(f)});
            }
          }
        }
      }
      // A particle in two cells of one bucket is found twice.
      std::sort(candidates.begin() + static_cast<long>(first), candidates.end(),
                [](const Candidate& l, const Candidate& r) { return l.particle < r.particle; });
      candidates.erase(std::unique(candidates.begin() + static_cast<long>(first), candidates.end(),
                                   [](const Candidate& l, const Candidate& r) { return l.particle == r.particle; }),
                       candidates.end());
    }
    found = x;
    found_within = within;
  }

  // The pairs in contact in this step: of the pairs that may come within `reach` of each other
  // (found anew when the particles have moved too far since they were last), those whose
  // particle was over the triangle at the step's start, on which side, and how far apart they
  // are to be.
  void find_contacts(double reach, double separate) {
    // A pair farther apart than found_within has come no nearer than found_within - 2 moved,
    // moved the farthest a particle has moved since, but for the cloth's common shift.
    double moved = 0;
    if (!found.empty()) {
      Vector3d shift = Vector3d::Zero();
      for (std::size_t i = 0; i < x.size(); ++i) shift += x[i] - found[i];
      shift /= static_cast<double>(x.size());
      for (std::size_t i = 0; i < x.size(); ++i) moved = std::max(moved, (x[i] - found[i] - shift).squaredNorm());
    }
    if (found.empty() || found_within - 2 * std::sqrt(moved) < reach) find_candidates(2 * reach);
    contacts.clear();
    for (const Candidate& candidate : candidates) {
      const Eigen::Vector3i& t = faces[at(candidate.face)];
      Vector3d normal;
      double over[3] = {0, 0, 0};
      const double distance = over_triangle(previous[at(candidate.particle)], previous[at(t[0])], previous[at(t[1])],
                                            previous[at(t[2])], normal, over);
      if (!(std::abs(distance) > 0) || std::abs(distance) > 2 * reach ||
          std::min({over[0], over[1], over[2]}) < -kSelfOver) {
        continue;
      }
      contacts.push_back({candidate.particle, candidate.face, distance > 0 ? 1.0 : -1.0,
                          std::min(reach, std::abs(distance) + separate)});
    }
  }

  // Moves each particle of `contacts` to its distance from its triangle's plane, on its side,
  // where it is over the triangle (kSelfOver); the triangle's particles move the other way, by
  // their part in the point of the triangle under it. The waistband's particles do not move.
  void keep_apart() {
    for (const Contact& contact : contacts) {
      const Eigen::Vector3i& t = faces[at(contact.face)];
      Vector3d& p = x[at(contact.particle)];
      Vector3d normal;
      double over[3] = {0, 0, 0};
      const double distance = contact.side * over_triangle(p, x[at(t[0])], x[at(t[1])], x[at(t[2])], normal, over);
      if (!(distance < contact.distance) || std::min({over[0], over[1], over[2]}) < -kSelfOver) continue;
      double denominator = mobility(contact.particle);
      for (double& o : over) {
        o = std::clamp(o, 0.0, 1.0);
      }
      const double sum = over[0] + over[1] + over[2];
      for (double& o : over) o /= sum;
      for (int k = 0; k < 3; ++k) denominator += over[k] * over[k] * mobility(t[k]);
      if (denominator == 0) continue;
      const Vector3d push = contact.side * (contact.distance - distance) / denominator * normal;
      p += mobility(contact.particle) * push;
      for (int k = 0; k < 3; ++k) x[at(t[k])] -= over[k] * mobility(t[k]) * push;
    }
  }

  // Moves the middle particle of each of `bends` towards its outer ones' midpoint, and them
  // away from it, where it is farther from it than `bend` of their distance.
  void straighten() {
    const double turn = std::tan(kRingTurn / 2) / 2;
    for (const Eigen::Vector3i& b : bends) {
      const Vector3d off = x[at(b[1])] - 0.5 * (x[at(b[0])] + x[at(b[2])]);
      const double length = off.norm(), limit = turn * (x[at(b[2])] - x[at(b[0])]).norm();
      if (length <= limit) continue;
      const double wa = mobility(b[0]), wm = mobility(b[1]), wb = mobility(b[2]);
      const double denominator = wm + 0.25 * (wa + wb);
      if (denominator == 0) continue;
      const Vector3d correction = kTurnStiffness * (length - limit) / length / denominator * off;
      x[at(b[1])] -= wm * correction;
      x[at(b[0])] += 0.5 * wa * correction;
      x[at(b[2])] += 0.5 * wb * correction;
    }
  }

  // One step of `dt` with the joints at `world`.
  void step(const std::vector<Isometry3d>& world, double dt, double drag) {
    set_joints(world);
    const TubeGrid& g = garment.grid;
    const Vector3d gravity(0, 0, -kGravity);
    const double keep = std::max(0.0, 1 - drag * dt);
    for (int i = g.columns; i < g.size(); ++i) {
      velocity[at(i)] = keep * (velocity[at(i)] + dt * gravity);
      previous[at(i)] = x[at(i)];
      x[at(i)] += dt * velocity[at(i)];
    }
    for (int c = 0; c < g.columns; ++c) {
      previous[at(c)] = x[at(c)];
      x[at(c)] = waist(c);
    }
    const double reach = kSelfContact * garment.thickness;
    find_contacts(reach, kSelfSeparate * dt);
    for (int pass = 0; pass < kPasses; ++pass) {
      for (const Link& l : links) pull(l.a, l.b, l.min, l.max, l.stiffness);
      straighten();
      keep_apart();
    }
    const double margin = 0.5 * garment.thickness + garment.clearance;
    std::vector<int> near;
    near.reserve(colliders.size());
    for (int i = g.columns; i < g.size(); ++i) collide(i, margin, near);
    keep_apart();  // as the body pushed the cloth, the cloth pushes back
    for (int i = g.columns; i < g.size(); ++i) velocity[at(i)] = (x[at(i)] - previous[at(i)]) / dt;
  }

  // Moves the joints from `from` to `to` over `seconds`.
  void simulate(const std::vector<Isometry3d>& from, const std::vector<Isometry3d>& to, double seconds,
                double drag) {
    follow_skin(from);
    const int steps = std::max(1, static_cast<int>(std::ceil(seconds / kMaxStep - 1e-9)));
    const double dt = seconds / steps;
    for (int k = 1; k <= steps; ++k) step(interpolate(from, to, static_cast<double>(k) / steps), dt, drag);
  }

  void start(const std::vector<Isometry3d>& world) {
    // The rest pose, placed where the frame's root (the pelvis) is, upright, facing its way.
    const Vector3d forward = world[0].linear() * rest_world[0].linear().transpose() * Vector3d::UnitX();
    Isometry3d place = Isometry3d::Identity();
    place.linear() = Eigen::AngleAxisd(std::atan2(forward.y(), forward.x()), Vector3d::UnitZ()).toRotationMatrix();
    const Vector3d shift = world[0].translation() - place.linear() * rest_world[0].translation();
    place.translation() = Vector3d(shift.x(), shift.y(), 0);
    std::vector<Isometry3d> rest(rest_world.size());
    for (std::size_t j = 0; j < rest.size(); ++j) rest[j] = place * rest_world[j];
    x.resize(garment.cut.size());
    found.clear();
    for (std::size_t i = 0; i < x.size(); ++i) x[i] = place * garment.cut[i];
    previous = x;
    velocity.assign(x.size(), Vector3d::Zero());
    simulate(rest, rest, kSettleRest, kSettleDrag);
    simulate(rest, world, kSettleBlend, kSettleDrag);
    simulate(world, world, kSettleHold, kSettleDrag);
    velocity.assign(x.size(), Vector3d::Zero());
    last = world;
  }
};

ClothSimulation::ClothSimulation(const Character& character) {
  if (!character.garment) throw InputError("cloth simulation: the character wears no garment");
  impl_ = std::make_unique<Impl>(character);
}

ClothSimulation::~ClothSimulation() = default;

void ClothSimulation::start(const std::vector<Isometry3d>& world_from_joint) { impl_->start(world_from_joint); }

void ClothSimulation::advance(const std::vector<Isometry3d>& world_from_joint, double seconds) {
  if (impl_->last.empty()) throw InputError("cloth simulation: advance() before start()");
  impl_->simulate(impl_->last, world_from_joint, seconds, kAirDrag);
  impl_->last = world_from_joint;
}

const std::vector<Vector3d>& ClothSimulation::positions() const { return impl_->x; }

// ---- The skirt as cut ----

namespace {

// The body's surface along the horizontal ray from (0, 0, z) at angle theta: the outermost
// crossing of the field, by bisection between the axis (inside) and `far` (outside).
Vector3d waist_point(const detail::BodyModel& body, double z, double theta, double far) {
  const Vector3d dir(std::cos(theta), std::sin(theta), 0);
  double lo = 0, hi = far;
  for (int k = 0; k < 60; ++k) {
    const double mid = 0.5 * (lo + hi);
    (detail::body_field(body, Vector3d(0, 0, z) + mid * dir) < 0 ? lo : hi) = mid;
  }
  return Vector3d(0, 0, z) + hi * dir;
}

// The horizontal outward normal of the body's field at p.
Vector3d horizontal_normal(const detail::BodyModel& body, const Vector3d& p) {
  const double h = 1e-5;
  const Vector3d n((detail::body_field(body, p + Vector3d(h, 0, 0)) - detail::body_field(body, p - Vector3d(h, 0, 0))),
                   (detail::body_field(body, p + Vector3d(0, h, 0)) - detail::body_field(body, p - Vector3d(0, h, 0))), 0);
  return n.normalized();
}

}  // namespace

std::shared_ptr<const Garment> make_skirt(const Character& character, const detail::BodyModel& body,
                                          const CharacterOptions& options) {
  auto garment = std::make_shared<Garment>();
  Garment& g = *garment;
  const double s = character.height / kNominalHeight;
  g.body = body;
  g.thickness = kThickness * s;
  g.clearance = kClearance * s;
  g.flare = options.skirt_flare * M_PI / 180;
  const int pelvis = character.skeleton.find("pelvis");
  if (pelvis < 0) throw InputError("skirt: the skeleton has no joint 'pelvis'");
  const double waist_z = character.skin.inverse_bind[at(pelvis)].inverse().translation().z() + kWaistAbovePelvis * s;
  g.length = options.skirt_length * waist_z;
  const double length = g.length;
  const int rows = std::max(4, static_cast<int>(std::lround(length / (kRowSpacing * s))));
  g.grid = TubeGrid{rows + 1, kColumns};

  // The waistband: around the body's cross-section, off it by half the shell and the clearance;
  // the cut runs down from it, out by the flare along the body's normal.
  std::vector<Vector3d> normals(kColumns);
  g.cut.resize(at(g.grid.size()));
  for (int c = 0; c < kColumns; ++c) {
    const double theta = 2 * M_PI * c / kColumns;
    const Vector3d surface = waist_point(body, waist_z, theta, 0.6 * s);
    normals[at(c)] = horizontal_normal(body, surface);
    g.cut[at(c)] = surface + (0.5 * g.thickness + g.clearance) * normals[at(c)];
    g.waist_radius += g.cut[at(c)].head<2>().norm() / kColumns;
  }
  for (int r = 1; r <= rows; ++r) {
    const double down = length * r / rows;
    for (int c = 0; c < kColumns; ++c) {
      g.cut[at(g.grid.index(r, c))] =
          g.cut[at(c)] + down * (std::sin(g.flare) * normals[at(c)] - std::cos(g.flare) * Vector3d::UnitZ());
    }
  }
  // The waistband moves with the skin under it.
  const Mesh& skin = character.skin.rest;
  for (int c = 0; c < kColumns; ++c) {
    std::size_t nearest = 0;
    float best = std::numeric_limits<float>::max();
    for (std::size_t v = 0; v < skin.num_vertices(); ++v) {
      const float d = (skin.positions[v] - g.cut[at(c)].cast<float>()).squaredNorm();
      if (d < best) best = d, nearest = v;
    }
    g.waist_joints.push_back(character.skin.joints[nearest]);
    g.waist_weights.push_back(character.skin.weights[nearest]);
  }

  // The shell's topology and UVs: the folded angle around the waist, the distance down.
  g.rest.triangles = tube_shell_triangles(g.grid);
  g.rest.uvs.resize(2 * at(g.grid.size()));
  for (int r = 0; r <= rows; ++r) {
    for (int c = 0; c < kColumns; ++c) {
      const double theta = 2 * M_PI * c / kColumns;
      const Vec2f uv = detail::skirt_uv(std::abs(std::remainder(theta, 2 * M_PI)), static_cast<double>(r) / rows);
      g.rest.uvs[at(g.grid.index(r, c))] = uv;
      g.rest.uvs[at(g.grid.size() + g.grid.index(r, c))] = uv;
    }
  }
  g.rest.texture = character.skin.rest.texture;

  // Hanging still on the rest pose.
  Character dressed = character;
  dressed.garment = garment;
  ClothSimulation cloth(dressed);
  std::vector<Isometry3d> rest;
  for (const Isometry3d& ib : character.skin.inverse_bind) rest.push_back(ib.inverse());
  cloth.start(rest);
  g.rest.positions = tube_shell_positions(g.grid, cloth.positions(), g.thickness);
  return garment;
}

// ---- The performer's surface ----

Mesh garment_surface(const Garment& garment, const std::vector<Vector3d>& sheet) {
  Mesh mesh;
  mesh.positions = tube_shell_positions(garment.grid, sheet, garment.thickness);
  mesh.triangles = garment.rest.triangles;
  mesh.uvs = garment.rest.uvs;
  mesh.texture = garment.rest.texture;
  return mesh;
}

namespace {

// `body` with `garment` appended (its vertices after the body's).
Mesh dress(Mesh body, const Mesh& garment) {
  const int offset = static_cast<int>(body.num_vertices());
  body.positions.insert(body.positions.end(), garment.positions.begin(), garment.positions.end());
  for (const Tri& t : garment.triangles) body.triangles.push_back(t + Tri::Constant(offset));
  if (!body.uvs.empty()) body.uvs.insert(body.uvs.end(), garment.uvs.begin(), garment.uvs.end());
  body.normals.clear();
  return body;
}

}  // namespace

PerformerSurface::PerformerSurface(const Character& character, double fps) : character_(character), fps_(fps) {
  if (character.garment) cloth_ = std::make_unique<ClothSimulation>(character);
}

PerformerSurface::~PerformerSurface() = default;

Mesh PerformerSurface::next(const Pose& pose) {
  const std::vector<Isometry3d> world = forward_kinematics(character_.skeleton, pose);
  Mesh body = skin_mesh(character_.skin, world);
  if (!cloth_) return body;
  if (!started_) {
    cloth_->start(world);
    started_ = true;
  } else {
    cloth_->advance(world, 1.0 / fps_);
  }
  return dress(std::move(body), garment_surface(*character_.garment, cloth_->positions()));
}

Mesh rest_surface(const Character& character) {
  if (!character.garment) return character.skin.rest;
  return dress(character.skin.rest, character.garment->rest);
}

}  // namespace fourd::synth
