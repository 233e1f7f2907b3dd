// Online transition search (trellis, Eq. 2) against brute force, and the precomputed baseline
// (runtime/transition.h).
#include "runtime/transition.h"

#include <gtest/gtest.h>

#include <random>

#include "tests/graph/test_graph.h"

namespace fourd {
namespace {

struct Case {
  MotionState from;
  TransitionTarget to;
  int edge;
};

std::vector<Case> random_cases(const MotionGraph& g, int count, std::uint32_t seed,
                               bool free_time) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Case> cases;
  for (int k = 0; k < count; ++k) {
    const int edge = static_cast<int>(rng() % g.edges.size());
    const GraphEdge& e = g.edges[edge];
    const GraphSpace& a = g.spaces[e.from];
    const GraphSpace& b = g.spaces[e.to];
    Case c;
    c.edge = edge;
    c.from = {e.from, u(rng), a.parameter_min() + u(rng) * (a.parameter_max() - a.parameter_min())};
    c.to = {e.to, b.parameter_min() + u(rng) * (b.parameter_max() - b.parameter_min()),
            free_time ? -1.0 : u(rng)};
    cases.push_back(c);
  }
  return cases;
}

void expect_same_optimum(const TransitionPath& fast, const TransitionPath& brute,
                         double lambda = 5.0) {
  ASSERT_TRUE(fast.found);
  ASSERT_TRUE(brute.found);
  EXPECT_NEAR(fast.cost, brute.cost, 1e-3 * std::max(1.0, brute.cost));
  // The reported cost is the cost of the reported path.
  EXPECT_NEAR(fast.similarity_cost + lambda * fast.latency_frames, fast.cost,
              1e-6 * fast.cost + 1e-9);
}

TEST(TransitionSearch, FindsTheBruteForceOptimumOnSmallGraphs) {
  const MotionGraph g = test::make_test_graph(true);
  TransitionSearch search;
  for (const bool free_time : {false, true}) {
    for (const int depth : {0, 1, 3, 5}) {
      TransitionOptions o;
      o.depth = depth;
      for (const Case& c : random_cases(g, 60, 100 + depth, free_time)) {
        const TransitionPath fast = search.search(g, c.edge, c.from, c.to, o);
        const TransitionPath brute = search_transition_brute_force(g, c.edge, c.from, c.to, o);
        SCOPED_TRACE(testing::Message() << "depth " << depth << " edge " << c.edge << " from t "
                                        << c.from.t << " p " << c.from.p << " to t " << c.to.t
                                        << " p " << c.to.p);
        expect_same_optimum(fast, brute);
        EXPECT_LE(fast.source_steps, depth);
        EXPECT_LE(fast.candidates, brute.candidates);
      }
    }
  }
}

TEST(TransitionSearch, OtherAlphaAndLambdaStillMatchBruteForce) {
  const MotionGraph g = test::make_test_graph(true);
  TransitionSearch search;
  TransitionOptions o;
  o.depth = 4;
  o.alpha = 0.17;
  o.lambda = 0.5;
  for (const Case& c : random_cases(g, 40, 7, false)) {
    expect_same_optimum(search.search(g, c.edge, c.from, c.to, o),
                        search_transition_brute_force(g, c.edge, c.from, c.to, o), o.lambda);
  }
}

TEST(TransitionSearch, PathIsConsistentWithTheTrellis) {
  const MotionGraph g = test::make_test_graph();
  TransitionSearch search;
  TransitionOptions o;
  const double dp_walk = o.alpha * 0.6, dp_jump = o.alpha * 0.6;
  for (const Case& c : random_cases(g, 100, 3, false)) {
    const TransitionPath p = search.search(g, c.edge, c.from, c.to, o);
    ASSERT_TRUE(p.found);
    // The exit is source_steps levels after the start; its parameter moved at most that many steps.
    const GraphSpace& src = g.spaces[p.start.space];
    if (src.cyclic()) {
      EXPECT_NEAR(p.source_span, p.source_steps * o.alpha, 1e-9);
      EXPECT_NEAR(std::fmod(p.start.t + p.source_span, 1.0), p.exit.t, 1e-9);
    } else {
      EXPECT_LE(p.exit.t, 1.0);
      EXPECT_NEAR(std::min(1.0, p.start.t + p.source_span), p.exit.t, 1e-9);
    }
    const double dps = src.name() == "locomotion" ? dp_walk : dp_jump;
    EXPECT_LE(std::abs(p.exit.p - p.start.p), p.source_steps * dps + 1e-9);
    EXPECT_GE(p.similarity, 0.0);
    EXPECT_LE(p.similarity, 1.0);
    EXPECT_EQ(p.end.t, c.to.t >= 0 ? c.to.t : p.end.t);
  }
}

TEST(TransitionSearch, LatencyWeightTradesSimilarityForDelay) {
  const MotionGraph g = test::make_test_graph();
  TransitionSearch search;
  const int edge = g.find_edge(0, 1);
  const MotionState from{0, 0.3, 1.2};
  const TransitionTarget to{1, 0.9, 0.5};
  TransitionOptions patient, hurried;
  patient.lambda = 0.01;
  hurried.lambda = 100;
  const TransitionPath a = search.search(g, edge, from, to, patient);
  const TransitionPath b = search.search(g, edge, from, to, hurried);
  EXPECT_LE(a.similarity_cost, b.similarity_cost + 1e-9);
  EXPECT_GE(a.latency_frames, b.latency_frames - 1e-9);
}

TEST(TransitionSearch, InvalidEdgeOrSpacesAreNotFound) {
  const MotionGraph g = test::make_test_graph();
  TransitionSearch search;
  TransitionOptions o;
  EXPECT_FALSE(search.search(g, 99, {0, 0, 1}, {1, 1, 0.5}, o).found);
  EXPECT_FALSE(search.search(g, g.find_edge(0, 1), {1, 0, 1}, {0, 1, 0.5}, o).found);
}

TEST(TransitionSearch, ClampsOutOfRangeParameters) {
  const MotionGraph g = test::make_test_graph();
  TransitionSearch search;
  TransitionOptions o;
  const TransitionPath p = search.search(g, g.find_edge(0, 1), {0, 0.2, 7.0}, {1, -3.0, 0.6}, o);
  ASSERT_TRUE(p.found);
  EXPECT_DOUBLE_EQ(p.start.p, 1.6);
  EXPECT_DOUBLE_EQ(p.end.p, 0.6);
}

TEST(PrecomputedTransitions, AreSortedSeparatedAndSelectable) {
  const MotionGraph g = test::make_test_graph();
  const int edge = g.find_edge(0, 1);
  const GraphEdge& e = g.edges[edge];
  ASSERT_EQ(e.precomputed.size(), 10u);
  for (std::size_t k = 1; k < e.precomputed.size(); ++k) {
    EXPECT_LE(e.precomputed[k - 1].distance, e.precomputed[k].distance);
    for (std::size_t j = 0; j < k; ++j) {
      double gap = std::abs(e.precomputed[k].source_t - e.precomputed[j].source_t);
      gap = std::min(gap, 1 - gap);
      EXPECT_GE(gap, 0.05 - 1e-6);
    }
  }
  TransitionOptions o;
  // More stored transitions can only lower the selected cost.
  double previous = 1e300;
  for (const int n : {1, 5, 10}) {
    const TransitionPath p =
        select_precomputed_transition(g, edge, n, {0, 0.4, 1.3}, {1, 0.8, 0.9}, o, false);
    ASSERT_TRUE(p.found);
    EXPECT_LE(p.cost, previous + 1e-9);
    previous = p.cost;
    EXPECT_GE(p.source_span, 0.0);
    EXPECT_LT(p.source_span, 1.0);
  }
}

TEST(PrecomputedTransitions, OneShotSourceCannotGoBack) {
  const MotionGraph g = test::make_test_graph();
  const int edge = g.find_edge(1, 0);
  TransitionOptions o;
  // At the very end of the jump every stored exit lies in the past, unless one sits at t = 1.
  const TransitionPath p =
      select_precomputed_transition(g, edge, 10, {1, 1.0, 0.9}, {0, 1.2, 0.5}, o, false);
  bool any_at_end = false;
  for (const auto& c : g.edges[edge].precomputed) any_at_end |= c.source_t >= 1.0f - 1e-6f;
  EXPECT_EQ(p.found, any_at_end);
}

// With the rate limit a stored exit is reached no sooner than the parameter can move there at
// dp per trellis step: from the far end of the range a cyclic source waits whole cycles.
TEST(PrecomputedTransitions, ParameterMovesNoFasterThanTheTrellisAllows) {
  const MotionGraph g = test::make_test_graph(/*with_turning=*/true);
  const int edge = g.find_edge(0, 2);  // locomotion -> turning: both cyclic, so both can wait
  ASSERT_GE(edge, 0);
  const GraphSpace& src = g.spaces[0];
  TransitionOptions o;
  const double dp = o.alpha * (src.parameter_max() - src.parameter_min());
  for (const double p0 : {src.parameter_min(), src.parameter_max()}) {
    const MotionState from{0, 0.4, p0};
    const TransitionTarget to{2, g.spaces[2].parameter_min(), 0.5};
    const TransitionPath free = select_precomputed_transition(g, edge, 10, from, to, o, false);
    const TransitionPath limited = select_precomputed_transition(g, edge, 10, from, to, o, true);
    ASSERT_TRUE(free.found);
    ASSERT_TRUE(limited.found);
    EXPECT_GE(limited.cost, free.cost - 1e-9);
    const double steps = std::ceil(std::abs(limited.exit.p - p0) / dp - 1e-9);
    EXPECT_GE(limited.source_span, steps * o.alpha - 1e-9);
  }
}

}  // namespace
}  // namespace fourd
