// The validation stage on tiny hand-made sessions: metrics.json keys and values, report.md,
// pictures, absent stages skipped, damaged ground truth reported.
#include "stages/validate/validate.h"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <fstream>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/mesh_io.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;

void write_text(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::trunc) << text;
}

// An octahedron of radius 0.4 m around `center`.
Mesh octahedron(const Eigen::Vector3f& center) {
  Mesh m;
  const float r = 0.4f;
  m.positions = {center + Vec3f(r, 0, 0),  center + Vec3f(-r, 0, 0), center + Vec3f(0, r, 0),
                 center + Vec3f(0, -r, 0), center + Vec3f(0, 0, r),  center + Vec3f(0, 0, -r)};
  m.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                 {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  return m;
}

std::vector<Camera> two_cameras() {
  std::vector<Camera> cameras(2);
  const Eigen::Vector3d eyes[2] = {{0, -3, 0.5}, {3, 0, 0.5}};
  for (int i = 0; i < 2; ++i) {
    Camera& c = cameras[i];
    c.name = "cam0" + std::to_string(i);
    c.intrinsics = {80, 60, 70, 70, 40, 30};
    c.camera_from_world = look_at(eyes[i], {0, 0, 0}, {0, 0, 1});
  }
  return cameras;
}

// Filled projection of the mesh (pixel centres at +0.5 in our convention, at integers in
// OpenCV's: shift by half a pixel).
cv::Mat render_silhouette(const Camera& camera, const Mesh& mesh) {
  cv::Mat mask(camera.intrinsics.height, camera.intrinsics.width, CV_8UC1, cv::Scalar(0));
  for (const auto& t : mesh.triangles) {
    std::vector<cv::Point> poly;
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector2d px;
      EXPECT_TRUE(camera.project(mesh.positions[t[k]].cast<double>(), &px));
      poly.emplace_back(static_cast<int>(std::lround(px.x() - 0.5)),
                        static_cast<int>(std::lround(px.y() - 0.5)));
    }
    cv::fillConvexPoly(mask, poly, cv::Scalar(255));
  }
  return mask;
}

class ValidateTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "fourd_validate_test_XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    root_ = pattern;
    write_text(root_ / "session.yaml",
               "name: tiny\nstages:\n  validate: {frames_per_take: 2, picture_takes: 1}\n");
  }
  void TearDown() override { fs::remove_all(root_); }

  // One take "walk" of 3 frames seen by two cameras; the performer moves 5 cm per frame.
  void make_synthetic_session() {
    cameras_ = two_cameras();
    write_colmap_model(root_ / "calibration", cameras_);
    write_ply(root_ / "ground_truth" / "template.ply", octahedron({0, 0, 0}));
    write_text(root_ / "ground_truth" / "takes" / "walk.json",
               R"({"kind": "walk", "fps": 25, "frames": 3, "cycle_frames": 20,
                   "parameters": {"speed": 1.25}, "root": [], "phase": []})");
    for (int f = 0; f < 3; ++f) {
      Mesh mesh = octahedron({0.05f * f, 0, 0});
      write_ply(root_ / "ground_truth" / "meshes" / "walk" / (frame_name(f) + ".ply"), mesh);
      for (const auto& c : cameras_) {
        cv::Mat mask = render_silhouette(c, mesh);
        write_image_atomic(
            root_ / "ground_truth" / "silhouettes" / "walk" / c.name / (frame_name(f) + ".png"),
            mask);
        cv::Mat image(mask.size(), CV_8UC3, cv::Scalar(40, 160, 40));
        image.setTo(cv::Scalar(60, 60, 200), mask);
        write_image_atomic(root_ / "capture" / "walk" / c.name / (frame_name(f) + ".png"), image);
      }
    }
  }

  std::vector<StageReport> validate() {
    Session session = Session::open(root_);
    ValidateOptions options;
    session.stage_options("validate", options);
    return run_validation(session, options);
  }

  nlohmann::json metrics() {
    return nlohmann::json::parse(read_file(root_ / "reports" / "metrics.json"));
  }

  // Files in reports/ other than the expected ones (leftover temp files of atomic writes).
  std::vector<std::string> stray_report_files() {
    std::vector<std::string> stray;
    for (const auto& e : fs::directory_iterator(root_ / "reports")) {
      std::string name = e.path().filename().string();
      if (name.front() == '.') stray.push_back(name);
    }
    return stray;
  }

  fs::path root_;
  std::vector<Camera> cameras_;
};

TEST_F(ValidateTest, AbsentStagesAreSkippedAndBothFilesWritten) {
  std::vector<StageReport> reports = validate();
  ASSERT_EQ(reports.size(), validators().size());
  EXPECT_EQ(reports[0].stage, "synth");
  EXPECT_FALSE(reports[0].present);
  EXPECT_EQ(metrics(), nlohmann::json::object());
  std::string md = read_file(root_ / "reports" / "report.md");
  EXPECT_NE(md.find("## synth"), std::string::npos);
  EXPECT_NE(md.find("Skipped"), std::string::npos);
  EXPECT_TRUE(stray_report_files().empty());
}

