#include "runtime/viewer/view_math.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace fourd::viewer {

Mat4f look_at(const Eigen::Vector3f& eye, const Eigen::Vector3f& target, const Eigen::Vector3f& up) {
  const Eigen::Vector3f f = (target - eye).normalized();
  const Eigen::Vector3f s = f.cross(up).normalized();
  const Eigen::Vector3f u = s.cross(f);
  Mat4f m = Mat4f::Identity();
  m.block<1, 3>(0, 0) = s.transpose();
  m.block<1, 3>(1, 0) = u.transpose();
  m.block<1, 3>(2, 0) = -f.transpose();
  m(0, 3) = -s.dot(eye);
  m(1, 3) = -u.dot(eye);
  m(2, 3) = f.dot(eye);
  return m;
}

Mat4f perspective(float fov_y, float aspect, float near_plane, float far_plane) {
  const float t = 1.0f / std::tan(0.5f * fov_y);
  Mat4f m = Mat4f::Zero();
  m(0, 0) = t / aspect;
  m(1, 1) = t;
  m(2, 2) = (far_plane + near_plane) / (near_plane - far_plane);
  m(2, 3) = 2 * far_plane * near_plane / (near_plane - far_plane);
  m(3, 2) = -1;
  return m;
}

void OrbitCamera::follow(double root_x, double root_y, double heading, double dt) {
  target = {static_cast<float>(root_x), static_cast<float>(root_y), target_height};
  const double k = 1 - std::exp(-follow_rate * std::max(dt, 0.0));
  follow_heading += static_cast<float>(k * (heading - follow_heading));
}

void OrbitCamera::rotate(float dx_pixels, float dy_pixels) {
  constexpr float kRadiansPerPixel = 0.006f;
  yaw -= dx_pixels * kRadiansPerPixel;
  pitch = std::clamp(pitch + dy_pixels * kRadiansPerPixel, -0.05f, 1.5f);
}

void OrbitCamera::zoom(float wheel_steps) {
  distance = std::clamp(distance * std::pow(0.9f, wheel_steps), 1.0f, 60.0f);
}

float OrbitCamera::world_yaw() const {
  return mode == CameraMode::kFollow ? follow_heading + yaw : yaw;
}

Eigen::Vector3f OrbitCamera::eye() const {
  const float a = world_yaw();
  const float c = std::cos(pitch);
  return target + distance * Eigen::Vector3f(-c * std::cos(a), -c * std::sin(a), std::sin(pitch));
}

Mat4f OrbitCamera::view() const { return look_at(eye(), target, Eigen::Vector3f::UnitZ()); }

Mat4f OrbitCamera::projection(float aspect) const {
  return perspective(fov_y, aspect, 0.05f, 200.0f);
}

bool pick_ground(const Mat4f& view, const Mat4f& projection, float x, float y, int width,
                 int height, Point2* out, float max_distance) {
  if (width <= 0 || height <= 0) return false;
  const Mat4f inverse = (projection * view).inverse();
  const float nx = 2 * x / width - 1, ny = 1 - 2 * y / height;
  auto unproject = [&](float z) {
    const Eigen::Vector4f p = inverse * Eigen::Vector4f(nx, ny, z, 1);
    return Eigen::Vector3f(p.head<3>() / p.w());
  };
  const Eigen::Vector3f a = unproject(-1), b = unproject(1);
  const Eigen::Vector3f d = b - a;
  if (!(d.z() < -1e-6f)) return false;  // parallel to the ground or looking up
  const float s = -a.z() / d.z();
  if (s < 0) return false;
  const Eigen::Vector3f hit = a + s * d;
  if ((hit - a).norm() > max_distance) return false;
  *out = {hit.x(), hit.y()};
  return true;
}

std::vector<BezierCurve> bezier_through(std::span<const Point2> input) {
  std::vector<Point2> p;
  for (const Point2& q : input) {
    if (p.empty() || std::hypot(q.x - p.back().x, q.y - p.back().y) >= 0.01) p.push_back(q);
  }
  std::vector<BezierCurve> curves;
  if (p.size() < 2) return curves;
  const std::size_t n = p.size();
  // Catmull-Rom tangent at point i (one-sided at the ends), as a Bezier control offset: 1/3 of
  // the tangent m_i = (p_{i+1} - p_{i-1}) / 2.
  auto tangent = [&](std::size_t i) {
    const Point2& a = p[i == 0 ? 0 : i - 1];
    const Point2& b = p[i + 1 == n ? n - 1 : i + 1];
    const double scale = (i == 0 || i + 1 == n) ? 1.0 / 3 : 1.0 / 6;
    return Point2{scale * (b.x - a.x), scale * (b.y - a.y)};
  };
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const Point2 t0 = tangent(i), t1 = tangent(i + 1);
    BezierCurve c;
    c.control = {p[i], Point2{p[i].x + t0.x, p[i].y + t0.y},
                 Point2{p[i + 1].x - t1.x, p[i + 1].y - t1.y}, p[i + 1]};
    curves.push_back(c);
  }
  return curves;
}

Point2 bezier_point(const BezierCurve& c, double u) {
  const double v = 1 - u;
  const double b0 = v * v * v, b1 = 3 * v * v * u, b2 = 3 * v * u * u, b3 = u * u * u;
  return {b0 * c.control[0].x + b1 * c.control[1].x + b2 * c.control[2].x + b3 * c.control[3].x,
          b0 * c.control[0].y + b1 * c.control[1].y + b2 * c.control[2].y + b3 * c.control[3].y};
}

}  // namespace fourd::viewer
