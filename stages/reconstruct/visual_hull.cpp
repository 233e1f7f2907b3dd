#include "stages/reconstruct/visual_hull.h"

#include <tbb/parallel_for.h>

#include <opencv2/imgproc.hpp>

#include "pipeline/core/error.h"

namespace fourd::reconstruct {
namespace {

constexpr float kUnseen = 1.0f;  // field value of points too few cameras see [m]

float bilinear(const cv::Mat& m, double x, double y) {
  // (x, y) in COLMAP pixel convention: pixel centres at +0.5.
  double fx = x - 0.5, fy = y - 0.5;
  int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy));
  x0 = std::clamp(x0, 0, m.cols - 2);
  y0 = std::clamp(y0, 0, m.rows - 2);
  double ax = std::clamp(fx - x0, 0.0, 1.0), ay = std::clamp(fy - y0, 0.0, 1.0);
  const float* r0 = m.ptr<float>(y0);
  const float* r1 = m.ptr<float>(y0 + 1);
  return static_cast<float>((1 - ay) * ((1 - ax) * r0[x0] + ax * r0[x0 + 1]) +
                            ay * ((1 - ax) * r1[x0] + ax * r1[x0 + 1]));
}

}  // namespace

void VisualHullOptions::check() const {
  if (volume_min.size() != 3 || volume_max.size() != 3) {
    throw ConfigError("volume_min and volume_max need three values (x, y, z)");
  }
  for (int i = 0; i < 3; ++i) {
    if (!(volume_min[i] < volume_max[i])) throw ConfigError("volume_min must be below volume_max");
  }
  if (coarse_voxel < voxel_size) {
    throw ConfigError(fmt::format(
        "voxel_size {} must not exceed the coarse pass's voxel ({} m at this subject's size)",
        voxel_size, coarse_voxel));
  }
}

