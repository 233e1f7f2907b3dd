#pragma once
// The precomputed-transitions baseline of Table 2 (after Heck & Gleicher 2007): offline, the
// played states of both spaces are sampled on a grid (every sample of time, `parameter_samples`
// parameter values evenly over the range), the frame distance d of every source/target pair
// is measured on the blends the runtime plays (not on the lower bound), and the n best pairs
// are kept. Pairs are picked greedily, best first, skipping any whose source time lies within
// `separation` of one already kept (circularly for a cyclic source): otherwise the n best
// would be n neighbours of one good pair and the baseline would gain no latency from n.
#include <vector>

#include "pipeline/core/config.h"
#include "runtime/motion_graph.h"

namespace fourd::graph {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/graph.md, "Advanced").
struct PrecomputeOptions {
  int count = 10;
  int parameter_samples = 11;  // parameter values per space (evenly over its range)
  double separation = 0.05;    // least distance in source time between kept transitions

  template <class V>
  void visit(V& v) {
    v("count", count, "precomputed transitions kept per edge", Range{0, 1000});
  }
};

// The best transitions from `source` to `target`, best first. Allocates (offline).
std::vector<PrecomputedTransition> precompute_transitions(const GraphSpace& source,
                                                          const GraphSpace& target,
                                                          const SimilarityDefinition& definition,
                                                          const PrecomputeOptions& options);

}  // namespace fourd::graph
