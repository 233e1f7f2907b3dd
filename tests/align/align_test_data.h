#pragma once
// Test data for alignment: an articulated figure of capsules (z up, facing +x, 1.7 m tall) with
// a consistent-topology skinned mesh per pose (the "ground truth"), frames re-meshed with
// fresh connectivity (the "reconstruction"), and the error measures of the validation contract
// computed against the ground truth.
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "pipeline/core/isosurface.h"
#include "pipeline/geometry/surface_query.h"
#include "stages/align/shape_descriptor.h"
#include "tests/test_shapes.h"

namespace fourd::test {

// ---- Articulated figure ---------------------------------------------------------------

struct Bone {
  int parent;
  Eigen::Vector3d head, tail;  // rest; the joint is at the head
  double radius;
};

struct Figure {
  std::vector<Bone> bones;
  Mesh rest;                                // consistent topology for every pose
  std::vector<std::vector<std::pair<int, double>>> weights;  // per vertex: (bone, weight)
};

inline double segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                               const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (p - (a + t * ab)).norm();
}

// Bones: 0 torso, 1 head, 2/3 left upper arm/forearm, 4/5 right, 6/7/8 left thigh/shin/foot,
// 9/10/11 right. Scale 1 is a 1.7 m figure. With the shoulders at +-0.23 m the arms float
// beside the trunk (the surface has three components); at +-0.17 m they join it.
inline std::vector<Bone> figure_bones(double scale = 1.0, double shoulder = 0.23) {
  std::vector<Bone> b;
  auto add = [&](int parent, Eigen::Vector3d head, Eigen::Vector3d tail, double r) {
    b.push_back({parent, scale * head, scale * tail, scale * r});
  };
  add(-1, {0, 0, 0.95}, {0, 0, 1.40}, 0.13);
  add(0, {0, 0, 1.50}, {0, 0, 1.62}, 0.095);
  for (int side : {1, -1}) {
    add(0, {0, side * shoulder, 1.40}, {0, side * 0.25, 1.12}, 0.045);
    add(static_cast<int>(b.size()) - 1, {0, side * 0.25, 1.12}, {0, side * 0.26, 0.86}, 0.038);
  }
  for (int side : {1, -1}) {
    add(0, {0, side * 0.09, 0.92}, {0, side * 0.10, 0.52}, 0.07);
    add(static_cast<int>(b.size()) - 1, {0, side * 0.10, 0.52}, {0, side * 0.10, 0.10}, 0.05);
    add(static_cast<int>(b.size()) - 1, {0, side * 0.10, 0.07}, {0.14, side * 0.10, 0.05}, 0.04);
  }
  return b;
}

inline double smooth_min(double a, double b, double k) {
  const double h = std::clamp(0.5 + 0.5 * (b - a) / k, 0.0, 1.0);
  return b * (1 - h) + a * h - k * h * (1 - h);
}

inline Figure make_figure(double voxel = 0.012, double scale = 1.0, double shoulder = 0.23) {
  Figure f;
  f.bones = figure_bones(scale, shoulder);
  auto sdf = [&](const Eigen::Vector3d& p) {
    double d = 1e9;
    for (const Bone& b : f.bones) d = smooth_min(d, segment_distance(p, b.head, b.tail) - b.radius, 0.02 * scale);
    return d;
  };
  f.rest = isosurface_of(sdf, scale * Eigen::Vector3d(-0.3, -0.45, -0.05),
                         scale * Eigen::Vector3d(0.35, 0.45, 1.8), voxel * scale);
  f.weights.resize(f.rest.num_vertices());
  for (std::size_t v = 0; v < f.rest.num_vertices(); ++v) {
    const Eigen::Vector3d p = f.rest.positions[v].cast<double>();
    std::vector<std::pair<double, int>> d;
    for (std::size_t b = 0; b < f.bones.size(); ++b) {
      d.emplace_back(segment_distance(p, f.bones[b].head, f.bones[b].tail) - f.bones[b].radius,
                     static_cast<int>(b));
    }
    std::sort(d.begin(), d.end());
    double sum = 0;
    for (int k = 0; k < 3; ++k) {
      const double w = std::exp(-std::pow((d[k].first - d[0].first) / (0.02 * scale), 2));
      f.weights[v].emplace_back(d[k].second, w);
      sum += w;
    }
    for (auto& [b, w] : f.weights[v]) w /= sum;
  }
  return f;
}

struct Pose {
  std::vector<Eigen::Matrix3d> rotation;  // per bone, about its head joint (rest axes)
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  double heading = 0;  // about +z [rad]
};

inline Pose rest_pose(const Figure& f) {
  Pose p;
  p.rotation.assign(f.bones.size(), Eigen::Matrix3d::Identity());
  return p;
}

inline Eigen::Matrix3d rot(double degrees, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(degrees * M_PI / 180, axis.normalized()).toRotationMatrix();
}

