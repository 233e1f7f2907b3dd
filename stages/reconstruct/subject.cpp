#include "stages/reconstruct/subject.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "pipeline/core/error.h"

namespace fourd::reconstruct {

nlohmann::json Box::to_json() const {
  return {{"min", {min.x(), min.y(), min.z()}}, {"max", {max.x(), max.y(), max.z()}}};
}

int required_views(const VisualHullOptions& options, int cameras) {
  return std::max(options.min_views,
                  static_cast<int>(std::ceil(options.min_view_fraction * cameras - 1e-9)));
}

namespace {

// The point nearest to every camera's optical axis (least squares): where a rig looks.
Eigen::Vector3d rig_target(const std::vector<Camera>& cameras) {
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero(), centroid = Eigen::Vector3d::Zero(),
                  mean_axis = Eigen::Vector3d::Zero();
  for (const Camera& c : cameras) {
    const Eigen::Vector3d d = c.camera_from_world.linear().row(2).transpose().normalized();
    const Eigen::Matrix3d p = Eigen::Matrix3d::Identity() - d * d.transpose();
    a += p;
    b += p * c.center();
    centroid += c.center() / cameras.size();
    mean_axis += d;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(a);
  if (eig.eigenvalues().minCoeff() > 1e-3 * eig.eigenvalues().maxCoeff()) return a.ldlt().solve(b);
  // Parallel axes (cameras side by side looking the same way): in front of the cameras, as
  // far as they are spread.
  double spread = 0;
  for (const Camera& c : cameras) spread = std::max(spread, (c.center() - centroid).norm());
  if (!(spread > 0) || !(mean_axis.norm() > 0)) {
    throw InputError("the calibrated cameras share one centre and look nowhere in common: no "
                     "capture volume can be found");
  }
  return centroid + mean_axis.normalized() * spread;
}

}  // namespace

Box shared_volume(const std::vector<Camera>& cameras, int views, int cells) {
  Box box;
  if (cameras.empty()) return box;
  const Eigen::Vector3d target = rig_target(cameras);
  double reach = 0;
  for (const Camera& c : cameras) reach = std::max(reach, (c.center() - target).norm());
  const Eigen::Vector3d lo = target - Eigen::Vector3d::Constant(reach);
  const double cell = 2 * reach / cells;
  std::vector<Box> per_z(cells + 1);
  std::vector<char> any(cells + 1, 0);
  tbb::parallel_for(0, cells + 1, [&](int z) {
    Box b;
    bool found = false;
    for (int y = 0; y <= cells; ++y) {
      for (int x = 0; x <= cells; ++x) {
        const Eigen::Vector3d p = lo + cell * Eigen::Vector3d(x, y, z);
        int seen = 0;
        for (const Camera& c : cameras) {
          Eigen::Vector2d px;
          seen += c.project(p, &px) && c.in_image(px);
        }
        if (seen < views) continue;
        if (!found) {
          b.min = b.max = p;
          found = true;
        }
        b.min = b.min.cwiseMin(p);
        b.max = b.max.cwiseMax(p);
      }
    }
    per_z[z] = b;
    any[z] = found;
  });
  bool found = false;
  for (int z = 0; z <= cells; ++z) {
    if (!any[z]) continue;
    box.min = found ? box.min.cwiseMin(per_z[z].min) : per_z[z].min;
    box.max = found ? box.max.cwiseMax(per_z[z].max) : per_z[z].max;
    found = true;
  }
  if (!found) return Box{};
  // The region seen reaches up to a cell beyond the last lattice point seen.
  box.min -= Eigen::Vector3d::Constant(cell);
  box.max += Eigen::Vector3d::Constant(cell);
  return box;
}

Box hull_box(const std::vector<Camera>& cameras, const std::vector<cv::Mat>& silhouettes,
             const VisualHullOptions& hull, const Box& volume, int cells) {
  VisualHullOptions h = hull;
  h.volume_min = {volume.min.x(), volume.min.y(), volume.min.z()};
  h.volume_max = {volume.max.x(), volume.max.y(), volume.max.z()};
  h.coarse_voxel = volume.size().maxCoeff() / cells;
  h.voxel_size = h.coarse_voxel / 4;
  h.margin = h.coarse_voxel;
  const ScalarGrid grid = VisualHull(cameras, silhouettes, h).grid();
  Box box;
  bool found = false;
  for (int z = 0; z < grid.nz; ++z) {
    for (int y = 0; y < grid.ny; ++y) {
      for (int x = 0; x < grid.nx; ++x) {
        if (!(grid.at(x, y, z) < 0)) continue;
        const Eigen::Vector3d p = grid.point(x, y, z);
        box.min = found ? box.min.cwiseMin(p) : p;
        box.max = found ? box.max.cwiseMax(p) : p;
        found = true;
      }
    }
  }
  if (!found) return Box{};
  // A sample inside stands for the half voxel around it.
  box.min -= Eigen::Vector3d::Constant(0.5 * grid.voxel);
  box.max += Eigen::Vector3d::Constant(0.5 * grid.voxel);
  return box;
}

nlohmann::json SubjectScale::to_json() const {
  return {{"subject_size_m", size},
          {"subject_height_m", height},
          {"scale_factor", factor},
          {"reference_size_m", kReferenceSubjectSize},
          {"measured", measured},
          {"frames_measured", frames_measured},
          {"shared_volume", shared.to_json()},
          {"hull_box", hull.empty() ? nlohmann::json() : hull.to_json()}};
}

namespace {
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}
}  // namespace

SubjectScale measure_subject(const std::vector<std::vector<Camera>>& frame_cameras,
                             const std::vector<std::vector<cv::Mat>>& frame_silhouettes,
                             const VisualHullOptions& hull, const Box& shared,
                             const SubjectScaleOptions& options) {
  SubjectScale s;
  s.shared = shared;
  if (options.subject_size > 0) {
    s.size = s.height = options.subject_size;
    s.factor = options.subject_size / kReferenceSubjectSize;
    return s;
  }
  // The measuring hull stands on the floor (z = 0): what the cameras see below it is not the
  // subject's.
  Box volume = shared;
  if (volume.min.z() < 0 && volume.max.z() > 0) volume.min.z() = 0;
  std::vector<double> sizes, heights;
  bool any = false;
  for (std::size_t f = 0; f < frame_cameras.size(); ++f) {
    const Box b = hull_box(frame_cameras[f], frame_silhouettes[f], hull, volume, options.grid);
    if (b.empty()) continue;
    sizes.push_back(b.size().maxCoeff());
    heights.push_back(b.size().z());
    s.hull.min = any ? s.hull.min.cwiseMin(b.min) : b.min;
    s.hull.max = any ? s.hull.max.cwiseMax(b.max) : b.max;
    any = true;
  }
  if (sizes.empty()) {
    throw InputError(fmt::format(
        "the subject's size cannot be measured: none of the {} sampled frame(s) has a visual "
        "hull inside the volume the cameras share (check the silhouettes and the calibration, "
        "or set stages.reconstruct.scale.subject_size)",
        frame_cameras.size()));
  }
  s.measured = true;
  s.frames_measured = static_cast<int>(sizes.size());
  s.size = median(sizes);
  s.height = median(heights);
  s.factor = subject_scale_factor(s.size, options.steps_per_decade);
  return s;
}

void derive_volume(VisualHullOptions& hull, const Box& shared, double factor) {
  const VisualHullOptions reference;
  for (int a = 0; a < 3; ++a) {
    const double lo = reference.volume_min[a] * factor, hi = reference.volume_max[a] * factor;
    hull.volume_min[a] = a == 2 ? lo : std::min(lo, shared.min[a]);
    hull.volume_max[a] = std::max(hi, shared.max[a]);
  }
}

}  // namespace fourd::reconstruct
