#include "pipeline/core/colmap_model.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fmt/format.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"

namespace fourd {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test, removed afterwards.
class ColmapModel : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           fmt::format("fourd_colmap_{}_{}", info->name(), ::getpid());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
};

// Eight cameras on a circle with awkward (non-round) numbers; every other one undistorted so
// both the OPENCV and the PINHOLE writer paths are used.
std::vector<Camera> make_rig() {
  std::vector<Camera> rig;
  for (int i = 0; i < 8; ++i) {
    Camera c;
    c.name = fmt::format("cam{:02d}", i);
    c.intrinsics.width = 640 + 2 * i;
    c.intrinsics.height = 480;
    c.intrinsics.fx = 600.0 + i / 3.0;
    c.intrinsics.fy = 601.0 + i / 7.0;
    c.intrinsics.cx = 320.0 + 0.1 * i;
    c.intrinsics.cy = 240.0 - 1.0 / 3.0;
    if (i % 2 == 0) {
      c.intrinsics.k1 = -0.2 + i / 1000.0;
      c.intrinsics.k2 = 0.03 + 1.0 / 3e3;
      c.intrinsics.p1 = 1e-3 / 3;
      c.intrinsics.p2 = -2e-4 * i;
    }
    const double angle = 2 * M_PI * i / 8 + 0.1;
    c.camera_from_world = look_at({3 * std::cos(angle), 3 * std::sin(angle), 1.6 + 0.01 * i},
                                  {0.01, -0.02, 0.9}, {0, 0, 1});
    rig.push_back(c);
  }
  return rig;
}

void expect_same_rig(const std::vector<Camera>& a, const std::vector<Camera>& b,
                     double pose_tolerance) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE(a[i].name);
    EXPECT_EQ(a[i].name, b[i].name);
    const Intrinsics &x = a[i].intrinsics, &y = b[i].intrinsics;
    // Intrinsics are printed in shortest round-trip form: they come back bit for bit.
    EXPECT_EQ(x.width, y.width);
    EXPECT_EQ(x.height, y.height);
    EXPECT_EQ(x.fx, y.fx);
    EXPECT_EQ(x.fy, y.fy);
    EXPECT_EQ(x.cx, y.cx);
    EXPECT_EQ(x.cy, y.cy);
    EXPECT_EQ(x.k1, y.k1);
    EXPECT_EQ(x.k2, y.k2);
    EXPECT_EQ(x.p1, y.p1);
    EXPECT_EQ(x.p2, y.p2);
    // Rotations pass through a quaternion, so they agree to rounding only.
    EXPECT_LT((a[i].camera_from_world.linear() - b[i].camera_from_world.linear()).norm(),
              pose_tolerance);
    EXPECT_LT(
        (a[i].camera_from_world.translation() - b[i].camera_from_world.translation()).norm(),
        pose_tolerance);
  }
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

