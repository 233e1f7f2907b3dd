// Closest-point matches between the deformed template and a frame, both ways.
#include "stages/align/registration_internal.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <limits>

namespace fourd::align::detail {

// Closest compatible surface points of every vertex, robustly weighted.
std::vector<Correspondence> find_correspondences(const std::vector<Vec3f>& positions,
                                                 const std::vector<Vec3f>& normals,
                                                 const SurfaceQuery& target, double max_distance,
                                                 double robust_scale,
                                                 const RegistrationOptions& options,
                                                 const std::vector<Correspondence>* previous) {
  std::vector<Correspondence> out(positions.size());
  const float min_cos = cos_degrees(options.normal_angle);
  tbb::parallel_for(std::size_t{0}, positions.size(), [&](std::size_t i) {
    SurfaceHit hit = target.closest(positions[i], static_cast<float>(max_distance), normals[i],
                                    min_cos, previous ? (*previous)[i].triangle : -1);
    if (!hit.found) return;
    out[i].triangle = hit.triangle;
    out[i].point = hit.point.cast<double>();
    out[i].normal = hit.normal.cast<double>();
    out[i].weight =
        confidence_weight(hit.confidence, options) * robust_weight(hit.distance, robust_scale);
  });
  return out;
}

FrameSamples sample_frame(const SurfaceQuery& target, std::size_t count) {
  const std::vector<Vec3f>& positions = target.positions();
  const std::vector<Vec3f> normals = vertex_normals(positions, target.triangles());
  FrameSamples samples;
  const std::size_t stride = std::max<std::size_t>(1, positions.size() / std::max<std::size_t>(count, 1));
  for (std::size_t i = 0; i < positions.size(); i += stride) {
    if (normals[i].isZero()) continue;  // not on any triangle
    samples.vertices.push_back(static_cast<int>(i));
    samples.points.push_back(positions[i]);
    samples.normals.push_back(normals[i]);
    samples.confidence.push_back(target.vertex_confidence(i));
  }
  return samples;
}

const SurfaceQuery& FittedSurface::at(const TemplateModel& model,
                                      const std::vector<Vec3f>& positions) {
  if (query_) {
    query_->move_vertices(positions);
  } else {
    query_ = std::make_unique<SurfaceQuery>(fitted_mesh(model, positions), true);
  }
  return *query_;
}

std::vector<ReverseMatch> find_reverse_correspondences(
    const TemplateModel& model, const std::vector<Vec3f>& positions, const FrameSamples& samples,
    double max_distance, double robust_scale, const RegistrationOptions& options,
    FittedSurface* fitted, const std::vector<ReverseMatch>* previous) {
  const SurfaceQuery& query = fitted->at(model, positions);
  const float min_cos = cos_degrees(options.normal_angle);
  std::vector<ReverseMatch> out(samples.points.size());
  tbb::parallel_for(std::size_t{0}, samples.points.size(), [&](std::size_t i) {
    const SurfaceHit hit = query.closest(samples.points[i], static_cast<float>(max_distance),
                                         samples.normals[i], min_cos,
                                         previous ? (*previous)[i].face : -1);
    if (!hit.found) return;
    out[i].face = hit.triangle;
    out[i].triangle = model.rest.triangles[hit.triangle];
    out[i].barycentric = hit.barycentric.cast<double>();
    out[i].point = samples.points[i].cast<double>();
    out[i].normal = samples.normals[i].cast<double>();
    out[i].weight = confidence_weight(samples.confidence[i], options) *
                    robust_weight(hit.distance, robust_scale);
  });
  return out;
}

int nearest_vertex(const std::vector<Vec3f>& positions, const Vec3f& p) {
  int best = -1;
  float best_d = std::numeric_limits<float>::infinity();
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const float d = (positions[i] - p).squaredNorm();
    if (d < best_d) {
      best_d = d;
      best = static_cast<int>(i);
    }
  }
  return best;
}

}  // namespace fourd::align::detail
