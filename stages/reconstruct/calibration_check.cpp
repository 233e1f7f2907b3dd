#include "stages/reconstruct/calibration_check.h"

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <sqlite3.h>
#include <fmt/ranges.h>

#include <fstream>
#include <iterator>
#include <memory>
#include <numeric>
#include <sstream>
#include <unordered_map>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/statistics.h"
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

// The whitespace-separated words of a line of a COLMAP text model.
std::vector<std::string> words(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> out;
  for (std::string w; in >> w;) out.push_back(w);
  return out;
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
                                  const std::vector<Camera>& cameras, std::size_t frames) {
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
  frames = std::max<std::size_t>(frames, 1);
  std::string per_camera;
  for (std::size_t i = 0; i * frames < features.size() && i < cameras.size(); ++i) {
    long sum = 0;
    for (std::size_t k = i * frames; k < (i + 1) * frames && k < features.size(); ++k) sum += features[k];
    per_camera += fmt::format("{}{} {}", i ? ", " : "", cameras[i].name, sum);
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
      "{} (SIFT features per camera{}: {}); the calibration cannot be checked on {} — "
      "cameras too far apart or images too small/untextured for SIFT. Try other frames "
      "(--check-frame, calibration_check.check_frames), a lower "
      "calibration_check.peak_threshold, or a rig with closer cameras. COLMAP log: {}",
      why, frames > 1 ? fmt::format(" over {} frames", frames) : std::string(),
      per_camera.empty() ? "unknown" : per_camera, frames > 1 ? "these frames" : "this frame",
      log.string());
}

