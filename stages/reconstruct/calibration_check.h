#pragma once
// Checks the rig calibration with COLMAP: SIFT features of every camera's images
// (feature_extractor, one run per camera so that each camera keeps its own intrinsics),
// matching between the cameras of the same frame, triangulation with our poses held fixed
// (point_triangulator), then the median (and mean) reprojection error of the triangulated points
// per camera. One frame triangulates a few points per camera (a performer in the middle of a
// ring of cameras), too few to judge a camera by, so the check triangulates several frames
// spread through the session: the cameras are static, so the points of all frames are merged
// into one model with one image per camera.
//
// Optionally refines the poses by COLMAP's bundle adjustment, on features from more frames
// spread through the session, merged the same way before bundle_adjuster runs. Every third frame is held out: those are triangulated with the written
// and with the refined calibration, and the refinement is kept only when it lowers the
// reprojection error on them (the error on the frames it was fitted to always drops). The result
// is brought back into our world frame (similarity fitted to the camera centres) and written.
//
// Files in <out>/ (replaced as a whole on success):
//   images/<camera>/<k>.png (frame k of the check), database.db, pairs.txt, input/ (our
//   calibration), triangulated/ (the checked frames, COLMAP text model), refined/ (our
//   calibration format, when refining), colmap.log, report.json
#include <filesystem>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"
#include "pipeline/core/config.h"
#include "pipeline/core/session.h"

namespace fourd::reconstruct {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/reconstruct.md, "Advanced").
struct CalibrationCheckOptions {
  bool enabled = true;
  std::string take;             // take of the checked frame ("": the first take)
  int frame = 0;                // the checked frame
  int check_frames = 16;        // frames triangulated: the checked one and others spread
                                // through the session (one frame's SIFT matches on a costume
                                // are a few points per camera, too few to judge by)
  double warn_error_px = 2.0;   // warn when a camera's median reprojection error is above
                                // (16 frames: the true calibration 0.6-1.5 px per camera,
                                // one perturbed by 0.3 deg, 10 mm, 1 % focal 1.7-4.8 px)
  int min_points = 15;          // fewer points in a camera's images: too few to judge it
  bool refine = false;
  bool refine_focal_length = false;  // refinement adjusts focal lengths too (principal points
                                     // and distortion stay); off: from points in the middle of
                                     // the rig a focal length is barely separable from the
                                     // camera's distance
  int refine_frames = 60;       // frames spread through the session: 2/3 fitted, 1/3 held out
  double refine_error_px = 2;   // refinement triangulates at max_error_px, then 2x, then 1x this
  int min_refine_points = 100;  // fewer triangulated points: no refinement (it would overfit)
  double max_refine_shift = 0.10;  // refinement moving a camera farther is rejected [m]
  double max_refine_turn_deg = 2.0;  // ... or turning it more [deg]
  double max_error_px = 12;     // largest reprojection error triangulation accepts [px]
  int max_features = 8192;      // SIFT features per image
  double peak_threshold = 0.002;  // SIFT peak threshold (COLMAP's default 0.0067 finds few
                                  // features on small images)
  double timeout_s = 300;
  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "check the calibration when the whole session is reconstructed");
    v("refine", refine,
      "refine the calibration with COLMAP's bundle adjustment (as --refine-calibration does)");
    v("timeout_s", timeout_s,
      "a COLMAP command still running after this long is killed and run once more [s]",
      Range{1, 1e6});
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
  double median_error_px = 0;  // robust to the mismatches a loose triangulation bound lets in
  std::size_t observations = 0;
};

// One frame of a take.
struct CheckFrame {
  std::string take;
  int frame = 0;
};

// The image of `camera` in `frame` (throws Error when it cannot be read).
using CheckImageLoader = std::function<cv::Mat(const CheckFrame& frame, const Camera& camera)>;

// Reprojection error over the points triangulated on some frames.
struct Reprojection {
  double mean_error_px = 0;
  std::size_t points = 0;
};

struct CalibrationCheckResult {
  std::string take;  // the first checked frame
  int frame = 0;
  std::size_t frames = 0;  // checked frames
  std::size_t points = 0;  // triangulated points
  std::map<std::string, CameraReprojection> cameras;  // by camera name
  std::map<std::string, CameraReprojection> refined;  // fitted frames, after bundle adjustment
  std::size_t fit_frames = 0, held_out_frames = 0;  // refinement (0: not refined)
  std::size_t fit_points = 0;                       // points of the last bundle adjustment
  Reprojection held_out_before, held_out_after;     // held-out frames, written vs refined
  std::vector<Camera> refined_calibration;  // empty: not refined (or the refinement rejected)
  std::vector<std::string> warnings;
  nlohmann::json to_json() const;
};

// Why point_triangulator failed, from its log (features per image, `frames` images per camera
// in camera order; matched pairs; triangulated points), as one message naming the cameras and
// what to try.
std::string triangulation_failure(const std::filesystem::path& log, int exit_code,
                                  const std::vector<Camera>& cameras, std::size_t frames = 1);

// Why a refined calibration (`after`, same order as `before`) must not replace `before`: a
// camera moved or turned more than the options allow. Empty: accept it.
std::string refinement_rejection(const std::vector<Camera>& before,
                                 const std::vector<Camera>& after,
                                 const CalibrationCheckOptions& options, std::size_t points);

// Runs the check on the frames `checked` (at least one; their points are merged per camera) in
// `out_dir`, and refines the calibration on `refine_frames` when that is not empty (at least
// 3). Throws SolverError when a COLMAP step fails (naming the step and quoting its log),
// InputError when an image does not fit its camera.
CalibrationCheckResult check_calibration(const std::string& colmap,
                                         const std::vector<Camera>& cameras,
                                         const std::vector<CheckFrame>& checked,
                                         const std::vector<CheckFrame>& refine_frames,
                                         const CheckImageLoader& load,
                                         const CalibrationCheckOptions& options,
                                         const std::filesystem::path& out_dir);

// `count` frames spread evenly through the takes (in order, each take's frames 0..n-1), fewer
// when the takes hold fewer.
std::vector<CheckFrame> spread_frames(const std::vector<std::pair<std::string, int>>& takes,
                                      int count);

// Mean reprojection error per image of a COLMAP text model (cameras from `cameras`, matched by
// image name "<camera>.png"; points3D.txt and the POINTS2D of images.txt from `model_dir`).
std::map<std::string, CameraReprojection> reprojection_errors(
    const std::vector<Camera>& cameras, const std::filesystem::path& model_dir,
    std::size_t* points = nullptr);

}  // namespace fourd::reconstruct