std::string error_of(const fs::path& dir) {
  try {
    read_colmap_model(dir);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST_F(ColmapModel, WriteReadRoundTrip) {
  const auto rig = make_rig();
  write_colmap_model(dir_, rig);
  for (const char* f : {"cameras.txt", "images.txt", "points3D.txt", "rig.json"}) {
    EXPECT_TRUE(fs::is_regular_file(dir_ / f)) << f;
  }
  const auto back = read_colmap_model(dir_);
  expect_same_rig(rig, back, 1e-14);
  for (const Camera& c : back) EXPECT_EQ(c.camera_from_world.translation(),
                                         rig[&c - back.data()].camera_from_world.translation());

  // No temp files left behind by the atomic writes.
  int files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) ++files;
  EXPECT_EQ(files, 4);

  // The written model uses OPENCV for distorted and PINHOLE for undistorted cameras.
  const std::string cameras = read_file(dir_ / "cameras.txt");
  EXPECT_NE(cameras.find("1 OPENCV 640 480 "), std::string::npos) << cameras;
  EXPECT_NE(cameras.find("2 PINHOLE 642 480 "), std::string::npos) << cameras;
  EXPECT_NE(read_file(dir_ / "images.txt").find(" 8 cam07.png\n\n"), std::string::npos);

  const auto rig_json = nlohmann::json::parse(read_file(dir_ / "rig.json"));
  ASSERT_TRUE(rig_json.is_array());
  ASSERT_EQ(rig_json.size(), 1u);
  EXPECT_EQ(rig_json[0]["ref_camera_id"], 1);
  ASSERT_EQ(rig_json[0]["cameras"].size(), 8u);
  EXPECT_EQ(rig_json[0]["cameras"][3]["camera_id"], 4);
  EXPECT_EQ(rig_json[0]["cameras"][3]["image_prefix"], "cam03");

  // Writing what was read gives the same model again (rewrite is stable).
  write_colmap_model(dir_, back);
  expect_same_rig(back, read_colmap_model(dir_), 1e-14);
}

// Through the real COLMAP: TXT -> BIN -> TXT with model_converter, then read with our reader.
TEST_F(ColmapModel, RoundTripThroughColmapModelConverter) {
  const std::string colmap = FOURD_COLMAP;
  if (colmap.empty()) GTEST_SKIP() << "colmap was not found at configure time";
  const auto rig = make_rig();
  const fs::path txt = dir_ / "txt", bin = dir_ / "bin", txt2 = dir_ / "txt2";
  write_colmap_model(txt, rig);
  fs::create_directories(bin);
  fs::create_directories(txt2);
  auto convert = [&](const fs::path& in, const fs::path& out, const char* type) {
    const std::string cmd =
        fmt::format("'{}' model_converter --input_path '{}' --output_path '{}' --output_type {} "
                    "> '{}' 2>&1",
                    colmap, in.string(), out.string(), type, (dir_ / "colmap.log").string());
    const int rc = std::system(cmd.c_str());
    ASSERT_EQ(rc, 0) << cmd << "\n" << read_file(dir_ / "colmap.log");
  };
  convert(txt, bin, "BIN");
  ASSERT_TRUE(fs::exists(bin / "cameras.bin"));
  ASSERT_TRUE(fs::exists(bin / "images.bin"));
  convert(bin, txt2, "TXT");
  ASSERT_TRUE(fs::exists(txt2 / "images.txt"));
  EXPECT_FALSE(fs::exists(txt2 / "rig.json"));  // COLMAP knows nothing of our rig file
  // COLMAP prints with 17 significant digits and normalises quaternions.
  expect_same_rig(rig, read_colmap_model(txt2), 1e-12);
}

TEST_F(ColmapModel, ReadsOtherCameraModels) {
  write_text(dir_ / "cameras.txt",
             "# comment\n"
             "1 SIMPLE_PINHOLE 100 80 50 49.5 40.5\n"
             "2 SIMPLE_RADIAL 100 80 51 50 40 -0.1\n"
             "\n"
             "3 RADIAL 100 80 52 50 40 -0.1 0.02\n"
             "4 PINHOLE 100 80 53 54 50 40\r\n");
  write_text(dir_ / "images.txt",
             "7 1 0 0 0 0 0 0 3 c.png\n\n"
             "5 1 0 0 0 0 0 0 1 a.png\n\n"
             "6 0.7071067811865476 0 0.7071067811865476 0 1 2 3 2 b.jpg\n"
             "10.5 20.5 -1 11 12 -1\n"
             "8 2 0 0 0 0 0 0 4 d.png\n");  // last POINTS2D line omitted; quaternion not unit
  write_text(dir_ / "points3D.txt", "");
  const auto cams = read_colmap_model(dir_);
  ASSERT_EQ(cams.size(), 4u);
  // IMAGE_ID order.
  EXPECT_EQ(cams[0].name, "a");
  EXPECT_EQ(cams[1].name, "b");
  EXPECT_EQ(cams[2].name, "c");
  EXPECT_EQ(cams[3].name, "d");
  EXPECT_EQ(cams[0].intrinsics.fx, 50);
  EXPECT_EQ(cams[0].intrinsics.fy, 50);
  EXPECT_EQ(cams[0].intrinsics.cx, 49.5);
  EXPECT_EQ(cams[0].intrinsics.cy, 40.5);
  EXPECT_FALSE(cams[0].intrinsics.has_distortion());
  EXPECT_EQ(cams[1].intrinsics.k1, -0.1);
  EXPECT_EQ(cams[1].intrinsics.k2, 0);
  EXPECT_EQ(cams[2].intrinsics.k1, -0.1);
  EXPECT_EQ(cams[2].intrinsics.k2, 0.02);
  EXPECT_EQ(cams[3].intrinsics.fx, 53);
  EXPECT_EQ(cams[3].intrinsics.fy, 54);
  // b: 90 degrees about y, t = (1, 2, 3).
  EXPECT_LT((cams[1].camera_from_world.linear() * Eigen::Vector3d(1, 0, 0) -
             Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
  EXPECT_EQ(cams[1].camera_from_world.translation(), Eigen::Vector3d(1, 2, 3));
  EXPECT_LT((cams[3].camera_from_world.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-15);
}

TEST_F(ColmapModel, MissingFolderAndFiles) {
  EXPECT_NE(error_of(dir_ / "nope").find("calibration folder does not exist"), std::string::npos);
  EXPECT_NE(error_of(dir_).find("cameras.txt: file does not exist"), std::string::npos)
      << error_of(dir_);
  write_text(dir_ / "cameras.txt", "1 PINHOLE 10 10 5 5 5 5\n");
  EXPECT_NE(error_of(dir_).find("images.txt: file does not exist"), std::string::npos);
  write_text(dir_ / "images.txt", "# nothing\n");
  EXPECT_NE(error_of(dir_).find("lists no images"), std::string::npos);
}

// Each malformed input gives an InputError naming the file, the line and what is wrong.
TEST_F(ColmapModel, MalformedFilesNameFileAndLine) {
  write_colmap_model(dir_, make_rig());
  const std::string good_cameras = read_file(dir_ / "cameras.txt");
  const std::string good_images = read_file(dir_ / "images.txt");
  struct Case {
    const char* file;
    std::string text;
    std::vector<std::string> expected;  // substrings of the message
  };
  const std::vector<Case> cases = {
      {"cameras.txt", "1 FISHEYE 640 480 1 2 3 4\n",
       {"cameras.txt:1:", "unknown camera model 'FISHEYE'"}},
      {"cameras.txt", "# c\n1 OPENCV 640 480 1 2 3 4 5 6 7\n",
       {"cameras.txt:2:", "OPENCV expects 8 parameters", "found 7"}},
      {"cameras.txt", "1 PINHOLE 640 480 600 600 abc 240\n",
       {"cameras.txt:1:", "'abc' is not a finite number"}},
      {"cameras.txt", "1 PINHOLE 640x 480 600 600 320 240\n",
       {"cameras.txt:1:", "WIDTH '640x' is not an integer"}},
      {"cameras.txt", "1 PINHOLE 0 480 600 600 320 240\n", {"cameras.txt:1:", "image size 0x480"}},
      {"cameras.txt", "1 PINHOLE 640 480 -600 600 320 240\n",
       {"cameras.txt:1:", "non-positive focal length"}},
      {"cameras.txt", "1 PINHOLE 640 480 600 600 320 240\n\n1 PINHOLE 640 480 600 600 320 240\n",
       {"cameras.txt:3:", "CAMERA_ID 1 appears twice"}},
      {"cameras.txt", "1 PINHOLE\n", {"cameras.txt:1:", "found 2 fields"}},
      {"images.txt", "1 1 0 0 0 0 0 0 99 cam00.png\n\n",
       {"images.txt:1:", "references CAMERA_ID 99", "cameras.txt does not define"}},
      {"images.txt", "1 1 0 0 0 0 0 0 1 cam00.png\n\n2 1 0 0 0 0 0 0 2 cam00.jpg\n\n",
       {"images.txt:3:", "camera name 'cam00'", "already used on line 1"}},
      {"images.txt", "1 1 0 0 0 0 0 0 1 cam00.png\n\n1 1 0 0 0 0 0 0 2 cam01.png\n\n",
       {"images.txt:3:", "IMAGE_ID 1 appears twice"}},
      {"images.txt", "1 1 0 0 0 0 0 0 1 cam00.png\n2 1 0 0 0 0 0 0 2 cam01.png\n",
       {"images.txt:2:", "POINTS2D line of image 1", "found 10 fields"}},
      {"images.txt", "1 1 0 0 0 0 0 1 cam00.png\n\n", {"images.txt:1:", "(10 fields), found 9"}},
      {"images.txt", "1 0 0 0 0 0 0 0 1 cam00.png\n\n", {"images.txt:1:", "zero quaternion"}},
      {"images.txt", "1 1 0 0 0 0 nan 0 1 cam00.png\n\n", {"images.txt:1:", "TY 'nan'"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.text);
    write_text(dir_ / "cameras.txt", good_cameras);
    write_text(dir_ / "images.txt", good_images);
    write_text(dir_ / c.file, c.text);
    fs::remove(dir_ / "rig.json");
    const std::string message = error_of(dir_);
    ASSERT_FALSE(message.empty()) << "no InputError";
    EXPECT_NE(message.find((dir_ / c.file).string()), std::string::npos) << message;
    for (const auto& s : c.expected) EXPECT_NE(message.find(s), std::string::npos) << message;
  }
}

TEST_F(ColmapModel, RigJsonMustAgreeWithModel) {
  write_colmap_model(dir_, make_rig());
  write_text(dir_ / "rig.json", R"([{"ref_camera_id": 1, "cameras": [{"camera_id": 42, "image_prefix": "cam00"}]}])");
  EXPECT_NE(error_of(dir_).find("camera_id 42 is not in cameras.txt"), std::string::npos);
  write_text(dir_ / "rig.json", R"([{"ref_camera_id": 1, "cameras": [{"camera_id": 1, "image_prefix": "cam05"}]}])");
  EXPECT_NE(error_of(dir_).find("starts with 'cam05'"), std::string::npos);
  write_text(dir_ / "rig.json", R"([{"ref_camera_id": 3, "cameras": [{"camera_id": 1, "image_prefix": "cam00"}]}])");
  EXPECT_NE(error_of(dir_).find("ref_camera_id 3 is not among its cameras"), std::string::npos);
  write_text(dir_ / "rig.json", "[{");
  EXPECT_NE(error_of(dir_).find("rig.json: not valid JSON"), std::string::npos);
}

TEST_F(ColmapModel, WriterRejectsBadRigs) {
  EXPECT_THROW(write_colmap_model(dir_, {}), InputError);
  auto rig = make_rig();
  rig[3].name = rig[1].name;
  EXPECT_THROW(write_colmap_model(dir_, rig), InputError);
  rig = make_rig();
  rig[0].name = "cam 0";
  EXPECT_THROW(write_colmap_model(dir_, rig), InputError);
  rig = make_rig();
  rig[2].intrinsics.fx = 0;
  EXPECT_THROW(write_colmap_model(dir_, rig), InputError);
  rig = make_rig();
  rig[2].camera_from_world.linear() *= 2;
  EXPECT_THROW(write_colmap_model(dir_, rig), InputError);
  // Nothing was written by the failed calls.
  EXPECT_TRUE(fs::is_empty(dir_));
}

}  // namespace
}  // namespace fourd
