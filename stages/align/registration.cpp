#include "stages/align/registration.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <functional>
#include <limits>

#include "pipeline/core/error.h"
#include "pipeline/core/log.h"
#include "pipeline/geometry/measures.h"
#include "stages/align/registration_internal.h"

namespace fourd::align {

using namespace detail;

Mesh fitted_mesh(const TemplateModel& model, const std::vector<Vec3f>& positions) {
  Mesh m;
  m.positions = positions;
  m.triangles = model.rest.triangles;
  return m;
}

void RegistrationOptions::check() const {
  if (stiffness.empty()) throw ConfigError("stiffness: needs at least one level");
  if (final_max_distance > max_distance) {
    throw ConfigError(fmt::format("final_max_distance ({}) exceeds max_distance ({})",
                                  final_max_distance, max_distance));
  }
}

std::vector<Vec3f> vertex_normals(const std::vector<Vec3f>& positions,
                                  const std::vector<Tri>& triangles) {
  std::vector<Vec3f> normals(positions.size(), Vec3f::Zero());
  for (const Tri& t : triangles) {
    const Vec3f n = (positions[t[1]] - positions[t[0]]).cross(positions[t[2]] - positions[t[0]]);
    for (int k = 0; k < 3; ++k) normals[t[k]] += n;
  }
  for (Vec3f& n : normals) {
    const float len = n.norm();
    if (len > 0) n /= len;
  }
  return normals;
}

Eigen::Isometry3d rigid_icp(const std::vector<Vec3f>& points, const std::vector<Vec3f>& normals,
                            const SurfaceQuery& target, int iterations, double max_distance,
                            const RegistrationOptions& options) {
  std::vector<Correspondence> matches;
  return detail::rigid_icp(points, normals, target, iterations, max_distance, options, &matches);
}

namespace detail {

Eigen::Isometry3d rigid_icp(const std::vector<Vec3f>& points, const std::vector<Vec3f>& normals,
                            const SurfaceQuery& target, int iterations, double max_distance,
                            const RegistrationOptions& options,
                            std::vector<Correspondence>* last_matches) {
  Eigen::Isometry3d total = Eigen::Isometry3d::Identity();
  std::vector<Vec3f> current = points, current_normals = normals;
  std::vector<Correspondence>& matches = *last_matches;
  matches.clear();
  for (int it = 0; it < iterations; ++it) {
    matches = find_correspondences(current, current_normals, target, max_distance,
                                   std::max(options.robust_scale, max_distance / 3), options,
                                   it > 0 ? &matches : nullptr);
    Vec3d centroid = Vec3d::Zero();
    double weight_sum = 0;
    int matched = 0;
    for (std::size_t i = 0; i < current.size(); ++i) {
      if (matches[i].weight <= 0) continue;
      centroid += matches[i].weight * current[i].cast<double>();
      weight_sum += matches[i].weight;
      ++matched;
    }
    if (matched < 6) break;
    centroid /= weight_sum;
    // Linearised about the centroid (better conditioned): x -> x + w x (x - c) + t.
    Mat6 a = Mat6::Zero();
    Vec6 b = Vec6::Zero();
    for (std::size_t i = 0; i < current.size(); ++i) {
      const Correspondence& m = matches[i];
      if (m.weight <= 0) continue;
      const Vec3d p = current[i].cast<double>() - centroid;
      const Vec3d e = current[i].cast<double>() - m.point;
      Eigen::Matrix<double, 3, 6> j;
      j << -skew(p), Mat3d::Identity();
      const Mat3d w = m.weight * (m.normal * m.normal.transpose() +
                                  options.point_to_point * Mat3d::Identity());
      a += j.transpose() * w * j;
      b += j.transpose() * w * e;
    }
    a.diagonal().array() += 1e-9 * (1.0 + a.diagonal().maxCoeff());
    const Vec6 x = a.ldlt().solve(-b);
    if (!x.allFinite()) break;
    const Mat3d r = rotation_from_vector(x.head<3>());
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    step.linear() = r;
    step.translation() = centroid + x.tail<3>() - r * centroid;
    for (std::size_t i = 0; i < current.size(); ++i) {
      current[i] = (step * current[i].cast<double>()).cast<float>();
      current_normals[i] = (r * current_normals[i].cast<double>()).cast<float>();
    }
    total = step * total;
    if (x.head<3>().norm() < 1e-7 && x.tail<3>().norm() < 1e-8) break;
  }
  return total;
}

}  // namespace detail

namespace {

// One registration from `start`, the landmarks pulling the coarse levels. It begins at level
// `first_level`: the coarse levels' stiff regulariser undoes a start's bends (it pulls the graph
// towards one rigid motion), so a start that already bends the limbs skips them.
DeformationState register_pass(const TemplateModel& model, const DeformationState& start,
                               const SurfaceQuery& target, const RegistrationOptions& options,
                               const std::vector<Landmark>& landmarks, int first_level = 0) {
  DeformationState state = start;
  std::vector<Vec3f> positions = deform_with_graph(model, state);
  const std::vector<int>& data_vertices = model.data_vertices;
  auto of_data = [&](const std::vector<Vec3f>& all) {
    std::vector<Vec3f> out(data_vertices.size());
    for (std::size_t i = 0; i < data_vertices.size(); ++i) out[i] = all[data_vertices[i]];
    return out;
  };
  // The latest matches both ways: the next search starts from them (the rigid fit's, of the
  // same vertices, for the first).
  std::vector<Correspondence> matches;
  std::vector<ReverseMatch> reverse;
  if (options.rigid_iterations > 0) {
    const Eigen::Isometry3d motion = detail::rigid_icp(
        of_data(positions), of_data(vertex_normals(positions, model.rest.triangles)), target,
        options.rigid_iterations, options.max_distance, options, &matches);
    apply_rigid(model, motion, &state);
  }

  const FrameSamples samples =
      options.reverse_weight > 0 ? sample_frame(target, data_vertices.size()) : FrameSamples{};
  GraphGaussNewton solver(model, options.reverse_weight > 0);
  FittedSurface fitted;
  const int levels = static_cast<int>(options.stiffness.size());
  for (int level = std::min(first_level, levels - 1); level < levels; ++level) {
    // The matching distance shrinks geometrically from max_distance to final_max_distance.
    const double t = levels > 1 ? static_cast<double>(level) / (levels - 1) : 1.0;
    const double max_distance =
        options.max_distance * std::pow(options.final_max_distance / options.max_distance, t);
    const double robust_scale = std::max(options.robust_scale, max_distance / 3);
    for (int it = 0; it < options.iterations_per_level; ++it) {
      positions = deform_with_graph(model, state);
      matches = find_correspondences(of_data(positions),
                                     of_data(vertex_normals(positions, model.rest.triangles)),
                                     target, max_distance, robust_scale, options,
                                     matches.empty() ? nullptr : &matches);
      if (options.reverse_weight > 0) {
        reverse = find_reverse_correspondences(model, positions, samples, max_distance,
                                               robust_scale, options, &fitted,
                                               reverse.empty() ? nullptr : &reverse);
      }
      const bool coarse = level < options.landmark_levels;
      if (!solver.step(matches, reverse, coarse ? landmarks : std::vector<Landmark>{},
                       options.stiffness[level], options, &state)) {
        throw SolverError("registration: the deformation graph system could not be solved");
      }
    }
  }
  state.positions = deform_with_graph(model, state);
  const std::vector<Vec3f> graph_positions = state.positions;
  refine_vertices(model, target, options, matches, samples, reverse, &state.positions);
  unfold(model, graph_positions, options.unfold_rings, &state.positions);
  return state;
}

}  // namespace

double two_sided_rms(const FitStats& s) {
  return std::sqrt(s.surface_rms * s.surface_rms + s.reverse_rms * s.reverse_rms);
}

std::size_t least_stretched_close_fit(const std::vector<FitStats>& fits, double stretch_tolerance,
                                      double stretch_margin) {
  std::size_t closest = 0;
  for (std::size_t i = 1; i < fits.size(); ++i) {
    if (two_sided_rms(fits[i]) < two_sided_rms(fits[closest])) closest = i;
  }
  std::size_t chosen = closest;
  for (std::size_t i = 0; i < fits.size(); ++i) {
    if (two_sided_rms(fits[i]) > stretch_tolerance * two_sided_rms(fits[closest])) continue;
    if (fits[i].stretch_rms < stretch_margin * fits[closest].stretch_rms &&
        fits[i].stretch_rms < fits[chosen].stretch_rms) {
      chosen = i;
    }
  }
  return chosen;
}

DeformationState register_to_surface(const TemplateModel& model, const DeformationState& start,
                                     const SurfaceQuery& target,
                                     const RegistrationOptions& options,
                                     RegistrationTrace* trace) {
  DeformationState fit = register_pass(model, start, target, options, {});
  if (options.landmark_weight <= 0) return fit;
  // A fit that covers the whole frame has followed every limb; the tips are looked for only
  // when part of the frame is left over.
  const FitStats first = evaluate_fit(model, fit.positions, target, options);
  if (first.uncovered_fraction <= options.landmark_uncovered) return fit;
  const TipLandmarks tips = tip_landmarks(model, fit.positions, target, options);
  if (tips.landmarks.empty()) return fit;
  // The retries, each from its own start (computed in its task). The limbs turned about their
  // joints are tried only when neither the tips alone nor the limbs bent along the frame give
  // a fit that covers the frame; where one does, the turned limbs landed on the same fit
  // (docs/align.md, "Speed of one registration").
  struct Retry {
    const char* what;
    std::function<DeformationState()> from;
    int first_level = 0;
    bool second = false;  // only when the others leave part of the frame uncovered
  };
  std::vector<Retry> retries;
  // A tip was missed: register again from the same start, pulled by the tips.
  if (tips.missed) retries.push_back({"tip landmarks", [&] { return start; }});
  if (options.limb_fraction > 0) {
    // The limbs turned about their joints towards the tips first (the tips may all be covered
    // by a limb bent at the wrong joint).
    retries.push_back({"limbs turned to the tips",
                       [&] {
                         return turn_limbs_to_tips(model, start, tips.landmarks,
                                                   options.limb_fraction, options.limb_blend);
                       },
                       0, true});
    retries.push_back({"limbs bent along the frame",
                       [&] {
                         return bend_limbs_along_frame(model, start, tips.landmarks,
                                                       tips.frame_tips, tips.frame,
                                                       tips.frame_rings, options.limb_fraction,
                                                       options.limb_band);
                       },
                       options.bent_first_level});
  }
  std::vector<DeformationState> retried(retries.size());
  std::vector<FitStats> stats(retries.size());
  std::vector<char> ran(retries.size(), 0);  // written from the tasks: not vector<bool>
  // One round: the retries of that round side by side (each pass's own loops are parallel
  // too, and much of a pass - the factorisations, the system's assembly - is serial), each
  // with the same result as alone.
  const auto run_round = [&](bool second) {
    std::vector<std::size_t> tasks;
    for (std::size_t i = 0; i < retries.size(); ++i) {
      if (retries[i].second == second) tasks.push_back(i);
    }
    tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t t) {
      const std::size_t i = tasks[t];
      retried[i] = register_pass(model, retries[i].from(), target, options, tips.landmarks,
                                 retries[i].first_level);
      stats[i] = evaluate_fit(model, retried[i].positions, target, options);
      ran[i] = 1;
    });
  };
  // A retry must fit clearly closer than the first fit (a tip matched to the wrong limb, a
  // foot to the other foot, can still fit a little closer).
  const auto closer_than_first = [&](std::size_t i) {
    return ran[i] && two_sided_rms(stats[i]) < options.landmark_gain * two_sided_rms(first);
  };
  run_round(false);
  bool covered = false;
  for (std::size_t i = 0; i < retries.size(); ++i) {
    covered = covered || (closer_than_first(i) &&
                          stats[i].uncovered_fraction <= options.landmark_uncovered);
  }
  if (!covered) run_round(true);
  for (std::size_t i = 0; i < retries.size(); ++i) {
    if (!ran[i]) continue;
    if (trace) trace->retries.push_back(retries[i].what);
    log::debug("{}: both-ways rms {:.1f} mm -> {:.1f} mm, stretch {:.3f} -> {:.3f}",
               retries[i].what, 1e3 * two_sided_rms(first), 1e3 * two_sided_rms(stats[i]),
               first.stretch_rms, stats[i].stretch_rms);
  }
  // Of the retries clearly closer than the first fit, the least stretched of the about
  // closest wins.
  std::vector<std::size_t> closer;
  std::vector<FitStats> closer_stats;
  for (std::size_t i = 0; i < retries.size(); ++i) {
    if (closer_than_first(i)) {
      closer.push_back(i);
      closer_stats.push_back(stats[i]);
    }
  }
  if (closer.empty()) return fit;
  const std::size_t chosen =
      closer[least_stretched_close_fit(closer_stats, options.stretch_tolerance,
                                       options.stretch_margin)];
  log::debug("kept: {}", retries[chosen].what);
  if (trace) trace->kept = retries[chosen].what;
  return std::move(retried[chosen]);
}

