// A transition between two motions of different speed and shape, as the character plays it:
// the worst per-frame vertex jump against the two motions' own speeds.
#include "runtime/transition_jump.h"

#include <gtest/gtest.h>

#include "tests/graph/test_graph.h"

namespace fourd {
namespace {

// A slow sway (small bend, 2 s a cycle) and a fast one (larger bend in another plane, 0.8 s a
// cycle, leaning forward), with transitions both ways.
MotionGraph slow_fast_graph() {
  test::SpaceRecipe slow = test::walk_recipe();
  slow.name = "slow";
  slow.amplitude = {10, 15};
  slow.duration = {2.0, 1.8};
  slow.forward = {0.8, 0.9};
  test::SpaceRecipe fast = test::walk_recipe();
  fast.name = "fast";
  fast.amplitude = {20, 25};
  fast.duration = {0.8, 0.7};
  fast.forward = {0.9, 1.0};
  fast.direction = 90;
  std::vector<MotionSpace> spaces{test::make_test_space(slow), test::make_test_space(fast)};
  // The fast motion leans forward throughout (x += 0.8 z): no phase of it meets the upright
  // slow one, so every switch has a gap to fade over.
  BlendSpace& b = spaces[1].blend;
  for (int k = 0; k < b.num_inputs; ++k) {
    for (int u = 0; u < b.num_frames; ++u) {
      float* f = b.frames.data() + (static_cast<std::size_t>(k) * b.num_frames + u) * b.frame_stride();
      for (int v = 0; v < b.num_vertices; ++v) f[v] += 0.8f * f[2 * b.plane_stride + v];
    }
  }
  std::vector<TransitionConfig> transitions{{"slow", "fast"}, {"fast", "slow"}};
  graph::GraphOptions options;
  options.precomputed.parameter_samples = 3;
  return graph::build_motion_graph("slow_fast", 25, std::move(spaces), transitions, options,
                                   nullptr);
}

struct Worst {
  double ratio = 0, fade = 0;
};

Worst worst_jump(const MotionGraph& graph, const CharacterOptions& options) {
  Character character(graph, TransitionOptions{}, options);
  Worst worst;
  for (int from = 0; from < 2; ++from) {
    for (double t : {0.0, 0.2, 0.45, 0.7, 0.9}) {
      const int to = 1 - from;
      const double p = graph.spaces[from].parameter_min();
      const TransitionJump j = measure_transition_jump(
          character, {from, t, p}, {to, graph.spaces[to].parameter_max(), -1}, graph.frame_time());
      EXPECT_TRUE(j.played);
      EXPECT_GT(j.source_p99_m, 0);
      worst.ratio = std::max(worst.ratio, j.ratio());
      worst.fade = std::max(worst.fade, character.state().fade_seconds);
    }
  }
  return worst;
}

TEST(TransitionJump, ACrossFadeSizedToTheMotionsKeepsVerticesAtTheirSpeed) {
  const MotionGraph graph = slow_fast_graph();
  // The fast motion moves its vertices several times faster than the slow one.
  const double slow = motion_displacement_p99(graph, 0, 1.0, graph.frame_time());
  const double fast = motion_displacement_p99(graph, 1, 1.0, graph.frame_time());
  EXPECT_GT(fast, 3 * slow);
  // A fixed 0.2 s fade without alignment: the switch between the two bends lurches.
  CharacterOptions fixed;
  fixed.crossfade_max_seconds = fixed.crossfade_seconds;
  fixed.align_at_switch = false;
  const Worst before = worst_jump(graph, fixed);
  const Worst after = worst_jump(graph, CharacterOptions{});
  CharacterOptions aligned_options;
  aligned_options.align_at_switch = true;
  const Worst aligned = worst_jump(graph, aligned_options);
  std::printf("jump ratio: fixed 0.2 s fade %.2f, sized %.2f (fade up to %.2f s), sized and "
              "aligned %.2f\n",
              before.ratio, after.ratio, after.fade, aligned.ratio);
  EXPECT_GT(before.ratio, 1.5);
  EXPECT_LE(after.ratio, 1.5);
  EXPECT_LE(aligned.ratio, 1.5);
  EXPECT_LT(after.ratio, before.ratio);
  EXPECT_GT(after.fade, 0.2);
}

// A jump is measured from the frame that crosses the switch to the last frame of the fade:
// the source playing towards its exit is the captured motion (dance_skirt's dance swings an
// arm at twice its 99th percentile there), no part of the transition.
TEST(TransitionJump, TheWindowRunsFromTheSwitchToTheEndOfTheFade) {
  CrossFadeWindow window;
  TransitionRecord r;
  CharacterState s;
  r.request_time = 0.5;
  EXPECT_FALSE(window.counts(r, s));  // the source plays
  EXPECT_FALSE(window.counts(r, s));
  r.switch_time = 0.9;
  s.fading = true;
  EXPECT_TRUE(window.counts(r, s));  // the switch
  EXPECT_TRUE(window.counts(r, s));  // the fade
  s.fading = false;
  EXPECT_TRUE(window.counts(r, s));  // the frame the fade ends in
  EXPECT_FALSE(window.counts(r, s));  // the target plays
  // A switch without a fade: its frame alone.
  r = TransitionRecord{};
  r.request_time = 2.0;
  r.switch_time = 2.0;
  EXPECT_TRUE(window.counts(r, s));
  EXPECT_FALSE(window.counts(r, s));
}

TEST(TransitionJump, TheMeterSeesTheLargestVertexStep) {
  const MotionGraph graph = test::make_test_graph();
  Character character(graph, TransitionOptions{});
  VertexJumpMeter meter;
  EXPECT_EQ(meter.add(character.frame()), 0.0);
  CharacterFrame moved = character.frame();
  moved.root.x += 0.25;  // the whole body 25 cm on
  EXPECT_NEAR(meter.add(moved), 0.25, 1e-5);
}

}  // namespace
}  // namespace fourd
