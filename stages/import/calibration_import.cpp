#include "stages/import/calibration_import.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/statistics.h"

namespace fourd::import {
namespace {

namespace fs = std::filesystem;

Eigen::Vector3d optical_axis(const Camera& c) {
  return c.camera_from_world.linear().transpose() * Eigen::Vector3d::UnitZ();
}

// The centre seen through the pinhole (no distortion): in front and inside the image.
bool sees_point(const Camera& c, const Eigen::Vector3d& p) {
  const Eigen::Vector3d x = c.camera_from_world * p;
  if (!(x.z() > 0)) return false;
  const Intrinsics& in = c.intrinsics;
  const Eigen::Vector2d pixel(in.fx * x.x() / x.z() + in.cx, in.fy * x.y() / x.z() + in.cy);
  return c.in_image(pixel);
}

Eigen::Vector3d nearest_point(const std::vector<Camera>& cameras, const std::vector<bool>& use) {
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  int used = 0;
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    if (!use[i]) continue;
    const Eigen::Vector3d d = optical_axis(cameras[i]);
    const Eigen::Matrix3d p = Eigen::Matrix3d::Identity() - d * d.transpose();
    a += p;
    b += p * cameras[i].center();
    ++used;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(a);
  if (used < 2 || eig.eigenvalues()(0) < 1e-6 * std::max(1.0, eig.eigenvalues()(2))) {
    throw InputError("the cameras' optical axes are (nearly) parallel: they look at no common volume");
  }
  return a.ldlt().solve(b);
}

// "+y", "-z"... for a unit axis.
std::string axis_name(const Eigen::Vector3d& axis) {
  for (int i = 0; i < 3; ++i) {
    if (std::abs(axis[i]) > 0.5) return fmt::format("{}{}", axis[i] > 0 ? '+' : '-', "xyz"[i]);
  }
  return "?";
}

Eigen::Vector3d parse_axis(const std::string& text) {
  const std::string t = text.size() == 1 ? "+" + text : text;
  if (t.size() == 2 && (t[0] == '+' || t[0] == '-')) {
    const auto i = std::string("xyz").find(t[1]);
    if (i != std::string::npos) return (t[0] == '+' ? 1.0 : -1.0) * Eigen::Vector3d::Unit(static_cast<int>(i));
  }
  throw ConfigError(fmt::format("--up '{}': expected auto, none or an axis (+x, -x, +y, -y, +z, -z)", text));
}

bool has_extension(const fs::path& p, std::initializer_list<const char*> extensions) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  return std::find(extensions.begin(), extensions.end(), e) != extensions.end();
}

}  // namespace

RigGeometry rig_geometry(const std::vector<Camera>& cameras) {
  if (cameras.size() < 2) {
    throw InputError(fmt::format("the calibration has {} camera(s); a capture rig needs at least 2",
                                 cameras.size()));
  }
  RigGeometry g;
  std::vector<bool> use(cameras.size(), true);
  g.centre = nearest_point(cameras, use);
  // A camera looking elsewhere pulls the point away: refit on the cameras that see it.
  std::vector<bool> seeing(cameras.size());
  for (std::size_t i = 0; i < cameras.size(); ++i) seeing[i] = sees_point(cameras[i], g.centre);
  if (std::count(seeing.begin(), seeing.end(), true) >= 2 && seeing != use) {
    g.centre = nearest_point(cameras, seeing);
  }
  for (const Camera& c : cameras) {
    const Eigen::Vector3d to = g.centre - c.center();
    const Eigen::Vector3d d = optical_axis(c);
    g.distance.push_back(to.norm());
    g.axis_offset.push_back((to - to.dot(d) * d).norm());
    g.sees.push_back(sees_point(c, g.centre));
  }
  return g;
}

void check_common_volume(const std::vector<Camera>& cameras, const RigGeometry& g) {
  std::string blind, seeing;
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    std::string& list = g.sees[i] ? seeing : blind;
    list += (list.empty() ? "" : ", ") + cameras[i].name;
  }
  if (!blind.empty()) {
    throw InputError(fmt::format(
        "the cameras do not see a common volume: {} do not see the point ({:.3f}, {:.3f}, {:.3f}) "
        "nearest the optical axes in front of them and inside their image; {} do",
        blind, g.centre.x(), g.centre.y(), g.centre.z(), seeing.empty() ? "none" : seeing));
  }
}

