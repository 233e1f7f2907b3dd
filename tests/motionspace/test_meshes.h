#pragma once
// Small shapes for the motion-space tests and benchmarks: a closed tube (a capsule with flat
// caps) along z, bent at its middle like an elbow, and a few measures on meshes.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <span>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd::test {

struct TubeShape {
  double radius = 0.08;         // [m]
  double half_length = 0.5;     // the tube spans z in [-half_length, half_length]
  double bend_half_zone = 0.2;  // the bend acts on z in [-bend_half_zone, bend_half_zone]
  double ellipticity = 1.0;     // x radius / y radius: != 1 makes the tube less symmetric
};

struct TestMesh {
  Eigen::Matrix3Xd positions;  // 3 x #V
  std::vector<Tri> triangles;  // #F, counter-clockwise seen from outside
};

// A closed tube of `rings` x `segments` vertices plus one centre vertex per cap.
inline TestMesh make_tube(int rings, int segments, const TubeShape& shape = {}) {
  TestMesh m;
  m.positions.resize(3, rings * segments + 2);
  for (int r = 0; r < rings; ++r) {
    const double z = -shape.half_length + 2 * shape.half_length * r / (rings - 1);
    for (int s = 0; s < segments; ++s) {
      const double a = 2 * std::numbers::pi * s / segments;
      m.positions.col(r * segments + s) << shape.radius * shape.ellipticity * std::cos(a),
          shape.radius * std::sin(a), z;
    }
  }
  const int bottom = rings * segments, top = bottom + 1;
  m.positions.col(bottom) << 0, 0, -shape.half_length;
  m.positions.col(top) << 0, 0, shape.half_length;
  auto id = [&](int r, int s) { return r * segments + (s % segments); };
  for (int r = 0; r + 1 < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      m.triangles.emplace_back(id(r, s), id(r, s + 1), id(r + 1, s + 1));
      m.triangles.emplace_back(id(r, s), id(r + 1, s + 1), id(r + 1, s));
    }
  }
  for (int s = 0; s < segments; ++s) {
    m.triangles.emplace_back(bottom, id(0, s + 1), id(0, s));
    m.triangles.emplace_back(top, id(rings - 1, s), id(rings - 1, s + 1));
  }
  return m;
}

// Bends the straight tube by `angle` [rad] in the y-z plane: z < -zone stays, the zone
// becomes a circular arc of the same length (radius 2 zone / angle) and the part above it
// moves rigidly, so the upper end's axis turns by exactly `angle` (an elbow without collapse).
// `direction` [rad] turns the bend's plane about z (0: towards +y).
inline Eigen::Matrix3Xd bend_tube(const Eigen::Matrix3Xd& straight, double angle,
                                  const TubeShape& shape = {}, double direction = 0) {
  const double h = shape.bend_half_zone;
  Eigen::Matrix3Xd out = straight;
  if (std::abs(angle) < 1e-12) return out;
  const double rho = 2 * h / angle;
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(direction, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (Eigen::Index v = 0; v < straight.cols(); ++v) {
    const Eigen::Vector3d p = turn.transpose() * straight.col(v);
    const double x = p.x(), y = p.y(), z = p.z();
    if (z <= -h) continue;
    const double s = std::min(z + h, 2 * h);    // arc length into the zone
    const double extra = std::max(0.0, z - h);  // beyond the zone, along the end's axis
    const double phi = s / rho;
    const Eigen::Vector3d centre(0, rho * (1 - std::cos(phi)), -h + rho * std::sin(phi));
    const Eigen::Vector3d tangent(0, std::sin(phi), std::cos(phi));
    const Eigen::Vector3d side(0, std::cos(phi), -std::sin(phi));
    out.col(v) = turn * (centre + extra * tangent + y * side + Eigen::Vector3d(x, 0, 0));
  }
  return out;
}

// The same shape rotated by `angle` about `axis` through its vertex centroid.
inline Eigen::Matrix3Xd rotate_about_centroid(const Eigen::Matrix3Xd& x, double angle,
                                              const Eigen::Vector3d& axis) {
  const Eigen::Vector3d c = x.rowwise().mean();
  const Eigen::Matrix3d r = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  return (r * (x.colwise() - c)).colwise() + c;
}

// Enclosed volume of a closed, consistently oriented mesh (divergence theorem).
inline double volume(const Eigen::Matrix3Xd& x, std::span<const Tri> triangles) {
  double v = 0;
  for (const Tri& t : triangles) v += x.col(t[0]).dot(x.col(t[1]).cross(x.col(t[2]))) / 6;
  return v;
}

// Largest relative change of any triangle edge length from `a` to `b`.
inline double max_edge_length_change(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b,
                                     std::span<const Tri> triangles) {
  double worst = 0;
  for (const Tri& t : triangles) {
    for (int k = 0; k < 3; ++k) {
      const double la = (a.col(t[k]) - a.col(t[(k + 1) % 3])).norm();
      const double lb = (b.col(t[k]) - b.col(t[(k + 1) % 3])).norm();
      worst = std::max(worst, std::abs(lb - la) / la);
    }
  }
  return worst;
}

inline double max_vertex_distance(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b) {
  return (a - b).colwise().norm().maxCoeff();
}

inline std::vector<Vec3f> to_vec3f(const Eigen::Matrix3Xd& x) {
  std::vector<Vec3f> out(x.cols());
  for (Eigen::Index v = 0; v < x.cols(); ++v) out[v] = x.col(v).cast<float>();
  return out;
}

}  // namespace fourd::test
