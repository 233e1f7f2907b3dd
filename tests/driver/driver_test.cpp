// The driver's stage table, completion records and skip decisions, exercised with tiny shell
// scripts standing in for stage executables (test fixtures) in a temporary folder.
#include "pipeline/driver/driver.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <map>
#include <sys/stat.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <functional>

#include "pipeline/core/files.h"

namespace fourd::driver {
namespace {

void write_text(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::trunc) << text;
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// A fake stage: appends a line to <session>/runs_<name>.txt (outside every stage folder),
// concatenates its input folders into <first output>/result.txt, records its arguments, and
// exits with `exit_code`.
void write_fake_stage(const fs::path& exe, const StageSpec& spec, int exit_code = 0) {
  std::string script = "#!/bin/sh\nset -e\ns=\"$1\"\n";
  script += fmt::format("echo run >> \"$s/runs_{}.txt\"\n", spec.name);
  for (const auto& out : spec.outputs) script += fmt::format("mkdir -p \"$s/{}\"\n", out);
  const std::string& first = spec.outputs.front();
  script += fmt::format(": > \"$s/{}/result.txt\"\n", first);
  for (const auto& in : spec.inputs) {
    script += fmt::format(
        "if [ -d \"$s/{0}\" ]; then find \"$s/{0}\" -type f -name '*.txt' | sort | "
        "xargs -r cat >> \"$s/{1}/result.txt\"; fi\n",
        in, first);
  }
  script += fmt::format("echo \"$@\" > \"$s/{}/args.log\"\n", first);
  script += fmt::format("exit {}\n", exit_code);
  write_text(exe, script);
  fs::permissions(exe, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec);
}

class DriverTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "fourd_driver_test_XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
    session_ = dir_ / "session";
    bin_ = dir_ / "bin";
    fs::create_directories(bin_);
    // raw/ plays the part of a capture nobody in this table writes.
    stages_ = {
        {"make", {"raw"}, {"a"}, false, {}},
        {"copy", {"a"}, {"b", "b2"}, true, {}},
        {"sum", {"a", "b"}, {"c"}, false, {}},
    };
    for (auto& s : stages_) {
      s.executable = bin_ / ("fourd-" + s.name);
      write_fake_stage(s.executable, s);
    }
    write_yaml("name: test\nfps: 25\nstages:\n  make: {gain: 1}\n  copy: {mode: fast}\n");
    write_text(session_ / "raw" / "x.txt", "raw-1\n");
  }
  void TearDown() override { fs::remove_all(dir_); }

  void write_yaml(const std::string& text) { write_text(session_ / "session.yaml", text); }
  int runs(const std::string& stage) {
    std::string text = read_text(session_ / ("runs_" + stage + ".txt"));
    return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
  }
  RunResult run(RunRequest request = {}) {
    events_.clear();
    return run_pipeline(session_, stages_, request,
                        [&](const StageEvent& e) { events_.push_back(e); });
  }
  std::string reason_of(const std::string& stage) {
    for (const auto& e : events_) {
      if (e.stage == stage && e.kind == StageEvent::Kind::kStarted) return e.reason;
    }
    return "";
  }

  fs::path dir_, session_, bin_;
  std::vector<StageSpec> stages_;
  std::vector<StageEvent> events_;
};

TEST(StageTable, PipelineOrderAndDataFlow) {
  const auto& table = stage_table();
  std::vector<std::string> names;
  for (const auto& s : table) names.push_back(s.name);
  EXPECT_EQ(names, (std::vector<std::string>{"synth", "segment", "reconstruct", "align", "timewarp", "motionspace",
                                             "texture", "graph", "validate"}));
  EXPECT_EQ(table.front().outputs,
            (std::vector<std::string>{"capture", "calibration", "ground_truth", "plates"}));
  EXPECT_TRUE(table.front().inputs.empty());
  EXPECT_EQ(table.back().outputs, (std::vector<std::string>{"reports"}));
  // Every folder a stage reads is written by an earlier stage, and no two stages share an
  // output folder (a stage never writes into another stage's folder).
  std::set<std::string> written;
  for (const auto& s : table) {
    for (const auto& in : s.inputs) {
      // Oracle folders are written by the oracle runs (with_oracle_variants), not the table;
      // control scripts, plates and masks by the user.
      bool oracle = in == kOracleFolder || in.ends_with("_oracle");
      bool user = in == kPlayFolder || in == kPlatesFolder || in == kMasksFolder;
      EXPECT_TRUE(oracle || user || written.count(in)) << s.name << " reads " << in;
    }
    for (const auto& out : s.outputs) EXPECT_TRUE(written.insert(out).second) << out;
  }
}