TEST_F(ValidateTest, SynthMetricsOnAConsistentSession) {
  make_synthetic_session();
  write_text(root_ / "reports" / "metrics.json", "{\"stale\": 1}");  // replaced, not merged
  std::vector<StageReport> reports = validate();
  ASSERT_TRUE(reports[0].present) << reports[0].summary;

  nlohmann::json m = metrics();
  EXPECT_FALSE(m.contains("stale"));
  ASSERT_TRUE(m.contains("synth")) << m.dump();
  const auto& s = m["synth"];
  EXPECT_EQ(s["takes"], 1);
  EXPECT_EQ(s["frames"], 3);
  EXPECT_EQ(s["cameras"], 2);
  EXPECT_EQ(s["topology_mismatched_frames"], 0);
  EXPECT_DOUBLE_EQ(s["silhouette_vertex_consistency"].get<double>(), 1.0);
  EXPECT_GT(s["capture_mb"].get<double>(), 0.0);
  EXPECT_LT(s["capture_mb"].get<double>(), 1.0);

  // One picture for the one take: 2 cameras (rows) x (capture, overlay), panels at the
  // images' own size (80 x 60: smaller than panel_width, so not enlarged).
  ASSERT_EQ(reports[0].pictures.size(), 1u);
  EXPECT_EQ(reports[0].pictures[0].file, "synth_walk.png");
  cv::Mat picture = read_image(root_ / "reports" / "synth_walk.png");
  EXPECT_EQ(picture.cols, 160);
  EXPECT_EQ(picture.rows, 120);
  // The overlay half has the red outline: pure red pixels exist on the right, not on the left.
  cv::Mat red;
  cv::inRange(picture, cv::Scalar(0, 0, 250), cv::Scalar(5, 5, 255), red);
  EXPECT_EQ(cv::countNonZero(red.colRange(0, 80)), 0);
  EXPECT_GT(cv::countNonZero(red.colRange(80, 160)), 20);

  std::string md = read_file(root_ / "reports" / "report.md");
  EXPECT_NE(md.find("![synth, take walk"), std::string::npos);
  EXPECT_NE(md.find("(synth_walk.png)"), std::string::npos);
  EXPECT_NE(md.find("`synth.silhouette_vertex_consistency` | 1 |"), std::string::npos) << md;
  EXPECT_NE(md.find("speed = 1.25"), std::string::npos);
  EXPECT_TRUE(stray_report_files().empty());
}

TEST_F(ValidateTest, SilhouettesThatMissTheMeshLowerConsistency) {
  make_synthetic_session();
  // Frame 2 (the last sampled frame) of cam01 loses its silhouette: every vertex of that frame
  // that cam01 sees is now inconsistent, frame 0 stays consistent.
  cv::Mat empty(60, 80, CV_8UC1, cv::Scalar(0));
  write_image_atomic(root_ / "ground_truth" / "silhouettes" / "walk" / "cam01" / "000002.png",
                     empty);
  validate();
  double consistency = metrics()["synth"]["silhouette_vertex_consistency"].get<double>();
  EXPECT_NEAR(consistency, 0.5, 1e-9);
}

TEST_F(ValidateTest, TopologyChangeIsCounted) {
  make_synthetic_session();
  Mesh other = octahedron({0.1f, 0, 0});
  std::swap(other.triangles[0], other.triangles[1]);
  write_ply(root_ / "ground_truth" / "meshes" / "walk" / "000002.ply", other);
  validate();
  EXPECT_EQ(metrics()["synth"]["topology_mismatched_frames"], 1);
}

TEST_F(ValidateTest, DamagedGroundTruthFailsButStillWritesReports) {
  make_synthetic_session();
  write_text(root_ / "ground_truth" / "takes" / "walk.json", "{\"kind\": \"walk\"}");  // no frames
  EXPECT_THROW(validate(), InputError);
  EXPECT_EQ(metrics(), nlohmann::json::object());
  std::string md = read_file(root_ / "reports" / "report.md");
  EXPECT_NE(md.find("**Validation failed:**"), std::string::npos);
  EXPECT_NE(md.find("walk.json"), std::string::npos);
}

TEST(MetricsJson, StageInputAndMetricNesting) {
  StageReport align;
  align.stage = "align";
  align.present = true;
  align.metrics = {{"correspondence_rms_mm", 7.5, InputKind::kOracle, ""},
                   {"correspondence_rms_mm", 12.25, InputKind::kPipeline, ""},
                   {"flipped_triangles", 0, InputKind::kNone, ""}};
  StageReport absent;
  absent.stage = "texture";
  nlohmann::json j = metrics_json({align, absent});
  EXPECT_EQ(j["align"]["oracle"]["correspondence_rms_mm"], 7.5);
  EXPECT_EQ(j["align"]["pipeline"]["correspondence_rms_mm"], 12.25);
  EXPECT_TRUE(j["align"]["flipped_triangles"].is_number_integer());
  EXPECT_FALSE(j.contains("texture"));
  EXPECT_EQ(metric_key("align", align.metrics[0]), "align.oracle.correspondence_rms_mm");
  EXPECT_EQ(metric_key("align", align.metrics[2]), "align.flipped_triangles");
}

}  // namespace
}  // namespace fourd::validate
