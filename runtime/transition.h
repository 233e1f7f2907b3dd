#pragma once
// Online transitions between parametric motion spaces (paper section 3.2, Eq. 2 and 3), and
// the precomputed baseline of Table 2.
//
// From the current source state (t_s, p_s), a trellis is sampled forward in time and
// parameter: level a sits at t_s + a dt with parameters p_s + k dp, |k| <= a, clamped to the
// space's range (dt = alpha, time t spans [0, 1]; dp = alpha (p_max - p_min)). From the
// requested target state (t_t, p_t) a trellis goes backward: level b at t_t - b dt, parameters
// p_t + k dp, |k| <= b. A candidate path plays the source from its current state to a node of
// the source trellis (the parameter ramps linearly), switches to a node of the target trellis,
// and plays the target to the requested state. Its cost (Eq. 2) is
//   E_S + lambda E_L,
//   E_S = cost_unit d_max (1 - w^s S (w^t)^T)    the upper bound of the frame distance at the
//                                                switch implied by Eq. 3, in cm^2 by default,
//   E_L = frames played from the current state to the requested one (capture frames, 1/fps,
//         at the blended pace of each node, trapezoid between the path's end parameters).
// A cyclic source wraps around; a one-shot source's trellis stops at t = 1 (a last, shorter
// step). A one-shot target's trellis stops at t = 0 likewise. When the request gives no target
// time: for a cyclic target any phase will do (the trellis covers every phase at dt, each
// node's latency being the steps its parameter needs to reach p_t); for a one-shot target the
// time defaults to options.one_shot_target_t.
//
// TransitionSearch holds fixed-size scratch arrays: a search allocates nothing.
#include <array>
#include <span>

#include "pipeline/core/config.h"
#include "runtime/motion_graph.h"

namespace fourd {

inline constexpr int kMaxTrellisDepth = 32;
inline constexpr int kMaxTrellisColumns = 101;  // free-phase target columns (alpha >= 0.01)

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/graph.md, "Advanced").
struct TransitionOptions {
  double alpha = 0.1;   // trellis step as a fraction of the time and parameter ranges
  double lambda = 5.0;
  int depth = 12;
  double cost_unit = 1e4;  // E_S = cost_unit x distance [m^2]: 1e4 gives cm^2 (the graph stage
                           // divides it by the square of the subject's scale factor)
  double one_shot_target_t = 0.3;  // target time of a one-shot space when the request has none

  template <class V>
  void visit(V& v) {
    v("lambda", lambda, "weight of latency E_L (cost per frame)", Range{0, 1e6});
    v("depth", depth, "trellis depth l_max: levels on each side", Range{0, kMaxTrellisDepth});
  }
  // Throws ConfigError naming the field.
  void check() const;
};

struct MotionState {
  int space = -1;
  double t = 0;  // [0, 1]
  double p = 0;  // high-level parameter
};

struct TransitionTarget {
  int space = -1;
  double p = 0;
  double t = -1;  // < 0: not given (see the top of this file)
};

struct TransitionPath {
  bool found = false;
  int edge = -1;
  MotionState start;         // the state the path starts from
  MotionState exit;          // where the source is left (t wrapped into [0, 1])
  double source_span = 0;    // normalised source time played before the switch
  int source_steps = 0;      // trellis level of the exit
  MotionState entry;         // where the target is entered
  MotionState end;           // the requested state, reached at the end of the path
  double target_span = 0;    // normalised target time played from entry to end
  int target_steps = 0;
  double similarity = 0;       // online: the lower bound of Eq. 3; precomputed: 1 - d / d_max
  double similarity_cost = 0;  // E_S
  double latency_frames = 0;   // E_L
  double cost = 0;             // E_S + lambda E_L
  int candidates = 0;          // candidate paths scored (after pruning)
};

// Scratch of one side of a search: the parameter values of its trellis nodes and its levels
// (source) or columns (target).
inline constexpr int kMaxTrellisValues = 2 * kMaxTrellisDepth + 3;
struct TrellisSide {
  int num_values = 0;
  std::array<double, kMaxTrellisValues> value{};  // parameters, sorted by steps
  std::array<int, kMaxTrellisValues> steps{};      // trellis steps from the root's parameter
  std::array<std::array<float, 3>, kMaxTrellisValues> weight{};
  std::array<double, kMaxTrellisValues> duration{};  // blended duration of the space [s]
  int num_columns = 0;
  bool free_time = false;                          // target only: any phase will do
  std::array<double, kMaxTrellisColumns> time{};   // wrapped t of each level / column
  std::array<double, kMaxTrellisColumns> span{};   // normalised time from / to the root
  std::array<int, kMaxTrellisColumns> count{};     // values usable at the column (a prefix)
  std::array<float, kMaxTrellisColumns> min_latency{};
  std::array<float, kMaxTrellisValues * kMaxTrellisColumns> latency{};  // [column][value] frames
};

// Online search (Eq. 2 over the two trellises). Reusable scratch, no allocation per search.
class TransitionSearch {
 public:
  // `from.space` must be the edge's source and `to.space` its target. Out-of-range parameters
  // and times are clamped. Returns found = false only for an invalid edge or mismatched spaces.
  TransitionPath search(const MotionGraph& graph, int edge, const MotionState& from,
                        const TransitionTarget& to, const TransitionOptions& options);

 private:
  TrellisSide source_, target_;
  std::array<float, kMaxTrellisValues> y_[3]{};  // S w_t per target value, one row per source input
  std::array<float, kMaxTrellisValues> target_cost_{};
  std::array<float, kMaxTrellisValues> pair_cost_{};
};

// The same optimum by plain enumeration of every pair of trellis nodes (no deduplication, no
// pruning, double precision): the reference for tests. Allocates.
TransitionPath search_transition_brute_force(const MotionGraph& graph, int edge,
                                             const MotionState& from, const TransitionTarget& to,
                                             const TransitionOptions& options);

// Baseline: the best of the edge's first `n` precomputed transitions for this request (the one
// of least E_S + lambda E_L among those reachable: a one-shot source cannot go back in time, a
// one-shot target cannot be entered after the requested time). With `parameter_rate_limit`
// the parameter moves at most dp per trellis step, as in the online search, so a stored exit
// (entry) whose parameter is far from the current (requested) one is reached only after enough
// time: a cyclic space waits whole cycles, a one-shot space cannot. Without it the parameter
// may ramp to the stored one over any span, however short. found = false if none is reachable.
TransitionPath select_precomputed_transition(const MotionGraph& graph, int edge, int n,
                                             const MotionState& from, const TransitionTarget& to,
                                             const TransitionOptions& options,
                                             bool parameter_rate_limit = true);

// The target time a request resolves to: `to.t` if given, else options.one_shot_target_t for a
// one-shot space, else -1 (any phase of a cyclic space).
double resolved_target_time(const MotionGraph& graph, const TransitionTarget& to,
                            const TransitionOptions& options);

}  // namespace fourd
