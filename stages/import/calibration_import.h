#pragma once
// Calibration import: a foreign calibration (calibration_formats.h) becomes the session's rig,
// in metres and in the session's world (z up, floor z = 0, as synth writes it), after the checks
// every rig must pass: the cameras look at a common volume, which each sees in front of it and
// inside its image.
#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/core/calibration_formats.h"
#include "pipeline/core/camera.h"

namespace fourd::import {

struct CalibrationSource {
  std::string format = "auto";  // auto | colmap | opencv | csv | json
  std::vector<std::filesystem::path> paths;
  std::string units;                      // "" (file's, else inferred) | m | cm | mm
  std::vector<std::string> camera_images;  // COLMAP: globs selecting one image per camera
  CsvOptions csv;
  bool drop_higher_distortion = false;  // import lenses with k3... by dropping those terms
  std::string up = "auto";              // auto | none | +x -x +y -y +z -z: the rig's up axis
};

// Where the cameras look: the point nearest every optical axis (least squares), and how each
// camera relates to it.
struct RigGeometry {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  std::vector<double> distance;     // camera centre to `centre`
  std::vector<double> axis_offset;  // `centre` to the camera's optical axis
  std::vector<bool> sees;           // `centre` in front of the camera and inside its image
};
// Throws InputError when fewer than two cameras or all optical axes are parallel.
RigGeometry rig_geometry(const std::vector<Camera>& cameras);

// The checks after any import: every camera sees the common point, else InputError naming the
// cameras that do not (and those that do).
void check_common_volume(const std::vector<Camera>& cameras, const RigGeometry& geometry);

// The mean up direction of the cameras' images (-y of each camera) in world coordinates.
Eigen::Vector3d mean_camera_up(const std::vector<Camera>& cameras);
// Moves the rig into the world x' = world_from_old * x.
void transform_world(std::vector<Camera>* cameras, const Eigen::Isometry3d& world_from_old);

struct ImportedCalibration {
  std::vector<Camera> cameras;  // metres, session world
  std::string convention;       // the reader's
  LengthUnit unit = LengthUnit::kMetre;
  std::string unit_origin;      // "declared (--units)", "declared by the file", "inferred ..."
  std::string up_axis;          // the axis found up ("+y"), and
  std::string world_change;     // what was done about it
  Eigen::Matrix3d world_rotation = Eigen::Matrix3d::Identity();  // session world from file world
  RigGeometry geometry;         // in the session world, metres
  std::vector<std::string> notes;    // dropped distortion terms
  std::vector<std::string> warnings;  // the cameras disagree on up; the volume is below the floor
};

// The format of `source` when "auto": a folder with cameras.txt -> colmap; .csv -> csv;
// .json -> json; .xml or a YAML file starting with "%YAML:1.0" -> opencv; other YAML -> json.
std::string detect_format(const CalibrationSource& source);

// Reads, converts, scales, orients and checks. Throws InputError/ConfigError naming the file and
// camera for anything wrong.
ImportedCalibration import_calibration(const CalibrationSource& source);

// The per-camera summary table (name, size, focal, principal point, distance to the common
// centre, distortion model), one line per camera.
std::string summary_table(const std::vector<Camera>& cameras, const RigGeometry& geometry);

// Writes the session's cameras in a foreign format: colmap (a folder), opencv (one file with
// camera nodes), opencv-names (the names list), opencv-files (a folder of one file per camera),
// csv, csv-pixels (intrinsics in pixels), json, json-keyed. Throws UsageError for an unknown
// format.
void export_calibration(const std::vector<Camera>& cameras, const std::string& format,
                        const std::filesystem::path& path, LengthUnit unit);
// The names export_calibration knows, for --help.
const std::vector<std::string>& export_formats();

}  // namespace fourd::import
