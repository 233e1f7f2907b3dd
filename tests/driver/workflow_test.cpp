// The generated Snakemake workflow (workflow.cpp) and the split of a stage into jobs that it
// shares with `fourd run` (driver.cpp's stage_jobs).
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/frame_selection.h"
#include "pipeline/driver/driver.h"
#include "pipeline/driver/workflow.h"

namespace fourd::driver {
namespace {

CaptureIndex two_takes() {
  CaptureIndex capture;
  capture.takes = {{"jump", 3, {}}, {"walk", 10, {}}};
  return capture;
}

StageSpec per_frame_stage() {
  StageSpec s;
  s.name = "segment";
  s.inputs = {"capture", "calibration"};
  s.outputs = {"segment"};
  s.frame_outputs = {"{take}/{camera}/{frame}.png"};
  return s;
}

TEST(StageJobs, PerFrameStagesSplitIntoRangesOfEachTakeThenFinish) {
  std::vector<std::string> names;
  for (const Job& j : stage_jobs(per_frame_stage(), two_takes(), 4)) names.push_back(j.name());
  EXPECT_EQ(names, (std::vector<std::string>{"segment.jump.0-2", "segment.walk.0-3",
                                             "segment.walk.4-7", "segment.walk.8-9",
                                             "segment.finish"}));
  const std::vector<Job> per_take = stage_jobs(per_frame_stage(), two_takes(), 0);
  ASSERT_EQ(per_take.size(), 3u);
  EXPECT_EQ(per_take[1].arguments(),
            (std::vector<std::string>{"--take", "walk", "--frames", "0:9"}));
  EXPECT_EQ(per_take[1].log_name(), "segment.walk.0-9.log");
  EXPECT_EQ(per_take[2].arguments(), (std::vector<std::string>{"--finish"}));
  EXPECT_EQ(per_take[2].log_name(), "segment.log");

  StageSpec single;
  single.name = "timewarp";
  single.outputs = {"timewarp"};
  const std::vector<Job> one = stage_jobs(single, two_takes(), 4);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_TRUE(one[0].arguments().empty());
  EXPECT_EQ(one[0].name(), "timewarp");
  EXPECT_THROW(stage_jobs(per_frame_stage(), two_takes(), -1), UsageError);
  EXPECT_TRUE(stage_table()[1].per_frame());   // segment
  EXPECT_TRUE(stage_table()[2].per_frame());   // reconstruct
  EXPECT_FALSE(stage_table()[3].per_frame());  // align: split along its tree, not by frames
  EXPECT_TRUE(stage_table()[3].tree_split);
}

TEST(StageJobs, TreeSplitStageRunsAsTreeBranchesAndFinish) {
  const StageSpec& align = stage_table()[3];
  ASSERT_EQ(align.name, "align");
  const std::vector<Job> jobs = stage_jobs(align, two_takes(), 4, 3);
  std::vector<std::string> names, logs;
  for (const Job& j : jobs) {
    names.push_back(j.name());
    logs.push_back(j.log_name());
  }
  EXPECT_EQ(names, (std::vector<std::string>{"align.tree", "align.branch0", "align.branch1",
                                             "align.branch2", "align.finish"}));
  EXPECT_EQ(logs, (std::vector<std::string>{"align.tree.log", "align.branch0.log",
                                            "align.branch1.log", "align.branch2.log",
                                            "align.log"}));
  EXPECT_EQ(jobs[0].arguments(), (std::vector<std::string>{"--tree", "--branches", "3"}));
  EXPECT_EQ(jobs[2].arguments(), (std::vector<std::string>{"--branch", "1"}));
  EXPECT_EQ(jobs[4].arguments(), (std::vector<std::string>{"--finish"}));
  EXPECT_EQ(jobs[0].tree_job_file("align"), "align/.jobs/plan.bin");
  EXPECT_EQ(jobs[3].tree_job_file("align_oracle"), "align_oracle/.jobs/branch2.bin");
  EXPECT_THROW(stage_jobs(align, two_takes(), 4, 0), UsageError);
}

// A session with a small real capture (two cameras, takes of 5 and 2 frames) and fake stage
// executables that log their arguments: `fourd run` and the workflow must cut the same jobs.
class JobsSession : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "fourd_jobs_test_XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
    session_ = dir_ / "session";
    write_file_atomic(session_ / "session.yaml", "name: t\nstages: {}\n");
    std::vector<Camera> cameras(2);
    for (int c = 0; c < 2; ++c) {
      cameras[c].name = fmt::format("cam{:02d}", c);
      cameras[c].intrinsics.width = 8;
      cameras[c].intrinsics.height = 6;
      cameras[c].intrinsics.fx = cameras[c].intrinsics.fy = 8;
    }
    write_colmap_model(session_ / "calibration", cameras);
    const cv::Mat image(6, 8, CV_8UC3, cv::Scalar(0, 255, 0));
    for (auto [take, frames] : {std::pair{"walk", 5}, std::pair{"jump", 2}}) {
      for (const Camera& c : cameras) {
        fs::create_directories(session_ / "capture" / take / c.name);
        for (int f = 0; f < frames; ++f) {
          cv::imwrite((session_ / "capture" / take / c.name / (frame_name(f) + ".png")).string(),
                      image);
        }
      }
    }
    // Fake stages: "seg" per-frame (writes its frame files), "sum" one job reading seg/.
    StageSpec seg = per_frame_stage();
    seg.name = "seg";
    seg.outputs = {"seg"};
    StageSpec sum;
    sum.name = "sum";
    sum.inputs = {"seg"};
    sum.outputs = {"sum"};
    for (StageSpec* s : {&seg, &sum}) {
      s->executable = dir_ / "bin" / ("fourd-" + s->name);
      write_file_atomic(s->executable,
                        fmt::format("#!/bin/sh\ns=\"$1\"\nshift\nmkdir -p \"$s/{0}\"\n"
                                    "echo \"$@\" >> \"$s/{0}/jobs.txt\"\n",
                                    s->name));
      fs::permissions(s->executable, fs::perms::owner_all);
    }
    stages_ = {seg, sum};
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_, session_;
  std::vector<StageSpec> stages_;
};

TEST_F(JobsSession, FourdRunRunsAPerFrameStageAsItsJobs) {
  RunRequest request;
  request.frames_per_job = 2;
  RunResult result = run_pipeline(session_, stages_, request, {});
  ASSERT_EQ(result.exit_code, 0);
  EXPECT_EQ(read_file(session_ / "seg" / "jobs.txt"),
            "--take jump --frames 0:1\n--take walk --frames 0:1\n--take walk --frames 2:3\n"
            "--take walk --frames 4:4\n--finish\n");
  EXPECT_EQ(read_file(session_ / "sum" / "jobs.txt"), "\n");
}

TEST_F(JobsSession, WorkflowHasOneRuleAndLogPerJobWithItsFramesAsOutputs) {
  WorkflowRequest request;
  request.frames_per_job = 2;
  WorkflowFiles files = write_workflow(session_, stages_, request);
  EXPECT_EQ(files.jobs, 6u);  // 4 ranges + finish + sum
  const std::string snakefile = read_file(files.snakefile);
  for (const char* rule : {"rule seg_jump_0_1:", "rule seg_walk_0_1:", "rule seg_walk_2_3:",
                           "rule seg_walk_4_4:", "rule seg_finish:", "rule sum:"}) {
    EXPECT_NE(snakefile.find(rule), std::string::npos) << rule;
  }
  EXPECT_NE(snakefile.find("\"seg/walk/cam01/000003.png\""), std::string::npos);
  EXPECT_NE(snakefile.find("\"capture/walk/cam00/000002.png\""), std::string::npos);
  EXPECT_NE(snakefile.find("--take walk --frames 2:3 --threads {threads}"), std::string::npos);
  EXPECT_NE(snakefile.find("\"logs/seg.walk.2-3.log\""), std::string::npos);
  EXPECT_NE(snakefile.find("touch(\"workflow/done/sum\")"), std::string::npos);
  const std::string profile = read_file(files.slurm_profile / "config.yaml");
  EXPECT_NE(profile.find("sbatch"), std::string::npos);
  EXPECT_NE(profile.find("--cpus-per-task={threads} --mem={resources.mem_mb}"), std::string::npos);
  EXPECT_NE(read_file(files.config).find("seg"), std::string::npos);

  // Snakemake itself (when installed) accepts the workflow and plans every job.
  if (std::system("snakemake --version >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "snakemake is not installed";
  }
  const fs::path out = dir_ / "dry_run.txt";
  // Run from the test's folder: Snakemake writes its own log (.snakemake/) where it starts.
  int status = std::system(fmt::format("cd '{}' && snakemake -s '{}' --cores 1 -n --quiet > '{}' 2>&1",
                                       dir_.string(), files.snakefile.string(), out.string())
                               .c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << read_file(out);
  const std::string plan = read_file(out);
  EXPECT_NE(plan.find("seg_walk_2_3"), std::string::npos) << plan;
  EXPECT_NE(plan.find("total"), std::string::npos) << plan;

  // Run it: the fake stages write their outputs, the markers appear.
  status = std::system(fmt::format("cd '{}' && snakemake -s '{}' --cores 1 --quiet > '{}' 2>&1",
                                   dir_.string(), files.snakefile.string(), out.string())
                           .c_str());
  // The fake seg writes no frame files, so Snakemake must report the missing outputs.
  EXPECT_FALSE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << read_file(out);
  EXPECT_NE(read_file(out).find("MissingOutputException"), std::string::npos) << read_file(out);
}

TEST_F(JobsSession, WorkflowNeedsACapture) {
  fs::remove_all(session_ / "capture");
  EXPECT_THROW(write_workflow(session_, stages_, WorkflowRequest{}), InputError);
  WorkflowRequest bad;
  bad.frames_per_job = 0;
  EXPECT_THROW(write_workflow(session_, stages_, bad), UsageError);
}

}  // namespace
}  // namespace fourd::driver
