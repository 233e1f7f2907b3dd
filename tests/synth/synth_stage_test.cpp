// The synth stage as a whole: what it refuses before writing anything.
#include "stages/synth/synth.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/session.h"

namespace fourd::synth {
namespace {

namespace fs = std::filesystem;

class SynthStage : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            ("fourd_synth_stage_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
             "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    fs::create_directories(root_);
    write_file_atomic(root_ / "session.yaml",
                      "name: t\nfps: 10\nstages:\n  synth:\n    seed: 3\n    rig: {count: 2, "
                      "width: 64, height_px: 48, focal_px: 60}\n    takes:\n      - {take: walk, "
                      "kind: walk, frames: 2, speed: 1.0}\n");
  }
  void TearDown() override { fs::remove_all(root_); }
  fs::path root_;
};

TEST_F(SynthStage, RefusesToOverwriteACaptureItDidNotMake) {
  const fs::path real = root_ / "capture" / "walk" / "cam00" / "000000.png";
  fs::create_directories(real.parent_path());
  write_file_atomic(real, "a real frame");
  const Session session = Session::open(root_);
  EXPECT_THROW(run_synth(session, StageArgs{}), InputError);
  EXPECT_EQ(read_file(real), "a real frame");
  EXPECT_FALSE(fs::exists(root_ / "ground_truth"));
}

TEST_F(SynthStage, ReplacesItsOwnCapture) {
  const Session session = Session::open(root_);
  run_synth(session, StageArgs{});
  ASSERT_TRUE(fs::exists(root_ / "capture" / "walk" / "cam00" / "000001.png"));
  // A stale take of an earlier run does not survive the next one.
  fs::create_directories(root_ / "capture" / "old_take" / "cam00");
  run_synth(session, StageArgs{});
  EXPECT_FALSE(fs::exists(root_ / "capture" / "old_take"));
  EXPECT_TRUE(fs::exists(root_ / "ground_truth" / "meshes" / "walk" / "000001.ply"));
}

}  // namespace
}  // namespace fourd::synth
