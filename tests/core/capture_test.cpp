#include "pipeline/core/capture.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fmt/format.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"

namespace fourd {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 32;
constexpr int kHeight = 24;

Camera small_camera(const std::string& name) {
  Camera c;
  c.name = name;
  c.intrinsics.width = kWidth;
  c.intrinsics.height = kHeight;
  c.intrinsics.fx = c.intrinsics.fy = 30;
  c.intrinsics.cx = kWidth / 2.0;
  c.intrinsics.cy = kHeight / 2.0;
  return c;
}

// A session folder in a temp dir with two calibrated cameras; tests add capture frames.
class Capture : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            fmt::format("fourd_capture_{}_{}", info->name(), ::getpid());
    fs::remove_all(root_);
    fs::create_directories(root_);
    // "stages: {}" because SessionConfig::check() rejects an absent stages section (a
    // default YAML::Node is Null, not a map): reported to the lead.
    write_file_atomic(root_ / "session.yaml", "name: t\nstages: {}\n");
    calibration_ = {small_camera("cam00"), small_camera("cam01")};
    write_colmap_model(root_ / "calibration", calibration_);
  }
  void TearDown() override { fs::remove_all(root_); }

  Session session() const { return Session::open(root_); }

  // A frame whose pixels encode camera, frame and position, so a read can be checked.
  static cv::Mat frame_image(int camera, int frame, int width = kWidth, int height = kHeight) {
    cv::Mat image(height, width, CV_8UC3);
    for (int r = 0; r < height; ++r) {
      for (int c = 0; c < width; ++c) {
        image.at<cv::Vec3b>(r, c) = cv::Vec3b(static_cast<uchar>(camera * 50), static_cast<uchar>(frame),
                                              static_cast<uchar>(r + c));
      }
    }
    return image;
  }

  void write_frames(const std::string& take, int camera, int count) {
    const Session s = session();
    for (int f = 0; f < count; ++f) {
      write_image_atomic(s.capture_image(take, calibration_[camera].name, f), frame_image(camera, f));
    }
  }

  // The InputError message of scan_capture, or "" when it succeeds.
  std::string scan_error() const {
    try {
      scan_capture(session(), calibration_);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }

  std::string read_error(const std::string& take, int camera, int frame) const {
    try {
      read_capture_image(session(), calibration_[camera], take, frame);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }

  fs::path root_;
  std::vector<Camera> calibration_;
};

TEST_F(Capture, ScansTakesAndReadsFrames) {
  write_frames("walk", 0, 3);
  write_frames("walk", 1, 3);
  write_frames("jump", 0, 2);
  write_frames("jump", 1, 2);
  fs::create_directories(root_ / "capture" / "walk" / "cam09");  // not calibrated
  write_file_atomic(root_ / "capture" / "walk" / "cam00" / "notes.txt", "not a frame");
  write_file_atomic(root_ / "capture" / "walk" / "cam00" / ".000003.tmp1-0.png", "half");

  const Session s = session();
  const auto cameras = read_colmap_model(s.calibration_dir());
  const CaptureIndex index = scan_capture(s, cameras);
  ASSERT_EQ(index.takes.size(), 2u);
  EXPECT_EQ(index.takes[0].name, "jump");  // sorted
  EXPECT_EQ(index.takes[0].frame_count, 2);
  EXPECT_EQ(index.takes[1].name, "walk");
  EXPECT_EQ(index.takes[1].frame_count, 3);
  EXPECT_EQ(index.takes[1].uncalibrated_folders, std::vector<std::string>{"cam09"});
  EXPECT_EQ(index.take("walk").frame_count, 3);
  EXPECT_THROW(index.take("run"), InputError);

  const cv::Mat image = read_capture_image(s, cameras[1], "walk", 2);
  ASSERT_EQ(image.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(image, frame_image(1, 2), cv::NORM_INF), 0);  // PNG is lossless
}

TEST_F(Capture, CameraWithoutFolderOrFrames) {
  write_frames("walk", 0, 3);
  std::string message = scan_error();
  EXPECT_NE(message.find("take 'walk'"), std::string::npos) << message;
  EXPECT_NE(message.find("camera 'cam01' has no folder"), std::string::npos) << message;

  fs::create_directories(root_ / "capture" / "walk" / "cam01");
  write_file_atomic(root_ / "capture" / "walk" / "cam01" / "readme.txt", "x");
  message = scan_error();
  EXPECT_NE(message.find("camera 'cam01' has no frames"), std::string::npos) << message;
}

TEST_F(Capture, FrameCountsDiffer) {
  write_frames("run", 0, 4);
  write_frames("run", 1, 3);
  const std::string message = scan_error();
  EXPECT_NE(message.find("take 'run'"), std::string::npos) << message;
  EXPECT_NE(message.find("camera 'cam01' has 3 frames but camera 'cam00' has 4"),
            std::string::npos)
      << message;
}

TEST_F(Capture, GapInFrameNumbering) {
  write_frames("run", 0, 4);
  write_frames("run", 1, 4);
  fs::remove(session().capture_image("run", "cam01", 2));
  // cam01 now has 000000, 000001, 000003: frame 000002 is missing.
  const std::string message = scan_error();
  EXPECT_NE(message.find("camera 'cam01' is missing frame 000002"), std::string::npos) << message;
  EXPECT_NE(message.find((fs::path("run") / "cam01" / "000002.png").string()), std::string::npos)
      << message;
}

TEST_F(Capture, MissingCaptureFolderOrNoTakes) {
  EXPECT_NE(scan_error().find("capture folder does not exist"), std::string::npos);
  fs::create_directories(root_ / "capture");
  EXPECT_NE(scan_error().find("no takes"), std::string::npos);
}

TEST_F(Capture, MissingCalibrationFolder) {
  fs::remove_all(root_ / "calibration");
  const Session s = session();
  try {
    read_colmap_model(s.calibration_dir());
    FAIL() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(s.calibration_dir().string()), std::string::npos)
        << e.what();
  }
}

