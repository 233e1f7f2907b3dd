#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <opencv2/core.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/exchange/texture_image.h"
#include "stages/validate/validate.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;

class TextureFlicker : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "fourd_flicker_test_XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
    // One chart: the left half of the atlas.
    atlas_.positions = {Vec3f(0, 0, 0), Vec3f(1, 0, 0), Vec3f(0, 1, 0), Vec3f(1, 1, 0)};
    atlas_.triangles = {Tri(0, 1, 2), Tri(1, 3, 2)};
    atlas_.uvs = {Vec2f(0, 0), Vec2f(0.5f, 0), Vec2f(0, 1), Vec2f(0.5f, 1)};
    atlas_.uv_triangles = atlas_.triangles;
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A texture whose chart half is `inside` and whose other half is `outside` (8-bit levels).
  void write(const std::string& take, int frame, int inside, int outside) {
    cv::Mat image(64, 64, CV_8UC3, cv::Scalar::all(outside));
    image.colRange(0, 32).setTo(cv::Scalar::all(inside));
    write_texture(dir_ / take / (frame_name(frame) + ".png"), image);
  }

  fs::path dir_;
  Mesh atlas_;
};

TEST_F(TextureFlicker, IsTheMeanChangeOfChartTexelsBetweenConsecutiveFrames) {
  write("a", 0, 100, 0);
  write("a", 1, 110, 200);  // the gutter outside the chart changes a lot: not counted
  write("a", 2, 110, 0);
  write("b", 0, 50, 0);     // a new take: no pair across takes
  write("b", 1, 56, 0);
  // Pairs: a 0-1 (10), a 1-2 (0), b 0-1 (6).
  EXPECT_NEAR(texture_flicker(dir_, ".png", {{"a", 3}, {"b", 2}}, atlas_), 16.0 / 3, 1e-3);
}

TEST_F(TextureFlicker, StaticTexturesDoNotFlicker) {
  for (int f = 0; f < 4; ++f) write("a", f, 77, f * 40);
  EXPECT_NEAR(texture_flicker(dir_, ".png", {{"a", 4}}, atlas_), 0.0, 1e-6);
}

TEST_F(TextureFlicker, AMissingOrResizedTextureIsAClearError) {
  write("a", 0, 100, 0);
  EXPECT_THROW(texture_flicker(dir_, ".png", {{"a", 2}}, atlas_), IoError);
  write_texture(dir_ / "a" / "000001.png", cv::Mat(32, 32, CV_8UC3, cv::Scalar::all(1)));
  EXPECT_THROW(texture_flicker(dir_, ".png", {{"a", 2}}, atlas_), InputError);
}

}  // namespace
}  // namespace fourd::validate
