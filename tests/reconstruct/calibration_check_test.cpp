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

// A refinement that keeps the cameras near where they were is accepted; one that moves or
// turns a camera beyond the limits (bundle adjustment over too few points) is rejected, naming
// the camera.
TEST(CalibrationCheck, RefinementThatMovesACameraFarIsRejected) {
  std::vector<Camera> before = cameras(3);
  for (int i = 0; i < 3; ++i) before[i].camera_from_world.translation() = Eigen::Vector3d(i, 0, 3);
  CalibrationCheckOptions options;  // 0.1 m, 2 deg
  std::vector<Camera> after = before;
  after[1].camera_from_world.translation() += Eigen::Vector3d(0.02, 0, 0);
  after[2].camera_from_world.linear() =
      Eigen::AngleAxisd(1.0 * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix();
  EXPECT_EQ(refinement_rejection(before, after, options, 500), "");

  std::vector<Camera> moved = before;
  moved[2].camera_from_world.translation() += Eigen::Vector3d(0, 0.3, 0);
  const std::string why = refinement_rejection(before, moved, options, 23);
  EXPECT_NE(why.find("camera cam02"), std::string::npos) << why;
  EXPECT_NE(why.find("23 triangulated points"), std::string::npos) << why;

  std::vector<Camera> turned = before;
  turned[0].camera_from_world.linear() =
      Eigen::AngleAxisd(10.0 * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_NE(refinement_rejection(before, turned, options, 23).find("camera cam00"),
            std::string::npos);
}

// Refinement frames are spread evenly over every take, first and last frame included, each
// frame at most once.
TEST(CalibrationCheck, RefinementFramesSpreadThroughTheSession) {
  const std::vector<std::pair<std::string, int>> takes = {{"jump", 4}, {"walk", 6}};
  auto text = [](const std::vector<CheckFrame>& frames) {
    std::string out;
    for (const CheckFrame& f : frames) out += f.take + std::to_string(f.frame) + " ";
    return out;
  };
  EXPECT_EQ(text(spread_frames(takes, 4)), "jump0 jump3 walk2 walk5 ");
  EXPECT_EQ(text(spread_frames(takes, 1)), "jump0 ");
  EXPECT_EQ(spread_frames(takes, 10).size(), 10u);
  EXPECT_EQ(text(spread_frames(takes, 50)), text(spread_frames(takes, 10)));  // all of them
  EXPECT_TRUE(spread_frames({}, 5).empty());
  EXPECT_TRUE(spread_frames(takes, 0).empty());
}

// A camera's error is judged by its median: a few mismatched points (which the triangulation's
// loose bound lets in) pull the mean up, not the median.
TEST(CalibrationCheck, ReprojectionErrorsGiveTheMedianBesideTheMean) {
  const fs::path dir = fs::temp_directory_path() / "fourd_calib_check_median";
  fs::remove_all(dir);
  fs::create_directories(dir);
  Camera cam;
  cam.name = "cam00";
  cam.intrinsics = {640, 480, 500, 500, 320, 240};
  // Five points 2 m in front of the camera, projecting to (320 + 50 k, 240); observed with
  // errors of 0.5, 0.5, 0.5, 0.6 and 10 px.
  const double offsets[] = {0.5, 0.5, 0.5, 0.6, 10};
  std::ofstream points(dir / "points3D.txt");
  std::string observations;
  for (int k = 0; k < 5; ++k) {
    points << k + 1 << " " << 0.2 * k << " 0 2 0 0 0 0 1 " << k << "\n";
    observations += std::to_string(320 + 50 * k + offsets[k]) + " 240 " + std::to_string(k + 1) + " ";
  }
  points.close();
  std::ofstream(dir / "images.txt") << "1 1 0 0 0 0 0 0 1 cam00.png\n" << observations << "\n";
  std::size_t n = 0;
  const auto errors = reprojection_errors({cam}, dir, &n);
  EXPECT_EQ(n, 5u);
  const CameraReprojection& e = errors.at("cam00");
  EXPECT_EQ(e.observations, 5u);
  EXPECT_NEAR(e.median_error_px, 0.5, 1e-6);
  EXPECT_NEAR(e.mean_error_px, 12.1 / 5, 1e-6);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace fourd::reconstruct
