// The paper's Table 2 on a small procedural graph.
#include "stages/graph/table2.h"

#include <gtest/gtest.h>

#include "pipeline/core/error.h"
#include "tests/graph/test_graph.h"

namespace fourd::graph {
namespace {

TEST(Table2, EveryMethodAnswersAndDeeperTrellisesNeverCostMore) {
  const MotionGraph graph = test::make_test_graph();
  TransitionOptions transitions;
  Table2Options options;
  options.transitions = 30;
  options.timing_repeats = 1;
  options.depths = {3, 8, 12};
  const Table2 table = evaluate_table2(graph, transitions, options, 1.5, 4.0);
  ASSERT_EQ(table.rows.size(), 9u);  // 3 online, 3 precomputed with and 3 without rate limit
  EXPECT_EQ(table.requests, 30);
  EXPECT_FALSE(table.edges.empty());
  for (const Table2Row& row : table.rows) {
    SCOPED_TRACE(row.method);
    if (row.n == 0 || !row.rate_limited) {
      EXPECT_GT(row.answered, 0);
    }
    EXPECT_GE(row.played_similarity_cost, 0);
    EXPECT_GE(row.latency_s, 0);
    EXPECT_NEAR(row.latency_cost, transitions.lambda * row.latency_s * graph.fps, 1e-6);
  }
  // The rate limit can only take requests away from the baseline.
  for (int k = 3; k < 6; ++k) EXPECT_LE(table.rows[k].answered, table.rows[k + 3].answered);
  // Online rows answer every request; a deeper trellis holds every path of a shallower one, so
  // its optimal cost (as scored) is never higher.
  for (int k = 0; k < 3; ++k) EXPECT_EQ(table.rows[k].answered, 30);
  for (int k = 1; k < 3; ++k) {
    EXPECT_LE(table.rows[k].similarity_cost + table.rows[k].latency_cost,
              table.rows[k - 1].similarity_cost + table.rows[k - 1].latency_cost + 1e-6);
  }
  // Every request played by a character, its worst vertex jump within 1.5 x the motions' own.
  EXPECT_EQ(table.jumps.played, 30);
  EXPECT_EQ(table.jumps.ratios.size(), 30u);
  EXPECT_GT(table.jumps.median_ratio, 0);
  EXPECT_LE(table.jumps.median_ratio, table.jumps.worst_ratio);
  EXPECT_LE(table.jumps.worst_ratio, 1.5);
  EXPECT_DOUBLE_EQ(table.rows[0].offline_cpu_s, 1.5);
  EXPECT_DOUBLE_EQ(table.rows[3].offline_cpu_s, 5.5);
  // The same seed gives the same requests.
  const Table2 again = evaluate_table2(graph, transitions, options, 1.5, 4.0);
  EXPECT_DOUBLE_EQ(again.rows[2].played_similarity_cost, table.rows[2].played_similarity_cost);
}

TEST(Table2, UnknownSpaceIsAConfigError) {
  const MotionGraph graph = test::make_test_graph();
  Table2Options options;
  options.spaces = {"locomotion", "no_such_space"};
  EXPECT_THROW(evaluate_table2(graph, TransitionOptions{}, options, 0, 0), ConfigError);
}

}  // namespace
}  // namespace fourd::graph
