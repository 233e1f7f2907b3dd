#include "stages/synth/motion.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "pipeline/core/error.h"
#include "pipeline/geometry/repair.h"
#include "tests/synth/debug_render.h"
#include "tests/synth/mesh_checks.h"
#include "tests/synth/motion_specs.h"

namespace fourd::synth {
namespace {

using test::dance;
using test::lowest;
using test::lowest_vertex;
using test::jump;
using test::make_spec;
using test::reach;
using test::run;
using test::turn;
using test::walk;

constexpr double kFps = 25;
constexpr double kGravity = 9.81;

const Character& performer() {
  static const Character character = [] {
    CharacterOptions options;
    options.texture_size = 256;
    return make_procedural_character(options, 1);
  }();
  return character;
}

double parameter(const MotionClip& clip, const std::string& name) {
  for (const auto& [key, value] : clip.parameters) {
    if (key == name) return value;
  }
  ADD_FAILURE() << "no parameter " << name;
  return std::nan("");
}

Eigen::Vector3d joint(const MotionClip& clip, int frame, const std::string& name) {
  const Skeleton& sk = performer().skeleton;
  return forward_kinematics(sk, clip.poses[static_cast<std::size_t>(frame)])[static_cast<std::size_t>(sk.find(name))].translation();
}

// Vertices carried mostly by a foot (foot + toe joints) of one side.
std::vector<int> foot_vertices(const std::string& side) {
  const Character& c = performer();
  const int foot = c.skeleton.find("foot_" + side), toe = c.skeleton.find("toe_" + side);
  std::vector<int> out;
  for (std::size_t v = 0; v < c.skin.weights.size(); ++v) {
    float w = 0;
    for (int k = 0; k < 4; ++k) {
      if (c.skin.joints[v][k] == foot || c.skin.joints[v][k] == toe) w += c.skin.weights[v][k];
    }
    if (w > 0.99f) out.push_back(static_cast<int>(v));
  }
  return out;
}

std::vector<Mesh> skin_all(const MotionClip& clip) {
  std::vector<Mesh> meshes;
  for (const Pose& pose : clip.poses) {
    meshes.push_back(skin_mesh(performer().skin, forward_kinematics(performer().skeleton, pose)));
  }
  return meshes;
}

constexpr float kContact = 0.005f;  // a foot touches the floor when its lowest point is this low

// For each run of frames in which a foot touches the floor: some point of the sole that is on
// the floor mid-run stays within `worst` (horizontally) of where it was mid-run, for the whole
// run. Returns the largest such drift over all runs and both feet.
double worst_stance_drift(const std::vector<Mesh>& meshes, int* runs) {
  double worst = 0;
  *runs = 0;
  for (const std::string side : {"l", "r"}) {
    const std::vector<int> foot = foot_vertices(side);
    const int n = static_cast<int>(meshes.size());
    for (int f = 0; f < n;) {
      if (lowest(meshes[f], foot) > kContact) {
        ++f;
        continue;
      }
      int end = f;
      while (end < n && lowest(meshes[end], foot) <= kContact) ++end;
      const int mid = (f + end - 1) / 2;
      double best = std::numeric_limits<double>::max();
      for (int v : foot) {
        const Vec3f& p = meshes[mid].positions[static_cast<std::size_t>(v)];
        if (p.z() > kContact) continue;
        double drift = 0;
        for (int g = f; g < end; ++g) {
          drift = std::max(drift, static_cast<double>((meshes[g].positions[static_cast<std::size_t>(v)] - p).head<2>().norm()));
        }
        best = std::min(best, drift);
      }
      worst = std::max(worst, best);
      ++*runs;
      f = end;
    }
  }
  return worst;
}

// Frames in which neither foot touches the floor.
int flight_frames(const std::vector<Mesh>& meshes) {
  const auto left = foot_vertices("l"), right = foot_vertices("r");
  int count = 0;
  for (const Mesh& m : meshes) count += lowest(m, left) > kContact && lowest(m, right) > kContact;
  return count;
}

void expect_continuous(const MotionClip& clip, double max_step) {
  ASSERT_EQ(clip.poses.size(), static_cast<std::size_t>(clip.spec.frames));
  ASSERT_EQ(clip.root.size(), clip.poses.size());
  ASSERT_EQ(clip.phase.size(), clip.poses.size());
  const Skeleton& sk = performer().skeleton;
  auto previous = forward_kinematics(sk, clip.poses[0]);
  for (std::size_t f = 1; f < clip.poses.size(); ++f) {
    const auto world = forward_kinematics(sk, clip.poses[f]);
    for (std::size_t j = 0; j < world.size(); ++j) {
      EXPECT_LT((world[j].translation() - previous[j].translation()).norm(), max_step)
          << clip.spec.take << " joint " << sk.names[j] << " frame " << f;
    }
    previous = world;
    EXPECT_GE(clip.phase[f], 0.0);
    EXPECT_LT(clip.phase[f], 1.0);
  }
}

// A gait on the floor: its feet do not slide while they stand (some sole point within 2 cm),
// it has at least `min_stances` stances, no vertex is below the floor and no joint jumps.
void expect_feet_planted(const MotionClip& clip, const std::vector<Mesh>& meshes, int min_stances) {
  int runs = 0;
  EXPECT_LT(worst_stance_drift(meshes, &runs), 0.02) << clip.spec.take;
  EXPECT_GE(runs, min_stances) << clip.spec.take;
  EXPECT_GE(lowest_vertex(meshes), -0.01f) << clip.spec.take;
  expect_continuous(clip, 0.25);
}

TEST(Motion, WalkSpeedIsExactAndStrideAndCadenceGrowWithSpeed) {
  double previous_speed = 0, previous_stride = 0, previous_cycle = 1e9;
  for (double speed : {0.8, 1.3, 1.8}) {
    const MotionClip clip = generate_motion(performer().skeleton, walk(speed), kFps);
    EXPECT_NEAR(parameter(clip, "speed"), speed, 1e-6 * speed);
    EXPECT_NEAR(parameter(clip, "direction_deg_per_s"), 0.0, 1e-9);
    // Independently: the pelvis over whole cycles travels at the speed (its sway averages out).
    const int cycle = static_cast<int>(clip.cycle_frames);
    ASSERT_EQ(clip.cycle_frames, cycle);
    const int whole = (clip.spec.frames - 1) / cycle * cycle;
    ASSERT_GT(whole, 0);
    const double pelvis_speed = (joint(clip, whole, "pelvis") - joint(clip, 0, "pelvis")).head<2>().norm() / (whole / kFps);
    EXPECT_NEAR(pelvis_speed, speed, 1e-6);
    EXPECT_GT(pelvis_speed, previous_speed);
    // Stride: one left foot's stance to the next, one cycle apart.
    const double stride = (joint(clip, cycle + 3, "toe_l") - joint(clip, 3, "toe_l")).head<2>().norm();
    EXPECT_NEAR(stride, speed * cycle / kFps, 1e-6);
    EXPECT_GT(stride, previous_stride);
    EXPECT_LT(clip.cycle_frames, previous_cycle + 1e-9);
    EXPECT_GT(stride, 0.8);  // plausible human strides
    EXPECT_LT(stride, 2.0);
    previous_speed = pelvis_speed;
    previous_stride = stride;
    previous_cycle = clip.cycle_frames;
  }
}

// At a low frame rate the cadence is still a person's: a whole number of frames per cycle as
// close to it as the rate allows, so a fast walk at 6 fps keeps a human stride (the old
// 8-frame minimum gave a 1.7 m/s walk a 2.3 m stride there).
TEST(Motion, AFastWalkAtSixFramesPerSecondKeepsAHumanStride) {
  for (double speed : {0.9, 1.7}) {
    const MotionClip clip = generate_motion(performer().skeleton, walk(speed), 6.0);
    const MotionClip fine = generate_motion(performer().skeleton, walk(speed), 60.0);
    EXPECT_GE(clip.cycle_frames, 4);
    // Within half a frame of the cadence sampled finely.
    EXPECT_NEAR(clip.cycle_frames / 6.0, fine.cycle_frames / 60.0, 0.5 / 6.0) << speed;
    EXPECT_LT(speed * clip.cycle_frames / 6.0, 2.0) << speed;  // the stride [m]
  }
}

TEST(Motion, WalkKeepsFeetPlantedAndAboveTheFloor) {
  const MotionClip clip = generate_motion(performer().skeleton, walk(1.3), kFps);
  const auto meshes = skin_all(clip);
  expect_feet_planted(clip, meshes, 4);
  EXPECT_EQ(flight_frames(meshes), 0);  // walking: always a foot on the floor
}

TEST(Motion, RunHasFlightPhasesAndExactSpeed) {
  for (double speed : {2.5, 3.5}) {
    const MotionClip clip = generate_motion(performer().skeleton, run(speed), kFps);
    EXPECT_NEAR(parameter(clip, "speed"), speed, 1e-6 * speed);
    const auto meshes = skin_all(clip);
    EXPECT_GT(flight_frames(meshes), 4) << speed;
    int runs = 0;
    EXPECT_LT(worst_stance_drift(meshes, &runs), 0.03);
    EXPECT_GE(runs, 4);
    EXPECT_GE(lowest_vertex(meshes), -0.01f);
    expect_continuous(clip, 0.5);
  }
  // Running strides are longer and quicker than walking ones.
  const MotionClip w = generate_motion(performer().skeleton, walk(1.8), kFps);
  const MotionClip r = generate_motion(performer().skeleton, run(3.0), kFps);
  EXPECT_LT(r.cycle_frames, w.cycle_frames);
}

// A foot in the air stays within the ankle's range relative to its shin (dorsiflexed at most
// 25 deg, plantarflexed at most 50 deg): a running heel kicked up behind does not fold the foot
// flat under the shin. The angle is between the foot's forward axis and the direction from ankle
// to knee (90 deg: neutral).
TEST(Motion, FeetInTheAirStayWithinTheAnklesRange) {
  const Skeleton& sk = performer().skeleton;
  for (const MotionSpec& spec : {walk(1.3), run(3.5), jump(1.2, 0.5)}) {
    const MotionClip clip = generate_motion(sk, spec, kFps);
    double lowest = 180, highest = 0;
    int in_air = 0;
    for (std::size_t f = 0; f < clip.poses.size(); ++f) {
      const auto world = forward_kinematics(sk, clip.poses[f]);
      for (const std::string side : {"l", "r"}) {
        const auto& foot = world[static_cast<std::size_t>(sk.find("foot_" + side))];
        const auto& knee = world[static_cast<std::size_t>(sk.find("shin_" + side))];
        if (foot.translation().z() < 0.2) continue;  // on or near the floor
        ++in_air;
        const Eigen::Vector3d up = (knee.translation() - foot.translation()).normalized();
        const Eigen::Vector3d forward = foot.linear() * Eigen::Vector3d::UnitX();
        const double angle = std::acos(std::clamp(up.dot(forward), -1.0, 1.0)) * 180 / M_PI;
        lowest = std::min(lowest, angle);
        highest = std::max(highest, angle);
      }
    }
    EXPECT_GT(in_air, 2) << spec.kind;
    EXPECT_GE(lowest, 90 - 25 - 0.01) << spec.kind;
    EXPECT_LE(highest, 90 + 50 + 0.01) << spec.kind;
  }
}

TEST(Motion, TurnFollowsACircularArcAtTheTurnRate) {
  for (double rate : {45.0, -30.0}) {
    MotionSpec spec = turn(1.0, rate);
    spec.start_heading = 20;
    spec.start_position = {0.5, -0.3};
    const MotionClip clip = generate_motion(performer().skeleton, spec, kFps);
    EXPECT_NEAR(parameter(clip, "direction_deg_per_s"), rate, 1e-6);
    EXPECT_NEAR(parameter(clip, "speed"), 1.0, 1e-4);  // chords of the arc: 1 - (w dt)^2 / 24
    const double omega = rate * M_PI / 180, radius = 1.0 / omega;
    const double h0 = 20 * M_PI / 180;
    const Eigen::Vector2d centre = Eigen::Vector2d(0.5, -0.3) + radius * Eigen::Vector2d(-std::sin(h0), std::cos(h0));
    for (int f = 0; f < spec.frames; ++f) {
      const RootState& r = clip.root[static_cast<std::size_t>(f)];
      // Heading change = rate * time, exactly; the root stays on the circle.
      EXPECT_NEAR(r.heading - h0, omega * f / kFps, 1e-9);
      EXPECT_NEAR((r.position - centre).norm(), std::abs(radius), 1e-9);
      // The pelvis faces along the root's heading, give or take the gait's hip rotation.
      const Eigen::Matrix3d pelvis = clip.poses[static_cast<std::size_t>(f)].local_rotations[0].toRotationMatrix();
      const Eigen::Vector3d forward = pelvis.col(0);
      EXPECT_LT(std::abs(std::remainder(std::atan2(forward.y(), forward.x()) - r.heading, 2 * M_PI)), 12 * M_PI / 180);
      EXPECT_LT((clip.poses[static_cast<std::size_t>(f)].root_position.head<2>() - r.position).norm(), 0.06);
    }
    expect_feet_planted(clip, skin_all(clip), 4);
  }
}

// A dance turns by the turn rate over the take, spinning in its middle; a foot is always on the
// floor, none below it; it starts and ends standing, arms hanging.
TEST(Motion, DanceSpinsByTheTurnRateOnTheSpot) {
  for (double rate : {180.0, -90.0}) {
    MotionSpec spec = dance(rate);
    spec.start_heading = 30;
    spec.start_position = {0.4, -0.2};
    const MotionClip clip = generate_motion(performer().skeleton, spec, kFps);
    const double seconds = (spec.frames - 1) / kFps;
    EXPECT_NEAR(parameter(clip, "direction_deg_per_s"), rate, 1e-9);
    EXPECT_NEAR(parameter(clip, "spin_deg"), rate * seconds, 1e-9);
    EXPECT_GT(std::abs(parameter(clip, "spin_peak_deg_per_s")), 2 * std::abs(rate));
    EXPECT_NEAR(clip.root.front().heading, 30 * M_PI / 180, 1e-12);
    EXPECT_NEAR(clip.root.back().heading - clip.root.front().heading, rate * seconds * M_PI / 180, 1e-9);
    for (const RootState& r : clip.root) EXPECT_LT((r.position - Eigen::Vector2d(0.4, -0.2)).norm(), 1e-12);
    // On the spot: the pelvis sways over the feet, no further.
    for (int f = 0; f < spec.frames; ++f) {
      EXPECT_LT((joint(clip, f, "pelvis").head<2>() - Eigen::Vector2d(0.4, -0.2)).norm(), 0.06) << f;
    }
    const auto meshes = skin_all(clip);
    EXPECT_EQ(flight_frames(meshes), 0);
    EXPECT_GE(lowest_vertex(meshes), -0.01f);
    // The spin's middle: arms held out, the hands far from the hips.
    const int middle = spec.frames / 2;
    EXPECT_GT((joint(clip, middle, "hand_l") - joint(clip, middle, "hand_r")).norm(), 1.2);
    for (int f : {0, spec.frames - 1}) {
      EXPECT_LT((joint(clip, f, "hand_l") - joint(clip, f, "hand_r")).norm(), 0.7) << f;
    }
    expect_continuous(clip, 0.35);
  }
}

// A turn that pauses: it slows to a stand over a gait cycle, stands still (the root does not
// move, the feet side by side and planted, the arms hanging, the body swaying by millimetres)
// and sets off again to the same speed and turn rate.
TEST(Motion, AWalkThatPausesStandsStillAndSetsOffAgain) {
  MotionSpec spec = turn(1.1, 60, 260);
  spec.pauses = {PauseSpec{100, 25}};
  const MotionClip clip = generate_motion(performer().skeleton, spec, kFps);
  const int cycle = static_cast<int>(clip.cycle_frames);
  ASSERT_EQ(clip.amplitude.size(), clip.poses.size());
  ASSERT_GT(100 - 2 * cycle, 10);
  ASSERT_LT(125 + 2 * cycle + 2, 250);
  EXPECT_NEAR(parameter(clip, "speed"), 1.1, 1e-4);
  EXPECT_NEAR(parameter(clip, "direction_deg_per_s"), 60, 1e-6);
  const auto meshes = skin_all(clip);
  for (int f = 1; f < spec.frames; ++f) {
    const auto i = static_cast<std::size_t>(f);
    const double step = (clip.root[i].position - clip.root[i - 1].position).norm();
    const double turned = clip.root[i].heading - clip.root[i - 1].heading;
    if (f > 100 && f < 125) {
      // Standing still: no root motion at all, every vertex within the sway's millimetre.
      EXPECT_EQ(clip.amplitude[i], 0.0) << f;
      EXPECT_LT(step, 1e-9) << f;
      EXPECT_LT(std::abs(turned), 1e-9) << f;
      double worst = 0;
      for (std::size_t v = 0; v < meshes[i].positions.size(); ++v) {
        worst = std::max(worst, static_cast<double>((meshes[i].positions[v] - meshes[i - 1].positions[v]).norm()));
      }
      EXPECT_LT(worst, 0.0015) << f;
    } else if (f < 100 - 2 * cycle || f > 125 + 2 * cycle + 2) {
      // Walking at full pace before and after.
      EXPECT_EQ(clip.amplitude[i], 1.0) << f;
      EXPECT_NEAR(step, 1.1 / kFps, 1e-4) << f;
      EXPECT_NEAR(turned, 60 * M_PI / 180 / kFps, 1e-9) << f;
    } else {
      EXPECT_LE(step, 1.1 / kFps + 1e-9) << f;  // slowing down or setting off
    }
  }
  // Standing: the feet side by side (along the heading within 5 cm), the hands by the hips.
  const double h = clip.root[112].heading;
  const Eigen::Vector2d forward(std::cos(h), std::sin(h));
  const Eigen::Vector3d apart = joint(clip, 112, "toe_l") - joint(clip, 112, "toe_r");
  EXPECT_LT(std::abs(apart.head<2>().dot(forward)), 0.05);
  EXPECT_GT(apart.head<2>().norm(), 0.08);
  EXPECT_LT((joint(clip, 112, "hand_l") - joint(clip, 112, "hand_r")).norm(), 0.7);
  expect_feet_planted(clip, meshes, 6);
}

TEST(Motion, RejectsPausesThatCannotBePerformed) {
  const Skeleton& sk = performer().skeleton;
  MotionSpec hop = jump(1.0, 0.3);
  hop.pauses = {PauseSpec{40, 5}};
  EXPECT_THROW(generate_motion(sk, hop, kFps), ConfigError);  // only a walk or a turn pauses
  MotionSpec past_the_end = walk(1.0, 80);
  past_the_end.pauses = {PauseSpec{70, 20}};
  EXPECT_THROW(generate_motion(sk, past_the_end, kFps), ConfigError);
  MotionSpec overlapping = walk(1.0, 200);
  overlapping.pauses = {PauseSpec{50, 20}, PauseSpec{60, 10}};
  EXPECT_THROW(generate_motion(sk, overlapping, kFps), ConfigError);
  MotionSpec too_soon = walk(1.0, 200);  // no time to set off, walk and slow down between
  too_soon.pauses = {PauseSpec{50, 20}, PauseSpec{120, 10}};
  EXPECT_THROW(generate_motion(sk, too_soon, kFps), ConfigError);
  MotionSpec apart = walk(1.0, 260);
  apart.pauses = {PauseSpec{50, 20}, PauseSpec{190, 10}};
  EXPECT_NO_THROW(generate_motion(sk, apart, kFps));
}

TEST(Motion, JumpHasExactLengthAndApexHeight) {
  struct Case {
    double length, height;
  };
  for (const Case c : {Case{0.6, 0.15}, Case{1.2, 0.35}, Case{0.0, 0.25}}) {
    MotionSpec spec = jump(c.length, c.height);
    spec.start_heading = -90;
    const MotionClip clip = generate_motion(performer().skeleton, spec, kFps);
    EXPECT_NEAR(parameter(clip, "jump_length"), c.length, 1e-6);
    EXPECT_NEAR(parameter(clip, "jump_height"), c.height, 1e-6);
    // Independently: the feet stand `length` further along the heading (-y) afterwards...
    const int last = spec.frames - 1;
    for (const char* foot : {"foot_l", "foot_r"}) {
      const Eigen::Vector3d moved = joint(clip, last, foot) - joint(clip, 0, foot);
      EXPECT_NEAR(moved.x(), 0.0, 1e-6);
      EXPECT_NEAR(-moved.y(), c.length, 1e-6);
      EXPECT_NEAR(moved.z(), 0.0, 1e-6);
    }
    // ...and the pelvis rises exactly `height` above standing, on a ballistic arc.
    double top = 0;
    int apex = 0;
    for (int f = 0; f <= last; ++f) {
      const double rise = joint(clip, f, "pelvis").z() - joint(clip, 0, "pelvis").z();
      if (rise > top) {
        top = rise;
        apex = f;
      }
    }
    EXPECT_NEAR(top, c.height, 1e-6);
    const double z0 = joint(clip, apex - 1, "pelvis").z(), z1 = joint(clip, apex, "pelvis").z(),
                 z2 = joint(clip, apex + 1, "pelvis").z();
    EXPECT_NEAR(z0 - 2 * z1 + z2, -kGravity / (kFps * kFps), 1e-9);
    const auto meshes = skin_all(clip);
    EXPECT_GT(flight_frames(meshes), 2);
    int runs = 0;
    EXPECT_LT(worst_stance_drift(meshes, &runs), 0.02);
    EXPECT_EQ(runs, 4);  // both feet before and after
    EXPECT_GE(lowest_vertex(meshes), -0.01f);
    expect_continuous(clip, 0.3);
  }
}

TEST(Motion, ReachBringsThePalmToTheTarget) {
  const std::vector<Eigen::Vector3d> targets = {
      {0.5, -0.2, 1.0}, {0.45, -0.25, 0.3}, {0.3, -0.2, 1.95}, {0.45, 0.15, 1.2}, {0.6, -0.35, 1.4}};
  for (const Eigen::Vector3d& t : targets) {
    MotionSpec spec = reach(t.x(), t.y(), t.z());
    spec.start_heading = 30;
    spec.start_position = {1, 2};
    const MotionClip clip = generate_motion(performer().skeleton, spec, kFps);
    EXPECT_NEAR(parameter(clip, "reach_x"), t.x(), 1e-6);
    EXPECT_NEAR(parameter(clip, "reach_y"), t.y(), 1e-6);
    EXPECT_NEAR(parameter(clip, "reach_z"), t.z(), 1e-6);
    // Independently, in the world: the palm comes within 1 cm of the target and goes back.
    const double h = 30 * M_PI / 180;
    const Eigen::Vector3d world(1 + std::cos(h) * t.x() - std::sin(h) * t.y(), 2 + std::sin(h) * t.x() + std::cos(h) * t.y(), t.z());
    double closest = 1e9;
    for (const Pose& pose : clip.poses) {
      closest = std::min(closest, (right_palm_position(performer().skeleton, forward_kinematics(performer().skeleton, pose)) - world).norm());
    }
    EXPECT_LT(closest, 0.01) << t.transpose();
    const auto first = forward_kinematics(performer().skeleton, clip.poses.front());
    const auto last = forward_kinematics(performer().skeleton, clip.poses.back());
    EXPECT_LT((right_palm_position(performer().skeleton, first) - right_palm_position(performer().skeleton, last)).norm(), 1e-6);
    EXPECT_GT((right_palm_position(performer().skeleton, first) - world).norm(), 0.2);
    const auto meshes = skin_all(clip);
    int runs = 0;
    EXPECT_LT(worst_stance_drift(meshes, &runs), 0.01);
    EXPECT_EQ(runs, 2);  // feet never leave the floor
    EXPECT_GE(lowest_vertex(meshes), -0.01f);
    expect_continuous(clip, 0.15);
  }
}

TEST(Motion, OtherBodiesMoveExactlyToo) {
  CharacterOptions options;
  options.height = 1.55;
  options.build = 1.25;
  options.target_vertices = 3000;
  options.texture_size = 256;
  const Character small = make_procedural_character(options, 2);
  const MotionClip w = generate_motion(small.skeleton, walk(1.1), kFps);
  EXPECT_NEAR(parameter(w, "speed"), 1.1, 1e-6);
  const MotionClip j = generate_motion(small.skeleton, jump(0.8, 0.2), kFps);
  EXPECT_NEAR(parameter(j, "jump_length"), 0.8, 1e-6);
  EXPECT_NEAR(parameter(j, "jump_height"), 0.2, 1e-6);
  const MotionClip r = generate_motion(small.skeleton, reach(0.4, -0.2, 1.3), kFps);
  const int hold = static_cast<int>(std::lround(0.525 * (r.spec.frames - 1)));
  const Eigen::Vector3d palm = right_palm_position(small.skeleton, forward_kinematics(small.skeleton, r.poses[static_cast<std::size_t>(hold)]));
  EXPECT_LT((palm - Eigen::Vector3d(0.4, -0.2, 1.3)).norm(), 0.01);
  // Shorter legs take quicker steps at the same speed.
  const MotionClip tall = generate_motion(performer().skeleton, walk(1.1), kFps);
  EXPECT_LE(w.cycle_frames, tall.cycle_frames);
  for (const MotionClip* clip : {&w, &j, &r}) {
    float lowest_z = 1e9f;
    for (const Pose& pose : clip->poses) {
      for (const Vec3f& p : skin_mesh(small.skin, forward_kinematics(small.skeleton, pose)).positions) lowest_z = std::min(lowest_z, p.z());
    }
    EXPECT_GE(lowest_z, -0.01f);
  }
}

// A body does not pass through itself: a heavier build's arms hang clear of its wider trunk
// (the skinned truth of a 1.58 m, build 1.3 body had its upper arms 1-2 cm inside its waist
// in every walking frame, and every re-meshing of it bridged arm and trunk with handles).
TEST(Motion, BodiesOfOtherBuildsWalkAndJumpWithoutPassingThroughThemselves) {
  for (const double build : {1.0, 1.3}) {
    CharacterOptions options;
    options.height = 1.58;
    options.build = build;
    options.texture_size = 256;
    const Character c = make_procedural_character(options, 4711);
    // The second_body recipe's takes at its 12 fps (its fast walk crossed the knees).
    for (const MotionSpec& spec : {walk(0.9, 22), walk(1.7, 16), jump(1.2, 0.2, 29)}) {
      const MotionClip clip = generate_motion(c.skeleton, spec, 12);
      for (std::size_t f = 0; f < clip.poses.size(); f += 2) {
        EXPECT_FALSE(has_self_intersections(skin_mesh(c.skin, forward_kinematics(c.skeleton, clip.poses[f]))))
            << "build " << build << ", " << spec.take << " frame " << f;
      }
    }
  }
}

TEST(Motion, StartStateAndPhase) {
  MotionSpec spec = walk(1.2, 40);
  spec.start_heading = 90;
  spec.start_position = {2, 3};
  spec.start_phase = 0.25;
  const MotionClip clip = generate_motion(performer().skeleton, spec, kFps);
  EXPECT_NEAR(clip.root[0].position.x(), 2, 1e-12);
  EXPECT_NEAR(clip.root[0].position.y(), 3, 1e-12);
  EXPECT_NEAR(clip.root[0].heading, M_PI / 2, 1e-12);
  // Heading 90 degrees: walking along +y.
  EXPECT_NEAR(clip.root.back().position.x(), 2, 1e-9);
  EXPECT_NEAR(clip.root.back().position.y(), 3 + 1.2 * 39 / kFps, 1e-9);
  EXPECT_NEAR(clip.phase[0], 0.25, 1e-12);
  for (std::size_t f = 1; f < clip.phase.size(); ++f) {
    EXPECT_NEAR(std::remainder(clip.phase[f] - clip.phase[f - 1] - 1.0 / clip.cycle_frames, 1.0), 0.0, 1e-12);
  }
  // The same gait, shifted in time: phase 0.25 at frame 0 is the pose of the phase-0 take
  // a quarter cycle in (relative to the root).
  MotionSpec base = walk(1.2, 40);
  const MotionClip b = generate_motion(performer().skeleton, base, kFps);
  const int quarter = static_cast<int>(clip.cycle_frames) / 4;
  if (static_cast<int>(clip.cycle_frames) % 4 == 0) {
    for (std::size_t j = 1; j < clip.poses[0].local_rotations.size(); ++j) {
      EXPECT_TRUE(clip.poses[0].local_rotations[j].isApprox(b.poses[static_cast<std::size_t>(quarter)].local_rotations[j], 1e-9));
    }
  }
}

TEST(Motion, Deterministic) {
  for (const MotionSpec& spec : {walk(1.1), run(3.0), turn(1.0, 30), jump(1.0, 0.3), reach(0.5, -0.2, 1.1), dance(120)}) {
    const MotionClip a = generate_motion(performer().skeleton, spec, kFps);
    const MotionClip b = generate_motion(performer().skeleton, spec, kFps);
    ASSERT_EQ(a.poses.size(), b.poses.size());
    for (std::size_t f = 0; f < a.poses.size(); ++f) {
      EXPECT_EQ(a.poses[f].root_position, b.poses[f].root_position);
      for (std::size_t j = 0; j < a.poses[f].local_rotations.size(); ++j) {
        EXPECT_EQ(a.poses[f].local_rotations[j].coeffs(), b.poses[f].local_rotations[j].coeffs());
      }
    }
    EXPECT_EQ(a.parameters, b.parameters);
  }
}

TEST(Motion, RootHeadingIsContinuous) {
  for (const MotionSpec& spec : {walk(1.1), run(3.0), turn(1.2, -60, 200), jump(1.0, 0.3), reach(0.5, -0.2, 1.1)}) {
    const MotionClip clip = generate_motion(performer().skeleton, spec, kFps);
    const double per_frame = std::abs(spec.kind == "turn" ? spec.turn_rate : 0.0) * M_PI / 180 / kFps;
    for (std::size_t f = 1; f < clip.root.size(); ++f) {
      EXPECT_NEAR(std::abs(clip.root[f].heading - clip.root[f - 1].heading), per_frame, 1e-12) << spec.take;
    }
  }
}

TEST(Motion, RejectsImpossibleSpecs) {
  const Skeleton& sk = performer().skeleton;
  EXPECT_THROW(generate_motion(sk, make_spec("cartwheel", 30), kFps), ConfigError);
  EXPECT_THROW(generate_motion(sk, dance(180, 20), kFps), ConfigError);  // too short
  EXPECT_THROW(generate_motion(sk, jump(1.0, 0.3, 10), kFps), ConfigError);  // too short
  EXPECT_THROW(generate_motion(sk, reach(0.5, -0.2, 3.0), kFps), ConfigError);
  EXPECT_THROW(generate_motion(sk, reach(0.5, -0.2, 1.0, 20), kFps), ConfigError);
  EXPECT_THROW(generate_motion(sk, run(0.5), kFps), ConfigError);
  MotionSpec bad = walk(1.0);
  bad.reach_target = {1, 2};
  EXPECT_THROW(generate_motion(sk, bad, kFps), ConfigError);
  Skeleton other;
  other.names = {"root"};
  other.parents = {-1};
  other.rest_offsets = {Eigen::Vector3d::Zero()};
  EXPECT_THROW(generate_motion(other, walk(1.0), kFps), InputError);
}

TEST(Motion, DebugViews) {
  if (debug_view::debug_dir().empty()) GTEST_SKIP() << "set FOURD_SYNTH_DEBUG_DIR to write views";
  const Character& c = performer();
  for (const MotionSpec& spec : {walk(1.3, 28), run(3.0, 19), turn(1.0, 45, 60), jump(1.2, 0.3), reach(0.45, -0.25, 0.3),
                                 dance(180)}) {
    const MotionClip clip = generate_motion(c.skeleton, spec, kFps);
    std::vector<cv::Mat> side, front;
    const int shown = 8, step = std::max(1, spec.frames / shown);
    for (int f = 0; f < spec.frames && static_cast<int>(side.size()) < shown; f += step) {
      const Mesh m = skin_mesh(c.skin, forward_kinematics(c.skeleton, clip.poses[static_cast<std::size_t>(f)]));
      const double h = clip.root[static_cast<std::size_t>(f)].heading;
      const Eigen::Vector3f fwd(std::cos(h), std::sin(h), 0), left(-std::sin(h), std::cos(h), 0);
      const Eigen::Vector3f centre(clip.poses[static_cast<std::size_t>(f)].root_position.x(),
                                   clip.poses[static_cast<std::size_t>(f)].root_position.y(), 0.9f);
      side.push_back(debug_view::render_orthographic(m, c.texture, -left, fwd, centre, 120, 240, 250));
      front.push_back(debug_view::render_orthographic(m, c.texture, fwd, -left, centre, 120, 240, 250));
    }
    cv::Mat a, b, both;
    cv::hconcat(side, a);
    cv::hconcat(front, b);
    cv::vconcat(a, b, both);
    debug_view::write_debug_image("motion_" + spec.take + ".png", both);
  }
}

}  // namespace
}  // namespace fourd::synth
