#include "stages/import/calibration_import.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/persistence.hpp>

#include "pipeline/core/calibration_formats.h"
#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "tests/import/import_test_data.h"
#include "tests/input_error.h"
#include "tests/scratch_dir.h"

namespace fourd::import {
namespace {

namespace fs = std::filesystem;

// Worst relative difference of two rigs over intrinsics, distortion, R and t: intrinsics relative
// to their value, distortion and R entries (of order 1) relative to max(|value|, 1), t relative
// to |t|.
double worst_relative_error(const std::vector<Camera>& a, const std::vector<Camera>& b) {
  EXPECT_EQ(a.size(), b.size());
  double worst = 0;
  auto rel = [&](double x, double y, double ref) { worst = std::max(worst, std::abs(x - y) / ref); };
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    EXPECT_EQ(a[i].name, b[i].name);
    const Intrinsics &p = a[i].intrinsics, &q = b[i].intrinsics;
    EXPECT_EQ(p.width, q.width);
    EXPECT_EQ(p.height, q.height);
    for (auto [x, y] : {std::pair{p.fx, q.fx}, {p.fy, q.fy}, {p.cx, q.cx}, {p.cy, q.cy}}) rel(x, y, std::abs(x));
    for (auto [x, y] : {std::pair{p.k1, q.k1}, {p.k2, q.k2}, {p.p1, q.p1}, {p.p2, q.p2}}) {
      rel(x, y, std::max(std::abs(x), 1.0));
    }
    const Eigen::Matrix3d ra = a[i].camera_from_world.linear(), rb = b[i].camera_from_world.linear();
    for (int k = 0; k < 9; ++k) rel(ra(k / 3, k % 3), rb(k / 3, k % 3), 1.0);
    const Eigen::Vector3d ta = a[i].camera_from_world.translation(), tb = b[i].camera_from_world.translation();
    worst = std::max(worst, (ta - tb).norm() / ta.norm());
  }
  return worst;
}

CalibrationSource source(const fs::path& p, const std::string& units = "") {
  CalibrationSource s;
  s.paths = {p};
  s.units = units;
  return s;
}

void write(const fs::path& file, const std::string& text) { write_file_atomic(file, text); }

TEST(ImportCalibration, RoundTripEveryFormat) {
  const fs::path dir = test::scratch_dir("import_round_trip");
  const std::vector<Camera> rig = test::circle_rig();
  struct Case {
    std::string format, file;
    LengthUnit unit;
  };
  const std::vector<Case> cases = {
      {"colmap", "colmap", LengthUnit::kMetre},       {"opencv", "rig.yml", LengthUnit::kMillimetre},
      {"opencv", "rig.xml", LengthUnit::kCentimetre}, {"opencv-names", "names.yml", LengthUnit::kMetre},
      {"opencv-files", "files", LengthUnit::kMillimetre}, {"csv", "rig.csv", LengthUnit::kMillimetre},
      {"csv-pixels", "pixels.csv", LengthUnit::kMetre},   {"json", "rig.json", LengthUnit::kMillimetre},
      {"json-keyed", "keyed.json", LengthUnit::kCentimetre}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.format + " " + c.file);
    const fs::path path = dir / c.file;
    export_calibration(rig, c.format, path, c.unit);
    CalibrationSource s = source(path);
    if (c.format == "opencv-files") {
      s.paths.clear();
      for (const Camera& cam : rig) s.paths.push_back(path / (cam.name + ".yml"));
    }
    const ImportedCalibration imported = import_calibration(s);
    EXPECT_EQ(imported.unit, c.unit) << imported.unit_origin;
    EXPECT_TRUE(imported.world_rotation.isIdentity()) << imported.world_change;
    const double worst = worst_relative_error(rig, imported.cameras);
    std::printf("round trip %-12s %-10s (%s): worst relative error %.3g\n", c.format.c_str(), c.file.c_str(),
                unit_name(c.unit), worst);
    EXPECT_LT(worst, 1e-6);
  }
}

