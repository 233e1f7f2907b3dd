#pragma once
// Calibration exchange formats: the files studios and public multi-view datasets publish,
// read into CameraRecords (each file's own conventions made explicit) and written from the
// session's cameras (camera.h), so a rig can go both ways.
//
//   COLMAP text model      any number of images per COLMAP camera (structure from motion);
//                          one image per physical camera is selected (colmap_model.h).
//   OpenCV FileStorage     XML or YAML (cv::FileStorage): one file per camera, one file with a
//                          camera_<name> node per camera, or the "names" list with K_<name>,
//                          dist_<name>, R_<name>/Rot_<name>, T_<name> (possibly split over an
//                          intrinsics and an extrinsics file).
//   CSV                    one row per camera: name, width, height, rx ry rz (axis-angle), tx ty
//                          tz, fx fy cx cy (normalised by the image size or in pixels), optional
//                          k1 k2 p1 p2 (k3).
//   JSON / YAML            per camera K, dist, R, t and the image size: an object keyed by camera
//                          name, or a list of cameras with "name" (optionally under "cameras"),
//                          with a declared "unit".
//
// Conventions every foreign format is read with unless it says otherwise (stated once here):
//   * R, t map world to camera: x_cam = R x_world + t (OpenCV's calibrateCamera/stereoCalibrate,
//     COLMAP, and the JSON layouts of the public multi-view datasets). The CSV layout of 4D
//     datasets stores the camera's pose in the world instead (world_from_camera, t = the
//     camera centre); CsvOptions::pose chooses.
//   * Pixel coordinates in pixels are OpenCV's: the centre of the top-left pixel is (0, 0).
//     The session's camera uses COLMAP's, where it is (0.5, 0.5): reading adds 0.5 to the
//     principal point, writing subtracts it. COLMAP models are taken as they are. Normalised
//     CSV intrinsics are fractions of the image from edge to edge (cx 0.5: the image centre).
//   * Distortion coefficients in OpenCV's order k1 k2 p1 p2 [k3 ...]; the session's camera
//     models k1 k2 p1 p2, so a non-zero k3 or higher term is refused unless dropped explicitly.
//   * Lengths (t) in the unit the file declares, the caller's, or one inferred from the rig's
//     size (see infer_length_unit).
#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"

namespace fourd {

enum class LengthUnit { kMetre, kCentimetre, kMillimetre };

// "m", "cm", "mm" (also metre(s)/meter(s), centimetre(s)..., millimetre(s)...). Throws
// ConfigError naming `where` and the units it knows for anything else.
LengthUnit parse_length_unit(const std::string& text, const std::string& where);
double metres_per_unit(LengthUnit unit);
const char* unit_name(LengthUnit unit);  // "m", "cm", "mm"

// The unit a rig's lengths are in, from the median distance of its cameras to the common
// point they look at (in file units): studios put cameras 1-10 m from the performer, so
// below 50 it is metres, below 1000 centimetres, else millimetres.
LengthUnit infer_length_unit(double median_camera_distance);

// One camera as a foreign file states it, before conversion to the session's Camera.
struct CameraRecord {
  std::string name;
  std::string source;  // where it was read, for messages: "calib.json: cameras[3]"
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  bool colmap_pixels = false;  // principal point already in COLMAP's convention (else OpenCV's)
  std::vector<double> distortion;  // OpenCV order: k1 k2 p1 p2 [k3 ...]; fewer: radial only
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // camera_from_world
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();   // camera_from_world, file units
  std::optional<LengthUnit> unit;  // declared by the file
};

// What a reader found: the cameras and the convention it assumed, in one line for the log.
struct CalibrationRecords {
  std::vector<CameraRecord> cameras;
  std::string convention;
};

// The shared conversion of every format. Checks (InputError naming the source and camera):
// positive image size and focal lengths, the principal point inside the image, R orthonormal
// with determinant +1 (to 1e-6; then made exactly orthonormal), finite values, and no non-zero
// distortion term beyond k1 k2 p1 p2 unless `drop_higher_distortion` (then `notes` says which
// were dropped). Translation is scaled by `metres_per_file_unit`.
Camera record_to_camera(const CameraRecord& record, double metres_per_file_unit,
                        bool drop_higher_distortion = false, std::vector<std::string>* notes = nullptr);

// --- Readers -----------------------------------------------------------------------------------

// A COLMAP text model with any number of images. `image_patterns` (fnmatch globs on the image
// NAME, e.g. "cam*/0001.jpg") select one image per physical camera; empty: the first image
// (lowest IMAGE_ID) of each COLMAP camera. A camera is named by the image's folder when the
// NAME has one ("cam03/0001.jpg" -> "cam03"), else by the NAME without its extension. Two
// selected images of one name are an error naming both.
CalibrationRecords read_colmap_calibration(const std::filesystem::path& dir,
                                           const std::vector<std::string>& image_patterns = {});

// OpenCV FileStorage files (.xml, .yml, .yaml), in any of the three layouts above; several
// files are merged (one file per camera, or intrinsics and extrinsics apart). R may be a 3x3
// matrix or a Rodrigues vector. Errors name the file, the node and the field.
CalibrationRecords read_opencv_calibration(const std::vector<std::filesystem::path>& files);

enum class CsvPose { kWorldFromCamera, kCameraFromWorld };
enum class CsvIntrinsics { kDetect, kNormalised, kPixels };
struct CsvOptions {
  CsvPose pose = CsvPose::kWorldFromCamera;  // the 4D datasets' convention
  CsvIntrinsics intrinsics = CsvIntrinsics::kDetect;  // detect: fx < 10 means normalised
};
// A CSV with a header row naming its columns (any order; "w"/"h" and "px"/"py" accepted for
// width/height and cx/cy). Errors name the file, line and column.
CalibrationRecords read_csv_calibration(const std::filesystem::path& file, const CsvOptions& options = {});

// A JSON or YAML file: an object keyed by camera name, a list of cameras with "name", either
// one possibly under "cameras"; per camera K (3x3, or fx fy cx cy), dist, R (3x3 or Rodrigues),
// t, and the image size (width/height, or size/resolution/image_size [w, h]); "unit" at the top
// or per camera. Errors name the file, line and field.
CalibrationRecords read_json_calibration(const std::filesystem::path& file);

// --- Writers (atomic; lengths written in `unit`) -----------------------------------------------

enum class OpenCvLayout { kCameraNodes, kNamesList, kFilePerCamera };
// kCameraNodes, kNamesList: `path` is the file (.yml, .yaml or .xml); kFilePerCamera: `path` is
// a folder that receives <camera>.yml. kNamesList writes R_<name> as a Rodrigues vector (and
// Rot_<name> as the matrix), the others R as a 3x3 matrix.
void write_opencv_calibration(const std::filesystem::path& path, const std::vector<Camera>& cameras,
                              LengthUnit unit, OpenCvLayout layout = OpenCvLayout::kCameraNodes);
void write_csv_calibration(const std::filesystem::path& file, const std::vector<Camera>& cameras,
                           LengthUnit unit, bool normalised, CsvPose pose = CsvPose::kWorldFromCamera);
// keyed: {"unit": u, "<name>": {...}, ...}; else {"unit": u, "cameras": [{"name": ...}, ...]}.
void write_json_calibration(const std::filesystem::path& file, const std::vector<Camera>& cameras,
                            LengthUnit unit, bool keyed_by_name = false);

}  // namespace fourd
