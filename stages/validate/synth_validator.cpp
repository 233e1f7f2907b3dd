// Validation of the synth stage's outputs: capture/, calibration/ and ground_truth/ agree.
//
// Ground truth layout (written by synth):
//   ground_truth/template.ply                          rest-pose mesh, topology of every frame
//   ground_truth/meshes/<take>/<frame>.ply             posed mesh per frame
//   ground_truth/silhouettes/<take>/<camera>/<frame>.png   0/255
//   ground_truth/takes/<take>.json                     {"kind", "fps", "frames", "parameters", ...}
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/camera.h"
#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/mesh_io.h"
#include "stages/validate/sampling.h"
#include "stages/validate/validate.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;

struct TakeTruth {
  std::string name;
  std::string kind;
  int frames = 0;
  nlohmann::json parameters;
};

std::vector<fs::path> files_with_extension(const fs::path& dir, const std::string& ext) {
  std::vector<fs::path> files;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.is_regular_file() && entry.path().extension() == ext &&
        entry.path().filename().string().front() != '.') {
      files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

TakeTruth read_take(const fs::path& path) {
  TakeTruth take;
  take.name = path.stem().string();
  try {
    nlohmann::json j = nlohmann::json::parse(read_file(path));
    take.kind = j.value("kind", "");
    take.frames = j.at("frames").get<int>();
    take.parameters = j.value("parameters", nlohmann::json::object());
  } catch (const nlohmann::json::exception& e) {
    throw InputError(
        fmt::format("{}: not a ground-truth take description: {}", path.string(), e.what()));
  }
  if (take.frames <= 0) {
    throw InputError(
        fmt::format("{}: take '{}' has {} frames", path.string(), take.name, take.frames));
  }
  return take;
}

// synth may perturb the calibration it writes (calibration_noise) while rendering with the true
// cameras: prefer the true cameras when the ground truth keeps them.
fs::path true_calibration_dir(const Session& session) {
  fs::path truth = session.ground_truth_dir() / "calibration";
  std::error_code ec;
  return fs::exists(truth / "cameras.txt", ec) ? truth : session.calibration_dir();
}


fs::path silhouette_path(const Session& session, const std::string& take, const Camera& camera,
                         int frame) {
  return session.ground_truth_dir() / "silhouettes" / take / camera.name /
         (frame_name(frame) + ".png");
}

cv::Mat read_silhouette(const Session& session, const std::string& take, const Camera& camera,
                        int frame) {
  fs::path path = silhouette_path(session, take, camera, frame);
  cv::Mat mask = read_image(path, cv::IMREAD_GRAYSCALE);
  if (mask.cols != camera.intrinsics.width || mask.rows != camera.intrinsics.height) {
    throw InputError(fmt::format("{}: silhouette of camera {} is {}x{}, its calibration says {}x{}",
                                 path.string(), camera.name, mask.cols, mask.rows,
                                 camera.intrinsics.width, camera.intrinsics.height));
  }
  return mask;
}

struct FrameCheck {
  std::size_t seen = 0;        // vertices inside the image of at least one camera
  std::size_t consistent = 0;  // ... and inside the silhouette of every such camera
  bool same_topology = true;   // triangles equal the template's
};

// Projects every vertex of the frame's ground-truth mesh into every camera. A vertex on the
// outline may fall in a pixel whose centre the body does not cover, so the silhouette is grown
// by one pixel: the check is "within one pixel of the silhouette".
FrameCheck check_frame(const Session& session, const std::vector<Camera>& cameras,
                       const Mesh& templ, const std::string& take, int frame) {
  fs::path mesh_path = session.ground_truth_dir() / "meshes" / take / (frame_name(frame) + ".ply");
  Mesh mesh = read_ply(mesh_path);
  FrameCheck check;
  check.same_topology = mesh.triangles == templ.triangles;
  std::vector<cv::Mat> masks;
  cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, {3, 3});
  for (const auto& camera : cameras) {
    cv::Mat grown;
    cv::dilate(read_silhouette(session, take, camera, frame), grown, kernel);
    masks.push_back(std::move(grown));
  }
  for (const auto& p : mesh.positions) {
    bool seen = false, inside_all = true;
    for (std::size_t c = 0; c < cameras.size(); ++c) {
      Eigen::Vector2d px;
      if (!cameras[c].project(p.cast<double>(), &px) || !cameras[c].in_image(px)) continue;
      seen = true;
      // Pixel (col,row) spans [col,col+1) x [row,row+1) in the COLMAP convention.
      if (masks[c].at<std::uint8_t>(static_cast<int>(px.y()), static_cast<int>(px.x())) == 0) {
        inside_all = false;
      }
    }
    check.seen += seen;
    check.consistent += seen && inside_all;
  }
  return check;
}

