#include "pipeline/geometry/mesh_query.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "pipeline/core/error.h"

namespace fourd {
namespace {

using K = CGAL::Simple_cartesian<double>;
using Point = K::Point_3;
using Triangle = K::Triangle_3;
using Primitive = CGAL::AABB_triangle_primitive<K, std::vector<Triangle>::const_iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

Eigen::Vector3d to_eigen(const Point& p) { return {p.x(), p.y(), p.z()}; }

// Barycentric coordinates of p (on or near the triangle) in a, b, c.
Vec3f barycentric(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                  const Eigen::Vector3d& c) {
  const Eigen::Vector3d v0 = b - a, v1 = c - a, v2 = p - a;
  const double d00 = v0.dot(v0), d01 = v0.dot(v1), d11 = v1.dot(v1);
  const double d20 = v2.dot(v0), d21 = v2.dot(v1);
  const double denom = d00 * d11 - d01 * d01;
  if (!(std::fabs(denom) > 0)) return Vec3f(1, 0, 0);
  const double v = (d11 * d20 - d01 * d21) / denom, w = (d00 * d21 - d01 * d20) / denom;
  return Vec3f(static_cast<float>(1 - v - w), static_cast<float>(v), static_cast<float>(w));
}

}  // namespace

struct MeshQuery::Impl {
  std::vector<Triangle> triangles;
  std::vector<int> index;  // triangles[i] is mesh triangle index[i]
  Tree tree;
};

MeshQuery::MeshQuery(const Mesh& mesh) : impl_(std::make_unique<Impl>()) {
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    auto p = [&](int k) {
      const Vec3f& v = mesh.positions[mesh.triangles[t][k]];
      return Point(v.x(), v.y(), v.z());
    };
    Triangle tri(p(0), p(1), p(2));
    if (tri.is_degenerate()) continue;
    impl_->triangles.push_back(tri);
    impl_->index.push_back(static_cast<int>(t));
  }
  if (impl_->triangles.empty()) throw InputError("mesh without a non-degenerate triangle");
  impl_->tree.insert(impl_->triangles.begin(), impl_->triangles.end());
  impl_->tree.build();
  impl_->tree.accelerate_distance_queries();
}

MeshQuery::~MeshQuery() = default;

ClosestPoint MeshQuery::closest(const Vec3f& p) const {
  const Point q(p.x(), p.y(), p.z());
  const auto [point, primitive] = impl_->tree.closest_point_and_primitive(q);
  const std::size_t i = static_cast<std::size_t>(primitive - impl_->triangles.begin());
  const Triangle& t = impl_->triangles[i];
  ClosestPoint out;
  out.point = to_eigen(point).cast<float>();
  out.triangle = impl_->index[i];
  out.barycentric = barycentric(to_eigen(point), to_eigen(t[0]), to_eigen(t[1]), to_eigen(t[2]));
  out.distance = std::sqrt(CGAL::squared_distance(q, point));
  return out;
}

double MeshQuery::distance(const Vec3f& p) const {
  return std::sqrt(impl_->tree.squared_distance(Point(p.x(), p.y(), p.z())));
}

std::vector<MeshQuery::Crossing> MeshQuery::crossings_along_x(double y, double z) const {
  const K::Line_3 line(Point(0, y, z), K::Vector_3(1, 0, 0));
  std::vector<Primitive::Id> hits;
  impl_->tree.all_intersected_primitives(line, std::back_inserter(hits));
  std::vector<Crossing> xs;
  for (const auto& id : hits) {
    const Triangle& t = *id;
    // Where the line meets the triangle's plane: n . ((x, y, z) - a) = 0.
    const Eigen::Vector3d a = to_eigen(t[0]), b = to_eigen(t[1]), c = to_eigen(t[2]);
    const Eigen::Vector3d n = (b - a).cross(c - a);
    if (std::fabs(n.x()) < 1e-300) continue;  // parallel to the line
    xs.push_back({a.x() - (n.y() * (y - a.y()) + n.z() * (z - a.z())) / n.x(), n.x() < 0 ? 1 : -1});
  }
  std::sort(xs.begin(), xs.end(), [](const Crossing& l, const Crossing& r) { return l.x < r.x; });
  return xs;
}

}  // namespace fourd