TEST(ImportCalibration, UnitsInferredFromTheRigSize) {
  const fs::path dir = test::scratch_dir("import_units");
  const std::vector<Camera> rig = test::circle_rig();
  for (LengthUnit unit : {LengthUnit::kMetre, LengthUnit::kCentimetre, LengthUnit::kMillimetre}) {
    write_csv_calibration(dir / "rig.csv", rig, unit, true);  // a CSV declares no unit
    const ImportedCalibration imported = import_calibration(source(dir / "rig.csv"));
    EXPECT_EQ(imported.unit, unit) << imported.unit_origin;
    EXPECT_NE(imported.unit_origin.find("inferred"), std::string::npos);
    EXPECT_LT(worst_relative_error(rig, imported.cameras), 1e-9);
  }
  // Declared on the command line, it wins over the inference (a rig in mm read as m is huge).
  const ImportedCalibration declared = import_calibration(source(dir / "rig.csv", "m"));
  EXPECT_EQ(declared.unit, LengthUnit::kMetre);
  EXPECT_NEAR(declared.geometry.distance[0], 1000 * 3.5, 100);
  EXPECT_THROW(import_calibration(source(dir / "rig.csv", "furlong")), ConfigError);
}

TEST(ImportCalibration, YUpRigIsTurnedZUp) {
  const fs::path dir = test::scratch_dir("import_up");
  const std::vector<Camera> rig = test::circle_rig();
  // The same rig in a y-up world: y_world = z_session.
  std::vector<Camera> y_up = rig;
  Eigen::Isometry3d y_from_z = Eigen::Isometry3d::Identity();
  y_from_z.linear() << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  transform_world(&y_up, y_from_z);
  write_json_calibration(dir / "y_up.json", y_up, LengthUnit::kMetre);
  const ImportedCalibration imported = import_calibration(source(dir / "y_up.json"));
  EXPECT_NE(imported.up_axis.find("+y"), std::string::npos) << imported.up_axis;
  EXPECT_NE(imported.world_change.find("rotated"), std::string::npos);
  EXPECT_LT(worst_relative_error(rig, imported.cameras), 1e-9);
  EXPECT_NEAR(imported.geometry.centre.z(), 1.0, 0.3);  // above the floor z = 0
  // --up none keeps the file's world.
  CalibrationSource keep = source(dir / "y_up.json");
  keep.up = "none";
  EXPECT_LT(worst_relative_error(y_up, import_calibration(keep).cameras), 1e-9);
}

TEST(ImportCalibration, CsvPoseConventionFlag) {
  const fs::path dir = test::scratch_dir("import_csv_pose");
  const std::vector<Camera> rig = test::circle_rig(4);
  write_csv_calibration(dir / "cfw.csv", rig, LengthUnit::kMetre, false, CsvPose::kCameraFromWorld);
  CalibrationSource s = source(dir / "cfw.csv");
  s.csv.pose = CsvPose::kCameraFromWorld;
  EXPECT_LT(worst_relative_error(rig, import_calibration(s).cameras), 1e-9);
  // Read with the other convention it is another rig (when its cameras still see a common
  // volume at all).
  s.csv.pose = CsvPose::kWorldFromCamera;
  try {
    EXPECT_GT(worst_relative_error(rig, import_calibration(s).cameras), 0.1);
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("common volume"), std::string::npos) << e.what();
  }
}

