#include "stages/import/import.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "pipeline/core/capture.h"
#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/log.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/core/session.h"
#include "pipeline/exchange/aligned_input.h"
#include "stages/import/media.h"
#include "tests/import/import_test_data.h"
#include "tests/input_error.h"
#include "tests/scratch_dir.h"
#include "tests/test_shapes.h"

namespace fourd::import {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr int kWidth = 64, kHeight = 48, kFrames = 12;

cv::Mat source_frame(int camera, int frame, int width = kWidth, int height = kHeight) {
  cv::Mat image(height, width, CV_8UC3);
  cv::RNG rng(static_cast<std::uint64_t>(1000 * camera + frame + 1));
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  return image;
}

bool same_pixels(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::countNonZero(a.reshape(1) != b.reshape(1)) == 0;
}

// A studio's material for a 2-camera rig: calibration.json, one lossless video per camera
// (ffmpeg, FFV1), the frames as PNG files too.
struct Studio {
  fs::path dir;
  std::vector<Camera> rig;
};

Studio make_studio(const std::string& name, int frames = kFrames) {
  Studio s{test::scratch_dir(name), test::circle_rig(2, kWidth, kHeight)};
  export_calibration(s.rig, "json", s.dir / "calibration.json", LengthUnit::kMillimetre);
  for (int c = 0; c < 2; ++c) {
    const std::string camera = s.rig[c].name;
    for (int f = 0; f < frames; ++f) {
      write_image_atomic(s.dir / "frames" / camera / fmt::format("img_{:04d}.png", f + 1), source_frame(c, f));
    }
    fs::create_directories(s.dir / "videos");
    const std::string command = fmt::format(
        "ffmpeg -loglevel error -y -framerate 10 -start_number 1 -i '{}/frames/{}/img_%04d.png' -c:v ffv1 "
        "-pix_fmt bgr0 '{}/videos/take_{}.mkv'",
        s.dir.string(), camera, s.dir.string(), camera);
    EXPECT_EQ(std::system(command.c_str()), 0) << command;
  }
  return s;
}

ImportOptions base_options(const Studio& s, const std::string& session) {
  ImportOptions o;
  o.session = s.dir / session;
  o.calibration.paths = {s.dir / "calibration.json"};
  return o;
}

json record(const fs::path& dir) { return json::parse(read_file(dir / "imported.json")); }

TEST(Import, VideosBecomeTakesPixelForPixel) {
  const Studio s = make_studio("import_videos");
  ImportOptions o = base_options(s, "session");
  o.videos = {s.dir / "videos"};
  o.takes = {"walk=0:5", "run=6:"};
  log::Timer timer;
  run_import(o);
  std::printf("video import: %d frames x 2 cameras in %.2f s\n", kFrames, timer.seconds());

  const Session session = Session::open(o.session);
  EXPECT_DOUBLE_EQ(session.config().fps, 10);
  const std::vector<Camera> cameras = read_colmap_model(session.calibration_dir());
  ASSERT_EQ(cameras.size(), 2u);
  const CaptureIndex index = scan_capture(session, cameras);
  ASSERT_EQ(index.takes.size(), 2u);
  EXPECT_EQ(index.take("walk").frame_count, 6);
  EXPECT_EQ(index.take("run").frame_count, 6);
  int compared = 0;
  for (int c = 0; c < 2; ++c) {
    for (int f = 0; f < 6; ++f) {
      EXPECT_TRUE(same_pixels(read_capture_image(session, cameras[c], "walk", f), source_frame(c, f)));
      EXPECT_TRUE(same_pixels(read_capture_image(session, cameras[c], "run", f), source_frame(c, 6 + f)));
      compared += 2;
    }
  }
  std::printf("video round trip: %d of %d frames pixel-identical\n", compared, 2 * kFrames);
  const json capture = record(session.capture_dir());
  EXPECT_EQ(capture["tool"], "fourd-import");
  EXPECT_EQ(capture["what"], "capture");
  EXPECT_EQ(capture["takes"]["run"]["frames"], 6);
  EXPECT_EQ(capture["takes"]["run"]["source_first"], 6);
  EXPECT_EQ(record(session.calibration_dir())["checks"]["units"], "mm");
  EXPECT_FALSE(fs::exists(o.session / ".calibration.staging.tmp"));

  // Extending the session: another take from the same videos, every 3rd frame; the others stay.
  ImportOptions more;
  more.session = o.session;
  more.videos = {s.dir / "videos"};
  more.takes = {"sparse"};
  more.step = 3;
  run_import(more);
  const CaptureIndex extended = scan_capture(Session::open(o.session), cameras);
  EXPECT_EQ(extended.takes.size(), 3u);
  EXPECT_EQ(extended.take("sparse").frame_count, 4);
  EXPECT_TRUE(same_pixels(read_capture_image(session, cameras[1], "sparse", 3), source_frame(1, 9)));
  EXPECT_EQ(record(session.capture_dir())["takes"].size(), 3u);
  // A take that exists is not overwritten without --replace.
  EXPECT_THROW(run_import(more), UsageError);
}

TEST(Import, ImageFoldersTimeRangesAndBadInputLeaveNothing) {
  const Studio s = make_studio("import_images");
  ImportOptions o = base_options(s, "session");
  o.images = (s.dir / "frames" / "{camera}" / "img_{frame:04d}.png").string();
  o.fps = 4;
  o.takes = {"a=0.5s:2s"};  // frames 2..7 at 4 fps
  run_import(o);
  const Session session = Session::open(o.session);
  const std::vector<Camera> cameras = read_colmap_model(session.calibration_dir());
  EXPECT_EQ(scan_capture(session, cameras).take("a").frame_count, 6);
  EXPECT_TRUE(same_pixels(read_capture_image(session, cameras[0], "a", 0), source_frame(0, 2)));

  // A take beyond the end of the videos: named, and nothing written.
  ImportOptions bad = base_options(s, "bad");
  bad.videos = {s.dir / "videos"};
  bad.takes = {"long=0:40"};
  {
    const std::string error = test::input_error([&] { run_import(bad); });
    EXPECT_NE(error.find("12 frames, but take long asks for frames 0:40"), std::string::npos) << error;
    EXPECT_NE(error.find("take_cam0"), std::string::npos) << error;
  }
  EXPECT_FALSE(fs::exists(bad.session / "calibration"));
  EXPECT_FALSE(fs::exists(bad.session / "capture"));
  EXPECT_FALSE(fs::exists(bad.session / "session.yaml"));
  // A camera without a video: both lists named.
  ImportOptions missing = base_options(s, "missing");
  missing.videos = {s.dir / "videos" / "take_cam00.mkv"};
  missing.takes = {"t"};
  {
    const std::string error = test::input_error([&] { run_import(missing); });
    EXPECT_NE(error.find("cameras with no video: cam01"), std::string::npos) << error;
    EXPECT_NE(error.find("calibration's cameras: cam00, cam01"), std::string::npos) << error;
  }
  EXPECT_FALSE(fs::exists(missing.session / "calibration"));
}

// Cameras of different resolutions: each frame must have its own camera's size.
TEST(Import, CamerasOfDifferentSizes) {
  const fs::path dir = test::scratch_dir("import_sizes");
  std::vector<Camera> rig = test::circle_rig(2, kWidth, kHeight);
  rig[1].intrinsics.width = 80;
  rig[1].intrinsics.height = 60;
  rig[1].intrinsics.cx = 40.2;
  rig[1].intrinsics.cy = 29.7;
  export_calibration(rig, "json", dir / "calibration.json", LengthUnit::kMetre);
  for (int c = 0; c < 2; ++c) {
    for (int f = 0; f < 4; ++f) {
      write_image_atomic(dir / "raw" / rig[c].name / fmt::format("{}.png", f),
                         source_frame(c, f, rig[c].intrinsics.width, rig[c].intrinsics.height));
    }
  }
  ImportOptions o;
  o.session = dir / "session";
  o.calibration.paths = {dir / "calibration.json"};
  o.images = (dir / "raw" / "{camera}" / "*.png").string();
  o.takes = {"t=1:"};
  run_import(o);
  const Session session = Session::open(o.session);
  const std::vector<Camera> cameras = read_colmap_model(session.calibration_dir());
  EXPECT_TRUE(same_pixels(read_capture_image(session, cameras[1], "t", 2), source_frame(1, 3, 80, 60)));
  EXPECT_EQ(scan_capture(session, cameras).take("t").frame_count, 3);

  write_image_atomic(dir / "raw" / "cam01" / "2.png", source_frame(1, 2));  // 64x48
  o.session = dir / "bad";
  const std::string error = test::input_error([&] { run_import(o); });
  EXPECT_NE(error.find("2.png (camera cam01, take t frame 000001): 64x48, but camera cam01 is calibrated at 80x60"),
            std::string::npos)
      << error;
  EXPECT_FALSE(fs::exists(o.session / "capture"));
}

TEST(Import, MasksAndPlates) {
  const Studio s = make_studio("import_masks", 6);
  for (int c = 0; c < 2; ++c) {
    for (int f = 0; f < 6; ++f) {
      cv::Mat mask(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
      mask(cv::Rect(10 + f, 10, 20, 20)).setTo(200);
      mask(cv::Rect(40, 30, 5, 5)).setTo(40);  // soft matte noise, below the threshold
      write_image_atomic(s.dir / "mattes" / fmt::format("{}_m{:03d}.png", s.rig[c].name, f), mask);
    }
  }
  write_image_atomic(s.dir / "plates" / "cam01_empty.png", source_frame(1, 99));
  ImportOptions o = base_options(s, "session");
  o.videos = {s.dir / "videos"};
  o.takes = {"t=1:4"};
  o.masks = (s.dir / "mattes" / "{camera}_m{frame:03d}.png").string();
  o.mask_threshold = 127;
  o.plates = {s.dir / "plates", s.dir / "videos" / "take_cam00.mkv"};
  o.plate_frames = 4;
  run_import(o);
  const fs::path masks = o.session / "masks" / "t";
  const cv::Mat m = read_image(masks / "cam01" / "000000.png", cv::IMREAD_UNCHANGED);
  ASSERT_EQ(m.type(), CV_8UC1);
  EXPECT_EQ(m.at<std::uint8_t>(15, 15), 255);   // frame 1's square starts at x = 11
  EXPECT_EQ(m.at<std::uint8_t>(15, 10), 0);
  EXPECT_EQ(m.at<std::uint8_t>(32, 42), 0);     // the soft noise is gone
  EXPECT_EQ(cv::countNonZero(m), 400);
  EXPECT_TRUE(fs::exists(masks / "cam00" / "000003.png"));
  EXPECT_FALSE(fs::exists(masks / "cam00" / "000004.png"));
  EXPECT_EQ(record(o.session / "masks")["what"], "masks");
  // Plates: 4 evenly sampled frames of the video (0, 1, 3, 5 of 6), one image.
  EXPECT_TRUE(same_pixels(read_image(o.session / "plates" / "cam00" / "000003.png"), source_frame(0, 5)));
  EXPECT_TRUE(same_pixels(read_image(o.session / "plates" / "cam00" / "000000.png"), source_frame(0, 0)));
  EXPECT_FALSE(fs::exists(o.session / "plates" / "cam00" / "000004.png"));
  EXPECT_TRUE(same_pixels(read_image(o.session / "plates" / "cam01" / "000000.png"), source_frame(1, 99)));
  EXPECT_EQ(record(o.session / "plates")["checks"]["plates_per_camera"]["cam00"], 4);

  // A mask of the wrong size: file, camera and frame named; the import leaves nothing.
  write_image_atomic(s.dir / "mattes" / "cam01_m003.png", cv::Mat(10, 10, CV_8UC1, cv::Scalar(255)));
  ImportOptions bad = o;
  bad.session = s.dir / "bad";
  {
    const std::string error = test::input_error([&] { run_import(bad); });
    EXPECT_NE(error.find("cam01_m003.png (camera cam01, take t frame 000002): 10x10"), std::string::npos) << error;
  }
  EXPECT_FALSE(fs::exists(bad.session / "masks"));
  EXPECT_FALSE(fs::exists(bad.session / "capture"));
}

Mesh moved(const Mesh& base, int frame) {
  Mesh m = base;
  for (Vec3f& p : m.positions) p += Vec3f(0.01f * frame, 0, 1.0f + 0.001f * frame * p.z());
  return m;
}

TEST(Import, MeshSequences) {
  const fs::path dir = test::scratch_dir("import_meshes");
  const Mesh sphere = test::make_icosphere(2, 0.3f);
  for (int f = 0; f < 5; ++f) {
    Mesh m = moved(sphere, f);
    for (Vec3f& p : m.positions) p *= 1000;  // millimetres
    write_ply(dir / "consistent" / fmt::format("mesh_{}.ply", f), m);
    write_mesh(dir / "mixed" / fmt::format("frame{}.obj", f), f == 3 ? test::make_icosphere(1, 300) : m);
  }
  ImportOptions o;
  o.session = dir / "session";
  o.meshes = {dir / "consistent"};
  o.consistent = true;
  o.takes = {"walk=0:3", "hop=4:4"};
  run_import(o);
  const AlignedInput aligned = open_aligned_input(o.session / "align");
  EXPECT_EQ(aligned.template_mesh.num_vertices(), sphere.num_vertices());
  const std::vector<Eigen::Matrix3Xd> walk = load_take(aligned, "walk");
  ASSERT_EQ(walk.size(), 4u);
  EXPECT_NEAR(walk[2](0, 0), moved(sphere, 2).positions[0].x(), 1e-6);  // mm -> m
  EXPECT_EQ(load_take(aligned, "hop").size(), 1u);
  const json r = record(o.session / "align");
  EXPECT_EQ(r["what"], "align");
  EXPECT_EQ(r["checks"]["units"], "mm");
  EXPECT_EQ(r["checks"]["manifold"]["open_frames"], 0);

  // Frame 3 of another topology: refused as consistent, naming it...
  ImportOptions mixed;
  mixed.session = dir / "mixed_session";
  mixed.meshes = {dir / "mixed"};
  mixed.consistent = true;
  mixed.takes = {"walk"};
  {
    const std::string error = test::input_error([&] { run_import(mixed); });
    EXPECT_NE(error.find("frame3.obj (take walk frame 000003): not the topology"), std::string::npos)
        << error;
  }
  EXPECT_FALSE(fs::exists(mixed.session / "align"));
  // ... and imported as reconstruct/ without --consistent.
  mixed.consistent = false;
  run_import(mixed);
  for (int f = 0; f < 5; ++f) EXPECT_TRUE(fs::exists(mixed.session / "reconstruct" / "walk" / (frame_name(f) + ".ply")));
  EXPECT_EQ(record(mixed.session / "reconstruct")["checks"]["confidence"], "none (not from fourd-reconstruct)");
  EXPECT_TRUE(read_ply(mixed.session / "reconstruct" / "walk" / "000000.ply").confidence.empty());
}

TEST(ImportMedia, PatternsNamesAndTakes) {
  EXPECT_TRUE(natural_less("img2.png", "img10.png"));
  EXPECT_FALSE(natural_less("img10.png", "img2.png"));
  EXPECT_TRUE(natural_less("a_9b", "a_10a"));
  const fs::path dir = test::scratch_dir("import_patterns");
  for (int f : {1, 2, 10}) write_file_atomic(dir / "c1" / fmt::format("x{}.jpg", f), "x");
  write_file_atomic(dir / "c1" / "x0003.jpg", "x");
  const auto globbed = images_from_pattern((dir / "{camera}" / "x*.jpg").string(), "c1");
  ASSERT_EQ(globbed.size(), 4u);
  EXPECT_EQ(globbed[0].filename(), "x1.jpg");
  EXPECT_EQ(globbed[2].filename(), "x0003.jpg");
  EXPECT_EQ(globbed[3].filename(), "x10.jpg");
  EXPECT_EQ(images_from_pattern((dir / "{camera}" / "x{frame:04d}.jpg").string(), "c1").size(), 1u);
  EXPECT_THROW(images_from_pattern((dir / "{camera}" / "y*.jpg").string(), "c1"), InputError);

  const TakeSpec t = parse_take("run=130:260", 0, -1, 2, {}, {});
  EXPECT_EQ(t.name, "run");
  EXPECT_EQ(t.first, 130);
  EXPECT_EQ(t.last, 260);
  EXPECT_EQ(t.step, 2);
  EXPECT_EQ(resolve_times(parse_take("a=1.5s:4s", 0, -1, 1, {}, {}), 10).first, 15);
  EXPECT_EQ(resolve_times(parse_take("a=1.5s:4s", 0, -1, 1, {}, {}), 10).last, 39);
  EXPECT_THROW(parse_take("bad name", 0, -1, 1, {}, {}), UsageError);
  EXPECT_THROW(parse_take("a=9:3", 0, -1, 1, {}, {}), UsageError);

  const std::vector<Camera> rig = test::circle_rig(11);
  std::vector<Camera> named = {rig[1], rig[10]};
  named[0].name = "cam1";
  named[1].name = "cam10";
  const auto m = match_files_to_cameras({"v/studio_cam1.mp4", "v/studio_cam10.mp4"}, {}, named, "video");
  EXPECT_EQ(m.at("cam1").front(), "v/studio_cam1.mp4");
  EXPECT_EQ(m.at("cam10").front(), "v/studio_cam10.mp4");
  {
    const std::string error = test::input_error([&] { match_files_to_cameras({"v/studio_cam1.mp4", "v/other.mp4"}, {}, named, "video"); });
    EXPECT_NE(error.find("video with no camera: v/other.mp4"), std::string::npos) << error;
    EXPECT_NE(error.find("cameras with no video: cam10"), std::string::npos) << error;
  }
}

}  // namespace
}  // namespace fourd::import
