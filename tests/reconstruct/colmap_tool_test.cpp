// Running COLMAP: a command that hangs is killed and started once more; a second hang is an
// error that names the command. A shell script stands in for COLMAP.
#include "stages/reconstruct/colmap_tool.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include "pipeline/core/files.h"
#include "pipeline/core/process.h"
#include "tests/scratch_dir.h"

namespace fourd::reconstruct {
namespace {

namespace fs = std::filesystem;

// An executable script in `dir` running `body` (sh; $1 is the COLMAP command, $2 the first
// argument).
std::string fake_colmap(const fs::path& dir, const std::string& body) {
  const fs::path script = dir / "colmap";
  write_file_atomic(script, "#!/bin/sh\n" + body + "\n");
  ::chmod(script.c_str(), 0755);
  return script.string();
}

TEST(ColmapTool, AHungCommandIsStartedAgainAndItsSecondRunCounts) {
  const fs::path dir = test::scratch_dir("colmap_tool_rerun");
  // Hangs on its first run (leaves a marker), finishes on the second.
  const std::string colmap = fake_colmap(
      dir, "if [ -e \"$2\" ]; then echo \"$1 second run\"; exit 0; fi\n"
           "touch \"$2\"\nexec sleep 60");
  const fs::path log = dir / "colmap.log";
  EXPECT_EQ(run_colmap(colmap, "feature_extractor", {(dir / "marker").string()}, log, 0.3), 0);
  const std::string text = read_file(log);
  EXPECT_NE(text.find("starting COLMAP feature_extractor again"), std::string::npos) << text;
  EXPECT_NE(text.find("feature_extractor second run"), std::string::npos) << text;
}

TEST(ColmapTool, ACommandThatHangsTwiceIsATimeoutNamingIt) {
  const fs::path dir = test::scratch_dir("colmap_tool_hang");
  const std::string colmap = fake_colmap(dir, "exec sleep 60");
  try {
    run_colmap_checked(colmap, "matches_importer", {"x"}, dir / "colmap.log", 0.2);
    FAIL() << "no TimeoutError";
  } catch (const TimeoutError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("COLMAP matches_importer did not finish within 0.2 s, 2 times"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find((dir / "colmap.log").string()), std::string::npos) << what;
  }
}

TEST(ColmapTool, AFailedCommandIsASolverErrorWithItsExitCode) {
  const fs::path dir = test::scratch_dir("colmap_tool_fail");
  const std::string colmap = fake_colmap(dir, "echo \"no such image\"; exit 1");
  try {
    run_colmap_checked(colmap, "point_triangulator", {}, dir / "colmap.log", 60);
    FAIL() << "no SolverError";
  } catch (const SolverError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("COLMAP point_triangulator failed (exit 1)"), std::string::npos) << what;
    EXPECT_NE(what.find("no such image"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace fourd::reconstruct