TEST_F(DriverTest, BuiltStagesAreThoseWithExecutablesInOrder) {
  fs::path bin = dir_ / "other_bin";
  write_fake_stage(bin / "fourd-validate", stage_table().back());
  write_fake_stage(bin / "fourd-segment", stage_table()[1]);
  write_text(bin / "fourd-align", "not executable");
  fs::permissions(bin / "fourd-align", fs::perms::owner_read | fs::perms::owner_write);
  std::vector<StageSpec> built = built_stages(bin);
  ASSERT_EQ(built.size(), 2u);
  EXPECT_EQ(built[0].name, "segment");
  EXPECT_EQ(built[1].name, "validate");
  EXPECT_EQ(built[1].executable, bin / "fourd-validate");
}

TEST_F(DriverTest, SecondRunSkipsEverything) {
  RunResult first = run();
  EXPECT_EQ(first.exit_code, 0);
  EXPECT_EQ(first.ran, (std::vector<std::string>{"make", "copy", "sum"}));
  EXPECT_TRUE(fs::exists(session_ / "a" / kRecordFile));
  EXPECT_TRUE(fs::exists(session_ / "b" / kRecordFile));  // first output folder only
  EXPECT_FALSE(fs::exists(session_ / "b2" / kRecordFile));
  ASSERT_EQ(events_.size(), 6u);
  EXPECT_EQ(events_[2].index, 2u);
  EXPECT_EQ(events_[2].count, 3u);

  RunResult second = run();
  EXPECT_TRUE(second.ran.empty());
  EXPECT_EQ(second.skipped.size(), 3u);
  EXPECT_EQ(runs("make"), 1);
  EXPECT_EQ(runs("sum"), 1);
  EXPECT_EQ(read_text(session_ / "c" / "result.txt"), "raw-1\nraw-1\n");
}

TEST_F(DriverTest, RecordHoldsInputOutputAndOptionHashes) {
  run();
  auto record = read_record(session_ / "a" / kRecordFile);
  ASSERT_TRUE(record);
  EXPECT_EQ(record->stage, "make");
  ASSERT_EQ(record->fingerprint.inputs.size(), 1u);
  EXPECT_EQ(record->fingerprint.inputs.at("raw/x.txt"), hash_hex(hash_bytes("raw-1\n")));
  EXPECT_EQ(record->fingerprint.executable_hash, hash_hex(hash_file(stages_[0].executable)));
  EXPECT_TRUE(record->outputs.count("a/result.txt"));
  EXPECT_FALSE(record->outputs.count(std::string("a/") + kRecordFile));
  EXPECT_GT(record->output_bytes, 0u);
  // What the stage's process used: a shell has some resident memory, and no time is negative.
  EXPECT_GT(record->peak_rss_bytes, 100u * 1024);
  EXPECT_GE(record->cpu_seconds, 0.0);
  EXPECT_LE(record->cpu_seconds, record->seconds * 64 + 1.0);
  // The record of make (in a/) is not an input of copy, which reads a/.
  auto copy = read_record(session_ / "b" / kRecordFile);
  ASSERT_TRUE(copy);
  for (const auto& [path, hash] : copy->fingerprint.inputs)
    EXPECT_EQ(path.find(kRecordFile), std::string::npos);
}

TEST_F(DriverTest, ChangedInputFileRerunsStageAndDownstream) {
  run();
  write_text(session_ / "raw" / "x.txt", "raw-2\n");
  Session session = Session::open(session_);
  std::string why = staleness(session_, stages_[0], fingerprint(session, stages_[0]));
  EXPECT_NE(why.find("inputs changed: 1 modified (raw/x.txt)"), std::string::npos) << why;

  RunResult result = run();
  EXPECT_EQ(result.ran, (std::vector<std::string>{"make", "copy", "sum"}));
  EXPECT_NE(reason_of("make").find("inputs changed"), std::string::npos);
  EXPECT_NE(reason_of("copy").find("upstream stage make ran"), std::string::npos);
  EXPECT_EQ(read_text(session_ / "c" / "result.txt"), "raw-2\nraw-2\n");

  write_text(session_ / "raw" / "new.txt", "more\n");  // an added file counts too
  EXPECT_EQ(run().ran.size(), 3u);
}

