// The motionspace stage after the timewarp stage on a session of synthetic walker takes:
// motion spaces the runtime evaluates at (t, p), Table 1, parameter accuracy, bad options.
#include "stages/motionspace/motionspace.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "stages/motionspace/hybrid_build.h"
#include "stages/motionspace/nonlinear_blend.h"
#include "stages/timewarp/timewarp.h"
#include "tests/timewarp/walker_session.h"

namespace fourd::motionspace {
namespace {

namespace fs = std::filesystem;

using test::oracle_args;

void run_both(const fs::path& root) {
  const Session session = Session::open(root);
  timewarp::run_timewarp(session, oracle_args(root));
  run_motionspace(session, oracle_args(root));
}

TEST(MotionspaceStage, BuildsSpacesEvaluatedAtTimeAndParameter) {
  test::WalkerSession s;
  s.write_standard();
  run_both(s.root());
  const fs::path out = s.root() / "motionspace_oracle";
  for (const char* name : {"locomotion", "jump_length"}) {
    ASSERT_TRUE(fs::exists(out / (std::string(name) + ".mspace"))) << name;
    const nlohmann::json js =
        nlohmann::json::parse(read_file(out / (std::string(name) + ".json")));
    EXPECT_LE(js["parameter_error_max_pct"].get<double>(), 2.0) << name;
    EXPECT_LE(js["hybrid_max_error_m"].get<double>(), 0.005) << name;
  }
  const MotionSpace walk = load_motion_space(out / "locomotion.mspace");
  EXPECT_EQ(walk.parameter_map.parameter, "speed");
  EXPECT_NEAR(walk.parameter_map.min_value(), 1.0, 0.02);
  EXPECT_NEAR(walk.parameter_map.max_value(), 1.6, 0.02);
  MotionSample sample = make_motion_sample(walk);
  evaluate_motion_space(walk, 0.4, 1.3, &sample);
  EXPECT_FALSE(sample.parameter.clamped);
  EXPECT_GT(sample.weights[0], 0.2f);
  EXPECT_GT(sample.weights[1], 0.2f);
  evaluate_motion_space(walk, 0.4, 1.8, &sample);  // faster than captured
  EXPECT_TRUE(sample.parameter.clamped);

  const nlohmann::json table = nlohmann::json::parse(read_file(out / "table1.json"));
  const double linear = table["linear_max_error_pct"], h1 = table["hybrid1_max_error_pct"],
               h3 = table["hybrid3_max_error_pct"];
  EXPECT_GT(linear, 0.0);
  EXPECT_LE(h1, linear);
  EXPECT_LE(h3, h1);
  EXPECT_TRUE(fs::exists(out / "figure4.png"));
  const nlohmann::json summary = nlohmann::json::parse(read_file(out / "summary.json"));
  EXPECT_LE(summary["parameter_error_pct"].get<double>(), 2.0);
}

TEST(MotionspaceStage, RejectsNonPositiveEpsilonAndMissingInput) {
  test::WalkerSession s;
  s.write_standard();
  {
    const Session session = Session::open(s.root());
    EXPECT_THROW(run_motionspace(session, oracle_args(s.root())), InputError);  // no timewarp yet
  }
  s.write_config({"{name: locomotion, takes: [walk_slow, walk_fast], parameter: speed, cyclic: true}"},
                 "stages:\n  motionspace: {epsilon: 0}\n");
  try {
    run_both(s.root());
    FAIL() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("epsilon"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(s.root() / "motionspace_oracle"));
}

TEST(LineReferences, HybridEqualsNonlinearAtEveryReference) {
  const test::Walker w = test::make_walker();
  const int frames = 3;
  BlendSpace space = make_blend_space(2, static_cast<int>(w.mesh.positions.cols()), frames);
  std::vector<std::array<Eigen::Matrix3Xd, 2>> inputs(frames);
  for (int f = 0; f < frames; ++f) {
    inputs[f][0] = test::pose_walker(w, 0.1 * f, -0.1 * f, 0, 0);
    inputs[f][1] = test::pose_walker(w, 1.2 - 0.1 * f, -1.0, 0.05, 0.2);
    for (int k = 0; k < 2; ++k) set_frame(&space, k, f, test::to_vec3f(inputs[f][k]));
  }
  const std::array<double, 3> s{0.25, 0.5, 0.75};
  add_line_references(w.mesh.positions, w.mesh.triangles, s, &space);
  ASSERT_EQ(space.num_references(), 5);
  ASSERT_EQ(space.cells.size(), 2u);  // quadratic segments [0, 0.5] and [0.5, 1]
  BlendedFrame out = make_blended_frame(space);
  for (int f = 0; f < frames; ++f) {
    const std::vector<Eigen::Matrix3Xd> in{inputs[f][0], inputs[f][1]};
    for (double sj : s) {
      const Eigen::Matrix3Xd nl = nonlinear_blend(w.mesh.positions, w.mesh.triangles, in,
                                                  std::array<double, 2>{1 - sj, sj});
      blend_hybrid(space, static_cast<double>(f) / (frames - 1),
                   std::array<float, 2>{static_cast<float>(1 - sj), static_cast<float>(sj)}, &out);
      double worst = 0;
      for (int v = 0; v < out.num_vertices; ++v) {
        worst = std::max(worst, (out.position(v).cast<double>() - nl.col(v)).norm());
      }
      // Exact but for the fp16 rounding of the references' displacements (runtime/blend.h).
      EXPECT_LT(worst, 2.5e-4) << "frame " << f << " w " << sj;
    }
  }
  EXPECT_THROW(add_line_references(w.mesh.positions, w.mesh.triangles, s, &space), InputError);
}

}  // namespace
}  // namespace fourd::motionspace