nlohmann::json CalibrationCheckResult::to_json() const {
  nlohmann::json j;
  j["take"] = take;
  j["frame"] = frame;
  j["frames"] = frames;
  j["points"] = points;
  auto errors = [](const std::map<std::string, CameraReprojection>& m) {
    nlohmann::json out = nlohmann::json::object();
    for (const auto& [name, e] : m) {
      out[name] = {{"mean_error_px", e.mean_error_px},
                   {"median_error_px", e.median_error_px},
                   {"observations", e.observations}};
    }
    return out;
  };
  j["cameras"] = errors(cameras);
  if (!refined.empty()) j["refined"] = errors(refined);
  if (fit_frames > 0) {
    auto reprojection = [](const Reprojection& r) {
      return nlohmann::json{{"mean_error_px", r.mean_error_px}, {"points", r.points}};
    };
    j["refinement"] = {{"fit_frames", fit_frames},
                       {"held_out_frames", held_out_frames},
                       {"fit_points", fit_points},
                       {"held_out_before", reprojection(held_out_before)},
                       {"held_out_after", reprojection(held_out_after)},
                       {"accepted", !refined_calibration.empty()}};
  }
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
    std::vector<double> errors;
    std::istringstream obs(lines[i + 1]);
    double x, y;
    long id;
    while (obs >> x >> y >> id) {
      if (id < 0) continue;
      auto p = xyz.find(id);
      if (p == xyz.end()) continue;
      Eigen::Vector2d px;
      if (!cam.project(p->second, &px)) continue;
      errors.push_back((px - Eigen::Vector2d(x, y)).norm());
    }
    e.observations = errors.size();
    if (errors.empty()) continue;
    e.mean_error_px = std::accumulate(errors.begin(), errors.end(), 0.0) / errors.size();
    e.median_error_px = median(errors);
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

std::vector<CheckFrame> spread_frames(const std::vector<std::pair<std::string, int>>& takes,
                                      int count) {
  long total = 0;
  for (const auto& take : takes) total += std::max(take.second, 0);
  std::vector<CheckFrame> out;
  const long n = std::min<long>(std::max(count, 0), total);
  for (long i = 0; i < n; ++i) {
    long index = n == 1 ? 0 : i * (total - 1) / (n - 1);  // strictly increasing: n <= total
    for (const auto& [take, frames] : takes) {
      if (index < frames) {
        out.push_back({take, static_cast<int>(index)});
        break;
      }
      index -= std::max(frames, 0);
    }
  }
  return out;
}

namespace {

// The COLMAP workspace of one check: the images of every frame with their SIFT features and
// the matches between the cameras of each frame, and triangulations of some of the frames with
// given poses.
//
// Frame k of camera i is the image "<camera>/<k>.png". One feature_extractor run per camera
// (the i-th run creates COLMAP camera i + 1, with that camera's intrinsics); COLMAP numbers the
// images in the order its threads finish them, so their ids are read back from its database:
// our models must use them, as point_triangulator requires.
class CheckWorkspace {
 public:
  CheckWorkspace(std::string colmap, fs::path dir, const std::vector<Camera>& cameras,
                 const CalibrationCheckOptions& options)
      : colmap_(std::move(colmap)), dir_(std::move(dir)), cameras_(cameras), options_(options) {}

  fs::path log() const { return dir_ / "colmap.log"; }

  void add_frames(const std::vector<CheckFrame>& frames, const CheckImageLoader& load) {
    frames_ = frames.size();
    const fs::path db = dir_ / "database.db";
    for (std::size_t i = 0; i < cameras_.size(); ++i) {
      const Camera& cam = cameras_[i];
      std::string list;
      for (std::size_t k = 0; k < frames.size(); ++k) {
        const cv::Mat image = load(frames[k], cam);
        if (image.cols != cam.intrinsics.width || image.rows != cam.intrinsics.height) {
          throw InputError(fmt::format(
              "calibration check: the image of camera {} in take {} frame {} is {}x{}, its "
              "calibration says {}x{}",
              cam.name, frames[k].take, frames[k].frame, image.cols, image.rows,
              cam.intrinsics.width, cam.intrinsics.height));
        }
        write_image_atomic(dir_ / "images" / image_name(i, k), image);
        list += image_name(i, k) + "\n";
      }
      write_file_atomic(dir_ / "list.txt", list);
      run_colmap_checked(
          colmap_, "feature_extractor",
          {"--database_path", db.string(), "--image_path", (dir_ / "images").string(),
           "--image_list_path", (dir_ / "list.txt").string(), "--ImageReader.camera_model",
           "OPENCV", "--ImageReader.single_camera", "1", "--ImageReader.camera_params",
           camera_params(cam), "--SiftExtraction.use_gpu", "0",
           "--SiftExtraction.num_threads", "2", "--SiftExtraction.max_num_features",
           std::to_string(options_.max_features), "--SiftExtraction.peak_threshold",
           fmt::format("{}", options_.peak_threshold)},
          log(), options_.timeout_s);
    }
    std::error_code ec;
    fs::remove(dir_ / "list.txt", ec);
    read_image_ids(db);
    // Matches between the cameras of the same frame only: the performer moves between frames.
    std::string pairs;
    for (std::size_t k = 0; k < frames_; ++k) {
      for (std::size_t a = 0; a < cameras_.size(); ++a) {
        for (std::size_t b = a + 1; b < cameras_.size(); ++b) {
          pairs += image_name(a, k) + " " + image_name(b, k) + "\n";
        }
      }
    }
    write_file_atomic(dir_ / "pairs.txt", pairs);
    run_colmap_checked(colmap_, "matches_importer",
                       {"--database_path", db.string(), "--match_list_path",
                        (dir_ / "pairs.txt").string(), "--match_type", "pairs",
                        "--SiftMatching.use_gpu", "0", "--SiftMatching.num_threads", "2",
                        "--SiftMatching.guided_matching", "1"},
                       log(), options_.timeout_s);
  }

  // Triangulates frames `which` (indices into add_frames' list) with the poses and intrinsics
  // of `rig` (our order), keeping points whose reprojection error is within `max_error_px`, into
  // <dir>/<name>/ (COLMAP text model, an image per camera and frame). Returns the folder of the
  // same points in a model with one image per camera ("<camera>.png"; the rig is static, so an
  // image's observations of every frame belong to one camera): <dir>/<name>/merged.
  fs::path triangulate(const std::vector<std::size_t>& which, const std::vector<Camera>& rig,
                       double max_error_px, const std::string& name) const {
    const fs::path input = dir_ / name / "input";
    const fs::path model = dir_ / name;
    write_model(input, rig, which);
    const std::string tol = fmt::format("{}", max_error_px);
    const int exit_code = run_colmap(
        colmap_, "point_triangulator",
        {"--database_path", (dir_ / "database.db").string(), "--image_path",
         (dir_ / "images").string(), "--input_path", input.string(), "--output_path",
         model.string(), "--Mapper.filter_max_reproj_error", tol,
         "--Mapper.tri_merge_max_reproj_error", tol, "--Mapper.tri_complete_max_reproj_error",
         tol, "--Mapper.tri_create_max_angle_error", "4", "--Mapper.tri_continue_max_angle_error",
         "4", "--Mapper.ba_refine_focal_length", "0", "--Mapper.ba_refine_extra_params", "0",
         "--Mapper.num_threads", "2"},
        log(), options_.timeout_s);
    if (exit_code != 0) {
      // COLMAP 3.8 aborts (exit 134, a failed CHECK in its bundle adjustment) when there is
      // nothing to triangulate: say why instead of showing its stack trace.
      throw SolverError(triangulation_failure(log(), exit_code, cameras_, frames_));
    }
    run_colmap_checked(colmap_, "model_converter",
                       {"--input_path", model.string(), "--output_path", model.string(),
                        "--output_type", "TXT"},
                       log(), options_.timeout_s);
    const fs::path merged = model / "merged";
    merge_frames(model, rig, merged);
    return merged;
  }

 private:
  std::string image_name(std::size_t i, std::size_t k) const {
    return fmt::format("{}/{:05d}.png", cameras_[i].name, k);
  }
  long image_id(std::size_t i, std::size_t k) const { return image_ids_.at(image_name(i, k)); }

  void read_image_ids(const fs::path& db) {
    sqlite3* handle = nullptr;
    const int opened = sqlite3_open_v2(db.c_str(), &handle, SQLITE_OPEN_READONLY, nullptr);
    std::unique_ptr<sqlite3, decltype(&sqlite3_close)> guard(handle, sqlite3_close);
    auto fail = [&](const char* what) {
      throw IoError(fmt::format("{}: cannot {} COLMAP's database: {}", db.string(), what,
                                handle ? sqlite3_errmsg(handle) : "out of memory"));
    };
    if (opened != SQLITE_OK) fail("open");
    sqlite3_stmt* statement = nullptr;
    if (sqlite3_prepare_v2(handle, "SELECT image_id, name, camera_id FROM images", -1,
                           &statement, nullptr) != SQLITE_OK) {
      fail("read the images of");
    }
    std::unique_ptr<sqlite3_stmt, decltype(&sqlite3_finalize)> rows(statement, sqlite3_finalize);
    std::map<std::string, long> camera_of;
    int step;
    while ((step = sqlite3_step(statement)) == SQLITE_ROW) {
      const unsigned char* name = sqlite3_column_text(statement, 1);
      if (!name) continue;
      image_ids_[reinterpret_cast<const char*>(name)] = sqlite3_column_int64(statement, 0);
      camera_of[reinterpret_cast<const char*>(name)] = sqlite3_column_int64(statement, 2);
    }
    if (step != SQLITE_DONE) fail("read the images of");
    for (std::size_t i = 0; i < cameras_.size(); ++i) {
      for (std::size_t k = 0; k < frames_; ++k) {
        auto it = camera_of.find(image_name(i, k));
        if (it == camera_of.end()) {
          throw SolverError(fmt::format("COLMAP feature_extractor did not add {} to {} (see {})",
                                        image_name(i, k), db.string(), log().string()));
        }
        if (it->second != static_cast<long>(i + 1)) {
          throw SolverError(fmt::format(
              "COLMAP gave {} camera {}, expected {} (one camera per feature_extractor run)",
              image_name(i, k), it->second, i + 1));
        }
      }
    }
  }

  // Our calibration as COLMAP's input model for frames `which`: camera i+1 as written by
  // write_colmap_model, an image per camera and frame with that camera's pose.
  void write_model(const fs::path& dir, const std::vector<Camera>& rig,
                   const std::vector<std::size_t>& which) const {
    write_colmap_model(dir, rig);
    std::error_code ec;
    fs::remove(dir / "rig.json", ec);  // COLMAP's readers do not know it
    const std::vector<std::vector<std::string>> poses = pose_lines(dir / "images.txt");
    std::string images;
    for (std::size_t k : which) {
      for (std::size_t i = 0; i < rig.size(); ++i) {
        images += fmt::format("{} {} {} {}\n\n", image_id(i, k),
                              fmt::join(poses[i].begin() + 1, poses[i].begin() + 8, " "),
                              poses[i][8], image_name(i, k));
      }
    }
    write_file_atomic(dir / "images.txt", images);
  }

  // The image lines (IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME) of a model that
  // write_colmap_model wrote, one per camera in order.
  std::vector<std::vector<std::string>> pose_lines(const fs::path& images_txt) const {
    std::vector<std::vector<std::string>> out;
    for (const std::string& line : data_lines(images_txt)) {
      std::vector<std::string> tokens = words(line);
      if (tokens.size() == 10) out.push_back(std::move(tokens));
    }
    if (out.size() != cameras_.size()) {
      throw SolverError(fmt::format("{}: expected {} images, read {}", images_txt.string(),
                                    cameras_.size(), out.size()));
    }
    return out;
  }

  void merge_frames(const fs::path& model, const std::vector<Camera>& rig,
                    const fs::path& out) const {
    const std::size_t n = rig.size();
    std::vector<std::string> observations(n);     // "X Y POINT3D_ID" triplets per camera
    std::vector<std::size_t> counts(n, 0);
    std::map<std::pair<long, long>, std::pair<std::size_t, std::size_t>> remap;
    const std::vector<std::string> lines = data_lines(model / "images.txt");
    for (std::size_t l = 0; l + 1 < lines.size(); l += 2) {
      const std::vector<std::string> tokens = words(lines[l]);
      if (tokens.size() < 10) continue;
      const long id = std::stol(tokens[0]);
      const long camera_id = std::stol(tokens[8]);
      if (camera_id < 1 || camera_id > static_cast<long>(n)) {
        throw SolverError(fmt::format("{}: image {} has camera {}, expected 1..{}",
                                      (model / "images.txt").string(), id, camera_id, n));
      }
      const std::size_t i = static_cast<std::size_t>(camera_id - 1);
      std::istringstream obs(lines[l + 1]);
      std::string x, y, point;
      for (long index = 0; obs >> x >> y >> point; ++index) {
        remap[{id, index}] = {i, counts[i]++};
        observations[i] += fmt::format("{}{} {} {}", observations[i].empty() ? "" : " ", x, y,
                                       point);
      }
    }
    std::string points;
    for (const std::string& line : data_lines(model / "points3D.txt")) {
      const std::vector<std::string> tokens = words(line);
      if (tokens.size() < 8) continue;
      std::string row = fmt::format("{}", fmt::join(tokens.begin(), tokens.begin() + 8, " "));
      for (std::size_t t = 8; t + 1 < tokens.size(); t += 2) {
        auto it = remap.find({std::stol(tokens[t]), std::stol(tokens[t + 1])});
        if (it == remap.end()) {
          throw SolverError(fmt::format("{}: point {} observed in an image it does not list",
                                        (model / "points3D.txt").string(), tokens[0]));
        }
        row += fmt::format(" {} {}", it->second.first + 1, it->second.second);
      }
      points += row + "\n";
    }
    write_colmap_model(out, rig);
    std::error_code ec;
    fs::remove(out / "rig.json", ec);
    const std::vector<std::vector<std::string>> poses = pose_lines(out / "images.txt");
    std::string images;
    for (std::size_t i = 0; i < n; ++i) {
      images += fmt::format("{}\n{}\n", fmt::join(poses[i], " "), observations[i]);
    }
    write_file_atomic(out / "images.txt", images);
    write_file_atomic(out / "points3D.txt", points);
  }

  std::string colmap_;
  fs::path dir_;
  const std::vector<Camera>& cameras_;
  const CalibrationCheckOptions& options_;
  std::size_t frames_ = 0;
  std::map<std::string, long> image_ids_;  // COLMAP's, by image name
};

// Mean reprojection error over every observation of a per-camera model, and its points.
Reprojection overall(const std::vector<Camera>& rig, const fs::path& model) {
  Reprojection r;
  double sum = 0;
  std::size_t observations = 0;
  for (const auto& [name, e] : reprojection_errors(rig, model, &r.points)) {
    sum += e.mean_error_px * static_cast<double>(e.observations);
    observations += e.observations;
  }
  r.mean_error_px = observations ? sum / static_cast<double>(observations) : 0;
  return r;
}

// Refines `cameras` on the fit frames and judges the result on the held-out frames (see the
// header). Fills the refinement fields of `result`; a refinement that fails or does not help
// leaves refined_calibration empty and says why in a warning.
void refine_calibration(const std::string& colmap, const CheckWorkspace& workspace,
                        const std::vector<Camera>& cameras, const std::vector<std::size_t>& fit,
                        const std::vector<std::size_t>& held_out,
                        const CalibrationCheckOptions& options, const fs::path& work,
                        CalibrationCheckResult& result) {
  result.fit_frames = fit.size();
  result.held_out_frames = held_out.size();
  const fs::path log = workspace.log();
  std::vector<Camera> current = cameras;
  const double tolerances[] = {options.max_error_px,
                               std::min(options.max_error_px, 2 * options.refine_error_px),
                               std::min(options.max_error_px, options.refine_error_px)};
  for (std::size_t step = 0; step < std::size(tolerances); ++step) {
    const fs::path merged = workspace.triangulate(fit, current, tolerances[step],
                                                  fmt::format("fit{}", step));
    std::size_t points = 0;
    reprojection_errors(current, merged, &points);
    if (step == 0 && points < static_cast<std::size_t>(options.min_refine_points)) {
      result.warnings.push_back(fmt::format(
          "refinement skipped: {} points triangulated on {} frames, fewer than {} "
          "(calibration_check.min_refine_points); bundle adjustment would fit the noise of so "
          "few (more calibration_check.refine_frames may help)",
          points, fit.size(), options.min_refine_points));
      return;
    }
    const fs::path adjusted = work / fmt::format("fit{}", step) / "adjusted";
    ensure_directory(adjusted);
    run_colmap_checked(
        colmap, "bundle_adjuster",
        {"--input_path", merged.string(), "--output_path", adjusted.string(),
         "--BundleAdjustment.refine_focal_length", options.refine_focal_length ? "1" : "0",
         "--BundleAdjustment.refine_principal_point", "0",
         "--BundleAdjustment.refine_extra_params", "0", "--BundleAdjustment.refine_extrinsics",
         "1"},
        log, options.timeout_s);
    run_colmap_checked(colmap, "model_converter",
                       {"--input_path", adjusted.string(), "--output_path", adjusted.string(),
                        "--output_type", "TXT"},
                       log, options.timeout_s);
    std::vector<Camera> colmap_rig = read_colmap_model(adjusted);
    result.refined = reprojection_errors(colmap_rig, adjusted);
    result.fit_points = points;
    // Back into our world frame: the similarity that best maps the adjusted camera centres
    // onto the calibrated ones (bundle adjustment fixes the gauge on its first cameras).
    std::map<std::string, const Camera*> by_name;
    for (const Camera& c : cameras) by_name[c.name] = &c;
    std::vector<Eigen::Vector3d> from, to;
    for (const Camera& c : colmap_rig) {
      auto it = by_name.find(c.name);
      if (it == by_name.end()) continue;
      from.push_back(c.center());
      to.push_back(it->second->center());
    }
    if (from.size() < 3) {
      throw SolverError("calibration check: bundle adjustment kept fewer than 3 cameras");
    }
    colmap_rig = transform_rig(colmap_rig, fit_similarity(from, to));
    std::map<std::string, Camera> refined_by_name;
    for (const Camera& c : colmap_rig) refined_by_name[c.name] = c;
    for (Camera& c : current) {  // our order and names, COLMAP's refined values
      auto it = refined_by_name.find(c.name);
      if (it != refined_by_name.end()) c = it->second;
    }
  }
  // The frames the refinement never saw, triangulated with each calibration at the same bound.
  const double held_out_tol = tolerances[1];
  result.held_out_before =
      overall(cameras, workspace.triangulate(held_out, cameras, held_out_tol, "held_out_written"));
  result.held_out_after =
      overall(current, workspace.triangulate(held_out, current, held_out_tol, "held_out_refined"));
  std::string rejected = refinement_rejection(cameras, current, options, result.fit_points);
  if (rejected.empty() &&
      !(result.held_out_after.points > 0 &&
        result.held_out_after.mean_error_px < result.held_out_before.mean_error_px)) {
    rejected = fmt::format(
        "refinement rejected: on the {} held-out frames it does not lower the reprojection "
        "error ({:.3f} px over {} points with the written calibration, {:.3f} px over {} with "
        "the refined one): it fits the noise of the {} fitted frames",
        held_out.size(), result.held_out_before.mean_error_px, result.held_out_before.points,
        result.held_out_after.mean_error_px, result.held_out_after.points, fit.size());
  }
  if (!rejected.empty()) {
    result.warnings.push_back(rejected);
    result.refined.clear();
    return;
  }
  result.refined_calibration = current;
  write_colmap_model(work / "refined", current);
}

}  // namespace

CalibrationCheckResult check_calibration(const std::string& colmap,
                                         const std::vector<Camera>& cameras,
                                         const std::vector<CheckFrame>& checked,
                                         const std::vector<CheckFrame>& refine_frames,
                                         const CheckImageLoader& load,
                                         const CalibrationCheckOptions& options,
                                         const fs::path& out_dir) {
  if (cameras.empty()) throw InputError("calibration check: the rig has no cameras");
  if (checked.empty()) throw InputError("calibration check: no frame to check");
  // Work in a fresh hidden folder beside the output and swap it in at the end (a killed run
  // leaves it hidden; the next run starts it afresh).
  const fs::path work = out_dir.parent_path() / ("." + out_dir.filename().string() + ".tmp");
  std::error_code ec;
  fs::remove_all(work, ec);
  ensure_directory(work / "images");
  CheckWorkspace workspace(colmap, work, cameras, options);
  CalibrationCheckResult result;
  result.take = checked.front().take;
  result.frame = checked.front().frame;
  result.frames = checked.size();
  try {
    // The checked frames first; the refinement's frames follow: two fitted, one held out.
    std::vector<CheckFrame> frames = checked;
    frames.insert(frames.end(), refine_frames.begin(), refine_frames.end());
    workspace.add_frames(frames, load);

    std::vector<std::size_t> checked_indices(checked.size());
    std::iota(checked_indices.begin(), checked_indices.end(), std::size_t{0});
    const fs::path checked_model = workspace.triangulate(checked_indices, cameras,
                                                         options.max_error_px, "triangulated");
    result.cameras = reprojection_errors(cameras, checked_model, &result.points);
    for (const Camera& c : cameras) {
      const CameraReprojection& e = result.cameras[c.name];
      if (e.observations > 0 && e.observations < static_cast<std::size_t>(options.min_points)) {
        result.warnings.push_back(fmt::format(
            "camera {}: only {} triangulated point(s) in its images (median reprojection error "
            "{:.2f} px) — too few to judge its calibration (few SIFT matches between the cameras; "
            "calibration_check.check_frames adds frames)",
            c.name, e.observations, e.median_error_px));
      } else if (e.observations == 0) {
        result.warnings.push_back(fmt::format(
            "camera {}: no point triangulated in its image — it sees nothing the others see, or "
            "its calibration is far off",
            c.name));
      } else if (e.median_error_px > options.warn_error_px) {
        result.warnings.push_back(fmt::format(
            "camera {}: median reprojection error {:.2f} px over {} points exceeds {:.2f} px — "
            "its calibration is off (refine it with --refine-calibration)",
            c.name, e.median_error_px, e.observations, options.warn_error_px));
      }
    }

    if (!refine_frames.empty()) {
      std::vector<std::size_t> fit, held_out;
      for (std::size_t k = 1; k <= refine_frames.size(); ++k) {
        ((k % 3) ? fit : held_out).push_back(checked.size() - 1 + k);
      }
      if (held_out.empty()) {
        result.warnings.push_back(
            "refinement skipped: it needs at least 3 frames (two fitted, one held out)");
      } else {
        try {
          refine_calibration(colmap, workspace, cameras, fit, held_out, options, work, result);
        } catch (const SolverError& e) {
          result.warnings.push_back(fmt::format("refinement failed: {}", e.what()));
          result.refined.clear();
          result.refined_calibration.clear();
        }
      }
    }
  } catch (const Error&) {
    // Keep COLMAP's log (the error names it) and drop the scratch: images, database, models.
    for (const auto& entry : fs::directory_iterator(work, ec)) {
      if (entry.path() != workspace.log()) fs::remove_all(entry.path(), ec);
    }
    throw;
  }
  fs::remove_all(out_dir, ec);
  fs::rename(work, out_dir, ec);
  if (ec) {
    throw IoError(fmt::format("cannot move {} to {}: {}", work.string(), out_dir.string(),
                              ec.message()));
  }
  return result;
}

}  // namespace fourd::reconstruct