TEST(ImportCalibration, ColmapModelWithManyImagesPerCamera) {
  const fs::path dir = test::scratch_dir("import_colmap_sfm");
  const std::vector<Camera> rig = test::circle_rig(3);
  std::string cameras = "# CAMERA_ID MODEL WIDTH HEIGHT PARAMS\n", images;
  for (std::size_t i = 0; i < rig.size(); ++i) {
    const Intrinsics& in = rig[i].intrinsics;
    cameras += fmt::format("{} OPENCV {} {} {} {} {} {} {} {} {} {}\n", i + 1, in.width, in.height, in.fx, in.fy,
                           in.cx, in.cy, in.k1, in.k2, in.p1, in.p2);
  }
  int id = 1;
  for (int frame : {7, 3}) {
    for (std::size_t i = 0; i < rig.size(); ++i) {
      Eigen::Quaterniond q(rig[i].camera_from_world.linear());
      const Eigen::Vector3d t = rig[i].camera_from_world.translation() * (frame == 7 ? 1.0 : 1.01);
      images += fmt::format("{} {} {} {} {} {} {} {} {} {}/{:04d}.jpg\n\n", id++, q.w(), q.x(), q.y(), q.z(), t.x(),
                            t.y(), t.z(), i + 1, rig[i].name, frame);
    }
  }
  write(dir / "cameras.txt", cameras);
  write(dir / "images.txt", images);
  // Default: the first image (lowest id) of each COLMAP camera: the frame-7 images.
  const ImportedCalibration first = import_calibration(source(dir, "m"));
  EXPECT_LT(worst_relative_error(rig, first.cameras), 1e-9);
  // A glob picks the frame-3 images instead (translations 1 % longer).
  CalibrationSource s = source(dir, "m");
  s.camera_images = {"*/0003.jpg"};
  const ImportedCalibration picked = import_calibration(s);
  ASSERT_EQ(picked.cameras.size(), 3u);
  EXPECT_NEAR(picked.cameras[0].camera_from_world.translation().norm(),
              1.01 * rig[0].camera_from_world.translation().norm(), 1e-9);
  // A glob that selects two images of one camera is an error naming both.
  s.camera_images = {"cam00/*"};
  {
    const std::string error = test::input_error([&] { import_calibration(s); });
    EXPECT_NE(error.find("0007.jpg"), std::string::npos) << error;
    EXPECT_NE(error.find("0003.jpg"), std::string::npos) << error;
  }
}

// COLMAP's binary model, as its reconstructions write it: cameras.bin and images.bin.
TEST(ImportCalibration, ColmapBinaryModel) {
  const fs::path dir = test::scratch_dir("import_colmap_bin");
  const std::vector<Camera> rig = test::circle_rig(4);
  std::string cameras, images;
  auto put = [](std::string* out, const auto& value) {
    out->append(reinterpret_cast<const char*>(&value), sizeof(value));
  };
  put(&cameras, std::uint64_t{rig.size()});
  for (std::size_t i = 0; i < rig.size(); ++i) {
    const Intrinsics& in = rig[i].intrinsics;
    put(&cameras, std::int32_t(i + 1));
    put(&cameras, std::int32_t(4));  // OPENCV
    put(&cameras, std::uint64_t(in.width));
    put(&cameras, std::uint64_t(in.height));
    for (double v : {in.fx, in.fy, in.cx, in.cy, in.k1, in.k2, in.p1, in.p2}) put(&cameras, v);
  }
  put(&images, std::uint64_t{rig.size()});
  for (std::size_t i = 0; i < rig.size(); ++i) {
    const Eigen::Quaterniond q(rig[i].camera_from_world.linear());
    const Eigen::Vector3d t = rig[i].camera_from_world.translation();
    put(&images, std::uint32_t(10 + i));
    for (double v : {q.w(), q.x(), q.y(), q.z(), t.x(), t.y(), t.z()}) put(&images, v);
    put(&images, std::uint32_t(i + 1));
    images += rig[i].name + ".jpg";
    images += '\0';
    put(&images, std::uint64_t{2});  // two POINTS2D: x, y, point3D_id
    for (int k = 0; k < 2; ++k) {
      put(&images, 1.5);
      put(&images, 2.5);
      put(&images, std::int64_t{-1});
    }
  }
  write(dir / "cameras.bin", cameras);
  write(dir / "images.bin", images);
  const ImportedCalibration imported = import_calibration(source(dir, "m"));
  EXPECT_LT(worst_relative_error(rig, imported.cameras), 1e-12);
  // Truncated: named with the byte where it ends.
  write(dir / "images.bin", images.substr(0, images.size() - 5));
  const std::string error = test::input_error([&] { import_calibration(source(dir, "m")); });
  EXPECT_NE(error.find("images.bin: byte"), std::string::npos) << error;
  EXPECT_NE(error.find("truncated in POINTS2D"), std::string::npos) << error;
}

