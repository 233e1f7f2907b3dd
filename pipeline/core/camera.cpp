#include "pipeline/core/camera.h"

#include <Eigen/LU>
#include <cmath>
#include <fmt/format.h>

#include "pipeline/core/error.h"

namespace fourd {
namespace {

// Jacobian of Camera::distort() with respect to the undistorted normalised coordinates.
Eigen::Matrix2d distortion_jacobian(const Intrinsics& in, const Eigen::Vector2d& u) {
  const double x = u.x(), y = u.y();
  const double r2 = x * x + y * y;
  const double radial = 1 + in.k1 * r2 + in.k2 * r2 * r2;
  // d(radial)/dx = (k1 + 2 k2 r2) * 2x, and likewise for y.
  const double dradial = 2 * (in.k1 + 2 * in.k2 * r2);
  Eigen::Matrix2d j;
  j(0, 0) = radial + x * dradial * x + 2 * in.p1 * y + 6 * in.p2 * x;
  j(0, 1) = x * dradial * y + 2 * in.p1 * x + 2 * in.p2 * y;
  j(1, 0) = y * dradial * x + 2 * in.p1 * x + 2 * in.p2 * y;
  j(1, 1) = radial + y * dradial * y + 6 * in.p1 * y + 2 * in.p2 * x;
  return j;
}

}  // namespace

Eigen::Matrix3d Intrinsics::opencv_camera_matrix() const {
  Eigen::Matrix3d k;
  k << fx, 0, cx - 0.5,  //
      0, fy, cy - 0.5,   //
      0, 0, 1;
  return k;
}

Eigen::Vector3d Camera::center() const {
  // x_cam = R x + t = 0  =>  x = -R^T t
  return -(camera_from_world.linear().transpose() * camera_from_world.translation());
}

Eigen::Vector2d Camera::distort(const Eigen::Vector2d& undistorted) const {
  const Intrinsics& in = intrinsics;
  const double x = undistorted.x(), y = undistorted.y();
  const double r2 = x * x + y * y;
  const double radial = 1 + in.k1 * r2 + in.k2 * r2 * r2;
  return {x * radial + 2 * in.p1 * x * y + in.p2 * (r2 + 2 * x * x),
          y * radial + in.p1 * (r2 + 2 * y * y) + 2 * in.p2 * x * y};
}

Eigen::Vector2d Camera::undistort(const Eigen::Vector2d& distorted) const {
  if (!intrinsics.has_distortion()) return distorted;
  // Newton's method on distort(u) - distorted = 0, started at the distorted point: the
  // distortion is a small perturbation of the identity for real lenses, so this converges
  // quadratically in a handful of steps.
  Eigen::Vector2d u = distorted;
  constexpr int kMaxIterations = 100;
  for (int i = 0; i < kMaxIterations; ++i) {
    const Eigen::Vector2d residual = distort(u) - distorted;
    const Eigen::Matrix2d j = distortion_jacobian(intrinsics, u);
    const double det = j.determinant();
    // A vanishing Jacobian means we are past the lens's fold-over radius: no better answer.
    if (!(std::abs(det) > 1e-12)) break;
    const Eigen::Vector2d step = j.inverse() * residual;
    u -= step;
    if (step.squaredNorm() <= 1e-30 * (1 + u.squaredNorm())) break;
  }
  return u;
}

bool Camera::project(const Eigen::Vector3d& world, Eigen::Vector2d* pixel) const {
  const Eigen::Vector3d p = camera_from_world * world;
  if (!(p.z() > 0)) return false;
  const Eigen::Vector2d d = distort(p.head<2>() / p.z());
  *pixel = {intrinsics.fx * d.x() + intrinsics.cx, intrinsics.fy * d.y() + intrinsics.cy};
  return true;
}

Ray Camera::unproject(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d d((pixel.x() - intrinsics.cx) / intrinsics.fx,
                          (pixel.y() - intrinsics.cy) / intrinsics.fy);
  const Eigen::Vector2d u = undistort(d);
  const Eigen::Vector3d dir_cam = Eigen::Vector3d(u.x(), u.y(), 1).normalized();
  return {center(), camera_from_world.linear().transpose() * dir_cam};
}

double Camera::depth(const Eigen::Vector3d& world) const {
  return camera_from_world.linear().row(2).dot(world) + camera_from_world.translation().z();
}

Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                          const Eigen::Vector3d& up) {
  const Eigen::Vector3d forward = target - eye;
  if (!(forward.norm() > 1e-12)) {
    throw InputError(fmt::format("look_at: eye ({}, {}, {}) and target coincide", eye.x(),
                                 eye.y(), eye.z()));
  }
  const Eigen::Vector3d z = forward.normalized();
  // Image y points down, so image x = y × z = (-up) × z = z × up.
  const Eigen::Vector3d x_raw = z.cross(up);
  if (!(x_raw.norm() > 1e-9 * up.norm()) || up.norm() == 0) {
    throw InputError("look_at: the up vector is zero or parallel to the viewing direction");
  }
  const Eigen::Vector3d x = x_raw.normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d world_from_camera_rotation;
  world_from_camera_rotation << x, y, z;  // columns: camera axes in world coordinates
  Eigen::Isometry3d camera_from_world = Eigen::Isometry3d::Identity();
  camera_from_world.linear() = world_from_camera_rotation.transpose();
  camera_from_world.translation() = -(world_from_camera_rotation.transpose() * eye);
  return camera_from_world;
}

}  // namespace fourd
