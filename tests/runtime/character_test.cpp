// The runtime character (runtime/character.h) and its controller (runtime/controller.h) on the
// small procedural graphs of tests/graph/test_graph.h.
#include "runtime/character.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <new>
#include <numbers>
#include <vector>

#include "runtime/asset.h"
#include "runtime/controller.h"
#include "tests/graph/test_graph.h"

// Counting global allocation: the no-allocation test reads the counter around its frame loop.
namespace {
std::atomic<long> g_allocations{0};
void* counted_malloc(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* counted_aligned(std::size_t n, std::align_val_t a) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  const std::size_t al = static_cast<std::size_t>(a);
  const std::size_t size = (std::max<std::size_t>(n, 1) + al - 1) / al * al;
  if (void* p = std::aligned_alloc(al, size)) return p;
  throw std::bad_alloc();
}
}  // namespace
void* operator new(std::size_t n) { return counted_malloc(n); }
void* operator new[](std::size_t n) { return counted_malloc(n); }
void* operator new(std::size_t n, std::align_val_t a) { return counted_aligned(n, a); }
void* operator new[](std::size_t n, std::align_val_t a) { return counted_aligned(n, a); }
// The nothrow forms too (std::stable_sort's temporary buffer uses them): otherwise they
// allocate with the library's operator new and free here, which AddressSanitizer reports.
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return counted_malloc(n);
  } catch (const std::bad_alloc&) {
    return nullptr;
  }
}
void* operator new[](std::size_t n, const std::nothrow_t& tag) noexcept {
  return operator new(n, tag);
}
void* operator new(std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  try {
    return counted_aligned(n, a);
  } catch (const std::bad_alloc&) {
    return nullptr;
  }
}
void* operator new[](std::size_t n, std::align_val_t a, const std::nothrow_t& tag) noexcept {
  return operator new(n, a, tag);
}
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept {
  std::free(p);
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

namespace fourd {
namespace {

const MotionGraph& graph() {
  static const MotionGraph g = test::make_test_graph(false);
  return g;
}
const MotionGraph& graph_with_turning() {
  static const MotionGraph g = test::make_test_graph(true);
  return g;
}

std::vector<Vec3f> world(const CharacterFrame& f) {
  std::vector<Vec3f> p;
  character_world_positions(f, &p);
  return p;
}

double max_displacement(const std::vector<Vec3f>& a, const std::vector<Vec3f>& b) {
  double d = 0;
  for (std::size_t v = 0; v < a.size(); ++v) d = std::max(d, static_cast<double>((a[v] - b[v]).norm()));
  return d;
}

// Largest vertex displacement between consecutive frames, per frame, of a run.
struct Recording {
  std::vector<double> step;  // step[k]: frame k vs frame k - 1 (step[0] = 0)
  std::vector<int> switch_frames;
  std::vector<std::vector<Vec3f>> frames;
  std::vector<RootTransform> roots;
  std::vector<double> ts;  // normalised time shown
};

// Plays `seconds` at `fps`, calling `script(time, character)` before every frame.
template <class Script>
Recording play(Character& c, double fps, double seconds, Script script) {
  Recording r;
  const int n = static_cast<int>(std::lround(seconds * fps));
  const double start = c.time();
  for (int k = 0; k <= n; ++k) {
    const double time = start + k / fps;
    const CharacterFrame& f = c.step(time - c.time());
    r.frames.push_back(world(f));
    r.roots.push_back(f.root);
    r.ts.push_back(c.state().t);
    r.step.push_back(k == 0 ? 0.0 : max_displacement(r.frames[k], r.frames[k - 1]));
    if (c.events().switches > 0) r.switch_frames.push_back(k);
    script(time, c);  // requests made at this frame's time
  }
  return r;
}

// Largest vertex "acceleration" |x[k+1] - 2 x[k] + x[k-1]| over frames [from, to) of a run: a
// pop is a spike of it.
double max_second_difference(const Recording& r, std::size_t from, std::size_t to) {
  double worst = 0;
  for (std::size_t k = std::max<std::size_t>(from, 1); k + 1 < std::min(to, r.frames.size()); ++k) {
    for (std::size_t v = 0; v < r.frames[k].size(); ++v) {
      const Vec3f a = r.frames[k + 1][v] - 2 * r.frames[k][v] + r.frames[k - 1][v];
      worst = std::max(worst, static_cast<double>(a.norm()));
    }
  }
  return worst;
}

TEST(RuntimeCharacter, TransitionStartsFromTheCurrentPoseAndSwitchesWithoutAPop) {
  const MotionGraph& g = graph();
  const int loco = g.find_space("locomotion"), jump = g.find_space("jump_length");
  // lambda = 1000: the search takes the quickest path whatever the similarity, so the switch
  // joins two rather different poses; the cross-fade must hide it.
  TransitionOptions search;
  search.lambda = 1000;
  for (const double crossfade : {0.25, 0.0}) {
    CharacterOptions o;
    o.crossfade_seconds = crossfade;
    Character c(g, search, o);
    c.reset(loco, 1.3, 0.2);
    const double fps = 60;
    // Plain locomotion first: the typical frame-to-frame motion and acceleration.
    const Recording plain = play(c, fps, 1.0, [](double, Character&) {});
    const double typical = *std::max_element(plain.step.begin(), plain.step.end());
    const double typical_acceleration = max_second_difference(plain, 0, plain.frames.size());
    ASSERT_GT(typical, 0);
    // The request: the frame at the request time is the current pose, exactly.
    const std::vector<Vec3f> before = plain.frames.back();
    const RequestStatus status = c.request_motion(jump, 0.9);
    EXPECT_EQ(status.result, RequestResult::kAccepted);
    EXPECT_EQ(max_displacement(world(c.step(0)), before), 0.0);
    // Through the switch; frame 0 is the request's frame.
    TransitionRecord first;
    const Recording through = play(c, fps, 1.0, [&](double, Character& ch) {
      if (first.request_time < 0) first = ch.last_transition();
    });
    EXPECT_EQ(max_displacement(through.frames[0], before), 0.0);
    // The path starts at the state the character was in.
    ASSERT_TRUE(first.path.found);
    EXPECT_EQ(first.path.start.space, loco);
    EXPECT_NEAR(first.path.start.p, 1.3, 1e-9);
    EXPECT_NEAR(first.request_time, 1.0, 1e-9);
    ASSERT_FALSE(through.switch_frames.empty());
    const std::size_t k = through.switch_frames.front();
    double worst = 0;
    for (std::size_t i = 1; i < through.step.size(); ++i) worst = std::max(worst, through.step[i]);
    const double acceleration = max_second_difference(through, k >= 2 ? k - 2 : 0, k + 3);
    SCOPED_TRACE(testing::Message() << "crossfade " << crossfade << " typical " << typical
                                    << " worst " << worst << " typical acceleration "
                                    << typical_acceleration << " at switch " << acceleration);
    if (crossfade > 0) {
      // The first frame after the request, and every frame through the switch, move no more
      // than plain locomotion does (measured: 1.27 x), and the switch adds no acceleration.
      EXPECT_LE(through.step[1], 1.5 * typical);
      EXPECT_LE(worst, 1.5 * typical);
      EXPECT_LE(acceleration, 2.0 * typical_acceleration);
    } else {
      // Without the cross-fade the same switch pops (measured: 0.52 m in one frame against
      // 0.045 m of plain locomotion): the checks above can fail.
      EXPECT_GT(worst, 1.5 * typical);
      EXPECT_GT(acceleration, 2.0 * typical_acceleration);
    }
    // The root never jumps.
    for (std::size_t i = 1; i < through.roots.size(); ++i) {
      const double dx = through.roots[i].x - through.roots[i - 1].x;
      const double dy = through.roots[i].y - through.roots[i - 1].y;
      EXPECT_LT(std::hypot(dx, dy), 2.0 / fps) << "frame " << i;  // < 2 m/s
    }
  }
}

TEST(RuntimeCharacter, CyclicLoopPlaysWithoutAPop) {
  const MotionGraph& g = graph();
  const int loco = g.find_space("locomotion");
  Character c(g, TransitionOptions{});
  c.reset(loco, 1.2, 0.8);
  const double fps = 50;
  const Recording run = play(c, fps, 2.5, [](double, Character&) {});
  // The frames where the cycle wrapped: compare their motion with their neighbours'.
  int wraps = 0;
  for (std::size_t k = 1; k < run.step.size(); ++k) {
    if (run.ts[k] < run.ts[k - 1]) {
      ++wraps;
      ASSERT_GE(k, 2u);
      ASSERT_LT(k + 1, run.step.size());
      const double around = std::max(run.step[k - 1], run.step[k + 1]);
      EXPECT_LE(run.step[k], 1.3 * around) << "frame " << k;
      EXPECT_GE(run.step[k], 0.7 * std::min(run.step[k - 1], run.step[k + 1])) << "frame " << k;
      // Root speed continuous across the wrap.
      auto speed = [&](std::size_t i) {
        return std::hypot(run.roots[i].x - run.roots[i - 1].x, run.roots[i].y - run.roots[i - 1].y);
      };
      EXPECT_NEAR(speed(k), speed(k - 1), 0.2 * speed(k - 1));
      EXPECT_NEAR(speed(k), speed(k + 1), 0.2 * speed(k - 1));
    }
  }
  EXPECT_GE(wraps, 2);
  // Root speed matches the space: ~1.2 m/s.
  const double dist = std::hypot(run.roots.back().x - run.roots.front().x,
                                 run.roots.back().y - run.roots.front().y);
  EXPECT_NEAR(dist / 2.5, 1.2, 0.1);
}

// A timeline of requests, by motion time.
void timeline(double time, Character& c) {
  const MotionGraph& g = c.graph();
  struct Event {
    double time;
    int kind;
    double value;
  };
  static const Event events[] = {{0.5, 0, 1.5}, {1.0, 1, 1.0}, {2.9, 0, 1.1}, {3.1, 2, 0.3},
                                 {3.6, 2, 0.0}, {4.0, 1, 0.7}};
  for (const Event& e : events) {
    if (std::abs(e.time - time) > 1e-9) continue;
    if (e.kind == 0) c.set_parameters(e.value);
    if (e.kind == 1) c.request_motion(g.find_space("jump_length"), e.value);
    if (e.kind == 2) c.set_turn_rate(e.value);
  }
}

TEST(RuntimeCharacter, SameTimelineGivesTheSameMotionAt30And60Hz) {
  const MotionGraph& g = graph();
  const int loco = g.find_space("locomotion");
  Character a(g, TransitionOptions{}), b(g, TransitionOptions{});
  a.reset(loco, 1.2, 0.1);
  b.reset(loco, 1.2, 0.1);
  // Events land on frame times of both rates (multiples of 1/30 s... and 0.5, 2.9, 3.1).
  const Recording r30 = play(a, 30, 5.4, timeline);
  const Recording r60 = play(b, 60, 5.4, timeline);
  ASSERT_EQ(r60.frames.size(), 2 * r30.frames.size() - 1);
  EXPECT_GE(a.last_transition().request_time, 4.0);  // both jumps happened
  double shape = 0, root = 0;
  for (std::size_t k = 0; k < r30.frames.size(); ++k) {
    shape = std::max(shape, max_displacement(r30.frames[k], r60.frames[2 * k]));
    root = std::max(root, std::hypot(r30.roots[k].x - r60.roots[2 * k].x,
                                     r30.roots[k].y - r60.roots[2 * k].y));
    root = std::max(root, std::abs(r30.roots[k].heading - r60.roots[2 * k].heading));
  }
  EXPECT_LT(shape, 1e-5);
  EXPECT_LT(root, 1e-6);
}

// The player's way of applying events between frames: split the step at the event.
TEST(RuntimeCharacter, EventsBetweenFramesGiveTheSameMotionAt25And60Hz) {
  const MotionGraph& g = graph();
  const int loco = g.find_space("locomotion"), jump = g.find_space("jump_length");
  auto run = [&](double fps) {
    Character c(g, TransitionOptions{});
    c.reset(loco, 1.2, 0.1);
    const double events[] = {0.53, 1.01, 2.87};
    std::size_t next = 0;
    std::vector<RootTransform> roots;
    std::vector<std::vector<Vec3f>> shapes;
    for (int k = 0; k <= static_cast<int>(std::lround(4.0 * fps)); ++k) {
      const double time = k / fps;
      while (next < 3 && events[next] <= time) {
        c.step(events[next] - c.time());
        if (next == 0) c.set_parameters(1.5);
        if (next == 1) c.request_motion(jump, 1.1);
        if (next == 2) c.set_parameters(1.0);
        ++next;
      }
      const CharacterFrame& f = c.step(time - c.time());
      if (k % static_cast<int>(std::lround(fps / 5)) == 0) {
        roots.push_back(f.root);
        shapes.push_back(world(f));
      }
    }
    return std::make_pair(roots, shapes);
  };
  const auto [roots25, shapes25] = run(25);
  const auto [roots60, shapes60] = run(60);
  ASSERT_EQ(roots25.size(), roots60.size());
  for (std::size_t k = 0; k < roots25.size(); ++k) {
    EXPECT_NEAR(roots25[k].x, roots60[k].x, 1e-6) << "sample " << k;
    EXPECT_NEAR(roots25[k].y, roots60[k].y, 1e-6) << "sample " << k;
    EXPECT_LT(max_displacement(shapes25[k], shapes60[k]), 1e-5) << "sample " << k;
  }
}

TEST(RuntimeCharacter, StepsAllocateNothing) {
  const MotionGraph& g = graph_with_turning();
  const int loco = g.find_space("locomotion"), jump = g.find_space("jump_length"),
            turning = g.find_space("turning");
  Character c(g, TransitionOptions{});
  Controller control(c);
  const GroundPath path({BezierCurve{{Point2{0, 0}, Point2{2, 0}, Point2{4, 1}, Point2{6, 1}}, 1.4}});
  c.reset(loco, 1.2, 0.0);
  c.step(1 / 60.0);
  const long before = g_allocations.load();
  control.follow(&path);
  int searches = 0, switches = 0;
  for (int k = 1; k <= 600; ++k) {
    if (k == 60) c.request_motion(jump, 0.8);
    if (k == 200) c.request_motion(turning, 20.0);
    if (k == 300) c.request_motion(jump, 5.0);  // clamped, routed through locomotion
    if (k == 450) c.set_parameters(-1);
    c.step(1 / 60.0);
    searches += c.events().searches;
    switches += c.events().switches;
  }
  const long after = g_allocations.load();
  EXPECT_EQ(after - before, 0);
  EXPECT_GE(searches, 4);
  EXPECT_GE(switches, 4);
  // The counter does count: a vector allocates.
  std::vector<int>* v = new std::vector<int>(10);
  delete v;
  EXPECT_GE(g_allocations.load() - after, 2);
}

// With textures the frame also lists the key textures to blend, and the CPU blend into a
// kept image allocates nothing either.
TEST(RuntimeCharacter, TexturedStepsAndTheirBlendAllocateNothing) {
  const MotionGraph& g = test::textured_test_graph();
  Character c(g, TransitionOptions{});
  c.reset(g.find_space("locomotion"), 1.2, 0.0);
  cv::Mat texture;
  blend_texture_image(g.textures, c.step(1 / 60.0).textures, &texture);
  const long before = g_allocations.load();
  for (int k = 1; k <= 300; ++k) {
    if (k == 60) c.request_motion(g.find_space("jump_length"), 0.8);
    blend_texture_image(g.textures, c.step(1 / 60.0).textures, &texture);
  }
  EXPECT_EQ(g_allocations.load() - before, 0);
  EXPECT_GT(c.frame().textures.count, 0);
}

TEST(RuntimeCharacter, ClampsAndReportsParametersAndRoutesRequestsWithoutAnEdge) {
  const MotionGraph& g = graph_with_turning();
  const int loco = g.find_space("locomotion"), jump = g.find_space("jump_length"),
            turning = g.find_space("turning");
  Character c(g, TransitionOptions{});
  RequestStatus s = c.reset(loco, 3.0);
  EXPECT_TRUE(s.clamped);
  EXPECT_DOUBLE_EQ(s.applied, 1.6);
  s = c.set_parameters(0.2);
  EXPECT_TRUE(s.clamped);
  EXPECT_DOUBLE_EQ(s.applied, 1.0);
  EXPECT_EQ(c.clamp_count(), 2);
  EXPECT_EQ(c.request_motion("nothing", 1.0).result, RequestResult::kUnknownSpace);
  // Into the jump, then ask for turning: no edge jump -> turning, so via locomotion.
  c.request_motion(jump, 1.0);
  for (int k = 0; k < 30 && c.state().space != jump; ++k) c.step(0.1);
  ASSERT_EQ(c.state().space, jump);
  s = c.request_motion(turning, 30.0);
  EXPECT_EQ(s.result, RequestResult::kRouted);
  EXPECT_EQ(s.hops, 2);
  bool visited_locomotion = false;
  for (int k = 0; k < 100 && !(c.state().space == turning && c.state().phase == PlayPhase::kFree);
       ++k) {
    c.step(0.05);
    visited_locomotion |= c.state().space == loco;
  }
  EXPECT_TRUE(visited_locomotion);
  EXPECT_EQ(c.state().space, turning);
  EXPECT_NEAR(c.state().p, 30.0, 1e-9);
}

TEST(RuntimeCharacter, RefusesARequestWithoutRouteAndKeepsPlaying) {
  // Only jump_length -> locomotion: nothing leads from locomotion to the jump.
  graph::GraphOptions options;
  options.precomputed.parameter_samples = 5;
  const std::vector<TransitionConfig> one_way{{"jump_length", "locomotion"}};
  const MotionGraph g = graph::build_motion_graph(
      "one-way", 25,
      {test::make_test_space(test::walk_recipe()), test::make_test_space(test::jump_recipe())},
      one_way, options, nullptr);
  const int loco = g.find_space("locomotion"), jump = g.find_space("jump_length");
  Character c(g, TransitionOptions{});
  c.reset(loco, 1.2);
  c.step(0.1);
  const double t = c.state().t;
  const RequestStatus s = c.request_motion(jump, 1.0);
  EXPECT_EQ(s.result, RequestResult::kNoRoute);
  EXPECT_EQ(s.hops, 0);
  int searches = 0;
  for (int k = 0; k < 100; ++k) {
    c.step(0.02);
    searches += c.events().searches;
    ASSERT_EQ(c.state().space, loco);
    ASSERT_EQ(c.state().phase, PlayPhase::kFree);
  }
  EXPECT_EQ(searches, 0);
  EXPECT_NE(c.state().t, t);  // still walking
  EXPECT_NEAR(c.state().p, 1.2, 1e-9);
}

TEST(RuntimeCharacter, OneShotMotionReturnsToTheCyclicSpace) {
  const MotionGraph& g = graph();
  const int loco = g.find_space("locomotion"), jump = g.find_space("jump_length");
  Character c(g, TransitionOptions{});
  c.reset(loco, 1.4);
  c.request_motion(jump, 1.2);
  bool jumped = false;
  double prev_x = 0;
  for (int k = 0; k < 300; ++k) {
    const CharacterFrame& f = c.step(1 / 50.0);
    jumped |= c.state().space == jump;
    EXPECT_GE(f.root.x, prev_x - 1e-9) << "the root keeps going forward";
    prev_x = f.root.x;
  }
  EXPECT_TRUE(jumped);
  EXPECT_EQ(c.state().space, loco);
  EXPECT_NEAR(c.state().p, 1.4, 1e-9);
}

// Follows a path; returns the controller's status.
FollowStatus follow(const MotionGraph& g, const GroundPath& path, double fps, double max_seconds,
                    double start_speed, double* final_p = nullptr) {
  Character c(g, TransitionOptions{});
  Controller control(c);
  const Point2 a = path.point_at(0);
  c.reset(g.find_space("locomotion"), start_speed, 0.0, {a.x, a.y, path.heading_at(0)});
  control.follow(&path);
  for (int k = 0; k < max_seconds * fps && !control.follow_status().done; ++k) c.step(1 / fps);
  if (final_p) *final_p = c.state().p;
  return control.follow_status();
}

GroundPath straight_path(Point2 a, double heading, double l1, double v1, double l2, double v2) {
  const double cx = std::cos(heading), sy = std::sin(heading);
  auto at = [&](double s) { return Point2{a.x + s * cx, a.y + s * sy}; };
  return GroundPath({BezierCurve{{at(0), at(l1 / 3), at(2 * l1 / 3), at(l1)}, v1},
                     BezierCurve{{at(l1), at(l1 + l2 / 3), at(l1 + 2 * l2 / 3), at(l1 + l2)}, v2}});
}

TEST(RuntimeController, FollowsAStraightPathWithASpeedChange) {
  const GroundPath path = straight_path({1, -2}, 30 * std::numbers::pi / 180, 4, 1.1, 5, 1.5);
  EXPECT_NEAR(path.length(), 9.0, 1e-6);
  double p = 0;
  const FollowStatus s = follow(graph(), path, 60, 30, 1.1, &p);
  EXPECT_TRUE(s.done);
  EXPECT_LE(s.max_abs_error, 0.25);
  EXPECT_NEAR(s.travelled, s.s - s.s_start, 0.02 * (s.s - s.s_start));
  EXPECT_NEAR(p, 1.5, 1e-6);  // the speed changed
}

TEST(RuntimeController, SteersOntoAnOffsetPathAndFollowsAGentleCurve) {
  // Start 0.2 m beside the path: the follower must converge; then a gentle S.
  const GroundPath path({BezierCurve{{Point2{0, 0.2}, Point2{2, 0.2}, Point2{4, 1.2}, Point2{6, 1.2}}, 1.2},
                         BezierCurve{{Point2{6, 1.2}, Point2{8, 1.2}, Point2{10, 0.2}, Point2{12, 0.2}}, -1}});
  Character c(graph(), TransitionOptions{});
  Controller control(c);
  c.reset(graph().find_space("locomotion"), 1.2, 0.0, {0, 0, 0});
  control.follow(&path);
  double late_error = 0;
  for (int k = 0; k < 60 * 20 && !control.follow_status().done; ++k) {
    c.step(1 / 60.0);
    if (control.follow_status().s > 2) late_error = std::max(late_error, std::abs(control.follow_status().lateral_error));
  }
  EXPECT_TRUE(control.follow_status().done);
  EXPECT_LE(late_error, 0.25);
}

// A pipeline-built asset named by FOURD_TEST_ASSET (e.g. the tiny sample's), when given; the
// end-to-end test also follows paths on the tiny sample's asset with fourd-play.
TEST(RuntimeController, FollowsAStraightPathOnTheTinySampleAsset) {
  const char* env = std::getenv("FOURD_TEST_ASSET");
  if (!env || !std::filesystem::exists(env)) GTEST_SKIP() << "FOURD_TEST_ASSET names no asset";
  const std::filesystem::path file = env;
  const Asset asset = load_asset(file);
  const GroundPath path = straight_path({0, 0}, 0.5, 4, 1.1, 5, 1.5);
  double p = 0;
  const FollowStatus s = follow(asset.graph, path, 30, 30, 1.1, &p);
  EXPECT_TRUE(s.done);
  EXPECT_LE(s.max_abs_error, 0.25);
  EXPECT_NEAR(s.travelled, s.s - s.s_start, 0.02 * (s.s - s.s_start));
  EXPECT_NEAR(p, 1.5, 1e-6);
}

// A straight path at 1.2 m/s with a gap of 0.9 m whose middle lies at `gap_middle`.
GroundPath gap_path(double gap_middle) {
  auto line = [](double a, double b, double speed, bool gap) {
    BezierCurve c{
        {Point2{a, 0}, Point2{a + (b - a) / 3, 0}, Point2{a + 2 * (b - a) / 3, 0}, Point2{b, 0}},
        speed};
    c.gap = gap;
    return c;
  };
  const double a = gap_middle - 0.45, b = gap_middle + 0.45;
  return GroundPath({line(0, a, 1.2, false), line(a, b, -1, true), line(b, b + 3, -1, false)});
}

TEST(RuntimeController, PlacesTheJumpOnTheGapWhereverTheGapIs) {
  // The gap's middle at several places along one walk cycle (about 1.1 m here). Requesting the
  // jump on the prediction step nearest to the gap left it up to half a cycle (~0.4-0.55 m)
  // away; with the approach speed adjusted, what is left is at most half a step (~0.2 m).
  for (const double middle : {4.0, 4.25, 4.5, 4.75, 5.0}) {
    const GroundPath path = gap_path(middle);
    const FollowStatus s = follow(graph(), path, 60, 30, 1.2);
    EXPECT_TRUE(s.done) << middle;
    EXPECT_EQ(s.jumps, 1) << middle;
    EXPECT_LE(std::abs(s.max_abs_jump_offset), 0.25) << "gap middle at " << middle;
    EXPECT_LE(s.max_abs_error, 0.25) << middle;
  }
}

// The S-curve of sample_capture/play/s_curve.txt.
GroundPath s_curve() {
  return GroundPath(
      {BezierCurve{{Point2{0, 0}, Point2{2, 0}, Point2{3, 1.5}, Point2{5, 1.5}}, 1.2},
       BezierCurve{{Point2{5, 1.5}, Point2{7, 1.5}, Point2{8, 0}, Point2{10, 0}}, -1}});
}

TEST(RuntimeController, TakesCurvesInTheTurningSpace) {
  const GroundPath path = s_curve();
  const FollowStatus turning = follow(graph_with_turning(), path, 60, 30, 1.2);
  const FollowStatus rotating = follow(graph(), path, 60, 30, 1.2);
  for (const FollowStatus* s : {&turning, &rotating}) {
    EXPECT_TRUE(s->done);
    EXPECT_LE(s->max_abs_error, 0.25);
    EXPECT_NEAR(s->travelled, s->s - s->s_start, 0.02 * (s->s - s->s_start));
  }
  EXPECT_GE(turning.turning_requests, 1);
  EXPECT_EQ(rotating.turning_requests, 0);
  // Without a turning space the root rotation makes all the turning; with one, the body's own
  // turning makes most of it.
  EXPECT_GT(rotating.root_turn, 0.9 * rotating.total_turn);
  EXPECT_LT(turning.root_turn, 0.5 * turning.total_turn);
}

TEST(RuntimeController, ReachPutsTheHandOnTheTarget) {
  const MotionGraph g = test::make_test_graph(false, 25, true);
  const GraphSpace& reach = g.spaces[g.find_space("reach")];
  const double height = 0.5 * (reach.parameter_min() + reach.parameter_max());
  for (const double x : {3.0, 3.35, 3.7, 4.05}) {
    Character c(g, TransitionOptions{});
    Controller control(c);
    ASSERT_TRUE(control.has_reach());
    c.reset(g.find_space("locomotion"), 1.2);
    const RequestStatus status = control.reach(x, 0.3, height);
    EXPECT_FALSE(status.clamped);
    for (int k = 0; k < 60 * 20 && !control.reach_status().done; ++k) c.step(1 / 60.0);
    // Sideways and in height the hand lands on the target; along the walk, within half a step
    // of the prediction's staircase (the reach is entered from a few favoured phases only).
    const ReachStatus& r = control.reach_status();
    EXPECT_TRUE(r.done) << x;
    EXPECT_NEAR(r.hand[1], 0.3, 0.05) << x;
    EXPECT_NEAR(r.hand[2], height, 0.05) << x;
    EXPECT_NEAR(r.hand[0], x, 0.35) << "target at x = " << x;
  }
  // Out of range: clamped and reported. Without a reach space: refused.
  Character c(g, TransitionOptions{});
  Controller control(c);
  EXPECT_TRUE(control.reach(3, 0, 10).clamped);
  Character plain(graph(), TransitionOptions{});
  Controller no_reach(plain);
  EXPECT_FALSE(no_reach.has_reach());
  EXPECT_EQ(no_reach.reach(3, 0, 1).result, RequestResult::kUnknownSpace);
}

TEST(GroundPath, RejectsBrokenPaths) {
  EXPECT_THROW(GroundPath(std::vector<BezierCurve>{}), InputError);
  EXPECT_THROW(GroundPath({BezierCurve{{Point2{0, 0}, Point2{1, 0}, Point2{2, 0}, Point2{3, 0}}},
                           BezierCurve{{Point2{3.5, 0}, Point2{4, 0}, Point2{5, 0}, Point2{6, 0}}}}),
               InputError);
  const GroundPath quarter({BezierCurve{{Point2{1, 0}, Point2{1, 0.5523}, Point2{0.5523, 1}, Point2{0, 1}}}});
  EXPECT_NEAR(quarter.length(), std::numbers::pi / 2, 2e-3);  // a quarter of the unit circle
  EXPECT_NEAR(quarter.closest({2, 2}, 0, quarter.length()), quarter.length() / 2, 0.01);
}

}  // namespace
}  // namespace fourd

namespace fourd {
namespace {

// A one-shot space that ends with no request goes on to the graph's default successor (here
// the locomotion it has an edge to) instead of freezing on its last frame.
TEST(Character, AOneShotSpaceEndingWithNoRequestGoesOnToItsDefaultSuccessor) {
  const MotionGraph graph = test::make_test_graph();
  const int jump = graph.find_space("jump_length"), loco = graph.find_space("locomotion");
  EXPECT_EQ(graph.default_successor(jump), loco);
  EXPECT_EQ(graph.default_successor(loco), -1);  // cyclic: it loops
  Character character(graph, TransitionOptions{});
  character.reset(jump, 0.9, 0.0);
  double last_x = 0;
  for (int f = 0; f < 150; ++f) {  // 6 s at 25 fps: the jump lasts about 1.3 s
    last_x = character.frame().root.x;
    character.step(0.04);
  }
  EXPECT_EQ(character.state().space, loco);
  EXPECT_EQ(character.state().phase, PlayPhase::kFree);
  // Still walking: the root moves on, at about the middle of the speed range's pace.
  EXPECT_GT(character.frame().root.x - last_x, 0.01);
  EXPECT_EQ(character.last_transition().from, jump);
  EXPECT_EQ(character.last_transition().to, loco);
}

}  // namespace
}  // namespace fourd
