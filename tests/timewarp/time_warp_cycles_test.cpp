// Periods and cycles of synthetic periodic motions whose period is known: non-integer periods,
// motions that nearly repeat at a sub-multiple of their period (a quadruped's limb pairs in
// antiphase), takes of little more than one cycle (as the sample's), and a long take with
// several cycles and pauses.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <random>

#include "stages/synth/character.h"
#include "stages/synth/motion.h"
#include "stages/timewarp/time_warp.h"
#include "stages/timewarp/timewarp.h"

namespace fourd::timewarp {
namespace {

constexpr double kTwoPi = 2 * std::numbers::pi;

// A body as a function of its gait phase (cycles), 3 x #V.
using Body = std::function<Eigen::Matrix3Xd(double phase)>;

// One limb: `count` points hanging from `hip`, swinging forward and back by `swing` m at the
// foot with the phase `offset` (cycles), the foot lifted while it swings forward.
void add_limb(Eigen::Matrix3Xd* x, int* at, const Eigen::Vector3d& hip, double length,
              double swing, double phase, int count) {
  const double a = kTwoPi * phase;
  for (int k = 1; k <= count; ++k) {
    const double f = static_cast<double>(k) / count;
    x->col((*at)++) = hip + Eigen::Vector3d(f * swing * std::sin(a),
                                            0, -f * length + 0.3 * f * swing * std::max(0.0, std::cos(a)));
  }
}

// A biped: two legs and two arms in antiphase, the torso bobbing twice per cycle.
Eigen::Matrix3Xd biped(double phase) {
  Eigen::Matrix3Xd x(3, 4 * 4 + 8);
  int at = 0;
  add_limb(&x, &at, {0, 0.1, 0.9}, 0.9, 0.35, phase, 4);
  add_limb(&x, &at, {0, -0.1, 0.9}, 0.9, 0.35, phase + 0.5, 4);
  add_limb(&x, &at, {0, 0.2, 1.4}, 0.6, 0.15, phase + 0.5, 4);
  add_limb(&x, &at, {0, -0.2, 1.4}, 0.6, 0.15, phase, 4);
  const double bob = 0.03 * std::cos(2 * kTwoPi * phase);
  for (int k = 0; k < 8; ++k) x.col(at++) = Eigen::Vector3d(0.02 * (k % 2), 0, 0.9 + 0.1 * k + bob);
  return x;
}

// A quadruped: a long body that bobs and pitches twice per stride (large), and thin legs whose
// left and right limb of each pair swing in antiphase (small): half a stride later the legs
// have only swapped sides, so the shape nearly repeats at half the period.
Eigen::Matrix3Xd quadruped(double phase, double hind_offset) {
  const int body = 24;
  Eigen::Matrix3Xd x(3, body + 4 * 3);
  int at = 0;
  const double a2 = 2 * kTwoPi * phase;
  for (int k = 0; k < body; ++k) {
    const double s = -0.6 + 1.2 * k / (body - 1);  // along the spine
    x.col(at++) = Eigen::Vector3d(s, 0.03 * ((k % 3) - 1), 0.8 + 0.08 * std::cos(a2) + 0.25 * s * std::sin(a2));
  }
  add_limb(&x, &at, {0.55, 0.06, 0.8}, 0.8, 0.08, phase, 3);
  add_limb(&x, &at, {0.55, -0.06, 0.8}, 0.8, 0.08, phase + 0.5, 3);
  add_limb(&x, &at, {-0.55, 0.06, 0.8}, 0.8, 0.08, phase + hind_offset, 3);
  add_limb(&x, &at, {-0.55, -0.06, 0.8}, 0.8, 0.08, phase + hind_offset + 0.5, 3);
  return x;
}

// A point that moves at twice the frequency with amplitude 1 and at the fundamental with
// amplitude `fundamental`: it repeats exactly only once per period, nearly at half of it.
Eigen::Matrix3Xd harmonic(double phase, double fundamental) {
  Eigen::Matrix3Xd x(3, 6);
  for (int k = 0; k < 6; ++k) {
    const double d = 0.1 * k;
    x.col(k) = Eigen::Vector3d(std::sin(2 * kTwoPi * phase + d) + fundamental * std::sin(kTwoPi * phase + 3 * d),
                               std::cos(2 * kTwoPi * phase + d), fundamental * std::cos(kTwoPi * phase));
  }
  return 0.2 * x;
}

// The take of `frames` frames of a body whose phase advances 1 / period per frame, with 1 mm of
// noise (seeded).
LocalTake make_take(const std::string& name, const Body& body, double period, int frames,
                    double start_phase = 0.13) {
  LocalTake take;
  take.name = name;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.001);
  for (int f = 0; f < frames; ++f) {
    Eigen::Matrix3Xd x = body(start_phase + f / period);
    for (Eigen::Index i = 0; i < x.size(); ++i) x.data()[i] += noise(rng);
    take.shapes.push_back(x);
    take.roots.push_back(RootTransform{});
  }
  return take;
}

struct Case {
  std::string name;
  Body body;
  double period;
  int frames;
};

std::vector<Case> periodic_cases() {
  std::vector<Case> cases;
  for (double p : {9.3, 13.7, 16.0, 24.4}) {
    cases.push_back({"biped_" + std::to_string(p).substr(0, 4), biped, p,
                     static_cast<int>(std::lround(3.2 * p))});
  }
  // Little more than one cycle, as the sample's takes at 12 fps.
  cases.push_back({"biped_short_13.7", biped, 13.7, 20});
  cases.push_back({"biped_short_17.2", biped, 17.2, 25});
  // Quadrupeds: a gallop (hind pair a quarter stride after the front) and a trot (diagonal
  // pairs together), the period of the gallop and a non-integer one.
  cases.push_back({"gallop_24", [](double u) { return quadruped(u, 0.25); }, 24.0, 80});
  cases.push_back({"gallop_18.6", [](double u) { return quadruped(u, 0.25); }, 18.6, 60});
  cases.push_back({"trot_17.5", [](double u) { return quadruped(u, 0.5); }, 17.5, 60});
  // Sub-multiple traps: the second harmonic dominates.
  cases.push_back({"harmonic_20", [](double u) { return harmonic(u, 0.3); }, 20.0, 64});
  cases.push_back({"harmonic_15.4", [](double u) { return harmonic(u, 0.3); }, 15.4, 50});
  return cases;
}

TEST(Period, WithinHalfAFrameOfTheTruthOnEveryPeriodicTake) {
  for (const Case& c : periodic_cases()) {
    const LocalTake take = make_take(c.name, c.body, c.period, c.frames);
    const double p = find_period(take, CycleOptions{});
    EXPECT_NEAR(p, c.period, 0.5) << c.name;
    RecordProperty(c.name, std::to_string(p));
    std::printf("period %-18s truth %6.2f found %6.2f\n", c.name.c_str(), c.period, p);
    const Cycle cycle = find_cycle(take, CycleOptions{});
    EXPECT_NEAR(cycle.period, c.period, 0.5) << c.name;
    EXPECT_LT(cycle.closure_ratio, 0.3) << c.name;
  }
}

// A loose part that moves a lot but repeats at no lag (a skirt's chaotic swing, as synth's
// dance_skirt walks: their body repeats to 0.0 mm, the skirt by 20-100 mm RMS a gait cycle
// later however long the walk) is left out of the cycle's scores: a biped with a third more
// points, each on a random walk of 3 cm a frame, has the biped's own period and a cycle that
// closes, on a take of little more than one cycle as on three.
TEST(Period, ALoosePartThatRepeatsAtNoLagIsLeftOut) {
  for (const auto& [period, frames] : {std::pair{17.2, 21}, std::pair{13.7, 44}}) {
    constexpr int kLoose = 8;
    std::mt19937 rng(11);
    std::normal_distribution<double> step(0.0, 0.03);
    std::vector<Eigen::Matrix3Xd> loose(static_cast<std::size_t>(frames), Eigen::Matrix3Xd(3, kLoose));
    for (int k = 0; k < kLoose; ++k) loose[0].col(k) = Eigen::Vector3d(0.1 * k - 0.35, 0.2, 0.6);
    for (int f = 1; f < frames; ++f) {
      loose[static_cast<std::size_t>(f)] = loose[static_cast<std::size_t>(f) - 1];
      for (Eigen::Index i = 0; i < loose[0].size(); ++i) loose[static_cast<std::size_t>(f)].data()[i] += step(rng);
    }
    constexpr double kStart = 0.13;  // make_take's
    const Body body = [&, period = period](double u) {
      const Eigen::Matrix3Xd b = biped(u);
      Eigen::Matrix3Xd x(3, b.cols() + kLoose);
      x << b, loose[static_cast<std::size_t>(std::lround((u - kStart) * period))];
      return x;
    };
    const LocalTake take = make_take("loose", body, period, frames, kStart);
    const double p = find_period(take, CycleOptions{});
    EXPECT_NEAR(p, period, 0.5) << frames;
    const Cycle cycle = find_cycle(take, CycleOptions{});  // throws where it cannot close
    EXPECT_NEAR(cycle.period, period, 0.5) << frames;
    EXPECT_LE(cycle.closure_ratio, 0.3) << frames;
    // The loose part does not close there: the whole surface ends several times further from
    // its start than the part the cycle is scored on.
    const double whole = std::sqrt(shape_distance(shape_at(take, cycle.start), shape_at(take, cycle.start + cycle.period)));
    EXPECT_GT(whole, 3 * cycle.closure_rms) << frames;
    std::printf("biped with a loose part, %d frames: period %.2f (truth %.1f), closure ratio %.2f, %.1f mm (all of "
                "it %.1f mm)\n", frames, p, period, cycle.closure_ratio, 1000 * cycle.closure_rms, 1000 * whole);
  }
}

// The trap is real: half the period repeats the shape nearly as well as the full period,
// within a fifth of the range of the mean distance over the lags (the rule that took half a
// stride for a stride), yet clearly worse than the full period.
TEST(Period, TheQuadrupedNearlyRepeatsAtHalfItsPeriod) {
  const LocalTake take = make_take("gallop", [](double u) { return quadruped(u, 0.25); }, 24, 80);
  auto mean_distance = [&](int lag) {
    double sum = 0;
    for (int f = 0; f + lag < take.num_frames(); ++f) sum += shape_distance(take.shapes[f], take.shapes[f + lag]);
    return sum / (take.num_frames() - lag);
  };
  double hi = 0;
  for (int lag = 4; lag < 60; ++lag) hi = std::max(hi, mean_distance(lag));
  const double half = mean_distance(12), full = mean_distance(24);
  std::printf("gallop: mean distance at half %.3g, full %.3g, largest %.3g\n", half, full, hi);
  EXPECT_LT(half - full, 0.2 * (hi - full));
  EXPECT_GT(half, 5 * full);
}

TEST(Cycles, ALongTakeYieldsItsCyclesAndItsPausesAsOneShots) {
  // Three cycles, a pause holding the pose, three cycles, a pause; 14.3 frames a cycle.
  const double period = 14.3;
  std::vector<double> phases;
  double u = 0.1;
  auto walk = [&](int frames) {
    for (int f = 0; f < frames; ++f) phases.push_back(u += 1 / period);
  };
  auto pause = [&](int frames) {
    for (int f = 0; f < frames; ++f) phases.push_back(u);
  };
  walk(43);
  pause(20);
  walk(43);
  pause(14);
  LocalTake take;
  take.name = "long";
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.001);
  for (double phase : phases) {
    Eigen::Matrix3Xd x = biped(phase);
    for (Eigen::Index i = 0; i < x.size(); ++i) x.data()[i] += noise(rng);
    take.shapes.push_back(x);
    take.roots.push_back(RootTransform{});
  }
  const TakeSegments s = find_cycles(take, CycleOptions{});
  EXPECT_NEAR(s.period, period, 0.5);
  EXPECT_GE(s.cycles.size(), 4u);
  for (const Cycle& c : s.cycles) {
    EXPECT_NEAR(c.period, period, 0.5) << "cycle at " << c.start;
    EXPECT_LE(c.closure_ratio, 0.3);
    // A cycle lies in a walking stretch, not across a pause.
    const bool first = c.start >= 0 && c.start + c.period <= 43 + 0.5;
    const bool second = c.start >= 63 - 0.5 && c.start + c.period <= 106 + 0.5;
    EXPECT_TRUE(first || second) << "cycle " << c.start << " + " << c.period;
  }
  // The pauses are offered as one-shot segments.
  auto covered = [&](int a, int b) {
    for (const FrameRange& r : s.one_shots) {
      if (r.first <= a && r.last >= b) return true;
    }
    return false;
  };
  EXPECT_TRUE(covered(45, 61));
  EXPECT_TRUE(covered(108, 119));
  std::printf("long take: period %.2f, %zu cycles, %zu one-shot segments\n", s.period,
              s.cycles.size(), s.one_shots.size());
}

