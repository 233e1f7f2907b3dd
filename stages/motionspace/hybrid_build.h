#pragma once
// Offline precomputation of hybrid non-linear blending (paper section 3.1.1): choose the
// reference weights w_j by recursive bisection of the weight simplex and store the non-linear
// blend M_NL(t, w_j) at every frame, so that the runtime (runtime/blend.h) evaluates Eq. 1.
//
// The weight simplex starts as one cell whose corners are the inputs (where the hybrid is
// exact). A cell is tested at interior weights (2 inputs: the segment's quarter and mid
// points; 3 inputs: the edge midpoints, the centroid and the points halfway from the centroid
// to each corner) at every frame; while the largest vertex distance |M_NL - M| there exceeds
// epsilon, the cell is bisected at the midpoint of its refinement edge, which becomes a new
// reference. Triangles are split by newest-vertex bisection with its usual closure (a
// neighbour sharing the split edge is split too), so the cells always meet edge to edge and
// the runtime blend stays continuous in w.
#include <Eigen/Core>
#include <span>

#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"
#include "runtime/blend.h"

namespace fourd {

struct HybridBuildOptions {
  double epsilon = 0.005;  // max vertex distance of the hybrid from the non-linear blend [m]
  int max_depth = 8;       // at most this many bisections from the whole simplex to a cell
  int max_references =
      32;  // at most this many added references (each costs #frames x #V x 12 bytes)

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

// Fixed references on the weight line of a 2-input space (the paper's Table 1: "hybrid with 1
// reference" is s = {0.5}, "with 3 references" s = {0.25, 0.5, 0.75}): adds a reference at
// weights (1 - s_j, s_j) for each s_j, strictly increasing inside (0, 1), stores its non-linear
// blend at every frame and tiles the line with the segments between consecutive references.
// `space` must hold only its 2 inputs and the single cell. Throws InputError otherwise.
void add_line_references(const Eigen::Matrix3Xd& reference, std::span<const Tri> triangles,
                         std::span<const double> s, BlendSpace* space);

}  // namespace fourd
