#include "stages/reconstruct/calibration_check.h"

#include <Eigen/Geometry>
#include <fmt/format.h>

#include <fstream>
#include <sstream>
#include <unordered_map>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "stages/reconstruct/colmap_tool.h"

namespace fourd::reconstruct {
namespace {

namespace fs = std::filesystem;

std::string camera_params(const Camera& c) {
  const Intrinsics& in = c.intrinsics;
  return fmt::format("{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}", in.fx, in.fy,
                     in.cx, in.cy, in.k1, in.k2, in.p1, in.p2);
}

std::vector<std::string> data_lines(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw IoError(fmt::format("{}: cannot read", path.string()));
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] == '#') continue;
    lines.push_back(line);
  }
  return lines;
}

// The similarity s R x + t that best maps `from` onto `to` (least squares, Umeyama).
Eigen::Matrix4d fit_similarity(const std::vector<Eigen::Vector3d>& from,
                               const std::vector<Eigen::Vector3d>& to) {
  Eigen::Matrix3Xd a(3, from.size()), b(3, to.size());
  for (std::size_t i = 0; i < from.size(); ++i) {
    a.col(i) = from[i];
    b.col(i) = to[i];
  }
  return Eigen::umeyama(a, b, true);
}

// Moves a rig by the similarity x -> s R x + t (COLMAP's bundle adjuster fixes the gauge on
// its first cameras; we want the rig back where the studio's world frame has it).
std::vector<Camera> transform_rig(std::vector<Camera> cameras, const Eigen::Matrix4d& sim) {
  const double s = std::cbrt(sim.topLeftCorner<3, 3>().determinant());
  const Eigen::Matrix3d rot = sim.topLeftCorner<3, 3>() / s;
  const Eigen::Vector3d t = sim.topRightCorner<3, 1>();
  for (Camera& c : cameras) {
    // x_cam = R_c x + t_c with x = (rot^T (y - t)) / s for the new world point y: scale the
    // camera translation so the camera frame keeps metric units.
    const Eigen::Vector3d centre = s * rot * c.center() + t;
    const Eigen::Matrix3d r_new = c.camera_from_world.linear() * rot.transpose();
    c.camera_from_world.linear() = r_new;
    c.camera_from_world.translation() = -r_new * centre;
  }
  return cameras;
}

}  // namespace

std::string triangulation_failure(const fs::path& log, int exit_code,
                                  const std::vector<Camera>& cameras) {
  std::ifstream in(log);
  std::string line;
  std::vector<long> features;
  long matches = -1, points = -1;
  auto number_after = [](const std::string& l, const std::string& key) -> long {
    const std::size_t at = l.find(key);
    if (at == std::string::npos) return -1;
    std::istringstream s(l.substr(at + key.size()));
    long n = -1;
    s >> n;
    return n;
  };
  while (std::getline(in, line)) {
    if (long n = number_after(line, "Features:"); n >= 0) features.push_back(n);
    if (long n = number_after(line, "Loading matches..."); n >= 0) matches = n;
    if (long n = number_after(line, "=> Triangulated"); n > 0) points = std::max(points, 0L) + n;
  }
  std::string per_camera;
  for (std::size_t i = 0; i < features.size() && i < cameras.size(); ++i) {
    per_camera += fmt::format("{}{} {}", i ? ", " : "", cameras[i].name, features[i]);
  }
  std::string why;
  if (matches == 0) {
    why = "COLMAP found no feature match between any two cameras";
  } else if (points <= 0) {
    why = fmt::format("COLMAP matched features ({} image pairs with matches) but could not "
                      "triangulate any point with the calibrated poses",
                      matches < 0 ? std::string("?") : std::to_string(matches));
  } else {
    why = fmt::format("COLMAP point_triangulator failed (exit {})", exit_code);
  }
  return fmt::format(
      "{} (SIFT features per image: {}); the calibration cannot be checked on this frame — "
      "cameras too far apart or images too small/untextured for SIFT. Try another frame "
      "(--check-frame), a lower calibration_check.peak_threshold, or a rig with closer "
      "cameras. COLMAP log: {}",
      why, per_camera.empty() ? "unknown" : per_camera, log.string());
}