TEST_F(DriverTest, RunRecordsInOutputsAreNotResults) {
  // A stage's report with its times and a log: rewriting them as another run would (other
  // times, other log text) changes no result, so nothing reruns; a result field does.
  write_text(session_ / "a" / "report.json",
             R"({"frames": 3, "seconds": 1.5, "per_frame": [{"seconds_total": 0.5, "rms": 2}],)"
             R"( "similarity_cpu_s": 0.1, "max_search_us": 7, "branch_jobs": 1})");
  write_text(session_ / "a" / "colmap.log", "started 10:00\n");
  run();
  ASSERT_EQ(run().ran.size(), 0u);
  write_text(session_ / "a" / "report.json",
             R"({"frames": 3, "seconds": 9.25, "per_frame": [{"seconds_total": 4, "rms": 2}],)"
             R"( "similarity_cpu_s": 3, "max_search_us": 70, "branch_jobs": 4})");
  write_text(session_ / "a" / "colmap.log", "started 11:00, other text\n");
  EXPECT_EQ(run().ran.size(), 0u);
  write_text(session_ / "a" / "report.json",
             R"({"frames": 3, "seconds": 9.25, "per_frame": [{"seconds_total": 4, "rms": 3}],)"
             R"( "similarity_cpu_s": 3, "max_search_us": 70, "branch_jobs": 4})");
  EXPECT_EQ(run().ran, (std::vector<std::string>{"make", "copy", "sum"}));

  EXPECT_TRUE(is_run_measurement("seconds_per_frame"));
  EXPECT_TRUE(is_run_measurement("reconstruct.pipeline.seconds_per_frame"));
  EXPECT_TRUE(is_run_measurement("blend.oracle.hybrid3_cost_ratio_to_linear"));
  EXPECT_TRUE(is_run_measurement("online_cpu_s"));
  EXPECT_FALSE(is_run_measurement("latency_s"));
  EXPECT_FALSE(is_run_measurement("frame_time_s"));
  EXPECT_FALSE(is_run_measurement("rms_mm"));
  // A split stage's job files are not results: a run split another way lists other ones.
  write_text(dir_ / "a" / "result.ply", "mesh");
  const FileHashes one_job = hash_folders(dir_, {"a"});
  write_text(dir_ / "a" / ".jobs" / "plan.bin", "plan 1");
  write_text(dir_ / "a" / ".jobs" / "branch2.bin", "branch 2 of 3");
  EXPECT_EQ(hash_folders(dir_, {"a"}), one_job);
  // A play's tables and transition records: their wall-clock columns and keys are left out.
  write_text(dir_ / "frames.csv", "frame,p,search_us\n0,1.5,70\n1,1.6,12\n");
  const auto frames = hash_result_file(dir_ / "frames.csv");
  write_text(dir_ / "frames.csv", "frame,p,search_us\n0,1.5,95\n1,1.6,11\n");
  EXPECT_EQ(hash_result_file(dir_ / "frames.csv"), frames);
  write_text(dir_ / "frames.csv", "frame,p,search_us\n0,1.5,95\n1,1.7,11\n");
  EXPECT_NE(hash_result_file(dir_ / "frames.csv"), frames);
  write_text(dir_ / "t.jsonl", "{\"cost\": 5, \"search_us\": 70}\n{\"cost\": 6}\n");
  const auto transitions = hash_result_file(dir_ / "t.jsonl");
  write_text(dir_ / "t.jsonl", "{\"cost\": 5, \"search_us\": 80}\n{\"cost\": 6}\n");
  EXPECT_EQ(hash_result_file(dir_ / "t.jsonl"), transitions);
  write_text(dir_ / "t.jsonl", "{\"cost\": 5, \"search_us\": 80}\n{\"cost\": 7}\n");
  EXPECT_NE(hash_result_file(dir_ / "t.jsonl"), transitions);
  // A file that is not valid JSON is hashed byte for byte.
  write_text(dir_ / "bad.json", "{\"seconds\": 1");
  const auto bad = hash_result_file(dir_ / "bad.json");
  write_text(dir_ / "bad.json", "{\"seconds\": 2");
  EXPECT_NE(hash_result_file(dir_ / "bad.json"), bad);
}

TEST_F(DriverTest, ChangedOptionRerunsOnlyThatStageAndDownstream) {
  run();
  // copy's section changes: make stays up to date.
  write_yaml("name: test\nfps: 25\nstages:\n  make: {gain: 1}\n  copy: {mode: slow}\n");
  RunResult result = run();
  EXPECT_EQ(result.ran, (std::vector<std::string>{"copy", "sum"}));
  EXPECT_EQ(reason_of("copy"), "options changed (session.yaml)");
  // The top-level config concerns every stage.
  write_yaml("name: test\nfps: 30\nstages:\n  make: {gain: 1}\n  copy: {mode: slow}\n");
  EXPECT_EQ(run().ran.size(), 3u);
}

TEST_F(DriverTest, CommentsAndKeyOrderInSessionYamlDoNotRerun) {
  run();
  write_yaml(
      "# a comment\nstages:\n  copy:\n    mode: fast\n  make:\n    gain: 1\nname: test\nfps: 25\n");
  EXPECT_TRUE(run().ran.empty());
  // Leaving out a top-level value equal to its default changes nothing either: the top-level
  // config is re-emitted with defaults filled in.
  write_yaml("name: test\nstages:\n  make: {gain: 1}\n  copy: {mode: fast}\n");
  EXPECT_TRUE(run().ran.empty());
  EXPECT_NE(options_hash(Session::open(session_), "make"),
            options_hash(Session::open(session_), "copy"));
}