// The shapes public multi-view datasets publish: a "cameras" list with "resolution", "distCoef"
// and t as a column ([[x], [y], [z]]) in centimetres; a bare list with "size", "matrix",
// "distortions" and a Rodrigues "rotation".
TEST(ImportCalibration, DatasetJsonShapes) {
  const fs::path dir = test::scratch_dir("import_dataset_json");
  const std::vector<Camera> rig = test::circle_rig(5);
  std::string column = R"({"cameras": [)", bare = "[";
  for (std::size_t i = 0; i < rig.size(); ++i) {
    const Camera& c = rig[i];
    const Intrinsics& in = c.intrinsics;
    const Eigen::Matrix3d r = c.camera_from_world.linear();
    const Eigen::Vector3d t = c.camera_from_world.translation() * 100;  // cm
    const Eigen::AngleAxisd aa(r);
    const Eigen::Vector3d rv = aa.angle() * aa.axis();
    const std::string k = fmt::format("[[{}, 0, {}], [0, {}, {}], [0, 0, 1]]", in.fx, in.cx - 0.5, in.fy, in.cy - 0.5);
    const std::string dist = fmt::format("[{}, {}, {}, {}, 0]", in.k1, in.k2, in.p1, in.p2);
    column += fmt::format(
        R"({}{{"name": "{}", "type": "hd", "resolution": [{}, {}], "K": {}, "distCoef": {}, "R": [[{}, {}, {}], [{}, {}, {}], [{}, {}, {}]], "t": [[{}], [{}], [{}]]}})",
        i ? ", " : "", c.name, in.width, in.height, k, dist, r(0, 0), r(0, 1), r(0, 2), r(1, 0), r(1, 1), r(1, 2),
        r(2, 0), r(2, 1), r(2, 2), t.x(), t.y(), t.z());
    bare += fmt::format(R"({}{{"name": "{}", "size": [{}, {}], "matrix": {}, "distortions": {}, "rotation": [{}, {}, {}], "translation": [{}, {}, {}]}})",
                        i ? ", " : "", c.name, in.width, in.height, k, dist, rv.x(), rv.y(), rv.z(), t.x(), t.y(), t.z());
  }
  write(dir / "column.json", column + "]}");
  write(dir / "bare.json", bare + "]");
  for (const char* file : {"column.json", "bare.json"}) {
    SCOPED_TRACE(file);
    const ImportedCalibration imported = import_calibration(source(dir / file));
    EXPECT_EQ(imported.unit, LengthUnit::kCentimetre) << imported.unit_origin;
    EXPECT_LT(worst_relative_error(rig, imported.cameras), 1e-9);
  }
}

