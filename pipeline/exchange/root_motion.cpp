#include "pipeline/exchange/root_motion.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fourd {

namespace {

constexpr double kTorsoLow = 0.50;     // torso band, fraction of the body height above its feet
constexpr double kTorsoHigh = 0.80;
constexpr double kTorsoRadius = 0.12;  // horizontal distance from the axis, fraction of height

Eigen::Vector2d rotate(const Eigen::Vector2d& p, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return {c * p.x() - s * p.y(), s * p.x() + c * p.y()};
}

Eigen::Vector2d weighted_centroid_xy(const Eigen::Matrix3Xd& x, std::span<const double> w) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (Eigen::Index v = 0; v < x.cols(); ++v) c += w[v] * x.col(v).head<2>();
  return c;
}

}  // namespace

double body_height(const Eigen::Matrix3Xd& t) {
  return t.cols() == 0 ? 0.0 : t.row(2).maxCoeff() - t.row(2).minCoeff();
}

std::vector<double> torso_weights(const Eigen::Matrix3Xd& t) {
  const Eigen::Index nv = t.cols();
  std::vector<double> w(nv, 0.0);
  if (nv == 0) return w;
  const double floor = t.row(2).minCoeff();
  const double height = body_height(t);
  const double lo = floor + kTorsoLow * height, hi = floor + kTorsoHigh * height;
  // The body's axis: the centroid of the band, then the band's vertices near it.
  Eigen::Vector2d axis = Eigen::Vector2d::Zero();
  int count = 0;
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (t(2, v) >= lo && t(2, v) <= hi) {
      axis += t.col(v).head<2>();
      ++count;
    }
  }
  if (count > 0) axis /= count;
  double sum = 0;
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (t(2, v) >= lo && t(2, v) <= hi &&
        (t.col(v).head<2>() - axis).norm() <= kTorsoRadius * height) {
      w[v] = 1;
      sum += 1;
    }
  }
  if (sum < 3) {  // no recognisable torso: the whole body
    std::fill(w.begin(), w.end(), 1.0);
    sum = static_cast<double>(nv);
  }
  for (double& x : w) x /= sum;
  return w;
}

RootTransform estimate_root(const Eigen::Matrix3Xd& frame, const Eigen::Matrix3Xd& templ,
                    std::span<const double> torso) {
  const Eigen::Vector2d cf = weighted_centroid_xy(frame, torso);
  const Eigen::Vector2d ct = weighted_centroid_xy(templ, torso);
  // 2D Procrustes: the angle maximising sum w <R a, b> is atan2(sum w a x b, sum w a . b).
  double cross = 0, dot = 0;
  for (Eigen::Index v = 0; v < frame.cols(); ++v) {
    if (torso[v] == 0) continue;
    const Eigen::Vector2d a = templ.col(v).head<2>() - ct;
    const Eigen::Vector2d b = frame.col(v).head<2>() - cf;
    cross += torso[v] * (a.x() * b.y() - a.y() * b.x());
    dot += torso[v] * a.dot(b);
  }
  const double heading = std::atan2(cross, dot);
  // The root sits where the template's torso centroid lands under the frame's rotation, so
  // that removing it moves the torso back over the template's.
  const Eigen::Vector2d t = cf - rotate(ct, heading);
  return {t.x(), t.y(), heading};
}

Eigen::Matrix3Xd remove_root(const Eigen::Matrix3Xd& frame, const RootTransform& root) {
  const double c = std::cos(root.heading), s = std::sin(root.heading);
  Eigen::Matrix3Xd out(3, frame.cols());
  for (Eigen::Index v = 0; v < frame.cols(); ++v) {
    const double x = frame(0, v) - root.x, y = frame(1, v) - root.y;
    out.col(v) << c * x + s * y, -s * x + c * y, frame(2, v);
  }
  return out;
}

Eigen::Matrix3Xd apply_root(const Eigen::Matrix3Xd& shape, const RootTransform& root) {
  const double c = std::cos(root.heading), s = std::sin(root.heading);
  Eigen::Matrix3Xd out(3, shape.cols());
  for (Eigen::Index v = 0; v < shape.cols(); ++v) {
    const double x = shape(0, v), y = shape(1, v);
    out.col(v) << c * x - s * y + root.x, s * x + c * y + root.y, shape(2, v);
  }
  return out;
}

void smooth_roots(std::vector<RootTransform>* roots, int passes) {
  std::vector<RootTransform>& r = *roots;
  for (int pass = 0; pass < passes && r.size() > 2; ++pass) {
    std::vector<RootTransform> s = r;
    for (std::size_t i = 1; i + 1 < r.size(); ++i) {
      s[i] = {0.25 * (r[i - 1].x + 2 * r[i].x + r[i + 1].x),
              0.25 * (r[i - 1].y + 2 * r[i].y + r[i + 1].y),
              0.25 * (r[i - 1].heading + 2 * r[i].heading + r[i + 1].heading)};
    }
    r = std::move(s);
  }
}

std::vector<RootTransform> estimate_roots(std::span<const Eigen::Matrix3Xd> frames,
                                  const Eigen::Matrix3Xd& templ, std::span<const double> torso) {
  std::vector<RootTransform> roots;
  roots.reserve(frames.size());
  for (const Eigen::Matrix3Xd& f : frames) {
    RootTransform r = estimate_root(f, templ, torso);
    if (!roots.empty()) {  // unwrap: continue from the previous heading
      r.heading = roots.back().heading + wrap_heading(r.heading - roots.back().heading);
    }
    roots.push_back(r);
  }
  return roots;
}

}  // namespace fourd
