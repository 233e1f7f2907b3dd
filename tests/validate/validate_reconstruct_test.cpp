// validate_segment and validate_reconstruct on hand-made sessions whose errors are known:
// silhouettes shifted by a known number of pixels, reconstructions that are the true sphere
// grown by a known distance.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <fstream>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/mesh_io.h"
#include "stages/validate/validate.h"
#include "tests/test_shapes.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;

class ValidateStagesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "fourd_validate_stages_XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    root_ = pattern;
    fs::create_directories(root_);
    std::ofstream(root_ / "session.yaml")
        << "name: t\nstages:\n  validate: {frames_per_take: 2, picture_takes: 1}\n";
    Camera c;
    c.name = "cam00";
    c.intrinsics = {80, 60, 70, 70, 40, 30};
    c.camera_from_world = look_at({0, -3, 0.5}, {0, 0, 0}, {0, 0, 1});
    write_colmap_model(root_ / "calibration", {c});
  }
  void TearDown() override { fs::remove_all(root_); }

  StageReport run(StageReport (*validator)(const ValidationContext&)) {
    Session session = Session::open(root_);
    ValidateOptions options;
    session.stage_options("validate", options);
    fs::create_directories(session.reports_dir());
    ValidationContext ctx{session, options, session.reports_dir()};
    return validator(ctx);
  }

  static double metric(const StageReport& r, const std::string& name, InputKind input) {
    for (const Metric& m : r.metrics) {
      if (m.name == name && m.input == input) return m.value;
    }
    ADD_FAILURE() << "no metric " << name;
    return -1;
  }

  fs::path root_;
};

Mesh sphere(float radius) {
  Mesh m = test::make_icosphere(4, radius);  // 2562 vertices, sagitta well below 1 mm at 0.3 m
  for (Vec3f& p : m.positions) p += Vec3f(0, 0, 0.5f);
  return m;
}

TEST_F(ValidateStagesTest, SegmentIouOfShiftedRectangles) {
  for (int f = 0; f < 3; ++f) {
    cv::Mat truth(60, 80, CV_8UC1, cv::Scalar(0)), mine = truth.clone();
    cv::rectangle(truth, cv::Rect(10, 10, 20, 20), 255, cv::FILLED);  // 400 px
    cv::rectangle(mine, cv::Rect(15, 10, 20, 20), 255, cv::FILLED);   // overlap 300 px
    write_image_atomic(root_ / "ground_truth/silhouettes/walk/cam00" / (frame_name(f) + ".png"), truth);
    write_image_atomic(root_ / "segment/walk/cam00" / (frame_name(f) + ".png"), mine);
  }
  StageReport r = run(validate_segment);
  ASSERT_TRUE(r.present) << r.summary;
  EXPECT_NEAR(metric(r, "iou_mean", InputKind::kNone), 300.0 / 500.0, 1e-9);
  EXPECT_NEAR(metric(r, "walk.iou_mean", InputKind::kNone), 0.6, 1e-9);
  EXPECT_EQ(metric(r, "silhouettes_missing", InputKind::kNone), 0);
}

TEST_F(ValidateStagesTest, SegmentAbsentIsSkipped) {
  StageReport r = run(validate_segment);
  EXPECT_FALSE(r.present);
}

TEST_F(ValidateStagesTest, ReconstructDistancesOfGrownSpheres) {
  for (int f = 0; f < 2; ++f) {
    const std::string file = frame_name(f) + ".ply";
    write_ply(root_ / "ground_truth/meshes/walk" / file, sphere(0.3f));
    write_ply(root_ / "reconstruct/walk" / file, sphere(0.303f));            // 3 mm out
    write_ply(root_ / "reconstruct/visual_hull/walk" / file, sphere(0.32f));  // 20 mm out
    std::ofstream(root_ / "reconstruct/walk" / (frame_name(f) + ".json"))
        << R"({"reconstructed": true, "seconds": {"a": 1.0, "b": 2.0}, "seconds_total": 3.0})";
  }
  StageReport r = run(validate_reconstruct);
  ASSERT_TRUE(r.present) << r.summary;
  const InputKind p = InputKind::kPipeline;
  EXPECT_NEAR(metric(r, "accuracy_median_mm", p), 3.0, 0.5);
  EXPECT_NEAR(metric(r, "accuracy_p90_mm", p), 3.0, 0.8);
  EXPECT_NEAR(metric(r, "completeness_10mm", p), 1.0, 1e-9);
  EXPECT_NEAR(metric(r, "fscore_5mm", p), 1.0, 1e-9);
  EXPECT_NEAR(metric(r, "visual_hull.accuracy_median_mm", p), 20.0, 1.0);
  EXPECT_NEAR(metric(r, "visual_hull.completeness_10mm", p), 0.0, 1e-9);
  EXPECT_NEAR(metric(r, "walk.accuracy_median_mm", p), 3.0, 0.5);
  EXPECT_NEAR(metric(r, "seconds_per_frame", p), 3.0, 1e-9);
  EXPECT_EQ(metric(r, "frames_compared", p), 2);
  EXPECT_EQ(metric(r, "frames_missing", p), 0);
  ASSERT_EQ(r.pictures.size(), 1u);
  cv::Mat picture = read_image(root_ / "reports" / r.pictures[0].file);
  EXPECT_GT(picture.cols, 80);
}

TEST_F(ValidateStagesTest, ReconstructMissingFrameIsCounted) {
  write_ply(root_ / "ground_truth/meshes/walk/000000.ply", sphere(0.3f));
  write_ply(root_ / "ground_truth/meshes/walk/000001.ply", sphere(0.3f));
  write_ply(root_ / "reconstruct/walk/000000.ply", sphere(0.3f));
  StageReport r = run(validate_reconstruct);
  ASSERT_TRUE(r.present);
  EXPECT_EQ(metric(r, "frames_missing", InputKind::kPipeline), 1);
  EXPECT_LT(metric(r, "accuracy_median_mm", InputKind::kPipeline), 0.5);
}

}  // namespace
}  // namespace fourd::validate
