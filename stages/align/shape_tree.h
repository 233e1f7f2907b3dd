#pragma once
// The minimum spanning tree over the frames' shape distances, rooted at its most central
// frame: alignment runs along its edges (parent to child), so every frame is reached from a
// similar one and the path from the root is short, whatever the time order.
#include <Eigen/Core>
#include <vector>

namespace fourd::align {

struct ShapeTree {
  int root = -1;
  std::vector<int> parent;                  // #N; -1 for the root
  std::vector<double> edge_cost;            // #N; distance to the parent (0 for the root)
  std::vector<std::vector<int>> children;   // #N
  std::vector<int> depth;                   // #N; edges from the root
  // Nodes in breadth-first order from the root: every parent before its children.
  std::vector<int> order;
};

// The most central frame: the least sum of shape distances to all frames (the medoid). A fit is
// expressed relative to the template at rest, so its error grows with the frame's shape
// distance from the root, whatever the path along the tree. Among the frames within
// `tolerance` (a fraction) of the least sum, the one with the fewest `handles` (when given, one
// per frame): a reconstruction with an arm merged into the body makes a poorer template.
int central_frame(const Eigen::MatrixXd& distance, const std::vector<int>& handles = {},
                  double tolerance = 0);

// Prim's algorithm on the dense symmetric matrix `distance` (N x N). With root < 0, the root
// is central_frame(distance).
ShapeTree minimum_spanning_tree(const Eigen::MatrixXd& distance, int root = -1);

// Re-roots an undirected tree given by parent links (any root) at `root`.
ShapeTree orient_tree(const std::vector<int>& parent, const Eigen::MatrixXd& distance, int root);

}  // namespace fourd::align