// Rows: cameras; columns: the capture image, and the same image with the ground-truth
// silhouette outline in red.
Picture picture_take(const ValidationContext& ctx, const std::vector<Camera>& cameras,
                     const TakeTruth& take) {
  const Session& session = ctx.session;
  int frame = take.frames / 2;
  int count = std::min<int>(ctx.options.picture_cameras, static_cast<int>(cameras.size()));
  std::vector<cv::Mat> rows;
  std::vector<std::string> names;
  for (int i = 0; i < count; ++i) {
    const Camera& camera = cameras[static_cast<std::size_t>(i) * cameras.size() / count];
    names.push_back(camera.name);
    cv::Mat image = read_image(session.capture_image(take.name, camera.name, frame));
    cv::Mat mask = read_silhouette(session, take.name, camera, frame);
    if (image.size() != mask.size()) {
      throw InputError(fmt::format("{}: capture image is {}x{} but its silhouette is {}x{}",
                                   session.capture_image(take.name, camera.name, frame).string(),
                                   image.cols, image.rows, mask.cols, mask.rows));
    }
    std::string label = fmt::format("{} {} frame {}", take.name, camera.name, frame);
    int width = std::min(ctx.options.panel_width, image.cols);  // shrink large images only
    cv::Mat left = panel(image, width, cv::INTER_AREA, label);
    cv::Mat right = panel(image, width, cv::INTER_AREA, "ground-truth silhouette");
    cv::Mat small_mask;
    cv::resize(mask, small_mask, left.size(), 0, 0, cv::INTER_NEAREST);
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(small_mask > 127, contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
    cv::drawContours(right, contours, -1, {0, 0, 255}, 1, cv::LINE_8);
    cv::Mat row;
    cv::hconcat(left, right, row);
    rows.push_back(row);
  }
  cv::Mat picture;
  cv::vconcat(rows, picture);
  Picture p;
  p.file = fmt::format("synth_{}.png", take.name);
  write_image_atomic(ctx.reports_dir / p.file, picture);
  p.caption = fmt::format(
      "synth, take {} frame {}: capture of {} (left) and the ground-truth "
      "silhouette outline in red (right)",
      take.name, frame, fmt::join(names, ", "));
  return p;
}

std::string takes_table(const std::vector<TakeTruth>& takes) {
  std::string md = "| take | kind | frames | parameters |\n|---|---|---:|---|\n";
  for (const auto& t : takes) {
    std::string params;
    for (const auto& [key, value] : t.parameters.items()) {
      params += fmt::format("{}{} = {}", params.empty() ? "" : ", ", key, value.dump());
    }
    md += fmt::format("| {} | {} | {} | {} |\n", t.name, t.kind, t.frames, params);
  }
  return md;
}

}  // namespace

StageReport validate_synth(const ValidationContext& ctx) {
  const Session& session = ctx.session;
  StageReport report;
  report.stage = "synth";
  std::vector<fs::path> take_files =
      files_with_extension(session.ground_truth_dir() / "takes", ".json");
  if (take_files.empty()) {
    report.summary =
        "Skipped: no ground_truth/takes/*.json (synth has not run, or the capture is real).";
    return report;
  }
  report.present = true;

  std::vector<TakeTruth> takes;
  int total_frames = 0;
  for (const auto& f : take_files) {
    takes.push_back(read_take(f));
    total_frames += takes.back().frames;
  }
  fs::path calibration = true_calibration_dir(session);
  std::vector<Camera> cameras = read_colmap_model(calibration);
  Mesh templ = read_ply(session.ground_truth_dir() / "template.ply");

  struct Sample {
    const TakeTruth* take;
    int frame;
  };
  std::vector<Sample> samples;
  for (const auto& t : takes) {
    for (int f : sample_frames(t.frames, ctx.options.frames_per_take)) samples.push_back({&t, f});
  }
  std::vector<FrameCheck> checks(samples.size());
  tbb::parallel_for(std::size_t{0}, samples.size(), [&](std::size_t i) {
    checks[i] = check_frame(session, cameras, templ, samples[i].take->name, samples[i].frame);
  });
  std::size_t seen = 0, consistent = 0, mismatched = 0;
  for (const auto& c : checks) {
    seen += c.seen;
    consistent += c.consistent;
    mismatched += !c.same_topology;
  }

  std::uint64_t capture_bytes = 0;
  std::error_code ec;
  if (fs::is_directory(session.capture_dir(), ec)) {
    // The images and the rig files: hidden files (synth's completion record, whose times change
    // from run to run, and temp files of an interrupted run) are not the capture.
    for (const auto& e : fs::recursive_directory_iterator(session.capture_dir())) {
      if (e.is_regular_file() && e.path().filename().string().front() != '.') {
        capture_bytes += e.file_size();
      }
    }
  }

  auto add = [&](const char* name, double value, const char* meaning) {
    report.metrics.push_back({name, value, InputKind::kNone, meaning});
  };
  add("takes", static_cast<double>(takes.size()), "takes in ground_truth/takes/");
  add("frames", total_frames, "frames over all takes");
  add("cameras", static_cast<double>(cameras.size()), "cameras in the calibration");
  if (seen > 0) {
    add("silhouette_vertex_consistency", double(consistent) / double(seen),
        "fraction of ground-truth vertices (sampled frames) within one pixel of the ground-truth "
        "silhouette in every camera whose image they fall in; should be 1");
  }
  add("topology_mismatched_frames", static_cast<double>(mismatched),
      "sampled frames whose ground-truth triangles differ from template.ply; should be 0");
  add("capture_mb", capture_bytes / 1.0e6, "size of capture/ [MB = 10^6 bytes]");

  report.summary = fmt::format(
      "Checked {} take(s), {} camera(s) (from {}), {} sampled frame(s) ({} per take at most).{}",
      takes.size(), cameras.size(), fs::relative(calibration, session.root(), ec).string(),
      samples.size(), ctx.options.frames_per_take,
      seen == 0 ? " No ground-truth vertex falls in any camera's image: consistency not measured."
                : "");
  report.details = takes_table(takes);

  int pictured = std::min<int>(ctx.options.picture_takes, static_cast<int>(takes.size()));
  for (int i = 0; i < pictured; ++i)
    report.pictures.push_back(picture_take(ctx, cameras, takes[i]));
  return report;
}

}  // namespace fourd::validate
