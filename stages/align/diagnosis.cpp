#include "stages/align/diagnosis.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <limits>

#include "pipeline/core/statistics.h"
#include "pipeline/geometry/geodesic.h"
#include "pipeline/geometry/measures.h"

namespace fourd::align {

TemplateRegions make_regions(const TemplateModel& model, int count) {
  const Mesh& rest = model.rest;
  const int nv = static_cast<int>(rest.num_vertices());
  TemplateRegions regions;
  regions.of_vertex.assign(nv, 0);
  if (nv == 0) return regions;
  count = std::max(1, std::min(count, nv));
  // Farthest-point seeds: the top of the template first (deterministic), then each time the
  // vertex geodesically farthest from every seed so far.
  std::vector<double> dist(nv, std::numeric_limits<double>::infinity());
  int seed = 0;
  for (int v = 1; v < nv; ++v) {
    if (rest.positions[v].z() > rest.positions[seed].z()) seed = v;
  }
  for (int k = 0; k < count; ++k) {
    geodesic_update(rest, model.rings, seed, k, std::numeric_limits<double>::infinity(), dist,
                    regions.of_vertex);
    seed = static_cast<int>(std::max_element(dist.begin(), dist.end()) - dist.begin());
    if (dist[seed] <= 0) {
      count = k + 1;
      break;
    }
  }
  // Where each patch sits on the template at rest, for its name.
  double z_min = std::numeric_limits<double>::infinity(), z_max = -z_min;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Vec3f& p : rest.positions) {
    z_min = std::min(z_min, static_cast<double>(p.z()));
    z_max = std::max(z_max, static_cast<double>(p.z()));
    centroid += p.cast<double>();
  }
  centroid /= nv;
  regions.centre.assign(count, Eigen::Vector3d::Zero());
  std::vector<int> size(count, 0);
  for (int v = 0; v < nv; ++v) {
    regions.centre[regions.of_vertex[v]] += rest.positions[v].cast<double>();
    ++size[regions.of_vertex[v]];
  }
  const double height = std::max(1e-9, z_max - z_min);
  for (int k = 0; k < count; ++k) {
    Eigen::Vector3d& c = regions.centre[k];
    if (size[k]) c /= size[k];
    const Eigen::Vector3d d = c - centroid;
    std::string side = "centre";
    if (std::hypot(d.x(), d.y()) > 0.06 * height) {
      side = std::abs(d.x()) >= std::abs(d.y()) ? (d.x() > 0 ? "+x" : "-x") : (d.y() > 0 ? "+y" : "-y");
    }
    regions.names.push_back(
        fmt::format("r{} ({:.0f}% up, {})", k, 100 * (c.z() - z_min) / height, side));
  }
  return regions;
}

std::vector<RegionCues> region_cues(const TemplateModel& model, const TemplateRegions& regions,
                                    const std::vector<Vec3f>& positions, const SurfaceQuery& target,
                                    double coverage_distance) {
  const std::size_t nv = positions.size();
  const std::size_t count = regions.names.size();
  std::vector<RegionCues> cues(count);
  // Residual: template vertices to the frame surface.
  std::vector<float> forward(nv);
  tbb::parallel_for(std::size_t{0}, nv, [&](std::size_t i) {
    const SurfaceHit hit = target.closest(positions[i], std::numeric_limits<float>::max());
    forward[i] = hit.found ? hit.distance : std::numeric_limits<float>::max();
  });
  std::vector<std::vector<double>> per_region(count);
  for (std::size_t i = 0; i < nv; ++i) per_region[regions.of_vertex[i]].push_back(forward[i]);
  for (std::size_t k = 0; k < count; ++k) {
    if (!per_region[k].empty()) cues[k].residual_p90 = percentile(per_region[k], 0.9);
  }

  // Uncovered: frame surface points (of confidence >= 0.5: a low-confidence membrane is not
  // the subject) whose nearest fitted point is in the patch but farther than coverage_distance.
  const Mesh fitted = fitted_mesh(model, positions);
  const SurfaceQuery fitted_query(fitted);
  const std::vector<Vec3f>& frame_points = target.positions();
  const std::size_t stride = std::max<std::size_t>(1, frame_points.size() / 20000);
  const std::size_t samples = (frame_points.size() + stride - 1) / stride;
  std::vector<int> owner(samples, -1);
  std::vector<char> far(samples, 0);
  tbb::parallel_for(std::size_t{0}, samples, [&](std::size_t s) {
    if (target.vertex_confidence(s * stride) < 0.5f) return;
    const SurfaceHit hit = fitted_query.closest(frame_points[s * stride], std::numeric_limits<float>::max());
    if (!hit.found) return;
    const Tri& tri = fitted_query.triangles()[hit.triangle];
    int corner = 0;
    for (int c = 1; c < 3; ++c) {
      if (hit.barycentric[c] > hit.barycentric[corner]) corner = c;
    }
    owner[s] = regions.of_vertex[tri[corner]];
    far[s] = hit.distance > coverage_distance;
  });
  std::vector<int> near_count(count, 0), far_count(count, 0);
  for (std::size_t s = 0; s < samples; ++s) {
    if (owner[s] < 0) continue;
    ++near_count[owner[s]];
    far_count[owner[s]] += far[s];
  }
  for (std::size_t k = 0; k < count; ++k) {
    // A patch the frame barely touches says little (a few stray points).
    if (near_count[k] >= 20) cues[k].uncovered = static_cast<double>(far_count[k]) / near_count[k];
  }

  // Stretch: the patch's edges (by their lower-numbered end).
  std::vector<double> stretch_sum(count, 0);
  std::vector<int> edges(count, 0);
  for_each_edge_strain(model.rest, model.rings, positions, [&](std::size_t v, int, double change) {
    const int k = regions.of_vertex[v];
    stretch_sum[k] += change * change;
    ++edges[k];
  });
  for (std::size_t k = 0; k < count; ++k) {
    if (edges[k]) cues[k].stretch_rms = std::sqrt(stretch_sum[k] / edges[k]);
  }
  for (int t : folded_triangles(model, positions)) {
    ++cues[regions.of_vertex[model.rest.triangles[t][0]]].flipped;
  }
  return cues;
}

