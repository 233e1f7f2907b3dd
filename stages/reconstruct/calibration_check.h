#pragma once
// Checks the rig calibration with COLMAP on one frame: SIFT features of every camera's image
// (feature_extractor, one run per camera so that COLMAP's camera and image ids follow our
// calibration), exhaustive matching, triangulation with our poses held fixed
// (point_triangulator), then the mean reprojection error of the triangulated points per camera.
// Optionally refines the poses (and focal lengths) by COLMAP's bundle adjustment, brings the
// result back into our world frame (similarity fitted to the camera centres) and writes the
// refined model.
//
// Files in <out>/ (replaced as a whole on success):
//   images/<camera>.png, database.db, input/ (our calibration), triangulated/ (COLMAP text
//   model), refined/ (our calibration format, when refining), colmap.log, report.json
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"
#include "pipeline/core/config.h"
#include "pipeline/core/session.h"

namespace fourd::reconstruct {

struct CalibrationCheckOptions {
  bool enabled = true;          // check when the stage runs over the whole session
  std::string take;             // take of the checked frame ("": the first take)
  int frame = 0;                // the checked frame
  double warn_error_px = 1.0;   // warn when a camera's mean reprojection error is above
  bool refine = false;          // refine the calibration by bundle adjustment
  bool refine_focal_length = true;  // ... focal lengths too (principal points and distortion stay)
  int min_refine_points = 100;  // fewer triangulated points: no refinement (it would overfit)
  double max_refine_shift = 0.10;  // refinement moving a camera farther is rejected [m]
  double max_refine_turn_deg = 2.0;  // ... or turning it more [deg]
  double max_error_px = 12;     // largest reprojection error triangulation accepts [px]
  int max_features = 8192;      // SIFT features per image
  double peak_threshold = 0.002;  // SIFT peak threshold (COLMAP's default 0.0067 finds few
                                  // features on small images)
  std::string executable = "colmap";  // name on PATH or path

  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "check the calibration when the whole session is reconstructed");
    v("take", take, "take of the checked frame (empty: the first take)");
    v("frame", frame, "checked frame", Range{0, 1e9});
    v("warn_error_px", warn_error_px, "warn above this mean reprojection error [px]",
      Range{0, 1000});
    v("refine", refine, "refine the calibration with COLMAP's bundle adjustment");
    v("refine_focal_length", refine_focal_length, "refinement also adjusts focal lengths");
    v("min_refine_points", min_refine_points,
      "refine only with at least this many triangulated points", Range{0, 1e9});
    v("max_refine_shift", max_refine_shift,
      "reject a refinement that moves a camera centre farther than this [m]", Range{0, 1e3});
    v("max_refine_turn_deg", max_refine_turn_deg,
      "reject a refinement that turns a camera more than this [deg]", Range{0, 180});
    v("max_error_px", max_error_px, "largest reprojection error triangulation accepts [px]",
      Range{0.5, 1000});
    v("max_features", max_features, "SIFT features per image", Range{100, 100000});
    v("peak_threshold", peak_threshold, "SIFT peak threshold (lower: more features)",
      Range{0.0001, 0.1});
    v("executable", executable, "colmap executable (name on PATH or path)");
  }
};

// What the command line asks for beyond the options (fourd-reconstruct --check-calibration...).
struct CalibrationCheckRequest {
  bool only = false;    // run the check and nothing else
  bool refine = false;  // force refinement
  std::string take;     // override the checked frame
  int frame = -1;
};

struct CameraReprojection {
  double mean_error_px = 0;
  std::size_t observations = 0;
};

struct CalibrationCheckResult {
  std::string take;
  int frame = 0;
  std::size_t points = 0;  // triangulated points
  std::map<std::string, CameraReprojection> cameras;  // by camera name
  std::map<std::string, CameraReprojection> refined;  // after bundle adjustment (when refined)
  std::vector<Camera> refined_calibration;  // empty: not refined (or the refinement rejected)
  std::vector<std::string> warnings;
  nlohmann::json to_json() const;
};

// Runs the check on the given capture images (one per camera, same order) in `out_dir`. Throws
// SolverError when a COLMAP step fails (naming the step and quoting its log), InputError when
// the images do not fit the cameras.
// Why point_triangulator failed, from its log (features per image, matched pairs,
// triangulated points), as one message naming the cameras and what to try.
std::string triangulation_failure(const std::filesystem::path& log, int exit_code,
                                  const std::vector<Camera>& cameras);

// Why a refined calibration (`after`, same order as `before`) must not replace `before`: a
// camera moved or turned more than the options allow. Empty: accept it.
std::string refinement_rejection(const std::vector<Camera>& before,
                                 const std::vector<Camera>& after,
                                 const CalibrationCheckOptions& options, std::size_t points);

CalibrationCheckResult check_calibration(const std::string& colmap,
                                         const std::vector<Camera>& cameras,
                                         const std::vector<cv::Mat>& images,
                                         const CalibrationCheckOptions& options, bool refine,
                                         const std::filesystem::path& out_dir);

// Mean reprojection error per image of a COLMAP text model (cameras from `cameras`, matched by
// image name "<camera>.png"; points3D.txt and the POINTS2D of images.txt from `model_dir`).
std::map<std::string, CameraReprojection> reprojection_errors(
    const std::vector<Camera>& cameras, const std::filesystem::path& model_dir,
    std::size_t* points = nullptr);

}  // namespace fourd::reconstruct
