// The calibration check explains a failed COLMAP triangulation from its log instead of
// showing COLMAP's stack trace.
#include <gtest/gtest.h>

#include <fstream>

#include "stages/reconstruct/calibration_check.h"

namespace fourd::reconstruct {
namespace {

namespace fs = std::filesystem;

std::vector<Camera> cameras(int n) {
  std::vector<Camera> out(n);
  for (int i = 0; i < n; ++i) out[i].name = "cam0" + std::to_string(i);
  return out;
}

TEST(CalibrationCheck, NoMatchesIsExplained) {
  const fs::path log = fs::temp_directory_path() / "fourd_calib_check_nomatch.log";
  std::ofstream(log) << "Processed file [1/1]\n  Features:        62\n"
                        "Processed file [1/1]\n  Features:        52\n"
                        "Loading matches... 0 in 0.000s\n"
                        "  => Triangulated 0 points\n"
                        "F20261123 sfm.cc:473] Check failed: bundle_adjuster.Solve(&reconstruction)\n";
  const std::string msg = triangulation_failure(log, 134, cameras(2));
  EXPECT_NE(msg.find("no feature match"), std::string::npos) << msg;
  EXPECT_NE(msg.find("cam00 62, cam01 52"), std::string::npos) << msg;
  EXPECT_EQ(msg.find("Check failed"), std::string::npos) << msg;
  fs::remove(log);
}

TEST(CalibrationCheck, MatchesWithoutPointsIsExplained) {
  const fs::path log = fs::temp_directory_path() / "fourd_calib_check_nopoints.log";
  std::ofstream(log) << "  Features:        900\n  Features:        800\n"
                        "Loading matches... 1 in 0.000s\n  => Triangulated 0 points\n";
  const std::string msg = triangulation_failure(log, 134, cameras(2));
  EXPECT_NE(msg.find("could not triangulate"), std::string::npos) << msg;
  fs::remove(log);
}

}  // namespace
}  // namespace fourd::reconstruct