// Every 8th vertex of a mesh (the test's cost; a cycle is as clear on 600 vertices as on 5,000).
Eigen::Matrix3Xd positions(const Mesh& mesh) {
  constexpr std::size_t kStride = 8;
  Eigen::Matrix3Xd x(3, static_cast<Eigen::Index>((mesh.positions.size() + kStride - 1) / kStride));
  for (std::size_t v = 0; v < mesh.positions.size(); v += kStride) {
    x.col(static_cast<Eigen::Index>(v / kStride)) = mesh.positions[v].cast<double>();
  }
  return x;
}

// Synth's performer walking round a circle at 12 fps with two stands (slowing to a stop,
// standing still, setting off) in a take of 260 frames, as variants/long_take_pauses: its root-removed take, as the stage
// makes it from aligned meshes, and the clip.
struct PausingWalk {
  synth::MotionClip clip;
  LocalTake take;
};

PausingWalk pausing_walk() {
  synth::CharacterOptions options;
  options.texture_size = 256;
  const synth::Character performer = synth::make_procedural_character(options, 1);
  synth::MotionSpec spec;
  spec.take = "circle_pauses";
  spec.kind = "turn";
  spec.frames = 260;
  spec.speed = 1.1;
  spec.turn_rate = 60;
  spec.pauses = {synth::PauseSpec{62, 18}, synth::PauseSpec{173, 18}};
  PausingWalk w;
  w.clip = synth::generate_motion(performer.skeleton, spec, 12.0);
  std::vector<Eigen::Matrix3Xd> frames;
  for (const synth::Pose& pose : w.clip.poses) {
    frames.push_back(positions(synth::skin_mesh(performer.skin, synth::forward_kinematics(performer.skeleton, pose))));
  }
  const Eigen::Matrix3Xd templ = positions(performer.skin.rest);
  w.take = make_local_take(spec.take, std::move(frames), templ, torso_weights(templ), 8);
  return w;
}