TEST_F(DriverTest, DeletedRecordReruns) {
  run();
  fs::remove(session_ / "b" / kRecordFile);
  RunResult result = run();
  EXPECT_EQ(result.ran, (std::vector<std::string>{"copy", "sum"}));
  EXPECT_NE(reason_of("copy").find("no completion record"), std::string::npos);
}

TEST_F(DriverTest, DamagedRecordReruns) {
  run();
  write_text(session_ / "c" / kRecordFile, "{not json");
  EXPECT_EQ(run().ran, (std::vector<std::string>{"sum"}));
  EXPECT_EQ(reason_of("sum"), "completion record unreadable");
}

TEST_F(DriverTest, ModifiedOrDeletedOutputReruns) {
  run();
  write_text(session_ / "b2" / "stray.txt", "edited by hand\n");
  EXPECT_EQ(run().ran, (std::vector<std::string>{"copy", "sum"}));
  EXPECT_NE(reason_of("copy").find("outputs changed: 1 added (b2/stray.txt)"), std::string::npos)
      << reason_of("copy");
  fs::remove(session_ / "c" / "result.txt");
  EXPECT_EQ(run().ran, (std::vector<std::string>{"sum"}));
}

TEST_F(DriverTest, ChangedExecutableReruns) {
  run();
  write_text(stages_[2].executable, read_text(stages_[2].executable) + "# new build\n");
  EXPECT_EQ(run().ran, (std::vector<std::string>{"sum"}));
  EXPECT_EQ(reason_of("sum"), "stage executable changed");
}

TEST_F(DriverTest, OracleRunsAVariantOnPreparedInputsBesideThePipelineRun) {
  // The oracle step is run by fourd-validate: a fake one that copies ground_truth/ to oracle/b.
  write_text(bin_ / "fourd-validate",
             "#!/bin/sh\nset -e\ns=\"$1\"\necho \"$@\" > \"$s/validate_args.log\"\n"
             "mkdir -p \"$s/oracle/b\"\ncp -r \"$s/ground_truth/.\" \"$s/oracle/b/\"\n");
  fs::permissions(bin_ / "fourd-validate", fs::perms::owner_all);
  StageSpec validate{"validate", {"ground_truth"}, {"reports"}, false, bin_ / "fourd-validate"};
  std::vector<StageSpec> built = stages_;
  built[2].supports_oracle = true;
  // sum reads b/, or oracle/b/ with --oracle, and writes c/ or sum_oracle/.
  write_text(built[2].executable,
             "#!/bin/sh\nset -e\ns=\"$1\"\nin=b; out=c\n"
             "if [ \"$2\" = --oracle ]; then in=oracle/b; out=sum_oracle; fi\n"
             "mkdir -p \"$s/$out\"\ncat \"$s/$in\"/*.txt > \"$s/$out/result.txt\"\n"
             "echo \"$@\" > \"$s/$out/args.log\"\n");
  built.push_back(validate);
  write_text(session_ / "ground_truth" / "t.txt", "truth\n");
  RunRequest oracle;
  oracle.oracle = {"sum"};
  oracle.only = "sum";
  ASSERT_EQ(run_pipeline(session_, built, {}, nullptr).exit_code, 0);
  RunResult r = run_pipeline(session_, built, oracle, nullptr);
  ASSERT_EQ(r.exit_code, 0) << r.failed_stage;
  // sum is up to date; the preparation step and the variant run.
  EXPECT_EQ(r.ran, (std::vector<std::string>{"oracle", "sum_oracle"}));
  EXPECT_EQ(r.skipped, (std::vector<std::string>{"sum"}));
  EXPECT_NE(read_text(session_ / "validate_args.log").find("--prepare-oracle"), std::string::npos);
  EXPECT_NE(read_text(session_ / "sum_oracle" / "args.log").find("--oracle"), std::string::npos);
  // The variant read the prepared copy of its input b/, not the pipeline's.
  EXPECT_NE(read_text(session_ / "sum_oracle" / "result.txt").find("truth"), std::string::npos);
  EXPECT_TRUE(read_record(session_ / "sum_oracle" / kRecordFile).has_value());
  EXPECT_TRUE(run_pipeline(session_, built, oracle, nullptr).ran.empty());
  // New ground truth: the preparation and the variant rerun, the pipeline stage does not.
  write_text(session_ / "ground_truth" / "t.txt", "new truth\n");
  EXPECT_EQ(run_pipeline(session_, built, oracle, nullptr).ran,
            (std::vector<std::string>{"oracle", "sum_oracle"}));
}

TEST_F(DriverTest, OracleForAStageThatCannotTakeItIsAUsageError) {
  RunRequest request;
  request.oracle = {"make"};
  EXPECT_THROW(run(request), UsageError);
  request.oracle = {"copy"};
  request.only = "sum";
  EXPECT_THROW(run(request), UsageError);  // copy is not part of this run
}