cv::Mat silhouette_signed_distance(const cv::Mat& silhouette) {
  cv::Mat fg = silhouette > 0, bg = silhouette == 0;
  cv::Mat dist_to_fg, dist_to_bg;
  // distanceTransform measures the distance to the nearest zero pixel.
  cv::distanceTransform(bg, dist_to_fg, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  cv::distanceTransform(fg, dist_to_bg, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  cv::Mat out(silhouette.size(), CV_32F);
  for (int r = 0; r < out.rows; ++r) {
    const std::uint8_t* f = fg.ptr<std::uint8_t>(r);
    const float* d_fg = dist_to_fg.ptr<float>(r);
    const float* d_bg = dist_to_bg.ptr<float>(r);
    float* o = out.ptr<float>(r);
    for (int c = 0; c < out.cols; ++c) o[c] = f[c] ? -(d_bg[c] - 0.5f) : d_fg[c] - 0.5f;
  }
  return out;
}

VisualHull::VisualHull(const std::vector<Camera>& cameras, const std::vector<cv::Mat>& silhouettes,
                       const VisualHullOptions& options)
    : cameras_(cameras), options_(options) {
  if (cameras.size() != silhouettes.size()) {
    throw InputError("visual hull: one silhouette per camera is needed");
  }
  min_views_ = std::max(options.min_views,
                        static_cast<int>(std::ceil(options.min_view_fraction * cameras.size() - 1e-9)));
  distance_.resize(cameras.size());
  tbb::parallel_for(std::size_t{0}, cameras.size(), [&](std::size_t i) {
    distance_[i] = silhouette_signed_distance(silhouettes[i]);
  });
}

float VisualHull::value(const Eigen::Vector3d& point) const {
  float best = -std::numeric_limits<float>::infinity();
  int views = 0;
  for (std::size_t i = 0; i < cameras_.size(); ++i) {
    const Camera& cam = cameras_[i];
    Eigen::Vector2d px;
    if (!cam.project(point, &px) || !cam.in_image(px)) continue;
    ++views;
    double metres_per_px = cam.depth(point) / cam.intrinsics.fx;
    best = std::max(best, static_cast<float>(bilinear(distance_[i], px.x(), px.y()) * metres_per_px));
  }
  // Too few cameras see the point to carve it: call it clearly outside.
  if (views < min_views_) return kUnseen;
  return best;
}

ScalarGrid VisualHull::grid() const {
  // Pass 1: the coarse grid over the whole capture volume finds the hull's bounding box.
  const Eigen::Vector3d lo(options_.volume_min[0], options_.volume_min[1], options_.volume_min[2]);
  const Eigen::Vector3d hi(options_.volume_max[0], options_.volume_max[1], options_.volume_max[2]);
  const double cv = options_.coarse_voxel;
  const Eigen::Vector3i n = ((hi - lo) / cv).array().ceil().cast<int>() + 1;
  std::vector<Eigen::Vector3d> inside;
  std::vector<std::vector<Eigen::Vector3d>> per_z(n.z());
  tbb::parallel_for(0, n.z(), [&](int z) {
    for (int y = 0; y < n.y(); ++y) {
      for (int x = 0; x < n.x(); ++x) {
        Eigen::Vector3d p = lo + cv * Eigen::Vector3d(x, y, z);
        // A coarse cell may hold surface if its centre is within half a diagonal of it.
        if (value(p) < cv) per_z[z].push_back(p);
      }
    }
  });
  for (auto& v : per_z) inside.insert(inside.end(), v.begin(), v.end());
  ScalarGrid grid;
  if (inside.empty()) return grid;
  Eigen::Vector3d bmin = inside[0], bmax = inside[0];
  for (const auto& p : inside) {
    bmin = bmin.cwiseMin(p);
    bmax = bmax.cwiseMax(p);
  }
  bmin -= Eigen::Vector3d::Constant(cv + options_.margin);
  bmax += Eigen::Vector3d::Constant(cv + options_.margin);
  bmin = bmin.cwiseMax(lo);
  bmax = bmax.cwiseMin(hi);

  // Pass 2: the fine grid, block by block; a block whose centre is far from the surface is
  // filled with that centre's value (the field is about 1-Lipschitz in metres).
  const double h = options_.voxel_size;
  const int b = options_.block;
  grid.origin = bmin;
  grid.voxel = h;
  grid.nx = static_cast<int>(std::ceil((bmax.x() - bmin.x()) / h)) + 1;
  grid.ny = static_cast<int>(std::ceil((bmax.y() - bmin.y()) / h)) + 1;
  grid.nz = static_cast<int>(std::ceil((bmax.z() - bmin.z()) / h)) + 1;
  grid.values.assign(static_cast<std::size_t>(grid.nx) * grid.ny * grid.nz, 0.f);
  const int bx = (grid.nx + b - 1) / b, by = (grid.ny + b - 1) / b, bz = (grid.nz + b - 1) / b;
  const double block_radius = 0.5 * std::sqrt(3.0) * b * h;
  tbb::parallel_for(0, bx * by * bz, [&](int index) {
    int kx = index % bx, ky = (index / bx) % by, kz = index / (bx * by);
    int x0 = kx * b, y0 = ky * b, z0 = kz * b;
    int x1 = std::min(x0 + b, grid.nx), y1 = std::min(y0 + b, grid.ny), z1 = std::min(z0 + b, grid.nz);
    Eigen::Vector3d centre = grid.point(x0, y0, z0) + 0.5 * h * Eigen::Vector3d(x1 - x0 - 1, y1 - y0 - 1, z1 - z0 - 1);
    float vc = value(centre);
    bool far = std::abs(vc) > 2.0 * block_radius;
    for (int z = z0; z < z1; ++z)
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x)
          grid.values[grid.index(x, y, z)] = far ? vc : value(grid.point(x, y, z));
  });
  return grid;
}

Mesh VisualHull::mesh() const {
  ScalarGrid g = grid();
  if (g.nx == 0) return {};
  return extract_isosurface(g, 0.0f);
}

}  // namespace fourd::reconstruct