nlohmann::json CalibrationCheckResult::to_json() const {
  nlohmann::json j;
  j["take"] = take;
  j["frame"] = frame;
  j["points"] = points;
  auto errors = [](const std::map<std::string, CameraReprojection>& m) {
    nlohmann::json out = nlohmann::json::object();
    for (const auto& [name, e] : m) {
      out[name] = {{"mean_error_px", e.mean_error_px}, {"observations", e.observations}};
    }
    return out;
  };
  j["cameras"] = errors(cameras);
  if (!refined.empty()) j["refined"] = errors(refined);
  j["warnings"] = warnings;
  return j;
}

std::map<std::string, CameraReprojection> reprojection_errors(const std::vector<Camera>& cameras,
                                                              const fs::path& model_dir,
                                                              std::size_t* points) {
  std::unordered_map<long, Eigen::Vector3d> xyz;
  for (const std::string& line : data_lines(model_dir / "points3D.txt")) {
    std::istringstream in(line);
    long id;
    double x, y, z;
    if (in >> id >> x >> y >> z) xyz[id] = {x, y, z};
  }
  if (points) *points = xyz.size();
  std::map<std::string, const Camera*> by_name;
  for (const Camera& c : cameras) by_name[c.name + ".png"] = &c;
  std::map<std::string, CameraReprojection> out;
  const std::vector<std::string> lines = data_lines(model_dir / "images.txt");
  for (std::size_t i = 0; i + 1 < lines.size(); i += 2) {
    std::istringstream head(lines[i]);
    std::string skip, name;
    for (int k = 0; k < 9; ++k) head >> skip;
    head >> name;
    auto it = by_name.find(name);
    if (it == by_name.end()) continue;
    const Camera& cam = *it->second;
    CameraReprojection& e = out[cam.name];
    double sum = 0;
    std::istringstream obs(lines[i + 1]);
    double x, y;
    long id;
    while (obs >> x >> y >> id) {
      if (id < 0) continue;
      auto p = xyz.find(id);
      if (p == xyz.end()) continue;
      Eigen::Vector2d px;
      if (!cam.project(p->second, &px)) continue;
      sum += (px - Eigen::Vector2d(x, y)).norm();
      e.observations += 1;
    }
    e.mean_error_px = e.observations ? sum / e.observations : 0;
  }
  return out;
}

std::string refinement_rejection(const std::vector<Camera>& before,
                                 const std::vector<Camera>& after,
                                 const CalibrationCheckOptions& options, std::size_t points) {
  for (std::size_t i = 0; i < before.size() && i < after.size(); ++i) {
    const double shift = (after[i].center() - before[i].center()).norm();
    const double turn = Eigen::AngleAxisd(after[i].camera_from_world.linear() *
                                          before[i].camera_from_world.linear().transpose())
                            .angle() *
                        180.0 / M_PI;
    if (shift > options.max_refine_shift || turn > options.max_refine_turn_deg) {
      return fmt::format(
          "refinement rejected: it moves camera {} by {:.3f} m and turns it by {:.2f} deg "
          "(limits {:.3f} m, {:.2f} deg): the {} triangulated points do not constrain the rig",
          before[i].name, shift, turn, options.max_refine_shift, options.max_refine_turn_deg,
          points);
    }
  }
  return {};
}

