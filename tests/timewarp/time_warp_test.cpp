// Root motion, cycle extraction and time registration on the synthetic walker, whose phase
// and root motion are known exactly.
#include "stages/timewarp/time_warp.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "pipeline/core/error.h"
#include "pipeline/exchange/root_motion.h"
#include "stages/timewarp/timewarp.h"
#include "tests/timewarp/walker.h"

namespace fourd::timewarp {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

// Circular distance between phases, in cycles (-0.5, 0.5].
double phase_difference(double a, double b) {
  double d = std::fmod(a - b, 1.0);
  if (d > 0.5) d -= 1;
  if (d <= -0.5) d += 1;
  return d;
}

LocalTake local_walk(const test::Walker& w, const test::WalkSpec& spec, const std::string& name) {
  const std::vector<double> torso = torso_weights(w.mesh.positions);
  return make_local_take(name, test::walk_frames(w, spec), w.mesh.positions, torso);
}

// A walk whose whole body also sways rigidly with the gait, as the torso of aligned meshes
// does: +-`lateral` m from side to side and +-`yaw` rad of heading, once per cycle. Its steady
// root is the walk's own root.
std::vector<Eigen::Matrix3Xd> swaying_walk(const test::Walker& w, const test::WalkSpec& spec,
                                           double lateral, double yaw) {
  std::vector<Eigen::Matrix3Xd> frames;
  for (int f = 0; f < spec.frames; ++f) {
    const double phase = test::walk_phase(spec, f);
    const RootTransform sway{0, lateral * std::sin(test::kTwoPi * phase),
                             yaw * std::sin(test::kTwoPi * phase + 1)};
    frames.push_back(apply_root(test::walk_shape(w, spec, phase),
                                root_compose(test::walk_root(spec, f), sway)));
  }
  return frames;
}

// Length of the ground-plane polyline through the roots over the distance between its ends.
double length_over_chord(const std::vector<RootTransform>& roots) {
  double length = 0;
  for (std::size_t i = 1; i < roots.size(); ++i) {
    length += (test::xy(roots[i]) - test::xy(roots[i - 1])).norm();
  }
  return length / (test::xy(roots.back()) - test::xy(roots.front())).norm();
}

TEST(RootMotion, TorsoIsTheUpperBodyNearTheAxis) {
  const test::Walker w = test::make_walker();
  const std::vector<double> torso = torso_weights(w.mesh.positions);
  double sum = 0;
  int selected = 0, legs = 0;
  for (int v = 0; v < static_cast<int>(torso.size()); ++v) {
    sum += torso[v];
    if (torso[v] > 0) {
      ++selected;
      if (v >= w.torso_end) ++legs;
    }
  }
  EXPECT_NEAR(sum, 1.0, 1e-12);
  EXPECT_GT(selected, 10);
  EXPECT_EQ(legs, 0);
}

TEST(RootMotion, RecoversARigidGroundPlaneMotion) {
  const test::Walker w = test::make_walker();
  const std::vector<double> torso = torso_weights(w.mesh.positions);
  const RootTransform root{1.3, -0.7, 2.9};  // close to +-pi: the heading must not flip
  const Eigen::Matrix3Xd moved = apply_root(w.mesh.positions, root);
  const RootTransform found = estimate_root(moved, w.mesh.positions, torso);
  EXPECT_NEAR(found.x, root.x, 1e-9);
  EXPECT_NEAR(found.y, root.y, 1e-9);
  EXPECT_NEAR(wrap_heading(found.heading - root.heading), 0.0, 1e-9);
  EXPECT_LT(test::max_vertex_distance(remove_root(moved, found), w.mesh.positions), 1e-9);
}

TEST(RootMotion, ComposeAndInverseAreConsistent) {
  const RootTransform a{0.5, 1.0, 0.7}, b{-0.2, 0.3, -2.0};
  const RootTransform ab = root_compose(a, b);
  EXPECT_LT((test::xyh(root_relative(a, ab)) - test::xyh(b)).norm(), 1e-12);
  EXPECT_LT(test::xyh(root_compose(a, root_inverse(a))).norm(), 1e-12);
  const Eigen::Matrix3Xd p = Eigen::Matrix3Xd::Random(3, 5);
  EXPECT_LT(test::max_vertex_distance(apply_root(apply_root(p, b), a), apply_root(p, ab)), 1e-12);
}

TEST(RootMotion, PowerMovesAlongTheScrew) {
  // A steady turning walk covers, in a fraction of its time, that fraction of its motion.
  test::WalkSpec spec;
  spec.speed = 1.3;
  spec.turn_rate = 40 * kDeg;
  const RootTransform whole = test::walk_root(spec, 25);
  for (double a : {0.0, 0.3, 1.0, 1.7, -0.4}) {
    EXPECT_LT((test::xyh(root_power(whole, a)) - test::xyh(test::walk_root(spec, 25 * a))).norm(), 1e-12) << a;
  }
  EXPECT_LT((test::xyh(root_power(RootTransform{0.8, -0.1, 0.0}, 0.25)) - Eigen::Vector3d(0.2, -0.025, 0.0)).norm(), 1e-12);
  const RootTransform a{0.5, 1.0, 2.5};
  EXPECT_LT((test::xyh(root_compose(root_power(a, 0.3), root_power(a, 0.7))) - test::xyh(a)).norm(), 1e-12);
}

TEST(RootMotion, HeadingsOfATurningWalkAreUnwrapped) {
  const test::Walker w = test::make_walker();
  test::WalkSpec spec;
  spec.turn_rate = 180 * kDeg;  // half a turn per second: crosses +-pi within the take
  spec.frames = 40;
  spec.start_heading = 150 * kDeg;
  const LocalTake take = local_walk(w, spec, "turn");
  for (int f = 0; f < spec.frames; ++f) {
    // The torso twists by up to 0.05 rad with the gait; the root follows the walk's heading.
    EXPECT_NEAR(take.roots[f].heading, test::walk_root(spec, f).heading, 0.06) << "frame " << f;
  }
}

// Frame-to-frame jitter on a steady walk's root is damped, a slow sway (40 frames a period)
// is kept, and the ends stay where they were.
TEST(RootMotion, SmoothingDampsJitterAndKeepsSlowSway) {
  std::vector<RootTransform> roots;
  for (int f = 0; f < 60; ++f) {
    const double jitter = (f % 2 ? 1 : -1) * 0.01;  // 1 cm, alternating every frame
    const double sway = 0.03 * std::sin(2 * std::numbers::pi * f / 40.0);
    roots.push_back({0.05 * f, sway + jitter, 0.002 * f});
  }
  const std::vector<RootTransform> before = roots;
  smooth_roots(&roots, 8);
  EXPECT_EQ(roots.front(), before.front());
  EXPECT_EQ(roots.back(), before.back());
  double jitter_left = 0, sway_kept = 0;
  for (int f = 10; f < 50; ++f) {
    const double sway = 0.03 * std::sin(2 * std::numbers::pi * f / 40.0);
    jitter_left = std::max(jitter_left, std::abs(roots[f].y - sway));
    sway_kept = std::max(sway_kept, std::abs(roots[f].y));
    EXPECT_NEAR(roots[f].x, 0.05 * f, 1e-9);  // a straight line is left alone
    EXPECT_NEAR(roots[f].heading, 0.002 * f, 1e-9);
  }
  EXPECT_LT(jitter_left, 0.003);  // 1 cm of jitter -> under 3 mm (sway attenuated a little)
  EXPECT_GT(sway_kept, 0.025);
}

TEST(Cycle, FindsAFractionalPeriodAndClosesIt) {
  const test::Walker w = test::make_walker();
  for (double period : {12.0, 12.5, 15.3}) {
    test::WalkSpec spec;
    spec.cycle_frames = period;
    spec.frames = 30;
    spec.turn_rate = 20 * kDeg;
    const LocalTake take = local_walk(w, spec, "walk");
    const Cycle c = find_cycle(take, CycleOptions{});
    EXPECT_NEAR(c.period, period, 0.1) << "period " << period;
    EXPECT_LT(c.closure_rms, 0.1 * c.variation_rms);
    // The closure-corrected cycle joins its start exactly.
    const TakeTiming timing = cyclic_timing(c);
    EXPECT_LT(test::max_vertex_distance(shape_at_phase(take, timing, 0.0),
                                        shape_at_phase(take, timing, 1.0 - 1e-12)),
              1e-6);
  }
}

TEST(Cycle, RootOfTheNextCycleContinuesTheMotion) {
  const test::Walker w = test::make_walker();
  test::WalkSpec spec;
  spec.cycle_frames = 12;
  spec.frames = 13;
  spec.turn_rate = 30 * kDeg;
  const LocalTake take = local_walk(w, spec, "walk");
  const TakeTiming timing = cyclic_timing(Cycle{0, 12, 0, 1});
  // Phase 1.5 lies in the next cycle: the walk's root 18 frames on, although the take ends at 12.
  const RootTransform r = root_at_phase(take, timing, 1.5);
  const RootTransform truth = test::walk_root(spec, 18);
  EXPECT_NEAR(r.x, truth.x, 0.02);
  EXPECT_NEAR(r.y, truth.y, 0.02);
  EXPECT_NEAR(r.heading, truth.heading, 0.06);
}

// The per-frame roots of a swaying walk weave; its steady root is the walk's own, and the
// sway stays in the shapes (the frames are unchanged).
TEST(Cycle, SteadyRootLeavesTheSwayInTheShape) {
  const test::Walker w = test::make_walker();
  const std::vector<double> torso = torso_weights(w.mesh.positions);
  for (double turn : {0.0, 30.0}) {
    test::WalkSpec spec;
    spec.cycle_frames = 15;
    spec.frames = 40;
    spec.turn_rate = turn * kDeg;
    spec.start_heading = 2.0;
    spec.start_position = {3.0, -5.0};
    const std::vector<Eigen::Matrix3Xd> frames = swaying_walk(w, spec, 0.05, 0.25);
    const LocalTake take = make_local_take("sway", frames, w.mesh.positions, torso, 8);
    const TakeTiming timing = cyclic_timing(find_cycle(take, CycleOptions{}));
    const LocalTake steady = steady_cycle_root(take, timing);
    std::vector<RootTransform> truth, cycle_weaving, cycle_steady;
    for (int f = 0; f < spec.frames; ++f) {
      truth.push_back(test::walk_root(spec, f));
      EXPECT_LT(test::max_vertex_distance(apply_root(steady.shapes[f], steady.roots[f]), frames[f]),
                1e-9);
      if (f < timing.start || f > timing.start + timing.length) continue;
      // Over the cycle (beyond it, the small error of the turn per cycle accumulates).
      EXPECT_LT((test::xy(steady.roots[f]) - test::xy(truth[f])).norm(), 0.005)
          << "turn " << turn << " frame " << f;
      EXPECT_NEAR(steady.roots[f].heading, truth[f].heading, 0.5 * kDeg) << "turn " << turn << " frame " << f;
    }
    std::vector<RootTransform> cycle_truth;
    for (int i = 0; i <= 60; ++i) {  // the cycle, 4 samples per frame
      const double x = timing.start + i / 60.0 * timing.length;
      cycle_truth.push_back(test::walk_root(spec, x));
      cycle_weaving.push_back(root_at(take, x));
      cycle_steady.push_back(root_at(steady, x));
    }
    const double true_ratio = length_over_chord(cycle_truth);
    EXPECT_NEAR(length_over_chord(cycle_steady), true_ratio, 0.002) << "turn " << turn;
    // The per-frame roots weave (this test means something).
    EXPECT_GT(length_over_chord(cycle_weaving), true_ratio + 0.01) << "turn " << turn;
  }
}

// The timewarp of a class of swaying walks: every take's root curve over the cycle is as
// straight (or as steadily curved) as the walk's, its heading turns at a constant rate, and the
// cycle still advances by the walk's motion.
TEST(Cycle, WarpedCyclesHaveSteadyRoots) {
  const test::Walker w = test::make_walker();
  const std::vector<double> torso = torso_weights(w.mesh.positions);
  for (double turn : {0.0, 30.0}) {
    std::vector<test::WalkSpec> specs(2);
    specs[0].cycle_frames = 15;
    specs[1].cycle_frames = 12;
    specs[1].speed = 1.6;
    specs[1].start_phase = 0.3;
    std::vector<LocalTake> takes;
    for (test::WalkSpec& s : specs) {
      s.frames = 30;
      s.turn_rate = turn * kDeg;
      takes.push_back(make_local_take(takes.empty() ? "slow" : "fast",
                                      swaying_walk(w, s, 0.05, 0.25), w.mesh.positions, torso, 8));
    }
    const MotionClassConfig motion{"walks", {"slow", "fast"}, "speed", true};
    const WarpedClass warped = warp_class(motion, 25, test::walker_mesh(w), std::move(takes), {});
    for (std::size_t k = 0; k < specs.size(); ++k) {
      const WarpedTake& t = warped.takes[k];
      const double seconds = t.seconds.back();
      std::vector<RootTransform> truth;
      for (int i = 0; i <= 60; ++i) truth.push_back(test::walk_root(specs[k], i / 60.0 * specs[k].cycle_frames));
      EXPECT_NEAR(length_over_chord(t.roots), length_over_chord(truth), 0.002) << t.name << " turn " << turn;
      EXPECT_NEAR(seconds, specs[k].cycle_frames / 25, 0.01) << t.name;
      const RootTransform& end = t.roots.back();
      EXPECT_NEAR(std::hypot(end.x, end.y), (test::xy(truth.back()) - test::xy(truth.front())).norm(), 0.01) << t.name;
      EXPECT_NEAR(end.heading, specs[k].turn_rate * seconds, 1 * kDeg) << t.name;
      for (std::size_t i = 0; i < t.roots.size(); ++i) {
        EXPECT_NEAR(t.roots[i].heading, end.heading * t.seconds[i] / seconds, 0.5 * kDeg)
            << t.name << " turn " << turn << " sample " << i;
      }
    }
  }
}

TEST(Cycle, ATakeShorterThanACycleCannotBeClosed) {
  const test::Walker w = test::make_walker();
  test::WalkSpec spec;
  spec.cycle_frames = 20;
  spec.frames = 12;  // only 60 % of a cycle
  const LocalTake take = local_walk(w, spec, "walk_short");
  try {
    find_cycle(take, CycleOptions{});
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("walk_short"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("cannot close"), std::string::npos) << e.what();
  }
  spec.frames = 3;
  EXPECT_THROW(find_cycle(local_walk(w, spec, "tiny"), CycleOptions{}), InputError);
}

TEST(Register, CyclesOfDifferentPeriodsAndStartsShareThePhase) {
  const test::Walker w = test::make_walker();
  test::WalkSpec slow;
  slow.cycle_frames = 15;
  slow.frames = 18;
  slow.start_phase = 0.1;
  test::WalkSpec fast = slow;
  fast.amplitude = 0.5;
  fast.cycle_frames = 11.5;
  fast.speed = 1.7;
  fast.start_phase = 0.65;
  fast.turn_rate = 15 * kDeg;
  const LocalTake a = local_walk(w, slow, "slow"), b = local_walk(w, fast, "fast");
  const TakeTiming ta = cyclic_timing(find_cycle(a, CycleOptions{}));
  const TakeTiming tb = cyclic_timing(find_cycle(b, CycleOptions{}));
  const Warp warp = register_take(a, ta, b, tb, WarpOptions{});
  // At reference phase u, take b must be at the same gait phase as the reference.
  for (int i = 0; i <= 20; ++i) {
    const double u = i / 20.0;
    const double phase_a = slow.start_phase + ta.frame_at(u) / slow.cycle_frames;
    const double phase_b = fast.start_phase + tb.frame_at(warp.at(u)) / fast.cycle_frames;
    EXPECT_LT(std::abs(phase_difference(phase_a, phase_b)) * fast.cycle_frames, 0.25)
        << "u " << u;
  }
  // The inverse maps back.
  for (double u : {0.1, 0.37, 0.8}) EXPECT_NEAR(warp.inverse(warp.at(u)), u, 1e-9);
}

TEST(Register, OneShotsWithANonUniformTimingAreAligned) {
  const test::Walker w = test::make_walker();
  const std::vector<double> torso = torso_weights(w.mesh.positions);
  test::JumpSpec a_spec;
  test::JumpSpec b_spec;
  b_spec.length = 1.1;
  b_spec.height = 0.25;
  b_spec.frames = 30;
  b_spec.time_power = 1.4;  // b runs through the jump non-uniformly
  const LocalTake a =
      make_local_take("short", test::jump_frames(w, a_spec), w.mesh.positions, torso);
  const LocalTake b = make_local_take("long", test::jump_frames(w, b_spec), w.mesh.positions, torso);
  const Warp warp = register_take(a, one_shot_timing(a), b, one_shot_timing(b), WarpOptions{});
  double error = 0;
  int count = 0;
  for (int f = 0; f < a_spec.frames; ++f) {
    const double u = static_cast<double>(f) / (a_spec.frames - 1);
    // Same normalised jump time u in both: b's frame is the one with jump_time == u.
    const double b_frame = std::pow(u, 1 / b_spec.time_power) * (b_spec.frames - 1);
    error += std::abs(one_shot_timing(b).frame_at(warp.at(u)) - b_frame);
    ++count;
  }
  EXPECT_LT(error / count, 0.5);  // mean error [frames of b]
}

}  // namespace
}  // namespace fourd::timewarp
