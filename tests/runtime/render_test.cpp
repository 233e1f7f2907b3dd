// Headless rendering of the player (runtime/player/render.h) on the small procedural graph:
// the character is in the picture and centred by the follow camera, textured when the asset
// has textures and shaded when not, studio cameras from a calibration folder, the video.
#include "runtime/player/render.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/process.h"
#include "tests/graph/test_graph.h"

namespace fourd {
namespace {

class PlayerRenderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / fmt::format("fourd_render_{}_{}", ::getpid(), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Plays half a second at 10 fps with `render` and returns the renderer's statistics.
  std::vector<RenderedFrameStats> play(const MotionGraph& graph, RenderOptions render,
                                       const std::string& script_text =
                                           "fps 10\nduration 0.5\nstart locomotion 1.2\n") {
    Asset asset;
    asset.graph = graph;
    const ControlScript script = parse_control_script(script_text, "test");
    FrameRenderer renderer(asset.graph, render);
    PlayerOptions options;
    options.out_dir = dir_ / "play";
    options.write_meshes = false;
    options.observer = &renderer;
    run_player(asset, script, options);
    renderer.finish(script.fps);
    textured_ = renderer.textured();
    return renderer.stats();
  }

  fs::path dir_;
  bool textured_ = false;
};

const MotionGraph& textured_graph() { return test::textured_test_graph(); }

TEST_F(PlayerRenderTest, FollowCameraKeepsTheTexturedCharacterCentred) {
  RenderOptions o;
  o.dir = dir_ / "frames";
  o.width = 160;
  o.height = 120;
  o.distance = 2.5;
  const std::vector<RenderedFrameStats> stats = play(textured_graph(), o);
  EXPECT_TRUE(textured_);
  ASSERT_EQ(stats.size(), 6u);
  for (const RenderedFrameStats& s : stats) {
    EXPECT_GT(s.foreground, 0.02) << "frame " << s.frame;
    EXPECT_LT(s.foreground, 0.6) << "frame " << s.frame;
    EXPECT_NEAR(s.centroid_x, 0.5, 0.12) << "frame " << s.frame;
    EXPECT_NEAR(s.centroid_y, 0.5, 0.2) << "frame " << s.frame;
    const cv::Mat image = read_image(o.dir / fmt::format("frame_{:05d}.png", s.frame));
    EXPECT_EQ(image.cols, 160);
    EXPECT_EQ(image.rows, 120);
  }
  const nlohmann::json j = nlohmann::json::parse(read_file(o.dir / "render.json"));
  EXPECT_EQ(j["frames"], 6);
  EXPECT_TRUE(j["textured"].get<bool>());
  EXPECT_LT(j["max_centroid_offset"].get<double>(), 0.2);
}

// The key textures' colours reach the picture; without textures the character is grey.
TEST_F(PlayerRenderTest, TexturedAndShadedCharactersDiffer) {
  RenderOptions o;
  o.dir = dir_ / "textured";
  o.width = 160;
  o.height = 120;
  o.distance = 2.5;
  play(textured_graph(), o);
  o.dir = dir_ / "shaded";
  play(test::make_test_graph(), o);
  EXPECT_FALSE(textured_);
  const cv::Mat a = read_image(dir_ / "textured" / "frame_00000.png");
  const cv::Mat b = read_image(dir_ / "shaded" / "frame_00000.png");
  // Grey shading: the character's pixels have (nearly) equal channels; the test textures do not.
  auto colourfulness = [](const cv::Mat& image) {
    const cv::Rect centre(image.cols * 2 / 5, image.rows / 3, image.cols / 5, image.rows / 3);
    double sum = 0;
    for (int r = centre.y; r < centre.y + centre.height; ++r) {
      for (int c = centre.x; c < centre.x + centre.width; ++c) {
        const cv::Vec3b p = image.at<cv::Vec3b>(r, c);
        sum += std::max({p[0], p[1], p[2]}) - std::min({p[0], p[1], p[2]});
      }
    }
    return sum / centre.area();
  };
  EXPECT_GT(colourfulness(a), colourfulness(b) + 15);
  EXPECT_GT(cv::norm(a, b, cv::NORM_L1) / a.total(), 5.0);
}

TEST_F(PlayerRenderTest, StudioCameraFromCalibration) {
  Camera cam;
  cam.name = "cam00";
  cam.intrinsics.width = 200;
  cam.intrinsics.height = 150;
  cam.intrinsics.fx = cam.intrinsics.fy = 180;
  cam.intrinsics.cx = 100;
  cam.intrinsics.cy = 75;
  cam.camera_from_world = look_at({0.5, -3, 1.2}, {0.5, 0, 0.5}, Eigen::Vector3d::UnitZ());
  write_colmap_model(dir_ / "calibration", {cam});
  RenderOptions o;
  o.dir = dir_ / "studio";
  o.camera = "studio:0";
  o.calibration = dir_ / "calibration";
  const std::vector<RenderedFrameStats> stats = play(textured_graph(), o);
  ASSERT_FALSE(stats.empty());
  EXPECT_GT(stats.front().foreground, 0.01);
  const cv::Mat image = read_image(o.dir / "frame_00000.png");
  EXPECT_EQ(image.cols, 200);
  EXPECT_EQ(image.rows, 150);

  o.camera = "studio:3";
  EXPECT_THROW(FrameRenderer(textured_graph(), o), InputError);
  o.camera = "studio:x";
  EXPECT_THROW(FrameRenderer(textured_graph(), o), UsageError);
  o.camera = "studio:0";
  o.calibration.clear();
  EXPECT_THROW(FrameRenderer(textured_graph(), o), UsageError);
}

TEST_F(PlayerRenderTest, VideoWithFfmpegAndAWarningWithout) {
  RenderOptions o;
  o.dir = dir_ / "frames";
  o.width = 96;
  o.height = 72;
  o.mp4 = dir_ / "video" / "play.mp4";
  if (!find_executable("ffmpeg").empty()) {
    play(textured_graph(), o);
    ASSERT_TRUE(fs::is_regular_file(o.mp4));
    EXPECT_GT(fs::file_size(o.mp4), 1000u);
    fs::remove(o.mp4);
  }
  // No ffmpeg on PATH: the PNGs are written, the video is not, and render.json says why.
  const char* old_path = std::getenv("PATH");
  const std::string saved = old_path ? old_path : "";
  ::setenv("PATH", (dir_ / "empty").c_str(), 1);
  play(textured_graph(), o);
  ::setenv("PATH", saved.c_str(), 1);
  EXPECT_FALSE(fs::exists(o.mp4));
  EXPECT_TRUE(fs::is_regular_file(o.dir / "frame_00005.png"));
  const nlohmann::json j = nlohmann::json::parse(read_file(o.dir / "render.json"));
  EXPECT_FALSE(j["mp4"]["written"].get<bool>());
}

}  // namespace
}  // namespace fourd
