#include "pipeline/geometry/geodesic.h"

#include <functional>
#include <limits>
#include <queue>
#include <utility>

namespace fourd {

std::vector<int> geodesic_update(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                                 int source, int source_id, double radius,
                                 std::vector<double>& dist, std::vector<int>& owner) {
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> heap;
  std::vector<int> reached;
  if (dist[source] > 0) {
    dist[source] = 0;
    owner[source] = source_id;
  }
  heap.emplace(0.0, source);
  reached.push_back(source);
  while (!heap.empty()) {
    auto [d, v] = heap.top();
    heap.pop();
    if (d > dist[v]) continue;
    for (int w : rings[v]) {
      const double nd = d + (mesh.positions[v] - mesh.positions[w]).cast<double>().norm();
      if (nd < dist[w] && nd <= radius) {
        if (dist[w] == std::numeric_limits<double>::infinity()) reached.push_back(w);
        dist[w] = nd;
        owner[w] = source_id;
        heap.emplace(nd, w);
      }
    }
  }
  return reached;
}

}  // namespace fourd
