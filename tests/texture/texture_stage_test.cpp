// The texture stage on a small session: a textured sphere filmed by a ring of cameras over two
// frames, aligned meshes in oracle/align/. Outputs, a camera image missing for one frame
// (skipped and reported), the EXR option, and bad options.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/exchange/texture_image.h"
#include "stages/texture/texture.h"
#include "tests/texture/textured_scene.h"

namespace fourd::texture {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

class SphereSession {
 public:
  SphereSession() {
    std::string pattern = (fs::temp_directory_path() / "fourd_texture_session_XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    root_ = pattern;
    cameras_ = test::camera_ring(6, 2.0, 0.6);
    write_colmap_model(root_ / "calibration", cameras_);
    const Mesh sphere = test::make_uv_sphere(Eigen::Vector3f::Zero(), 0.5f, 24, 48);
    const cv::Mat truth = test::smooth_texture();
    Mesh shape;
    shape.triangles = sphere.triangles;
    for (int f = 0; f < 2; ++f) {
      Mesh posed = sphere;
      for (Vec3f& p : posed.positions) p += Vec3f(0.1f * f, 0, 0);  // the sphere moves
      shape.positions = posed.positions;
      if (f == 0) write_ply(root_ / "oracle" / "align" / "template.ply", shape);
      write_ply(root_ / "oracle" / "align" / "roll" / (frame_name(f) + ".ply"), shape);
      const MeshRenderer renderer(posed, truth);
      for (const Camera& c : cameras_) {
        write_image_atomic(root_ / "capture" / "roll" / c.name / (frame_name(f) + ".png"),
                           test::record(renderer, c));
      }
    }
    write_config("");
  }
  ~SphereSession() {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  SphereSession(const SphereSession&) = delete;
  SphereSession& operator=(const SphereSession&) = delete;

  void write_config(const std::string& texture_options) {
    std::ofstream(root_ / "session.yaml", std::ios::trunc)
        << "name: sphere\nfps: 10\nstages:\n  texture: {resolution: 256" << texture_options << "}\n";
  }
  void run() const {
    StageArgs args;
    args.session_dir = root_.string();
    args.oracle = true;
    run_texture(Session::open(root_), args);
  }
  const fs::path& root() const { return root_; }
  fs::path out() const { return root_ / "texture_oracle"; }
  const std::vector<Camera>& cameras() const { return cameras_; }

 private:
  fs::path root_;
  std::vector<Camera> cameras_;
};

TEST(TextureStage, WritesAtlasTexturesAndReport) {
  SphereSession s;
  s.run();
  const Mesh atlas = read_ply(s.out() / "atlas.ply");
  EXPECT_EQ(atlas.uv_triangles.size(), atlas.triangles.size());
  EXPECT_EQ(atlas.texture, "roll/000000.png");
  for (int f = 0; f < 2; ++f) {
    const cv::Mat t = read_texture(s.out() / "roll" / (frame_name(f) + ".png"));
    EXPECT_EQ(t.rows, 256);
    EXPECT_EQ(t.cols, 256);
    EXPECT_TRUE(fs::exists(s.out() / "roll" / "unseen" / (frame_name(f) + ".png")));
  }
  EXPECT_TRUE(fs::exists(s.out() / "atlas.png"));
  EXPECT_TRUE(fs::exists(s.out() / "options.yaml"));
  const json atlas_json = json::parse(read_file(s.out() / "atlas.json"));
  EXPECT_EQ(atlas_json.at("overlapping_texels").get<int>(), 0);
  EXPECT_EQ(atlas_json.at("flipped_faces").get<int>(), 0);
  const json report = json::parse(read_file(s.out() / "report.json"));
  EXPECT_EQ(report.at("input").get<std::string>(), "oracle/align");
  EXPECT_EQ(report.at("frames").get<int>(), 2);
  EXPECT_EQ(report.at("takes").at("roll").size(), 2u);
  EXPECT_TRUE(report.at("skipped_cameras").empty());
  EXPECT_GT(report.at("seconds_per_frame").get<double>(), 0.0);
  // Every camera painted part of the sphere.
  for (const auto& [camera, texels] : report.at("takes").at("roll")[0].at("texels_per_camera").items()) {
    EXPECT_GT(texels.get<int>(), 0) << camera;
  }
}

TEST(TextureStage, MissingImageSkipsThatCameraForThatFrame) {
  SphereSession s;
  const std::string camera = s.cameras()[2].name;
  fs::remove(s.root() / "capture" / "roll" / camera / "000001.png");
  s.run();
  const json report = json::parse(read_file(s.out() / "report.json"));
  ASSERT_EQ(report.at("skipped_cameras").size(), 1u);
  const json& skipped = report.at("skipped_cameras")[0];
  EXPECT_EQ(skipped.at("camera").get<std::string>(), camera);
  EXPECT_EQ(skipped.at("frame").get<int>(), 1);
  EXPECT_NE(skipped.at("reason").get<std::string>().find("000001.png"), std::string::npos);
  const json& frame1 = report.at("takes").at("roll")[1];
  EXPECT_EQ(frame1.at("skipped_cameras")[0].get<std::string>(), camera);
  EXPECT_FALSE(frame1.at("texels_per_camera").contains(camera));
  EXPECT_TRUE(fs::exists(s.out() / "roll" / "000001.png"));
}

TEST(TextureStage, ExrOption) {
  SphereSession s;
  s.write_config(", format: exr");
  s.run();
  const cv::Mat t = read_texture(s.out() / "roll" / "000000.exr");
  EXPECT_EQ(t.rows, 256);
  double lo, hi;
  cv::minMaxLoc(t.reshape(1), &lo, &hi);
  EXPECT_GE(lo, 0.0);
  EXPECT_LE(hi, 1.001);
  EXPECT_GT(hi, 0.5);
}

TEST(TextureStage, BadInputIsNamed) {
  SphereSession s;
  s.write_config(", format: jpg");
  EXPECT_THROW(s.run(), ConfigError);
  s.write_config("");
  // No camera image at all for frame 0: nothing sees the surface.
  for (const Camera& c : s.cameras()) fs::remove(s.root() / "capture" / "roll" / c.name / "000000.png");
  try {
    s.run();
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("take roll frame 000000"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(s.out()));  // nothing half-written
}

}  // namespace
}  // namespace fourd::texture
