#include "stages/align/shape_tree.h"

#include <limits>
#include <queue>
#include <utility>

#include "pipeline/core/error.h"

namespace fourd::align {
namespace {

std::vector<std::vector<int>> adjacency(const std::vector<int>& parent) {
  std::vector<std::vector<int>> adj(parent.size());
  for (std::size_t i = 0; i < parent.size(); ++i) {
    if (parent[i] >= 0) {
      adj[i].push_back(parent[i]);
      adj[parent[i]].push_back(static_cast<int>(i));
    }
  }
  return adj;
}

}  // namespace

ShapeTree orient_tree(const std::vector<int>& parent, const Eigen::MatrixXd& distance, int root) {
  const int n = static_cast<int>(parent.size());
  const auto adj = adjacency(parent);
  ShapeTree tree;
  tree.root = root;
  tree.parent.assign(n, -1);
  tree.edge_cost.assign(n, 0.0);
  tree.children.assign(n, {});
  tree.depth.assign(n, -1);
  std::queue<int> queue;
  queue.push(root);
  tree.depth[root] = 0;
  while (!queue.empty()) {
    int u = queue.front();
    queue.pop();
    tree.order.push_back(u);
    for (int v : adj[u]) {
      if (tree.depth[v] >= 0) continue;
      tree.depth[v] = tree.depth[u] + 1;
      tree.parent[v] = u;
      tree.edge_cost[v] = distance(u, v);
      tree.children[u].push_back(v);
      queue.push(v);
    }
  }
  if (static_cast<int>(tree.order.size()) != n) {
    throw SolverError("shape tree: the parent links do not form one tree");
  }
  return tree;
}

int central_frame(const Eigen::MatrixXd& distance, const std::vector<int>& handles,
                  double tolerance) {
  const Eigen::Index n = distance.rows();
  if (n == 0) throw InputError("shape tree: no frames");
  if (!handles.empty() && static_cast<Eigen::Index>(handles.size()) != n) {
    throw InputError("shape tree: one handle count per frame expected");
  }
  const Eigen::VectorXd sums = distance.rowwise().sum();
  const double limit = sums.minCoeff() * (1 + tolerance);
  const auto rank = [&](int k) { return std::pair(handles.empty() ? 0 : handles[k], sums[k]); };
  int best = -1;
  for (int k = 0; k < n; ++k) {
    if (sums[k] <= limit && (best < 0 || rank(k) < rank(best))) best = k;
  }
  return best;
}

ShapeTree minimum_spanning_tree(const Eigen::MatrixXd& distance, int root) {
  const int n = static_cast<int>(distance.rows());
  if (n == 0) throw InputError("shape tree: no frames");
  if (root >= n) throw InputError("shape tree: root index out of range");
  // Prim, O(N^2): fine for dense matrices of a few thousand frames.
  std::vector<int> parent(n, -1);
  std::vector<double> best(n, std::numeric_limits<double>::infinity());
  std::vector<char> in_tree(n, 0);
  best[0] = 0;
  for (int step = 0; step < n; ++step) {
    int u = -1;
    for (int v = 0; v < n; ++v) {
      if (!in_tree[v] && (u < 0 || best[v] < best[u])) u = v;
    }
    in_tree[u] = 1;
    for (int v = 0; v < n; ++v) {
      if (!in_tree[v] && distance(u, v) < best[v]) {
        best[v] = distance(u, v);
        parent[v] = u;
      }
    }
  }
  if (root < 0) root = central_frame(distance);
  return orient_tree(parent, distance, root);
}

}  // namespace fourd::align