TEST_F(Capture, WrongImageSize) {
  write_frames("walk", 0, 2);
  write_frames("walk", 1, 2);
  write_image_atomic(session().capture_image("walk", "cam01", 1), frame_image(1, 1, 40, 24));
  // The scan only looks at names; the size is checked when the frame is read.
  EXPECT_EQ(scan_error(), "");
  const std::string message = read_error("walk", 1, 1);
  EXPECT_NE(message.find("000001.png"), std::string::npos) << message;
  EXPECT_NE(message.find("image is 40x24 but the calibration of camera 'cam01' is 32x24"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("frame 000001"), std::string::npos) << message;
}

TEST_F(Capture, CorruptPng) {
  write_frames("walk", 0, 2);
  write_frames("walk", 1, 2);
  const fs::path file = session().capture_image("walk", "cam00", 1);
  fs::resize_file(file, fs::file_size(file) / 2);  // truncated: the IDAT chunk is cut
  std::string message = read_error("walk", 0, 1);
  EXPECT_NE(message.find(file.string()), std::string::npos) << message;
  EXPECT_NE(message.find("camera 'cam00'"), std::string::npos) << message;
  EXPECT_NE(message.find("frame 000001"), std::string::npos) << message;

  write_file_atomic(file, "");  // empty file
  message = read_error("walk", 0, 1);
  EXPECT_NE(message.find(file.string()), std::string::npos) << message;

  // The other frame still reads.
  EXPECT_NO_THROW(read_capture_image(session(), calibration_[0], "walk", 0));
}

TEST_F(Capture, MissingFrameFile) {
  write_frames("walk", 0, 2);
  const std::string message = read_error("walk", 0, 5);
  EXPECT_NE(message.find("000005.png: frame file does not exist"), std::string::npos) << message;
  EXPECT_NE(message.find("camera 'cam00'"), std::string::npos) << message;
}

TEST(ImageIo, WriteImageAtomicErrors) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("fourd_image_io_{}", ::getpid());
  fs::remove_all(dir);
  EXPECT_THROW(write_image_atomic(dir / "a.png", cv::Mat()), IoError);
  EXPECT_THROW(write_image_atomic(dir / "a.unknownext", cv::Mat(4, 4, CV_8UC3)), IoError);
  // Folder created, no temp files left behind by the failures.
  write_image_atomic(dir / "sub" / "b.png", cv::Mat(4, 4, CV_8UC1, cv::Scalar(7)));
  const cv::Mat back = read_image(dir / "sub" / "b.png", cv::IMREAD_UNCHANGED);
  EXPECT_EQ(back.type(), CV_8UC1);
  EXPECT_EQ(back.at<uchar>(3, 3), 7);
  int files = 0;
  for ([[maybe_unused]] const auto& e : fs::recursive_directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 2);  // sub/ and sub/b.png
  EXPECT_THROW(read_image(dir / "missing.png"), IoError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace fourd