TEST_F(DriverTest, ForceOnlyAndFromSelectStages) {
  run();
  RunRequest force;
  force.force = true;
  EXPECT_EQ(run(force).ran.size(), 3u);
  EXPECT_EQ(reason_of("make"), "forced");

  RunRequest only;
  only.only = "copy";
  only.force = true;
  EXPECT_EQ(run(only).ran, (std::vector<std::string>{"copy"}));
  ASSERT_EQ(events_.size(), 2u);
  EXPECT_EQ(events_[0].count, 1u);

  // make is stale, but --from copy leaves it out; copy and sum are up to date (copy's forced
  // rerun wrote the same bytes).
  write_yaml("name: test\nfps: 25\nstages:\n  make: {gain: 5}\n  copy: {mode: fast}\n");
  RunRequest from;
  from.from = "copy";
  RunResult result = run(from);
  EXPECT_EQ(result.skipped, (std::vector<std::string>{"copy", "sum"}));
  EXPECT_TRUE(result.ran.empty());
  EXPECT_EQ(runs("make"), 2);

  RunRequest both;
  both.only = "copy";
  both.from = "make";
  EXPECT_THROW(run(both), UsageError);
}

TEST_F(DriverTest, UnknownStageNameListsTheAvailableStages) {
  RunRequest request;
  request.only = "segmnet";
  try {
    run(request);
    FAIL() << "expected a UsageError";
  } catch (const UsageError& e) {
    std::string message = e.what();
    EXPECT_NE(message.find("unknown stage 'segmnet'"), std::string::npos) << message;
    EXPECT_NE(message.find("make, copy, sum"), std::string::npos) << message;
    EXPECT_EQ(e.exit_code(), kExitUsage);
  }
  // A stage of the pipeline that is not built is named as such.
  try {
    find_stage(stages_, "align");
    FAIL() << "expected a UsageError";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("not built"), std::string::npos) << e.what();
  }
}

TEST_F(DriverTest, NonexistentSessionIsAnInputError) {
  EXPECT_THROW(run_pipeline(dir_ / "no_such_session", stages_, {}, nullptr), InputError);
  EXPECT_THROW(session_status(dir_ / "no_such_session", stages_), InputError);
}

TEST_F(DriverTest, FailingStageStopsTheRunWithItsExitCodeAndLeavesNoRecord) {
  run();
  write_text(session_ / "raw" / "x.txt", "raw-3\n");
  write_fake_stage(stages_[1].executable, stages_[1], 4);
  RunResult result = run();
  EXPECT_EQ(result.exit_code, 4);
  EXPECT_EQ(result.failed_stage, "copy");
  EXPECT_EQ(result.log_file, session_ / "logs" / "copy.log");
  EXPECT_EQ(result.ran, (std::vector<std::string>{"make"}));
  EXPECT_EQ(runs("sum"), 1);  // not started
  // The earlier record of copy was removed before it ran: its outputs are not trusted.
  EXPECT_FALSE(fs::exists(session_ / "b" / kRecordFile));
  EXPECT_EQ(events_.back().kind, StageEvent::Kind::kFailed);

  auto status = session_status(session_, stages_);
  ASSERT_EQ(status.size(), 3u);
  EXPECT_EQ(status[0].state, StageStatus::State::kDone);
  EXPECT_EQ(status[1].state, StageStatus::State::kIncomplete);
  EXPECT_EQ(status[2].state, StageStatus::State::kChanged);  // its inputs a/ changed
}

TEST_F(DriverTest, StatusReportsDoneChangedAndNotRun) {
  auto before = session_status(session_, stages_);
  for (const auto& s : before) EXPECT_EQ(s.state, StageStatus::State::kNotRun) << s.stage;
  run();
  auto after = session_status(session_, stages_);
  for (const auto& s : after) {
    EXPECT_EQ(s.state, StageStatus::State::kDone) << s.stage << ": " << s.detail;
    ASSERT_TRUE(s.record);
    EXPECT_FALSE(s.record->finished.empty());
    EXPECT_GT(s.output_bytes, 0u);
  }
  write_yaml("name: test\nfps: 25\nstages:\n  make: {gain: 2}\n  copy: {mode: fast}\n");
  auto changed = session_status(session_, stages_);
  EXPECT_EQ(changed[0].state, StageStatus::State::kChanged);
  EXPECT_EQ(changed[0].detail, "options changed (session.yaml)");
  // copy itself is unchanged, but make will rerun before it.
  EXPECT_EQ(changed[1].state, StageStatus::State::kChanged);
  EXPECT_EQ(changed[1].detail, "upstream stage make will rerun");
}