TEST(ImportCalibration, EasyMocapStyleIntrinsicsAndExtrinsicsFiles) {
  const fs::path dir = test::scratch_dir("import_intri_extri");
  const std::vector<Camera> rig = test::circle_rig(4);
  // Intrinsics in one file, extrinsics in another, as such datasets publish them (written here
  // with cv::FileStorage itself).
  {
    cv::FileStorage intri((dir / "intri.yml").string(), cv::FileStorage::WRITE);
    cv::FileStorage extri((dir / "extri.yml").string(), cv::FileStorage::WRITE);
    for (cv::FileStorage* f : {&intri, &extri}) {
      *f << "names" << "[";
      for (const Camera& c : rig) *f << c.name;
      *f << "]";
    }
    for (const Camera& c : rig) {
      const Intrinsics& in = c.intrinsics;
      cv::Mat k = (cv::Mat_<double>(3, 3) << in.fx, 0, in.cx - 0.5, 0, in.fy, in.cy - 0.5, 0, 0, 1);
      cv::Mat dist = (cv::Mat_<double>(1, 5) << in.k1, in.k2, in.p1, in.p2, 0);
      intri << "K_" + c.name << k << "dist_" + c.name << dist << "W_" + c.name << in.width << "H_" + c.name
            << in.height;
      cv::Mat r(3, 3, CV_64F), rvec, t(3, 1, CV_64F);
      for (int i = 0; i < 9; ++i) r.at<double>(i / 3, i % 3) = c.camera_from_world.linear()(i / 3, i % 3);
      for (int i = 0; i < 3; ++i) t.at<double>(i) = c.camera_from_world.translation()[i];
      cv::Rodrigues(r, rvec);
      extri << "R_" + c.name << rvec << "T_" + c.name << t;  // no Rot_: the Rodrigues vector is used
    }
  }
  CalibrationSource s;
  s.paths = {dir / "intri.yml", dir / "extri.yml"};
  EXPECT_EQ(detect_format(s), "opencv");
  EXPECT_LT(worst_relative_error(rig, import_calibration(s).cameras), 1e-9);
  // Without the extrinsics file the rotation is missing: named.
  s.paths = {dir / "intri.yml"};
  {
    const std::string error = test::input_error([&] { import_calibration(s); });
    EXPECT_NE(error.find("R_cam00"), std::string::npos) << error;
    EXPECT_NE(error.find("camera 'cam00'"), std::string::npos) << error;
  }
}

// The error of importing `text` as a JSON calibration.
std::string json_error(const std::string& text) {
  const fs::path file = test::scratch_dir("import_json_bad") / "calibration.json";
  write(file, text);
  try {
    import_calibration(source(file));
  } catch (const Error& e) {
    return e.what();
  }
  return "(accepted)";
}

std::string camera_json(const std::string& name, const std::string& k, const std::string& r, const std::string& t,
                        const std::string& extra = "") {
  return fmt::format(R"({{"name": "{}", "width": 640, "height": 480, "K": {}, "dist": [0, 0, 0, 0], "R": {}, "t": {}{}}})",
                     name, k, r, t, extra);
}

TEST(ImportCalibration, MalformedJsonNamesFileCameraAndField) {
  const std::string k = "[[500, 0, 320], [0, 500, 240], [0, 0, 1]]";
  // Three cameras 2 m from the origin, looking at it: from -x, +x and -y.
  const std::string r_a = "[[0, -1, 0], [0, 0, -1], [1, 0, 0]]", r_b = "[[0, 1, 0], [0, 0, -1], [-1, 0, 0]]";
  const std::string r_c = "[[1, 0, 0], [0, 0, -1], [0, 1, 0]]", t = "[0, 0, 2]";
  const std::string a = camera_json("a", k, r_a, t), b = camera_json("b", k, r_b, t), c = camera_json("c", k, r_c, t);
  auto rig = [](const std::string& cameras, const std::string& unit = R"("unit": "m", )") {
    return fmt::format(R"({{{}"cameras": [{}]}})", unit, cameras);
  };
  EXPECT_EQ(json_error(rig(a + ", " + b + ", " + c)), "(accepted)");
  std::string e = json_error(rig(fmt::format(R"({}, {}, {{"name": "d", "width": 640, "height": 480, "K": {}, "R": {}}})",
                                             a, b, k, r_c)));
  EXPECT_NE(e.find("camera 'd'"), std::string::npos) << e;
  EXPECT_NE(e.find("missing field (t"), std::string::npos) << e;
  EXPECT_NE(e.find("calibration.json:"), std::string::npos) << e;
  e = json_error(rig(a + ", " + c + ", " + camera_json("b", k, "[[0, 1, 0], [0, 0, -1], [-1, 0, 0.2]]", t)));
  EXPECT_NE(e.find("camera 'b'"), std::string::npos) << e;
  EXPECT_NE(e.find("not a rotation"), std::string::npos) << e;
  e = json_error(rig(camera_json("a", "[[500, 0, 700], [0, 500, 240], [0, 0, 1]]", r_a, t) + ", " + b + ", " + c));
  EXPECT_NE(e.find("camera 'a'"), std::string::npos) << e;
  EXPECT_NE(e.find("principal point"), std::string::npos) << e;
  e = json_error(rig(a + ", " + b + ", " + c, R"("unit": "parsec", )"));
  EXPECT_NE(e.find("unknown length unit 'parsec'"), std::string::npos) << e;
  e = json_error(rig(a + ", " + c + ", " + camera_json("b", "[[-500, 0, 320], [0, 500, 240], [0, 0, 1]]", r_b, t)));
  EXPECT_NE(e.find("focal lengths must be positive"), std::string::npos) << e;
  e = json_error(rig(a + ", " + c + ", " + camera_json("b", k, r_b, t, R"(, "D": [0.1, 0.01, 0, 0, 0.05])")));
  EXPECT_EQ(e, "(accepted)");  // "dist" comes first; its zeros are used
  e = json_error(rig(a + ", " + c + ", " +
                     fmt::format(R"({{"name": "b", "width": 640, "height": 480, "K": {}, "distCoef": [0.1, 0.01, 0, 0, 0.05], "R": {}, "t": {}}})",
                                 k, r_b, t)));
  EXPECT_NE(e.find("distortion coefficient 5"), std::string::npos) << e;
  e = json_error(R"({"cameras": [{"name": "a", "K": [1, 2], )");
  EXPECT_NE(e.find("not valid JSON/YAML"), std::string::npos) << e;
  // A fourth camera looking away from the others: named as the one that does not see.
  e = json_error(rig(a + ", " + b + ", " + c + ", " + camera_json("away", k, r_a, "[0, 0, -2]")));
  EXPECT_NE(e.find("do not see a common volume: away do not see"), std::string::npos) << e;
  EXPECT_NE(e.find("a, b, c do"), std::string::npos) << e;
}

