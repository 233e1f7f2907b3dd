#include "stages/reconstruct/plausibility.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <opencv2/imgproc.hpp>

#include "pipeline/geometry/measures.h"

namespace fourd::reconstruct {

OutlineOverlap outline_overlap(const Camera& camera, const Mesh& mesh, const cv::Mat& silhouette) {
  constexpr int kShift = 4;  // sub-pixel vertex positions for fillConvexPoly
  cv::Mat outline = cv::Mat::zeros(silhouette.size(), CV_8UC1);
  std::vector<cv::Point> px(mesh.positions.size());
  std::vector<char> ok(mesh.positions.size());
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    Eigen::Vector2d p;
    // COLMAP pixel convention (centres at +0.5) to OpenCV's (centres at integers).
    ok[i] = camera.project(mesh.positions[i].cast<double>(), &p) &&
            std::abs(p.x()) < 1e6 && std::abs(p.y()) < 1e6;
    if (ok[i]) {
      px[i] = cv::Point(static_cast<int>(std::lround((p.x() - 0.5) * (1 << kShift))),
                        static_cast<int>(std::lround((p.y() - 0.5) * (1 << kShift))));
    }
  }
  for (const Tri& t : mesh.triangles) {
    if (!ok[t[0]] || !ok[t[1]] || !ok[t[2]]) continue;
    const cv::Point tri[3] = {px[t[0]], px[t[1]], px[t[2]]};
    cv::fillConvexPoly(outline, tri, 3, cv::Scalar(255), cv::LINE_8, kShift);
  }
  const cv::Mat sil = silhouette > 0;
  const double sil_px = cv::countNonZero(sil), outline_px = cv::countNonZero(outline);
  const double both = cv::countNonZero(sil & outline);
  OutlineOverlap o;
  o.coverage = sil_px > 0 ? both / sil_px : 0.0;
  o.spill = outline_px > 0 ? (outline_px - both) / outline_px : 0.0;
  return o;
}

namespace {
double largest_extent(const Mesh& mesh) {
  Vec3f lo, hi;
  bounding_box(mesh, &lo, &hi);
  return mesh.positions.empty() ? 0.0 : static_cast<double>((hi - lo).maxCoeff());
}
}  // namespace

PlausibilityReport check_plausibility(const std::vector<Camera>& cameras,
                                      const std::vector<cv::Mat>& silhouettes,
                                      const Mesh& hull, const Mesh& mesh, double voxel,
                                      const PlausibilityOptions& options) {
  PlausibilityReport r;
  if (!options.enabled || hull.triangles.empty()) return r;
  const std::size_t n = cameras.size();
  r.hull.resize(n);
  if (!mesh.triangles.empty()) r.mesh.resize(n);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    r.hull[i] = outline_overlap(cameras[i], hull, silhouettes[i]);
    if (!mesh.triangles.empty()) r.mesh[i] = outline_overlap(cameras[i], mesh, silhouettes[i]);
  });
  for (std::size_t i = 0; i < n; ++i) {
    const OutlineOverlap& h = r.hull[i];
    if (h.coverage < options.min_hull_coverage) {
      r.warnings.push_back(fmt::format(
          "camera {}: the visual hull covers only {:.0f}% of its silhouette: the other cameras "
          "carved away what it sees (the silhouettes disagree across cameras, the calibration "
          "is off, or the hull's voxels are too coarse)",
          cameras[i].name, 100 * h.coverage));
    }
  }
  const double hull_extent = largest_extent(hull);
  if (voxel > 0 && hull_extent / voxel < options.min_voxels) {
    r.warnings.push_back(fmt::format(
        "the visual hull spans only {:.0f} voxels of {:.3g} m ({:.3g} m): the voxel size is too "
        "coarse for this subject (leave stages.reconstruct.visual_hull.voxel_size unset to have "
        "it derived from the subject's size, or set it below {:.3g} m)",
        hull_extent / voxel, voxel, hull_extent, hull_extent / options.min_voxels));
  }
  if (mesh.triangles.empty()) return r;
  for (std::size_t i = 0; i < n; ++i) {
    const OutlineOverlap& m = r.mesh[i];
    if (m.coverage < options.min_mesh_coverage) {
      r.warnings.push_back(fmt::format("camera {}: the mesh covers only {:.0f}% of its silhouette",
                                       cameras[i].name, 100 * m.coverage));
    }
    if (m.spill > options.max_mesh_spill) {
      r.warnings.push_back(fmt::format("camera {}: {:.0f}% of the mesh's outline lies outside its "
                                       "silhouette",
                                       cameras[i].name, 100 * m.spill));
    }
  }
  const double hull_volume = enclosed_volume(hull);
  r.volume_ratio = hull_volume > 0 ? enclosed_volume(mesh) / hull_volume : 0.0;
  r.extent_ratio = hull_extent > 0 ? largest_extent(mesh) / hull_extent : 0.0;
  if (r.volume_ratio < options.min_size_ratio || r.extent_ratio < options.min_size_ratio) {
    r.warnings.push_back(fmt::format(
        "the mesh is far smaller than the visual hull: {:.0f}% of its volume, {:.0f}% of its "
        "extent",
        100 * r.volume_ratio, 100 * r.extent_ratio));
  }
  return r;
}

}  // namespace fourd::reconstruct