// A folder fourd-import filled (its record, imported.json, in the stage's first output folder)
// is the user's: the driver never runs its stage, not even with --force, and --only of it is
// refused; the stages reading it use what was imported.
TEST_F(DriverTest, ImportedStageIsNeverRunAndItsReadersUseIt) {
  write_text(session_ / "b" / "mesh.txt", "imported mesh\n");
  write_text(session_ / "b" / kImportRecordFile, "{\"tool\": \"fourd-import\"}\n");
  RunResult first = run();
  EXPECT_EQ(first.exit_code, 0);
  EXPECT_EQ(first.ran, (std::vector<std::string>{"make", "sum"}));
  EXPECT_EQ(runs("copy"), 0);
  EXPECT_EQ(read_text(session_ / "b" / "mesh.txt"), "imported mesh\n");
  EXPECT_NE(read_text(session_ / "c" / "result.txt").find("imported mesh"), std::string::npos);

  auto status = session_status(session_, stages_);
  ASSERT_EQ(status.size(), 3u);
  EXPECT_EQ(status[1].state, StageStatus::State::kImported);
  EXPECT_STREQ(state_name(status[1].state), "imported");
  EXPECT_NE(status[1].detail.find("b/imported.json"), std::string::npos) << status[1].detail;
  EXPECT_EQ(status[2].state, StageStatus::State::kDone) << status[2].detail;

  EXPECT_TRUE(run().ran.empty());  // nothing changed
  RunRequest force;
  force.force = true;
  EXPECT_EQ(run(force).ran, (std::vector<std::string>{"make", "sum"}));
  EXPECT_EQ(runs("copy"), 0);
  RunRequest only;
  only.only = "copy";
  try {
    run(only);
    FAIL() << "expected a UsageError";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("imported"), std::string::npos) << e.what();
  }
  // An edit of the imported files reruns their readers.
  write_text(session_ / "b" / "mesh.txt", "edited mesh\n");
  EXPECT_EQ(run().ran, (std::vector<std::string>{"sum"}));
}

// A stage that flagged frames it could not do well (its report's `warnings`) says so in the
// status table.
TEST_F(DriverTest, StatusCountsTheWarningsOfAStagesReport) {
  run();
  EXPECT_EQ(session_status(session_, stages_)[1].warnings, 0u);
  write_text(session_ / "b" / "report.json",
             "{\"warnings\": [\"walk/cam03/000012: foreground 0.0004\", \"walk/000012: x\"]}");
  auto status = session_status(session_, stages_);
  EXPECT_EQ(status[1].warnings, 2u);
  EXPECT_NE(status[1].detail.find("2 warning(s): see b/report.json"), std::string::npos)
      << status[1].detail;
}

// A stage whose outputs only imported stages read has nothing to do; in a session with imported
// stages and no capture/, the stages that need the images are not used either.
TEST_F(DriverTest, StagesOnlyImportedStagesReadAreLeftAlone) {
  stages_[2].inputs = {"b"};  // make -> a -> copy -> b -> sum
  write_text(session_ / "b" / kImportRecordFile, "{}\n");
  write_text(session_ / "b" / "mesh.txt", "imported\n");
  EXPECT_EQ(run().ran, (std::vector<std::string>{"sum"}));
  EXPECT_EQ(runs("make"), 0);
  auto status = session_status(session_, stages_);
  EXPECT_EQ(status[0].state, StageStatus::State::kNotUsed);
  EXPECT_NE(status[0].detail.find("only copy"), std::string::npos) << status[0].detail;

  Session session = Session::open(session_);
  std::vector<StageSpec> with_capture = stages_;
  with_capture.push_back({"texture", {"b", "capture"}, {"t"}, false, {}});
  auto alone = stages_left_alone(session, with_capture);
  EXPECT_TRUE(alone.count("texture"));  // no capture/ in this session
  write_text(session_ / "capture" / "walk" / "cam" / "000000.txt", "frame\n");
  alone = stages_left_alone(session, with_capture);
  EXPECT_FALSE(alone.count("texture"));
  // Without any import record nothing is left alone.
  fs::remove(session_ / "b" / kImportRecordFile);
  EXPECT_TRUE(stages_left_alone(session, with_capture).empty());
}

