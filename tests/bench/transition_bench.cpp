// One online transition search (runtime/transition.h, Eq. 2 and 3 over the two trellises)
// from locomotion to a one-shot jump, at trellis depth range(0), on the procedural graph of
// tests/graph/test_graph.h with the default sample's frame counts (a 2-input walk cycle of 29
// samples, a 2-input jump of 47). The cost does not depend on the vertex count: the search
// reads only the edge's similarity matrices. Each iteration answers the next of 64 requests
// from random source states (time, speed) to random jump lengths. The goal is <= 20 us at
// depth 12 (the paper: 190 us); the precomputed baseline's selection is BM_PrecomputedSelect.
//   fourd_bench --benchmark_filter='Transition|Precomputed'
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "runtime/transition.h"
#include "tests/graph/test_graph.h"

namespace fourd {
namespace {

const MotionGraph& transition_graph() {
  static const MotionGraph g = [] {
    test::SpaceRecipe walk = test::walk_recipe(), jump = test::jump_recipe();
    walk.samples = 29;
    jump.samples = 47;
    const std::vector<TransitionConfig> transitions{{"locomotion", "jump_length"},
                                                    {"jump_length", "locomotion"}};
    graph::GraphOptions options;
    options.precomputed.parameter_samples = 5;
    return graph::build_motion_graph("bench", 25,
                                     {test::make_test_space(walk), test::make_test_space(jump)},
                                     transitions, options, nullptr);
  }();
  return g;
}

struct Request {
  MotionState from;
  TransitionTarget to;
};

std::vector<Request> requests(const MotionGraph& g) {
  const int loco = g.find_space("locomotion"), jump = g.find_space("jump_length");
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Request> out;
  for (int k = 0; k < 64; ++k) {
    out.push_back({{loco, u(rng), 1.0 + 0.6 * u(rng)}, {jump, 0.6 + 0.6 * u(rng), -1}});
  }
  return out;
}

void BM_TransitionSearch(benchmark::State& state) {
  const MotionGraph& g = transition_graph();
  const int edge = g.find_edge(g.find_space("locomotion"), g.find_space("jump_length"));
  const std::vector<Request> list = requests(g);
  TransitionOptions options;
  options.depth = static_cast<int>(state.range(0));
  TransitionSearch search;
  std::size_t k = 0;
  for (auto _ : state) {
    const Request& r = list[k++ & 63];
    const TransitionPath p = search.search(g, edge, r.from, r.to, options);
    if (!p.found) state.SkipWithError("no path");
    benchmark::DoNotOptimize(p.cost);
  }
}

void BM_PrecomputedSelect(benchmark::State& state) {
  const MotionGraph& g = transition_graph();
  const int edge = g.find_edge(g.find_space("locomotion"), g.find_space("jump_length"));
  const std::vector<Request> list = requests(g);
  const TransitionOptions options;
  const int n = static_cast<int>(state.range(0));
  std::size_t k = 0;
  for (auto _ : state) {
    const Request& r = list[k++ & 63];
    const TransitionPath p = select_precomputed_transition(g, edge, n, r.from, r.to, options, false);
    benchmark::DoNotOptimize(p.cost);
  }
}

BENCHMARK(BM_TransitionSearch)->Arg(3)->Arg(5)->Arg(10)->Arg(12)->Arg(16)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrecomputedSelect)->Arg(1)->Arg(5)->Arg(10)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace fourd