TEST(ImportCalibration, MalformedCsvAndOpenCvNameLineAndField) {
  const fs::path dir = test::scratch_dir("import_bad_csv");
  const std::vector<Camera> rig = test::circle_rig(4);
  write_csv_calibration(dir / "rig.csv", rig, LengthUnit::kMetre, true);
  std::string text = read_file(dir / "rig.csv");
  const auto third_line = text.find('\n', text.find('\n') + 1) + 1;
  text.replace(text.find(',', third_line) + 1, 3, "6x0");  // cam01's width
  write(dir / "bad.csv", text);
  {
    const std::string error = test::input_error([&] { import_calibration(source(dir / "bad.csv")); });
    EXPECT_NE(error.find("bad.csv:3: column width: '6x0"), std::string::npos) << error;
  }
  write(dir / "short.csv", "name,width,height,rx,ry,rz,tx,ty,tz,fx,fy\ncam00,640,480,0,0,0,0,0,0,1,1\n");
  {
    const std::string error = test::input_error([&] { import_calibration(source(dir / "short.csv")); });
    EXPECT_NE(error.find("no column cx"), std::string::npos) << error;
  }
  write(dir / "nok.yml", "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\nR: [1, 0, 0]\nt: [0, 0, 1]\n");
  {
    const std::string error = test::input_error([&] { import_calibration(source(dir / "nok.yml")); });
    EXPECT_NE(error.find("nok.yml: top level: missing field (K"), std::string::npos) << error;
  }
}

TEST(ImportCalibration, SummaryTableListsEveryCamera) {
  const std::vector<Camera> rig = test::circle_rig(3);
  const RigGeometry g = rig_geometry(rig);
  const std::string table = summary_table(rig, g);
  for (const Camera& c : rig) EXPECT_NE(table.find(c.name), std::string::npos);
  EXPECT_NE(table.find("640x480"), std::string::npos);
  EXPECT_NE(table.find("OPENCV k1"), std::string::npos);
  EXPECT_NE(table.find("none (pinhole)"), std::string::npos);
  for (std::size_t i = 0; i < rig.size(); ++i) {
    EXPECT_TRUE(g.sees[i]);
    EXPECT_NEAR(g.distance[i], 3.5, 0.3);
  }
}

}  // namespace
}  // namespace fourd::import