Eigen::Vector3d mean_camera_up(const std::vector<Camera>& cameras) {
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  for (const Camera& c : cameras) up -= c.camera_from_world.linear().transpose() * Eigen::Vector3d::UnitY();
  return up.norm() > 0 ? Eigen::Vector3d(up.normalized()) : up;
}

void transform_world(std::vector<Camera>* cameras, const Eigen::Isometry3d& world_from_old) {
  for (Camera& c : *cameras) c.camera_from_world = c.camera_from_world * world_from_old.inverse();
}

std::string detect_format(const CalibrationSource& source) {
  if (source.format != "auto") return source.format;
  if (source.paths.empty()) throw UsageError("--calibration: no file or folder given");
  const fs::path& p = source.paths.front();
  if (fs::is_directory(p)) {
    if (fs::exists(p / "cameras.txt") || fs::exists(p / "cameras.bin")) return "colmap";
    throw InputError(fmt::format("{}: a folder without cameras.txt (not a COLMAP model): give the "
                                 "calibration file(s) instead",
                                 p.string()));
  }
  if (has_extension(p, {".csv"})) return "csv";
  if (has_extension(p, {".json"})) return "json";
  if (has_extension(p, {".xml"})) return "opencv";
  if (has_extension(p, {".yml", ".yaml"})) {
    const std::string head = read_file(p).substr(0, 9);
    return head == "%YAML:1.0" || head == "%YAML 1.0" ? "opencv" : "json";
  }
  throw UsageError(fmt::format("{}: cannot tell the calibration format from the name; give "
                               "--calibration-format (colmap, opencv, csv, json)",
                               p.string()));
}

ImportedCalibration import_calibration(const CalibrationSource& source) {
  const std::string format = detect_format(source);
  CalibrationRecords records;
  if (format == "colmap") {
    if (source.paths.size() != 1) throw UsageError("a COLMAP model is one folder");
    records = read_colmap_calibration(source.paths.front(), source.camera_images);
  } else if (format == "opencv") {
    records = read_opencv_calibration(source.paths);
  } else if (format == "csv" || format == "json") {
    if (source.paths.size() != 1) throw UsageError(fmt::format("a {} calibration is one file", format));
    records = format == "csv" ? read_csv_calibration(source.paths.front(), source.csv)
                              : read_json_calibration(source.paths.front());
  } else {
    throw UsageError(fmt::format("--calibration-format '{}': expected auto, colmap, opencv, csv or json", format));
  }
  if (format != "colmap" && !source.camera_images.empty()) {
    throw UsageError("--camera-images selects images of a COLMAP model only");
  }
  ImportedCalibration out;
  out.convention = records.convention;

  // Unit: the command line's, else the file's, else inferred from the rig's size.
  std::optional<LengthUnit> declared;
  for (const CameraRecord& r : records.cameras) {
    if (r.unit && declared && *r.unit != *declared) {
      throw InputError(fmt::format("{}: camera '{}' declares unit {}, another camera {}", r.source,
                                   r.name, unit_name(*r.unit), unit_name(*declared)));
    }
    if (r.unit) declared = r.unit;
  }
  for (const CameraRecord& r : records.cameras) {
    out.cameras.push_back(record_to_camera(r, 1.0, source.drop_higher_distortion, &out.notes));
  }
  for (std::size_t i = 0; i < out.cameras.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (out.cameras[i].name == out.cameras[j].name) {
        throw InputError(fmt::format("{}: camera name '{}' appears twice", records.cameras[i].source,
                                     out.cameras[i].name));
      }
    }
  }
  const RigGeometry file_geometry = rig_geometry(out.cameras);
  std::vector<double> distances = file_geometry.distance;
  const double median_distance = median(distances);
  if (!source.units.empty()) {
    out.unit = parse_length_unit(source.units, "--units");
    out.unit_origin = "declared (--units)";
  } else if (declared) {
    out.unit = *declared;
    out.unit_origin = "declared by the file";
  } else {
    out.unit = infer_length_unit(median_distance);
    out.unit_origin = fmt::format("inferred: the cameras are {:.4g} units from their common centre",
                                  median_distance);
  }
  const double scale = metres_per_unit(out.unit);
  for (Camera& c : out.cameras) c.camera_from_world.translation() *= scale;

  // The session's world is z-up with the floor at z = 0 (synth's): find the rig's up.
  Eigen::Vector3d up;
  const Eigen::Vector3d mean_up = mean_camera_up(out.cameras);
  if (source.up == "auto") {
    int axis = 0;
    mean_up.cwiseAbs().maxCoeff(&axis);
    up = Eigen::Vector3d::Unit(axis) * (mean_up[axis] >= 0 ? 1.0 : -1.0);
    const double angle = std::acos(std::clamp(mean_up.dot(up), -1.0, 1.0)) * 180 / M_PI;
    out.up_axis = fmt::format("{} (the cameras' mean up is {:.0f} deg from it)", axis_name(up), angle);
    if (angle > 30) {
      out.warnings.push_back(fmt::format("the cameras' mean up direction is {:.0f} deg from the "
                                         "nearest axis {}: the up axis is a guess (give --up)",
                                         angle, axis_name(up)));
    }
  } else if (source.up == "none") {
    up = Eigen::Vector3d::UnitZ();
    out.up_axis = "+z (--up none: the world is kept as it is)";
  } else {
    up = parse_axis(source.up);
    out.up_axis = fmt::format("{} (--up)", axis_name(up));
  }
  if ((up - Eigen::Vector3d::UnitZ()).norm() < 1e-12) {
    out.world_change = "none: the rig is z-up like the session";
  } else {
    const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(up, Eigen::Vector3d::UnitZ());
    out.world_rotation = q.toRotationMatrix().array().round().matrix();  // an exact axis permutation
    Eigen::Isometry3d w = Eigen::Isometry3d::Identity();
    w.linear() = out.world_rotation;
    transform_world(&out.cameras, w);
    out.world_change = fmt::format("rotated the world so that {} becomes +z (the session's up)", axis_name(up));
  }
  out.geometry = rig_geometry(out.cameras);
  check_common_volume(out.cameras, out.geometry);
  if (out.geometry.centre.z() < 0) {
    out.warnings.push_back(fmt::format(
        "the common centre of the cameras is at z = {:.3f} m, below the floor z = 0 the session "
        "assumes: the world's origin is not on the floor",
        out.geometry.centre.z()));
  }
  return out;
}

