#include "stages/graph/precomputed.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "stages/graph/similarity.h"

namespace fourd::graph {

namespace {

struct State {
  float t = 0;
  float p = 0;
};

std::vector<State> state_grid(const GraphSpace& space, int parameter_samples) {
  std::vector<State> grid;
  const int f = space.num_samples();
  const double lo = space.parameter_min(), hi = space.parameter_max();
  const int np = hi > lo ? parameter_samples : 1;
  for (int u = 0; u < f; ++u) {
    for (int k = 0; k < np; ++k) {
      const double p = np > 1 ? lo + (hi - lo) * k / (np - 1) : lo;
      grid.push_back({f > 1 ? static_cast<float>(u) / (f - 1) : 0.f, static_cast<float>(p)});
    }
  }
  return grid;
}

// Played-state features of every grid state, one column each.
Eigen::MatrixXf grid_features(const GraphSpace& space, const std::vector<State>& grid,
                              const SimilarityDefinition& definition) {
  const int nv = space.motion.blend.num_vertices;
  Eigen::MatrixXf out(6 * nv, static_cast<Eigen::Index>(grid.size()));
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, grid.size()),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      MotionSample scratch = make_motion_sample(space.motion);
                      for (std::size_t k = r.begin(); k < r.end(); ++k) {
                        std::array<float, 3> w{};
                        space_weights(space, grid[k].p, &w);
                        out.col(static_cast<Eigen::Index>(k)) = played_state_features(
                            space.motion, grid[k].t,
                            std::span<const float>(w.data(), space.num_inputs()), definition,
                            &scratch);
                      }
                    });
  return out;
}

}  // namespace

std::vector<PrecomputedTransition> precompute_transitions(const GraphSpace& source,
                                                          const GraphSpace& target,
                                                          const SimilarityDefinition& definition,
                                                          const PrecomputeOptions& options) {
  if (options.count <= 0) return {};
  const std::vector<State> sg = state_grid(source, options.parameter_samples);
  const std::vector<State> tg = state_grid(target, options.parameter_samples);
  const Eigen::MatrixXf a = grid_features(source, sg, definition);
  const Eigen::MatrixXf b = grid_features(target, tg, definition);
  const double nv = source.motion.blend.num_vertices;
  // d = (|a|^2 + |b|^2 - 2 a.b) / #V for every pair, in double for the subtraction.
  Eigen::MatrixXd d = -2.0 * (a.transpose() * b).cast<double>();
  d.colwise() += a.colwise().squaredNorm().transpose().cast<double>();
  d.rowwise() += b.colwise().squaredNorm().cast<double>();
  d = (d / nv).cwiseMax(0.0);

  std::vector<std::size_t> order(static_cast<std::size_t>(d.size()));
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](std::size_t x, std::size_t y) { return d.data()[x] < d.data()[y]; });
  std::vector<PrecomputedTransition> kept;
  for (const std::size_t k : order) {
    if (static_cast<int>(kept.size()) >= options.count) break;
    const State& s = sg[k % sg.size()];  // column-major: row = source state
    const State& t = tg[k / sg.size()];
    const bool too_close = std::any_of(kept.begin(), kept.end(), [&](const auto& c) {
      double gap = std::abs(c.source_t - s.t);
      if (source.cyclic()) gap = std::min(gap, 1 - gap);
      return gap < options.separation;
    });
    if (too_close) continue;
    kept.push_back({s.t, s.p, t.t, t.p, static_cast<float>(d.data()[k])});
  }
  return kept;
}

}  // namespace fourd::graph
