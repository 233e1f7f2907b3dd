#include "pipeline/core/process.h"

#include <gtest/gtest.h>

#include "pipeline/core/files.h"
#include "tests/scratch_dir.h"

namespace fourd {
namespace {

TEST(Process, ReturnsTheExitCodeAndAppendsTheOutputToTheLog) {
  const auto dir = test::scratch_dir("process_exit");
  const auto log = dir / "tool.log";
  write_file_atomic(log, "before\n");
  EXPECT_EQ(run_process({"/bin/sh", "-c", "echo out; echo err >&2; exit 3"}, log), 3);
  EXPECT_EQ(read_file(log), "before\nout\nerr\n");
}

TEST(Process, AToolThatFinishesInTimeIsNotKilled) {
  const auto dir = test::scratch_dir("process_in_time");
  EXPECT_EQ(run_process({"/bin/sh", "-c", "exit 0"}, dir / "tool.log", 60), 0);
}

TEST(Process, AToolPastItsTimeLimitIsKilledAndSaysSoInTheLog) {
  const auto dir = test::scratch_dir("process_timeout");
  const auto log = dir / "tool.log";
  try {
    run_process({"/bin/sleep", "60"}, log, 0.2);
    FAIL() << "no TimeoutError";
  } catch (const TimeoutError& e) {
    EXPECT_NE(std::string(e.what()).find("/bin/sleep did not finish within 0.2 s"),
              std::string::npos)
        << e.what();
  }
  EXPECT_NE(read_file(log).find("was killed"), std::string::npos);
}

TEST(Process, AMissingProgramIsAnIoError) {
  const auto dir = test::scratch_dir("process_missing");
  EXPECT_THROW(run_process({"/nonexistent/tool"}, dir / "tool.log"), IoError);
}

}  // namespace
}  // namespace fourd