std::string summary_table(const std::vector<Camera>& cameras, const RigGeometry& g) {
  std::size_t width = 6;
  for (const Camera& c : cameras) width = std::max(width, c.name.size());
  std::string out = fmt::format("{:<{}}  {:>11}  {:>19}  {:>19}  {:>9}  {}\n", "camera", width,
                                "size", "focal fx, fy [px]", "principal [px]", "to centre", "distortion");
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const Intrinsics& in = cameras[i].intrinsics;
    const std::string lens = in.has_distortion()
                                 ? fmt::format("OPENCV k1 {:.4g} k2 {:.4g} p1 {:.3g} p2 {:.3g}", in.k1, in.k2, in.p1, in.p2)
                                 : std::string("none (pinhole)");
    out += fmt::format("{:<{}}  {:>11}  {:>19}  {:>19}  {:>7.3f} m  {}\n", cameras[i].name, width,
                       fmt::format("{}x{}", in.width, in.height), fmt::format("{:.2f}, {:.2f}", in.fx, in.fy),
                       fmt::format("{:.2f}, {:.2f}", in.cx, in.cy), g.distance[i], lens);
  }
  return out;
}

const std::vector<std::string>& export_formats() {
  static const std::vector<std::string> formats = {"colmap", "opencv",     "opencv-names", "opencv-files",
                                                   "csv",    "csv-pixels", "json",         "json-keyed"};
  return formats;
}

void export_calibration(const std::vector<Camera>& cameras, const std::string& format,
                        const fs::path& path, LengthUnit unit) {
  if (format == "colmap") {
    if (unit != LengthUnit::kMetre) throw UsageError("a COLMAP model is written in metres (no --units)");
    write_colmap_model(path, cameras);
  } else if (format == "opencv") {
    write_opencv_calibration(path, cameras, unit, OpenCvLayout::kCameraNodes);
  } else if (format == "opencv-names") {
    write_opencv_calibration(path, cameras, unit, OpenCvLayout::kNamesList);
  } else if (format == "opencv-files") {
    write_opencv_calibration(path, cameras, unit, OpenCvLayout::kFilePerCamera);
  } else if (format == "csv" || format == "csv-pixels") {
    write_csv_calibration(path, cameras, unit, format == "csv", CsvPose::kWorldFromCamera);
  } else if (format == "json" || format == "json-keyed") {
    write_json_calibration(path, cameras, unit, format == "json-keyed");
  } else {
    std::string known;
    for (const auto& f : export_formats()) known += (known.empty() ? "" : ", ") + f;
    throw UsageError(fmt::format("--export-calibration '{}': unknown format (known: {})", format, known));
  }
}

}  // namespace fourd::import
