#include "stages/reconstruct/fusion.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace fourd::reconstruct {

void fuse_depth_maps(ScalarGrid& field, const std::vector<PinholeCamera>& cameras,
                     const std::vector<DepthMap>& depth_maps, double min_score,
                     const FusionOptions& options, ScalarGrid* depth_weight) {
  if (depth_weight) {
    depth_weight->origin = field.origin;
    depth_weight->voxel = field.voxel;
    depth_weight->nx = field.nx;
    depth_weight->ny = field.ny;
    depth_weight->nz = field.nz;
    depth_weight->values.assign(field.values.size(), 0.0f);
  }
  const float tau = static_cast<float>(options.truncation);
  const float band = static_cast<float>(options.band);
  const float hull_weight = static_cast<float>(options.hull_weight);
  const float score_weight = static_cast<float>(options.score_weight);
  const float filled_weight = static_cast<float>(options.filled_weight);
  const float score_floor = static_cast<float>(min_score);
  const std::size_t n_cams = cameras.size();
  tbb::parallel_for(0, field.nz, [&](int z) {
    for (int y = 0; y < field.ny; ++y) {
      for (int x = 0; x < field.nx; ++x) {
        float& value = field.values[field.index(x, y, z)];
        const float hull = value;
        // Outside the hull stays outside (trimming); deep inside stays inside.
        if (!(hull <= 0 && hull > -band)) continue;
        const Eigen::Vector3d p = field.point(x, y, z);
        float sum = 0, weight = 0;
        for (std::size_t i = 0; i < n_cams; ++i) {
          const PinholeCamera& cam = cameras[i];
          const cv::Mat& depth = depth_maps[i].depth;
          if (depth.empty()) continue;
          Eigen::Vector3d c = cam.to_camera(p);
          if (c.z() <= 0) continue;
          Eigen::Vector2d px = cam.pixel(c);
          if (!cam.in_image(px)) continue;
          const int u = static_cast<int>(px.x()), v = static_cast<int>(px.y());
          const float d = depth.at<float>(v, u);
          if (d <= 0) continue;
          const float sd = d - static_cast<float>(c.z());  // > 0: in front of the surface
          if (sd < -tau) continue;                          // far behind: maybe hidden
          const cv::Mat& filled = depth_maps[i].filled;
          const float s = depth_maps[i].score.at<float>(v, u);
          const float w =
              !filled.empty() && filled.at<std::uint8_t>(v, u)
                  ? filled_weight
                  : (1 - score_weight) +
                        score_weight * std::max(0.05f, (s - score_floor) / (1 - score_floor));
          sum += w * std::min(sd, tau);
          weight += w;
        }
        if (depth_weight) depth_weight->values[field.index(x, y, z)] = weight;
        if (weight <= 0) continue;
        const float fused =
            (sum + hull_weight * std::clamp(hull, -tau, tau)) / (weight + hull_weight);
        value = std::max(fused, hull);
      }
    }
  });
}

std::vector<float> surface_confidence(const Mesh& mesh, const ScalarGrid& depth_weight,
                                      const FusionOptions& options) {
  const float hull_weight = static_cast<float>(options.hull_weight);
  std::vector<float> confidence(mesh.num_vertices(), 0.0f);
  tbb::parallel_for(std::size_t{0}, mesh.num_vertices(), [&](std::size_t i) {
    const Eigen::Vector3d g =
        (mesh.positions[i].cast<double>() - depth_weight.origin) / depth_weight.voxel;
    const int x0 = static_cast<int>(std::floor(g.x()));
    const int y0 = static_cast<int>(std::floor(g.y()));
    const int z0 = static_cast<int>(std::floor(g.z()));
    float w = 0;
    for (int dz = 0; dz <= 1; ++dz) {
      for (int dy = 0; dy <= 1; ++dy) {
        for (int dx = 0; dx <= 1; ++dx) {
          const int x = x0 + dx, y = y0 + dy, z = z0 + dz;
          if (x < 0 || y < 0 || z < 0 || x >= depth_weight.nx || y >= depth_weight.ny ||
              z >= depth_weight.nz) {
            continue;
          }
          w = std::max(w, depth_weight.at(x, y, z));
        }
      }
    }
    confidence[i] = w > 0 ? w / (w + hull_weight) : 0.0f;
  });
  return confidence;
}

}  // namespace fourd::reconstruct