std::vector<double> region_jumps(const TemplateRegions& regions, const std::vector<Vec3f>& positions,
                                 const std::vector<Vec3f>& before, const std::vector<Vec3f>& after) {
  const std::size_t count = regions.names.size();
  std::vector<double> sum(count, 0);
  std::vector<int> n(count, 0);
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const int k = regions.of_vertex[i];
    sum[k] += (positions[i] - 0.5f * (before[i] + after[i])).norm();
    ++n[k];
  }
  for (std::size_t k = 0; k < count; ++k) sum[k] = n[k] ? sum[k] / n[k] : 0.0;
  return sum;
}

DiagnosisLimits diagnosis_limits(double size) {
  // Fractions of the subject's size; at 1.75 m: residual 21 mm, jump 26 mm.
  DiagnosisLimits limits;
  limits.residual = 0.012 * size;
  limits.uncovered = 0.3;
  limits.stretch = 0.25;
  limits.flipped = 3;
  limits.jump = 0.015 * size;
  limits.jump_ratio = 3;
  return limits;
}

namespace {

// Whether a patch jumps from its take neighbours' midpoint by more than `factor` x the jump
// limit, and by more than the limit's ratio to the take's median jump of the patch.
bool jumps_over(const RegionCues& c, const DiagnosisLimits& limits, double factor) {
  return c.jump > factor * limits.jump && c.jump_ratio > limits.jump_ratio;
}

}  // namespace

std::vector<RegionVerdict> judge(const std::vector<RegionCues>& cues, const DiagnosisLimits& limits) {
  std::vector<RegionVerdict> out;
  for (std::size_t k = 0; k < cues.size(); ++k) {
    const RegionCues& c = cues[k];
    const int r = static_cast<int>(k);
    if (c.residual_p90 > limits.residual) out.push_back({r, "residual", c.residual_p90, limits.residual});
    if (c.uncovered > limits.uncovered) out.push_back({r, "uncovered", c.uncovered, limits.uncovered});
    if (c.stretch_rms > limits.stretch) out.push_back({r, "stretch", c.stretch_rms, limits.stretch});
    if (c.flipped >= limits.flipped) {
      out.push_back({r, "flipped", static_cast<double>(c.flipped), static_cast<double>(limits.flipped)});
    }
    if (jumps_over(c, limits, 1)) out.push_back({r, "jump", c.jump, limits.jump});
  }
  std::sort(out.begin(), out.end(), [](const RegionVerdict& a, const RegionVerdict& b) {
    return a.value / a.limit > b.value / b.limit;
  });
  return out;
}

bool jumps_far(const std::vector<RegionCues>& cues, const DiagnosisLimits& limits, double factor) {
  return std::any_of(cues.begin(), cues.end(),
                     [&](const RegionCues& c) { return jumps_over(c, limits, factor); });
}

double badness(const std::vector<RegionCues>& cues, const DiagnosisLimits& limits) {
  double worst = 0;
  for (const RegionCues& c : cues) {
    worst = std::max({worst, c.residual_p90 / limits.residual, c.uncovered / limits.uncovered,
                      c.stretch_rms / limits.stretch,
                      static_cast<double>(c.flipped) / limits.flipped,
                      c.jump_ratio > limits.jump_ratio ? c.jump / limits.jump : 0.0});
  }
  return worst;
}

}  // namespace fourd::align