CalibrationCheckResult check_calibration(const std::string& colmap,
                                         const std::vector<Camera>& cameras,
                                         const std::vector<cv::Mat>& images,
                                         const CalibrationCheckOptions& options, bool refine,
                                         const fs::path& out_dir) {
  if (cameras.size() != images.size()) {
    throw InputError("calibration check: one image per camera is needed");
  }
  // Work in a fresh hidden folder beside the output and swap it in at the end (a killed run
  // leaves it hidden; the next run starts it afresh).
  const fs::path work = out_dir.parent_path() / ("." + out_dir.filename().string() + ".tmp");
  std::error_code ec;
  fs::remove_all(work, ec);
  ensure_directory(work / "images");
  const fs::path log = work / "colmap.log";
  const fs::path db = work / "database.db";
  CalibrationCheckResult result;
  try {
    // One feature_extractor run per camera: COLMAP gives image i and camera i the id i + 1, as
    // write_colmap_model numbers our calibration, and each camera keeps its own intrinsics.
    for (std::size_t i = 0; i < cameras.size(); ++i) {
      const std::string name = cameras[i].name + ".png";
      write_image_atomic(work / "images" / name, images[i]);
      write_file_atomic(work / "list.txt", name + "\n");
      run_colmap_checked(
          colmap, "feature_extractor",
          {"--database_path", db.string(), "--image_path", (work / "images").string(),
           "--image_list_path", (work / "list.txt").string(), "--ImageReader.camera_model",
           "OPENCV", "--ImageReader.camera_params", camera_params(cameras[i]),
           "--SiftExtraction.use_gpu", "0", "--SiftExtraction.num_threads", "2",
           "--SiftExtraction.max_num_features", std::to_string(options.max_features),
           "--SiftExtraction.peak_threshold", fmt::format("{}", options.peak_threshold)},
          log);
    }
    run_colmap_checked(colmap, "exhaustive_matcher",
                       {"--database_path", db.string(), "--SiftMatching.use_gpu", "0",
                        "--SiftMatching.num_threads", "2", "--SiftMatching.guided_matching", "1"},
                       log);
    write_colmap_model(work / "input", cameras);
    fs::remove(work / "input" / "rig.json", ec);  // COLMAP's readers do not know it
    const std::string tol = fmt::format("{}", options.max_error_px);
    ensure_directory(work / "triangulated");
    const int triangulator_exit = run_colmap(colmap, "point_triangulator",
                                             {"--database_path",
                                              db.string(),
                                              "--image_path",
                                              (work / "images").string(),
                                              "--input_path",
                                              (work / "input").string(),
                                              "--output_path",
                                              (work / "triangulated").string(),
                                              "--Mapper.filter_max_reproj_error",
                                              tol,
                                              "--Mapper.tri_merge_max_reproj_error",
                                              tol,
                                              "--Mapper.tri_complete_max_reproj_error",
                                              tol,
                                              "--Mapper.tri_create_max_angle_error",
                                              "4",
                                              "--Mapper.tri_continue_max_angle_error",
                                              "4",
                                              "--Mapper.ba_refine_focal_length",
                                              "0",
                                              "--Mapper.ba_refine_extra_params",
                                              "0",
                                              "--Mapper.num_threads",
                                              "2"},
                                             log);
    if (triangulator_exit != 0) {
      // COLMAP 3.8 aborts (exit 134, a failed CHECK in its bundle adjustment) when there is
      // nothing to triangulate: say why instead of showing its stack trace.
      throw SolverError(triangulation_failure(log, triangulator_exit, cameras));
    }
    run_colmap_checked(colmap, "model_converter",
                       {"--input_path", (work / "triangulated").string(), "--output_path",
                        (work / "triangulated").string(), "--output_type", "TXT"},
                       log);

    result.cameras = reprojection_errors(cameras, work / "triangulated", &result.points);
    for (const Camera& c : cameras) {
      const CameraReprojection& e = result.cameras[c.name];
      if (e.observations > 0 && e.observations < 10) {
        result.warnings.push_back(fmt::format(
            "camera {}: only {} triangulated point(s) in its image (mean reprojection error "
            "{:.2f} px) — too few to judge its calibration (few SIFT matches between the cameras)",
            c.name, e.observations, e.mean_error_px));
      } else if (e.observations == 0) {
        result.warnings.push_back(fmt::format(
            "camera {}: no point triangulated in its image — it sees nothing the others see, or "
            "its calibration is far off",
            c.name));
      } else if (e.mean_error_px > options.warn_error_px) {
        result.warnings.push_back(fmt::format(
            "camera {}: mean reprojection error {:.2f} px over {} points exceeds {:.2f} px — its "
            "calibration is off (refine it with --refine-calibration)",
            c.name, e.mean_error_px, e.observations, options.warn_error_px));
      }
    }

    if (refine && result.points < static_cast<std::size_t>(options.min_refine_points)) {
      result.warnings.push_back(fmt::format(
          "refinement skipped: {} triangulated points, fewer than {} "
          "(calibration_check.min_refine_points); bundle adjustment would fit the noise of so few",
          result.points, options.min_refine_points));
      refine = false;
    }
    if (refine) {
      ensure_directory(work / "adjusted");
      run_colmap_checked(
          colmap, "bundle_adjuster",
          {"--input_path", (work / "triangulated").string(), "--output_path",
           (work / "adjusted").string(), "--BundleAdjustment.refine_focal_length",
           options.refine_focal_length ? "1" : "0", "--BundleAdjustment.refine_principal_point",
           "0", "--BundleAdjustment.refine_extra_params", "0",
           "--BundleAdjustment.refine_extrinsics", "1"},
          log);
      run_colmap_checked(colmap, "model_converter",
                         {"--input_path", (work / "adjusted").string(), "--output_path",
                          (work / "adjusted").string(), "--output_type", "TXT"},
                         log);
      std::vector<Camera> adjusted = read_colmap_model(work / "adjusted");
      result.refined = reprojection_errors(adjusted, work / "adjusted");
      // Back into our world frame: the similarity that best maps the adjusted camera centres
      // onto the calibrated ones.
      std::map<std::string, const Camera*> by_name;
      for (const Camera& c : cameras) by_name[c.name] = &c;
      std::vector<Eigen::Vector3d> from, to;
      for (const Camera& c : adjusted) {
        auto it = by_name.find(c.name);
        if (it == by_name.end()) continue;
        from.push_back(c.center());
        to.push_back(it->second->center());
      }
      if (from.size() < 3) {
        throw SolverError("calibration check: bundle adjustment kept fewer than 3 cameras");
      }
      adjusted = transform_rig(adjusted, fit_similarity(from, to));
      // Our order and names, COLMAP's refined values.
      std::map<std::string, Camera> refined_by_name;
      for (const Camera& c : adjusted) refined_by_name[c.name] = c;
      for (const Camera& c : cameras) {
        auto it = refined_by_name.find(c.name);
        result.refined_calibration.push_back(it == refined_by_name.end() ? c : it->second);
      }
      // Few or badly spread points let bundle adjustment move cameras far to fit them: such a
      // result is worse than the calibration it started from.
      const std::string rejected =
          refinement_rejection(cameras, result.refined_calibration, options, result.points);
      if (!rejected.empty()) {
        result.warnings.push_back(rejected);
        result.refined_calibration.clear();
        result.refined.clear();
      }
      if (!result.refined_calibration.empty()) {
        write_colmap_model(work / "refined", result.refined_calibration);
      }
    }

  } catch (const Error&) {
    // Keep COLMAP's log (the error names it) and drop the scratch: images, database, models.
    for (const auto& entry : fs::directory_iterator(work, ec)) {
      if (entry.path() != log) fs::remove_all(entry.path(), ec);
    }
    throw;
  }
  fs::remove(work / "list.txt", ec);
  fs::remove_all(out_dir, ec);
  fs::rename(work, out_dir, ec);
  if (ec) {
    throw IoError(fmt::format("cannot move {} to {}: {}", work.string(), out_dir.string(),
                              ec.message()));
  }
  return result;
}

}  // namespace fourd::reconstruct
