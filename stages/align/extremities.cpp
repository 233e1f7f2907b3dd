#include "stages/align/extremities.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#include "pipeline/geometry/geodesic.h"

namespace fourd::align {

Extremities find_extremities(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                             int centre, const ExtremityOptions& options) {
  Extremities out;
  out.centre = centre;
  const int nv = static_cast<int>(mesh.num_vertices());
  if (centre < 0 || centre >= nv || options.max_count == 0) return out;
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> g(nv, inf);
  std::vector<int> owner(nv, -1);
  geodesic_update(mesh, rings, centre, 0, inf, g, owner);
  double farthest = 0;
  for (double d : g) {
    if (std::isfinite(d)) farthest = std::max(farthest, d);
  }

  // Candidates: vertices no farther than any of their neighbours, farthest first.
  std::vector<int> candidates;
  for (int v = 0; v < nv; ++v) {
    if (!std::isfinite(g[v]) || g[v] < options.min_fraction * farthest) continue;
    bool peak = true;
    for (int w : rings[v]) peak = peak && g[w] <= g[v];
    if (peak) candidates.push_back(v);
  }
  std::sort(candidates.begin(), candidates.end(),
            [&](int a, int b) { return g[a] != g[b] ? g[a] > g[b] : a < b; });

  // A candidate is a tip when nothing within `radius` of it is farther from the centre; a tip
  // suppresses every candidate within `radius`.
  std::vector<char> suppressed(nv, 0);
  std::vector<double> local(nv, inf);
  std::vector<int> local_owner(nv, -1);
  for (int c : candidates) {
    if (suppressed[c]) continue;
    const std::vector<int> reached =
        geodesic_update(mesh, rings, c, 0, options.radius, local, local_owner);
    bool tip = true;
    for (int w : reached) {
      tip = tip && g[w] <= g[c];
      local[w] = inf;
    }
    if (!tip) continue;
    for (int w : reached) suppressed[w] = 1;
    out.vertices.push_back(c);
    out.geodesic.push_back(g[c]);
    if (static_cast<int>(out.vertices.size()) == options.max_count) break;
  }
  return out;
}

std::vector<TipMatch> match_extremities(const Extremities& templ,
                                        const std::vector<Eigen::Vector3d>& template_positions,
                                        const Extremities& frame,
                                        const std::vector<Eigen::Vector3d>& frame_positions,
                                        const ExtremityOptions& options) {
  const int nt = static_cast<int>(templ.vertices.size());
  const int nf = static_cast<int>(frame.vertices.size());
  auto compatible = [&](int i, int j) {
    const double tolerance =
        std::max(options.min_tolerance, options.tolerance * templ.geodesic[i]);
    return std::abs(templ.geodesic[i] - frame.geodesic[j]) <= tolerance &&
           (template_positions[i] - frame_positions[j]).norm() <= options.max_match_distance;
  };
  // Exhaustive search over one-to-one assignments (at most 8 tips a side).
  std::vector<int> assignment(nt, -1), best(nt, -1);
  std::vector<char> used(nf, 0);
  int best_count = 0;
  double best_cost = std::numeric_limits<double>::infinity();
  std::function<void(int, int, double)> search = [&](int i, int count, double cost) {
    if (i == nt) {
      if (count > best_count || (count == best_count && cost < best_cost)) {
        best_count = count;
        best_cost = cost;
        best = assignment;
      }
      return;
    }
    if (count + (nt - i) < best_count) return;  // cannot reach the best count any more
    for (int j = 0; j < nf; ++j) {
      if (used[j] || !compatible(i, j)) continue;
      used[j] = 1;
      assignment[i] = j;
      search(i + 1, count + 1, cost + (template_positions[i] - frame_positions[j]).norm());
      assignment[i] = -1;
      used[j] = 0;
    }
    search(i + 1, count, cost);
  };
  search(0, 0, 0.0);
  std::vector<TipMatch> matches;
  for (int i = 0; i < nt; ++i) {
    if (best[i] >= 0) matches.push_back({i, best[i]});
  }
  return matches;
}

int anchored_tip(const std::vector<Eigen::Vector3d>& template_tips,
                 const std::vector<Eigen::Vector3d>& template_roots, const std::vector<char>& used,
                 const Eigen::Vector3d& at, const Eigen::Vector3d& root, double anchor_distance) {
  int best = -1;
  double best_root = anchor_distance;
  for (std::size_t i = 0; i < template_tips.size(); ++i) {
    const double r = (template_roots[i] - root).norm();
    if (!used[i] && (template_tips[i] - at).norm() < anchor_distance && r < best_root) {
      best = static_cast<int>(i);
      best_root = r;
    }
  }
  return best;
}

}  // namespace fourd::align