// Oracle variants of the real stage table read ground truth wherever it can stand in for their
// input (so each inherits no error from the stages before it), and chain otherwise.
TEST_F(DriverTest, OracleVariantsReadGroundTruthWhereItStandsIn) {
  write_yaml("name: test\noracle: [align, timewarp, motionspace, texture, graph]\n");
  std::vector<StageSpec> built;
  for (const auto& s : stage_table()) {
    if (s.name != "synth") built.push_back(s);
  }
  const Session session = Session::open(session_);
  std::map<std::string, std::vector<std::string>> inputs;
  for (const auto& s : plan_run(session, built, RunRequest{})) inputs[s.name] = s.inputs;
  ASSERT_TRUE(inputs.count("align_oracle") && inputs.count("timewarp_oracle"));
  EXPECT_EQ(inputs["align_oracle"], (std::vector<std::string>{"oracle/reconstruct"}));
  EXPECT_EQ(inputs["timewarp_oracle"], (std::vector<std::string>{"oracle/align"}));
  EXPECT_EQ(inputs["motionspace_oracle"], (std::vector<std::string>{"timewarp_oracle"}));
  // Texture reads the ground-truth meshes and the capture itself (raw data, never an oracle).
  EXPECT_EQ(inputs["texture_oracle"],
            (std::vector<std::string>{"oracle/align", "capture", "calibration"}));
  // Graph reads the time warps too: which captured frame each key texture shows.
  EXPECT_EQ(inputs["graph_oracle"], (std::vector<std::string>{
                                        "motionspace_oracle", "timewarp_oracle", "texture_oracle"}));
  EXPECT_TRUE(inputs.count("oracle"));  // the preparation step runs before them
}

class SynthDriverTest : public DriverTest {
 protected:
  void SetUp() override {
    DriverTest::SetUp();
    stages_ = {stage_table()[0], stage_table()[1]};  // synth, segment
    // The fake capture is no real capture: segment runs as one job here (its split into
    // frame-range jobs is tested in jobs_test.cpp).
    stages_[1].frame_outputs.clear();
    for (auto& s : stages_) {
      s.executable = bin_ / ("fourd-" + s.name);
      write_fake_stage(s.executable, s);
    }
  }
};

TEST_F(SynthDriverTest, SynthRunsOnlyWhenSessionYamlHasASynthSection) {
  write_yaml("name: real\nstages:\n  segment: {}\n");
  write_text(session_ / "capture" / "walk" / "cam00" / "000000.txt", "real frame\n");
  RunResult result = run();
  EXPECT_EQ(result.ran, (std::vector<std::string>{"segment"}));
  EXPECT_EQ(read_text(session_ / "capture" / "walk" / "cam00" / "000000.txt"), "real frame\n");
  RunRequest only;
  only.only = "synth";
  EXPECT_THROW(run(only), UsageError);
  auto status = session_status(session_, stages_);
  EXPECT_EQ(status[0].state, StageStatus::State::kNotUsed);

  // (A synth section over a capture synth did not make is refused by synth itself, not the
  // driver: see SynthStage.RefusesToOverwriteACaptureItDidNotMake.)
}

TEST_F(SynthDriverTest, SyntheticSessionRunsSynthFirst) {
  write_yaml("name: synthetic\nstages:\n  synth: {seed: 1}\n");
  EXPECT_EQ(run().ran, (std::vector<std::string>{"synth", "segment"}));
  EXPECT_TRUE(fs::exists(session_ / "capture" / kRecordFile));
  EXPECT_TRUE(run().ran.empty());
  write_yaml("name: synthetic\nstages:\n  synth: {seed: 2}\n");
  EXPECT_EQ(run().ran, (std::vector<std::string>{"synth", "segment"}));
}

TEST_F(DriverTest, PresetsApplyBeforeSessionYamlAndTheirChangesRerun) {
  write_text(dir_ / "presets" / "p.yaml", "stages:\n  copy: {mode: slow, level: 2}\n");
  write_yaml("name: test\nfps: 25\npresets: [../presets/p.yaml]\n"
             "stages:\n  make: {gain: 1}\n  copy: {mode: fast}\n");
  Session session = Session::open(session_);
  // Both layers apply to copy, the preset first; make has only session.yaml's.
  ASSERT_EQ(session.stage_sections("copy").size(), 2u);
  EXPECT_EQ(session.stage_sections("copy")[0]["level"].as<int>(), 2);
  EXPECT_EQ(session.stage_sections("copy")[1]["mode"].as<std::string>(), "fast");
  EXPECT_EQ(session.stage_sections("make").size(), 1u);
  run();
  // Editing the preset reruns the stages whose section it changes, and only those.
  write_text(dir_ / "presets" / "p.yaml", "stages:\n  copy: {mode: slow, level: 3}\n");
  EXPECT_EQ(run().ran, (std::vector<std::string>{"copy", "sum"}));
  EXPECT_TRUE(run().ran.empty());
}