// A walk cycle at `phase` [rad]: legs swing about y, arms counter-swing, knees and elbows bend.
inline Pose walk_pose(const Figure& f, double phase, double x = 0, double heading = 0) {
  Pose p = rest_pose(f);
  const Eigen::Vector3d y = Eigen::Vector3d::UnitY();
  const double s = std::sin(phase);
  p.rotation[6] = rot(-28 * s, y);
  p.rotation[9] = rot(28 * s, y);
  p.rotation[7] = rot(8 + 30 * std::max(0.0, std::sin(phase + 1.6)), y);
  p.rotation[10] = rot(8 + 30 * std::max(0.0, std::sin(phase + 1.6 + M_PI)), y);
  p.rotation[2] = rot(22 * s, y) * rot(6, Eigen::Vector3d::UnitX());
  p.rotation[4] = rot(-22 * s, y) * rot(-6, Eigen::Vector3d::UnitX());
  p.rotation[3] = rot(-20, y);
  p.rotation[5] = rot(-20, y);
  p.translation = {x, 0, 0.02 * std::abs(std::cos(phase))};
  p.heading = heading;
  return p;
}

// Arms raised sideways by `degrees` (90: horizontal).
inline Pose arms_raised_pose(const Figure& f, double degrees) {
  Pose p = rest_pose(f);
  p.rotation[2] = rot(degrees, Eigen::Vector3d::UnitX());
  p.rotation[4] = rot(-degrees, Eigen::Vector3d::UnitX());
  return p;
}

// Linear blend skinning of the rest mesh.
inline Mesh pose_figure(const Figure& f, const Pose& pose) {
  std::vector<Eigen::Isometry3d> world(f.bones.size());
  Eigen::Isometry3d root = Eigen::Isometry3d::Identity();
  root.translate(pose.translation);
  root.rotate(Eigen::AngleAxisd(pose.heading, Eigen::Vector3d::UnitZ()));
  for (std::size_t b = 0; b < f.bones.size(); ++b) {
    Eigen::Isometry3d local = Eigen::Isometry3d::Identity();
    local.translate(f.bones[b].head);
    local.rotate(pose.rotation[b]);
    local.translate(-f.bones[b].head);
    world[b] = (f.bones[b].parent < 0 ? root : world[f.bones[b].parent]) * local;
  }
  Mesh out = f.rest;
  for (std::size_t v = 0; v < out.num_vertices(); ++v) {
    const Eigen::Vector3d p = f.rest.positions[v].cast<double>();
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    for (const auto& [b, w] : f.weights[v]) q += w * (world[b] * p);
    out.positions[v] = q.cast<float>();
  }
  return out;
}

// ---- Error measures against ground truth -------------------------------------------------

// Where each template vertex lies on the ground-truth mesh of the template's frame.
struct SurfaceBinding {
  std::vector<int> triangle;
  std::vector<Vec3f> barycentric;
};

inline SurfaceBinding bind_to_surface(const std::vector<Vec3f>& points, const Mesh& truth) {
  const SurfaceQuery query(truth);
  SurfaceBinding b;
  for (const Vec3f& p : points) {
    const SurfaceHit hit = query.closest(p, 1e3f);
    b.triangle.push_back(hit.triangle);
    b.barycentric.push_back(hit.barycentric);
  }
  return b;
}

inline Vec3f bound_point(const SurfaceBinding& b, std::size_t i, const Mesh& truth) {
  const Tri& t = truth.triangles[b.triangle[i]];
  return b.barycentric[i].x() * truth.positions[t[0]] + b.barycentric[i].y() * truth.positions[t[1]] +
         b.barycentric[i].z() * truth.positions[t[2]];
}

struct ErrorAccumulator {
  std::vector<double> correspondence;  // [m]
  std::vector<double> surface;         // [m]

  // `aligned`: the template's vertices fitted to a frame whose truth is `truth` (same
  // topology as `truth_root`, which `binding` refers to).
  void add(const std::vector<Vec3f>& aligned, const SurfaceBinding& binding, const Mesh& truth) {
    const SurfaceQuery query(truth);
    for (std::size_t i = 0; i < aligned.size(); ++i) {
      correspondence.push_back((aligned[i] - bound_point(binding, i, truth)).norm());
      surface.push_back(query.closest(aligned[i], 1e3f).distance);
    }
  }
  static double rms(const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x * x;
    return v.empty() ? 0 : std::sqrt(s / v.size());
  }
  static double percentile(std::vector<double> v, double q) {
    if (v.empty()) return 0;
    const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * v.size()));
    std::nth_element(v.begin(), v.begin() + k, v.end());
    return v[k];
  }
  double correspondence_rms() const { return rms(correspondence); }
  double correspondence_p95() const { return percentile(correspondence, 0.95); }
  double surface_rms() const { return rms(surface); }
};

}  // namespace fourd::test
