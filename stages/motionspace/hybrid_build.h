#pragma once
// Offline precomputation of hybrid non-linear blending (paper section 3.1.1): choose the
// reference weights w_j by recursive bisection of the weight simplex and store the non-linear
// blend M_NL(t, w_j) at every frame, so that the runtime (runtime/blend.h) evaluates Eq. 1.
//
// Every cell is quadratic (runtime/blend.h): its nodes are its corners and the references at
// its edge midpoints. The weight simplex starts as one cell whose corners are the inputs (where
// the hybrid is exact), linear until its error calls for references: its first refinement adds
// its edge midpoints (2 inputs: w = 1/2; 3 inputs: the three edge midpoints) and makes it
// quadratic. A cell is tested between its nodes (2 inputs: the segment's quarter points;
// 3 inputs: the edge quarter points, the centroid and the points half way from each corner to
// the opposite edge's midpoint; the linear root also at its edge midpoints) at every frame;
// while the largest vertex distance |M_NL - M| there exceeds epsilon, a quadratic cell is
// bisected at the midpoint of its refinement edge (already a reference), and the children's new
// edge midpoints become new references. Triangles are split by newest-vertex bisection with its usual closure (a
// neighbour sharing the split edge is split too), so the cells always meet edge to edge, each
// shared edge has the same three nodes on both sides, and the runtime blend stays continuous.
// A 2-input segment also tries the arc basis (runtime/blend.h) with the angle its nodes draw
// (segment_arc_angle) and keeps it where it errs less at the cell's tests.
#include <Eigen/Core>
#include <span>

#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"
#include "runtime/blend.h"

namespace fourd {

struct HybridBuildOptions {
  double epsilon = 0.005;  // max vertex distance of the hybrid from the non-linear blend [m]
  // At most this many bisections from the whole simplex to a cell (0: the root alone, made
  // quadratic if linear blending misses epsilon).
  int max_depth = 8;
  // At most this many added references (each costs #frames x #V x 6 bytes: an fp16
  // displacement per coordinate, runtime/blend.h). The root cell's midpoints take 1 (2 inputs)
  // or 3 (3 inputs); a smaller budget leaves the blend linear.
  int max_references = 32;

  template <class V>
  void visit(V& v) {
    v("epsilon", epsilon, "max vertex distance of the hybrid from the non-linear blend [m]");
    v("max_depth", max_depth, "bisection levels per cell at most", Range{0, 30});
    v("max_references", max_references, "added references at most", Range{0, 100000});
  }
  // Throws ConfigError naming the field.
  void check() const;
};

struct HybridBuildReport {
  int references_added = 0;
  int cells = 0;
  int max_depth = 0;     // deepest cell
  double max_error = 0;  // [m] largest |M_NL - M| over the final cells' test weights and all frames
  double linear_max_error = 0;  // [m] largest |M_NL - M_L| over every weight tested
  bool converged = false;  // max_error <= epsilon (false: a depth or reference limit stopped it)
  int nonlinear_solves = 0;
};

// Adds references and cells to `space`, which must hold only its N inputs (references
// 0..N-1) and the single cell. `reference` (3 x #V) and `triangles` define the non-linear
// blend's gradient operator (e.g. the template mesh). Frames are processed in parallel (TBB);
// the result does not depend on the number of threads. Throws ConfigError for bad options,
// InputError for a space that does not fit, SolverError if a solve fails.
HybridBuildReport build_hybrid_references(const HybridBuildOptions& options,
                                          const Eigen::Matrix3Xd& reference,
                                          std::span<const Tri> triangles, BlendSpace* space);

// The arc angle of a 2-input segment with corners a, b and midpoint node m (references; m < 0:
// 0): per vertex and frame, the angle of the circle through the three nodes' positions (the
// inscribed angle at m is pi - theta / 2), averaged with the squared sagitta |x_m - (x_a +
// x_b) / 2|^2 as weight, so the vertices that bend most decide; in [0, pi].
double segment_arc_angle(const BlendSpace& space, int a, int m, int b);

// Fixed references on the weight line of a 2-input space (the paper's Table 1: "hybrid with 1
// reference" is s = {0.5}: one quadratic segment [0, 1] with its midpoint; "with 3 references"
// s = {0.25, 0.5, 0.75}: quadratic segments [0, 0.5] and [0.5, 1]): adds a reference at
// weights (1 - s_j, s_j) for each s_j, strictly increasing inside (0, 1), stores its non-linear
// blend at every frame and tiles the line from s = 0 to 1: a node exactly half way between its
// neighbours becomes the midpoint of a quadratic segment (with its arc angle from
// segment_arc_angle), otherwise consecutive nodes bound a linear segment.
// `space` must hold only its 2 inputs and the single cell. Throws InputError otherwise.
void add_line_references(const Eigen::Matrix3Xd& reference, std::span<const Tri> triangles,
                         std::span<const double> s, BlendSpace* space);

}  // namespace fourd