TEST_F(DriverTest, BadPresetsAreConfigErrorsNamingTheFile) {
  auto error_of = [&](const std::string& preset_text) {
    write_text(dir_ / "p.yaml", preset_text);
    write_yaml("name: test\npresets: [../p.yaml]\n");
    try {
      Session::open(session_);
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(error_of("stages: {copy: {mode: slow}}\nfps: 3\n").find("p.yaml:2: unknown key 'fps'"),
            std::string::npos);
  EXPECT_NE(error_of("stages: [1, 2]\n").find("expected a mapping"), std::string::npos);
  write_yaml("name: test\npresets: [nowhere.yaml]\n");
  try {
    Session::open(session_);
    ADD_FAILURE() << "a missing preset was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("'nowhere.yaml' does not exist"), std::string::npos)
        << e.what();
  }
}

// The `fourd` executable itself, when it is built: exit codes of the command line.
int run_command(const std::string& command) {
  int status = std::system((command + " >/dev/null 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST_F(DriverTest, FourdExecutableExitCodes) {
  fs::path fourd = fs::path(FOURD_BIN_DIR) / "fourd";
  if (!fs::exists(fourd)) GTEST_SKIP() << "fourd is not built";
  EXPECT_EQ(run_command(fourd.string() + " run " + (dir_ / "missing").string()), kExitInput);
  EXPECT_EQ(run_command(fourd.string() + " run " + session_.string() + " --only nosuchstage"),
            kExitUsage);
  EXPECT_EQ(run_command(fourd.string() + " --help"), kExitOk);
  EXPECT_EQ(run_command(fourd.string()), kExitUsage);
  EXPECT_EQ(run_command(fourd.string() + " status " + session_.string()), kExitOk);
}

// config/defaults.yaml is what `fourd defaults` prints from the built stages: regenerate it
// with `build/bin/fourd defaults > config/defaults.yaml` when an option changes.
TEST(DefaultsFile, MatchesWhatTheBuiltStagesPrint) {
  fs::path fourd = fs::path(FOURD_BIN_DIR) / "fourd";
  if (!fs::exists(fourd)) GTEST_SKIP() << "fourd is not built";
  std::vector<StageSpec> built = built_stages(FOURD_BIN_DIR);
  ASSERT_FALSE(built.empty());
  const std::string printed = default_options_yaml(built);
  const std::string committed = read_text(fs::path(FOURD_SOURCE_DIR) / "config" / "defaults.yaml");
  EXPECT_EQ(printed, committed) << "config/defaults.yaml is out of date: regenerate it with "
                                   "`fourd defaults > config/defaults.yaml`";
  // Every stage that has options is in it, and each section maps back onto its stage.
  YAML::Node doc = YAML::Load(printed);
  for (const char* stage : {"synth", "segment", "reconstruct", "align", "timewarp",
                            "motionspace", "graph", "validate", "oracle"}) {
    EXPECT_TRUE(doc["stages"][stage].IsMap()) << stage;
  }
}

// Fails the test for every key of `section` (a stages: mapping) that `reference` (the
// stages: mapping of config/defaults.yaml) does not know.
void expect_known_options(const YAML::Node& section, const YAML::Node& reference,
                          const std::string& path) {
  for (const auto& kv : section) {
    const std::string key = kv.first.as<std::string>();
    EXPECT_TRUE(reference[key].IsDefined()) << path << "." << key << " is not an option";
    if (reference[key].IsDefined() && kv.second.IsMap() && reference[key].IsMap()) {
      expect_known_options(kv.second, reference[key], path + "." + key);
    }
  }
}

YAML::Node committed_defaults() {
  return YAML::LoadFile((fs::path(FOURD_SOURCE_DIR) / "config" / "defaults.yaml").string());
}

// Every preset under config/presets/ is a valid preset: a session using it opens, and each
// section names a stage section that config/defaults.yaml knows, with keys it knows.
TEST(DefaultsFile, PresetsNameOnlyKnownOptions) {
  const fs::path config = fs::path(FOURD_SOURCE_DIR) / "config";
  const YAML::Node defaults = committed_defaults();
  int count = 0;
  for (const auto& entry : fs::directory_iterator(config / "presets")) {
    if (entry.path().extension() != ".yaml") continue;
    ++count;
    YAML::Node preset = YAML::LoadFile(entry.path().string());
    expect_known_options(preset["stages"], defaults["stages"],
                         entry.path().filename().string() + ": stages");
  }
  EXPECT_GT(count, 0);
}

// The sessions shipped with the repository (the default sample, the tiny one, the studio
// variants) open and set only options the stages have.
TEST(DefaultsFile, ShippedSessionsOpenAndSetOnlyKnownOptions) {
  const fs::path samples = fs::path(FOURD_SOURCE_DIR) / "sample_capture";
  std::vector<fs::path> sessions = {samples, samples / "tiny"};
  for (const auto& entry : fs::directory_iterator(samples / "variants")) {
    if (fs::exists(entry.path() / "session.yaml")) sessions.push_back(entry.path());
  }
  EXPECT_GE(sessions.size(), 9u);
  const YAML::Node defaults = committed_defaults();
  for (const fs::path& dir : sessions) {
    EXPECT_NO_THROW(Session::open(dir)) << dir;
    YAML::Node config = YAML::LoadFile((dir / "session.yaml").string());
    expect_known_options(config["stages"], defaults["stages"], dir.string() + ": stages");
  }
}

}  // namespace
}  // namespace fourd::driver
