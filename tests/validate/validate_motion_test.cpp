// Validation of the motion stages from their JSON outputs and the ground-truth phase.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "pipeline/core/files.h"
#include "pipeline/core/session.h"
#include "stages/validate/validate.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

class ValidateMotion : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            ("fourd_validate_motion_" +
             std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(root_);
    fs::create_directories(root_ / "timewarp");
    write_file_atomic(root_ / "session.yaml",
                      "name: t\nfps: 10\nmotions:\n  - {name: loco, takes: [a, b], parameter: "
                      "speed, cyclic: true}\n  - {name: hop, takes: [c], parameter: length}\n");
    write_file_atomic(root_ / "timewarp" / "options.yaml", "{}\n");
  }
  void TearDown() override { fs::remove_all(root_); }

  // Ground truth: take `name` with `frames` frames, phase f / cycle (cyclic) or f / frames.
  void truth(const std::string& name, int frames, double cycle) {
    json j;
    std::vector<double> phase;
    for (int f = 0; f < frames; ++f) {
      phase.push_back(cycle > 0 ? std::fmod(f / cycle, 1.0) : double(f) / frames);
    }
    j["phase"] = phase;
    j["frames"] = frames;
    j["cycle_frames"] = cycle;
    write_file_atomic(root_ / "ground_truth" / "takes" / (name + ".json"), j.dump());
  }
  void warp(const std::string& cls, bool cyclic, const std::vector<std::pair<std::string, std::vector<double>>>& takes) {
    json j;
    j["class"] = cls;
    j["cyclic"] = cyclic;
    for (const auto& [name, t] : takes) j["takes"].push_back({{"take", name}, {"frame_t", t}});
    write_file_atomic(root_ / "timewarp" / (cls + ".json"), j.dump());
  }
  const Metric* metric(const StageReport& r, const std::string& name) {
    for (const Metric& m : r.metrics) {
      if (m.name == name) return &m;
    }
    return nullptr;
  }
  fs::path root_;
};

TEST_F(ValidateMotion, PhaseErrorIgnoresTheCycleOriginAndMeasuresFrames) {
  truth("a", 12, 10);
  truth("b", 12, 10);
  truth("c", 9, 0);
  std::vector<double> ta, tb, tc;
  for (int f = 0; f < 12; ++f) {
    ta.push_back(std::fmod(f / 10.0 + 0.3, 1.0));  // the warp's origin is its own choice
    tb.push_back(std::fmod(f / 10.0 + 0.3, 1.0));
  }
  for (int f = 0; f < 9; ++f) tc.push_back(f / 8.0);
  warp("loco", true, {{"a", ta}, {"b", tb}});
  warp("hop", false, {{"c", tc}});
  const Session session = Session::open(root_);
  ValidateOptions options;
  const StageReport exact = validate_timewarp({session, options, root_});
  ASSERT_TRUE(exact.present);
  ASSERT_NE(metric(exact, "phase_error_frames"), nullptr);
  EXPECT_NEAR(metric(exact, "phase_error_frames")->value, 0, 1e-9);
  EXPECT_EQ(metric(exact, "phase_error_frames")->input, InputKind::kPipeline);

  // One frame of b half a frame late: 0.5 frame on 1 of 33 frames, minus the shift of the
  // circular mean it causes (small).
  tb[4] = std::fmod(tb[4] + 0.05, 1.0);
  warp("loco", true, {{"a", ta}, {"b", tb}});
  const StageReport off = validate_timewarp({session, options, root_});
  EXPECT_NEAR(metric(off, "phase_error_max_frames")->value, 0.5, 0.05);
  EXPECT_GT(metric(off, "phase_error_frames")->value, 0.5 / 33 * 0.9);
}

// The period of each cyclic take's cycle against the true gait cycle (a fraction of frames, as
// the quadruped's), the worst over the takes; the worst closure error beside it.
TEST_F(ValidateMotion, PeriodErrorIsTheWorstTakesAgainstTheTrueCycle) {
  truth("a", 30, 10.8);
  truth("b", 30, 9.6);
  truth("c", 9, 0);
  std::vector<double> t(30, 0.0), tc(9, 0.0);
  warp("loco", true, {{"a", t}, {"b", t}});
  warp("hop", false, {{"c", tc}});
  const Session session = Session::open(root_);
  ValidateOptions options;
  // Without cycles in the summary: no period metric.
  EXPECT_EQ(metric(validate_timewarp({session, options, root_}), "period_error_frames"), nullptr);
  json j = read_json(root_ / "timewarp" / "loco.json");
  const double found[2] = {10.9, 9.0}, closure[2] = {0.004, 0.012};
  for (int k = 0; k < 2; ++k) {
    j["takes"][k]["cycle_frames"] = found[k];
    j["takes"][k]["closure_rms_m"] = closure[k];
    j["takes"][k]["closure_ratio"] = 0.1;
  }
  write_file_atomic(root_ / "timewarp" / "loco.json", j.dump());
  const StageReport report = validate_timewarp({session, options, root_});
  ASSERT_NE(metric(report, "period_error_frames"), nullptr);
  EXPECT_NEAR(metric(report, "period_error_frames")->value, 0.6, 1e-9);  // b: 9.0 for 9.6
  EXPECT_NEAR(metric(report, "closure_rms_max_mm")->value, 12, 1e-9);
  EXPECT_NE(report.details.find("| loco | b | 9.600 | 9.000 | 0.600 |"), std::string::npos) << report.details;
}

TEST_F(ValidateMotion, FrameCountsThatDisagreeWithTheTruthAreAnError) {
  truth("a", 12, 10);
  truth("b", 12, 10);
  warp("loco", true, {{"a", std::vector<double>(11, 0.0)}, {"b", std::vector<double>(12, 0.0)}});
  const Session session = Session::open(root_);
  ValidateOptions options;
  EXPECT_THROW(validate_timewarp({session, options, root_}), InputError);
}

}  // namespace
}  // namespace fourd::validate