FitStats evaluate_fit(const TemplateModel& model, const std::vector<Vec3f>& positions,
                      const SurfaceQuery& target, const RegistrationOptions& options) {
  FitStats stats;
  const std::size_t nv = positions.size();
  std::vector<double> forward(nv, 0.0), forward_weight(nv, 1.0);
  tbb::parallel_for(std::size_t{0}, nv, [&](std::size_t i) {
    SurfaceHit hit = target.closest(positions[i], std::numeric_limits<float>::max());
    forward[i] = hit.found ? hit.distance : std::numeric_limits<double>::infinity();
    forward_weight[i] = confidence_weight(hit.confidence, options);
  });
  // The rms weights the frame's surface as the registration does: a fit that keeps away from
  // a membrane of low confidence is not a worse fit.
  double sum = 0, weights = 0;
  for (std::size_t i = 0; i < nv; ++i) {
    sum += forward_weight[i] * forward[i] * forward[i];
    weights += forward_weight[i];
  }
  stats.surface_rms = weights > 0 ? std::sqrt(sum / weights) : 0.0;
  if (nv) {
    std::vector<double> sorted = forward;
    const std::size_t k = std::min(nv - 1, static_cast<std::size_t>(0.95 * nv));
    std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
    stats.surface_p95 = sorted[k];
    stats.surface_max = *std::max_element(forward.begin(), forward.end());
  }

  // Reverse: does the fit cover the whole frame (a limb left behind shows up here only)?
  const SurfaceQuery fitted_query(fitted_mesh(model, positions));
  const std::vector<Vec3f>& frame_points = target.positions();
  const std::size_t stride = std::max<std::size_t>(1, frame_points.size() / 20000);
  const std::size_t samples = (frame_points.size() + stride - 1) / stride;
  std::vector<double> reverse(samples, 0.0);
  tbb::parallel_for(std::size_t{0}, samples, [&](std::size_t s) {
    SurfaceHit hit = fitted_query.closest(frame_points[s * stride], std::numeric_limits<float>::max());
    reverse[s] = hit.found ? hit.distance : std::numeric_limits<double>::infinity();
  });
  // Frame surface of low confidence counts for less.
  double reverse_sum = 0, uncovered = 0, total = 0;
  for (std::size_t s = 0; s < samples; ++s) {
    const double c = confidence_weight(target.vertex_confidence(s * stride), options);
    reverse_sum += c * reverse[s] * reverse[s];
    if (reverse[s] > options.coverage_distance) uncovered += c;
    total += c;
  }
  if (total > 0) {
    stats.reverse_rms = std::sqrt(reverse_sum / total);
    stats.uncovered_fraction = uncovered / total;
  }

  // Stretch: how far the fit is from an isometry of the template (edge lengths).
  double stretch_sum = 0;
  std::size_t edges = 0;
  for_each_edge_strain(model.rest, model.rings, positions, [&](std::size_t, int, double change) {
    stretch_sum += change * change;
    ++edges;
  });
  stats.stretch_rms = edges ? std::sqrt(stretch_sum / edges) : 0.0;

  stats.flipped_triangles = static_cast<int>(folded_triangles(model, positions).size());
  return stats;
}

}  // namespace fourd::align