// The walking bouts' period is found through the stands, every cycle lies within a bout, each
// stand is offered as a one-shot segment, the cycle a class loops is not a stand, and its
// steady root turns at the full pace.
TEST(Cycles, ThePerformersWalkWithPausesLoopsItsBoutsAndOffersItsStands) {
  const PausingWalk w = pausing_walk();
  const TakeSegments s = find_cycles(w.take, CycleOptions{});
  const double truth = w.clip.cycle_frames;
  EXPECT_NEAR(s.period, truth, 0.5);
  EXPECT_NEAR(find_period(w.take, CycleOptions{}), truth, 0.5);
  ASSERT_GE(s.cycles.size(), 3u);
  for (const Cycle& c : s.cycles) {
    EXPECT_NEAR(c.period, truth, 0.15 * truth) << "cycle at " << c.start;
    // No cycle takes in a stand: somewhere in it the gait is under way, not standing.
    for (int f = static_cast<int>(std::ceil(c.start)); f <= static_cast<int>(c.start + c.period); ++f) {
      EXPECT_GT(w.clip.amplitude[static_cast<std::size_t>(f)], 0.0) << "cycle " << c.start << " + " << c.period;
    }
  }
  for (const synth::PauseSpec& p : w.clip.spec.pauses) {
    bool offered = false;
    for (const FrameRange& r : s.one_shots) offered |= r.first <= p.at && r.last >= p.at + p.frames - 1;
    EXPECT_TRUE(offered) << "the stand from frame " << p.at;
  }
  // The class's cycle: where the take closes best while it moves. A stand closes better still
  // (1.6 mm) but is no cycle (its state varies three times less than it fails to close).
  const Cycle c = find_cycle(w.take, CycleOptions{});
  EXPECT_LE(c.closure_ratio, 0.3);
  EXPECT_NEAR(c.period, truth, 0.5);
  for (int f = static_cast<int>(std::ceil(c.start)); f <= static_cast<int>(c.start + c.period); ++f) {
    EXPECT_EQ(w.clip.amplitude[static_cast<std::size_t>(f)], 1.0) << "the class's cycle " << c.start;
  }
  // Its steady root turns as the walk does at full pace: the mean motion per cycle is taken
  // over the windows that close as cycles; over the whole take, the stands would slow it to
  // about half.
  const TakeTiming timing = cyclic_timing(c);
  auto turn = [&](const LocalTake& take) {
    return root_at(take, c.start + c.period).heading - root_at(take, c.start).heading;
  };
  const double true_turn = w.clip.root[239 + 14].heading - w.clip.root[239].heading;
  const double looping = turn(steady_cycle_root(w.take, timing));
  const double whole = turn(steady_cycle_root(w.take, timing, CycleOptions{.max_closure_ratio = 1e9}));
  EXPECT_NEAR(looping, true_turn * c.period / truth, 1.5 * std::numbers::pi / 180);
  EXPECT_LT(whole, 0.75 * looping);
  std::printf("walk with pauses: period %.2f (truth %.0f), %zu cycles, %zu one-shot segments, the class's cycle "
              "%.2f + %.2f turning %.1f deg (truth %.1f; %.1f measured over the whole take)\n", s.period, truth,
              s.cycles.size(), s.one_shots.size(), c.start, c.period, looping * 180 / std::numbers::pi,
              true_turn * c.period / truth * 180 / std::numbers::pi, whole * 180 / std::numbers::pi);
}

TEST(Cycles, AMotionThatDoesNotLoopIsOneOneShot) {
  LocalTake take;
  take.name = "reach";
  for (int f = 0; f < 30; ++f) {
    const double a = f / 29.0;
    Eigen::Matrix3Xd x = biped(0.0);
    x.row(2) += Eigen::RowVectorXd::Constant(x.cols(), 0.5 * a * a);
    take.shapes.push_back(x);
    take.roots.push_back(RootTransform{});
  }
  const TakeSegments s = find_cycles(take, CycleOptions{});
  EXPECT_TRUE(s.cycles.empty());
  ASSERT_EQ(s.one_shots.size(), 1u);
  EXPECT_EQ(s.one_shots[0].first, 0);
  EXPECT_EQ(s.one_shots[0].last, 29);
}

}  // namespace
}  // namespace fourd::timewarp
