// High-level parameters: measured on blended motions of the synthetic walker, inverted
// (w = h^-1(p)), and measured again: h(h^-1(p)) must return p.
#include "stages/motionspace/parameters.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "pipeline/core/error.h"
#include "runtime/parameter_map.h"
#include "stages/motionspace/motionspace.h"
#include "stages/timewarp/timewarp.h"
#include "tests/timewarp/walker.h"

namespace fourd {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

timewarp::LocalTake local(const test::Walker& w, std::vector<Eigen::Matrix3Xd> frames,
                          const std::string& name) {
  return timewarp::make_local_take(name, std::move(frames), w.mesh.positions,
                                   torso_weights(w.mesh.positions));
}

// Walks of a class, one per spec, registered and built into a motion space.
MotionSpace walk_space(const test::Walker& w, const std::vector<test::WalkSpec>& specs,
                       const std::string& parameter, motionspace::MotionSpaceReport* report) {
  std::vector<timewarp::LocalTake> takes;
  for (std::size_t k = 0; k < specs.size(); ++k) {
    takes.push_back(local(w, test::walk_frames(w, specs[k]), "walk" + std::to_string(k)));
  }
  MotionClassConfig motion{"walks", {}, parameter, true};
  for (const auto& t : takes) motion.takes.push_back(t.name);
  const WarpedClass warped =
      timewarp::warp_class(motion, 25, test::walker_mesh(w), std::move(takes), {});
  return motionspace::build_motion_space(warped, {}, report);
}

test::WalkSpec walk(double speed, double cycle_frames, double amplitude, double turn_deg = 0) {
  test::WalkSpec s;
  s.speed = speed;
  s.cycle_frames = cycle_frames;
  s.amplitude = amplitude;
  s.turn_rate = turn_deg * kDeg;
  s.frames = static_cast<int>(std::ceil(cycle_frames)) + 2;
  return s;
}

// h(h^-1(p)) over the whole range, measured anew on the blend, within `tolerance` of the range.
void expect_round_trip(const MotionSpace& space, const ParameterProbe& probe, double tolerance) {
  const ParameterMap& map = space.parameter_map;
  const double lo = map.min_value(), hi = map.max_value();
  ASSERT_GT(hi, lo);
  MotionSample sample = make_motion_sample(space);
  const int n = space.num_inputs();
  for (int j = 0; j <= 40; ++j) {
    const double p = j == 40 ? hi : lo + (hi - lo) * j / 40;
    std::array<float, 3> w{};
    const ParameterLookup look = weights_for_parameter(map, p, std::span<float>(w.data(), n));
    EXPECT_FALSE(look.clamped);
    const double measured = measure_parameter(probe, space, std::span<const float>(w.data(), n),
                                              &sample);
    EXPECT_NEAR(measured, p, tolerance * (hi - lo)) << probe.parameter << " " << p;
  }
}

TEST(Parameters, SpeedInverseThenForwardReturnsTheRequest) {
  const test::Walker w = test::make_walker();
  motionspace::MotionSpaceReport report;
  const MotionSpace space = walk_space(w, {walk(1.0, 15, 0.3), walk(1.8, 12, 0.45)}, "speed",
                                       &report);
  const ParameterProbe probe = make_parameter_probe("walks", "speed", w.mesh.positions, space);
  EXPECT_NEAR(space.parameter_map.min_value(), 1.0, 0.02);
  EXPECT_NEAR(space.parameter_map.max_value(), 1.8, 0.02);
  expect_round_trip(space, probe, 0.005);
  EXPECT_LE(report.accuracy.max_error_pct, 0.5);
  EXPECT_EQ(report.accuracy.requested.size(), 21u);
}

TEST(Parameters, TurnRateOfThreeInputsIsMonotoneDecreasing) {
  const test::Walker w = test::make_walker();
  motionspace::MotionSpaceReport report;
  const MotionSpace space =
      walk_space(w, {walk(1.3, 14, 0.35, 40), walk(1.3, 14, 0.35, 0), walk(1.3, 14, 0.35, -40)},
                 "direction", &report);
  ASSERT_EQ(report.parameters.input_values.size(), 3u);
  EXPECT_NEAR(report.parameters.input_values[0], 40, 1.5);
  EXPECT_NEAR(report.parameters.input_values[1], 0, 1.5);
  EXPECT_NEAR(report.parameters.input_values[2], -40, 1.5);
  const ParameterProbe probe = make_parameter_probe("walks", "direction", w.mesh.positions, space);
  expect_round_trip(space, probe, 0.005);
  // Straight ahead is the middle input.
  std::array<float, 3> wts{};
  weights_for_parameter(space.parameter_map, report.parameters.input_values[1], wts);
  EXPECT_NEAR(wts[1], 1.0, 1e-4);
}

TEST(Parameters, JumpHeightIsMeasuredOnTheBlendedShapes) {
  const test::Walker w = test::make_walker();
  test::JumpSpec low, high;
  high.height = 0.35;
  high.length = 0.9;
  std::vector<timewarp::LocalTake> takes{local(w, test::jump_frames(w, low), "jump_low"),
                                         local(w, test::jump_frames(w, high), "jump_high")};
  const MotionClassConfig motion{"jumps", {"jump_low", "jump_high"}, "height", false};
  const WarpedClass warped =
      timewarp::warp_class(motion, 25, test::walker_mesh(w), std::move(takes), {});
  motionspace::MotionSpaceReport report;
  const MotionSpace space = motionspace::build_motion_space(warped, {}, &report);
  // The torso's rise (the crouch before the flight lowers it first, not counted).
  EXPECT_NEAR(report.parameters.input_values[0], 0.15, 0.01);
  EXPECT_NEAR(report.parameters.input_values[1], 0.35, 0.01);
  const ParameterProbe probe = make_parameter_probe("jumps", "height", w.mesh.positions, space);
  expect_round_trip(space, probe, 0.01);
}

TEST(Parameters, OutOfRangeRequestsAreClampedAndReported) {
  ParameterMap map;
  map.parameter = "speed";
  map.num_inputs = 2;
  map.path = {0, 0.5, 1};
  map.values = {1.0, 1.5, 1.8};
  map.check();
  std::array<float, 2> w{};
  ParameterLookup look = weights_for_parameter(map, 2.5, w);
  EXPECT_TRUE(look.clamped);
  EXPECT_DOUBLE_EQ(look.applied, 1.8);
  EXPECT_FLOAT_EQ(w[1], 1.f);
  look = weights_for_parameter(map, 0.2, w);
  EXPECT_TRUE(look.clamped);
  EXPECT_FLOAT_EQ(w[0], 1.f);
  look = weights_for_parameter(map, 1.25, w);
  EXPECT_FALSE(look.clamped);
  EXPECT_NEAR(look.path_position, 0.25, 1e-12);
  EXPECT_NEAR(parameter_at_path(map, look.path_position), 1.25, 1e-12);
  look = weights_for_parameter(map, std::nan(""), w);
  EXPECT_TRUE(look.clamped);
}

TEST(Parameters, MapRejectsNonMonotoneSamplesAndTakesOutOfOrder) {
  ParameterMap map;
  map.parameter = "speed";
  map.num_inputs = 2;
  map.path = {0, 0.5, 1};
  map.values = {1.0, 1.9, 1.8};
  EXPECT_THROW(map.check(), InputError);
  map.values = {1.0, 1.0, 1.8};
  EXPECT_THROW(map.check(), InputError);

  const test::Walker w = test::make_walker();
  motionspace::MotionSpaceReport report;
  try {
    walk_space(w, {walk(1.0, 15, 0.3), walk(1.8, 12, 0.45), walk(1.4, 13, 0.4)}, "speed",
               &report);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not in speed order"), std::string::npos) << e.what();
  }
  EXPECT_THROW(walk_space(w, {walk(1.0, 15, 0.3), walk(1.8, 12, 0.45)}, "swagger", &report),
               ConfigError);
}

}  // namespace
}  // namespace fourd
