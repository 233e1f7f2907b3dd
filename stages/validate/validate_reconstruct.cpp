// Validation of the reconstruct stage: its meshes against the ground-truth surfaces.
//
//   reconstruct/<take>/<frame>.ply               final mesh   (reconstruct_oracle/: oracle)
//   reconstruct/visual_hull/<take>/<frame>.ply   visual hull alone
//   reconstruct/<take>/<frame>.json              per-frame record: seconds per step
//   ground_truth/meshes/<take>/<frame>.ply       the true surface
//
// Both surfaces are sampled uniformly by area (a fixed number of points per mesh, fixed seed);
// accuracy = distance of reconstruction samples to the true surface, completeness = fraction of
// true-surface samples within 10 mm of the reconstruction, F-score at 5 mm from precision and
// recall at 5 mm. Distances by MeshQuery (CGAL's AABB tree). The same relative to the subject's
// height H (the vertical extent of ground_truth/template.ply, the rest pose), so subjects of
// any size compare: accuracy in % of H, completeness within 0.6 % of H (10.5 mm at 1.75 m).
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "pipeline/core/camera.h"
#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/geometry/mesh_query.h"
#include "stages/validate/sampling.h"
#include "stages/validate/validate.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;

constexpr int kSamplesPerMesh = 20000;
constexpr double kCompletenessMm = 10, kFscoreMm = 5;
constexpr double kHeatMaxMm = 20;  // colour scale of the heat-maps

// `count` points uniformly distributed over the surface by area.
std::vector<Vec3f> sample_surface(const Mesh& mesh, int count, unsigned seed) {
  std::vector<double> cumulative;
  cumulative.reserve(mesh.triangles.size());
  double total = 0;
  for (const Tri& t : mesh.triangles) {
    const Vec3f& a = mesh.positions[t[0]];
    total += 0.5 * (mesh.positions[t[1]] - a).cross(mesh.positions[t[2]] - a).norm();
    cumulative.push_back(total);
  }
  std::vector<Vec3f> out;
  if (total <= 0) return out;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  out.reserve(count);
  for (int i = 0; i < count; ++i) {
    const double r = u(rng) * total;
    std::size_t f = std::lower_bound(cumulative.begin(), cumulative.end(), r) - cumulative.begin();
    f = std::min(f, mesh.triangles.size() - 1);
    const Tri& t = mesh.triangles[f];
    double a = u(rng), b = u(rng);
    if (a + b > 1) {
      a = 1 - a;
      b = 1 - b;
    }
    const Vec3f& p0 = mesh.positions[t[0]];
    out.push_back(p0 + float(a) * (mesh.positions[t[1]] - p0) +
                  float(b) * (mesh.positions[t[2]] - p0));
  }
  return out;
}

double fraction_within(const std::vector<double>& v, double bound) {
  if (v.empty()) return 0;
  return double(std::count_if(v.begin(), v.end(), [&](double d) { return d <= bound; })) / v.size();
}

// Distances in mm of one reconstruction to the truth, both ways.
struct Distances {
  std::vector<double> accuracy;      // reconstruction samples -> truth
  std::vector<double> completeness;  // truth samples -> reconstruction
  void append(const Distances& o) {
    accuracy.insert(accuracy.end(), o.accuracy.begin(), o.accuracy.end());
    completeness.insert(completeness.end(), o.completeness.begin(), o.completeness.end());
  }
};

constexpr double kCompletenessPctHeight = 0.6;

struct Scores {
  double accuracy_median = 0, accuracy_p90 = 0, completeness = 0, fscore = 0;
  double completeness_relative = 0;  // within kCompletenessPctHeight % of the height
  // `height_mm`: the subject's height (0: unknown).
  static Scores of(const Distances& d, double height_mm) {
    Scores s;
    s.accuracy_median = percentile(d.accuracy, 0.5);
    s.accuracy_p90 = percentile(d.accuracy, 0.9);
    s.completeness = fraction_within(d.completeness, kCompletenessMm);
    s.completeness_relative =
        fraction_within(d.completeness, kCompletenessPctHeight / 100 * height_mm);
    const double precision = fraction_within(d.accuracy, kFscoreMm);
    const double recall = fraction_within(d.completeness, kFscoreMm);
    s.fscore = precision + recall > 0 ? 2 * precision * recall / (precision + recall) : 0;
    return s;
  }
};

Distances compare(const Mesh& mesh, const Mesh& truth, const MeshQuery& to_truth,
                  unsigned seed) {
  Distances d;
  const MeshQuery to_mesh(mesh);
  const std::vector<Vec3f> a = sample_surface(mesh, kSamplesPerMesh, seed);
  const std::vector<Vec3f> b = sample_surface(truth, kSamplesPerMesh, seed + 1);
  d.accuracy.resize(a.size());
  d.completeness.resize(b.size());
  for (std::size_t i = 0; i < a.size(); ++i) d.accuracy[i] = 1000 * to_truth.distance(a[i]);
  for (std::size_t i = 0; i < b.size(); ++i) d.completeness[i] = 1000 * to_mesh.distance(b[i]);
  return d;
}

// Error heat-map: the mesh seen by `camera`, each triangle coloured by the mean distance of its
// vertices to the truth (0 .. kHeatMaxMm, JET), shaded by its slant to the camera.
cv::Mat heat_map(const Camera& camera, const Mesh& mesh, const std::vector<double>& vertex_mm,
                 double scale, const std::string& label) {
  const int w = std::max(1, static_cast<int>(std::lround(camera.intrinsics.width * scale)));
  const int h = std::max(1, static_cast<int>(std::lround(camera.intrinsics.height * scale)));
  cv::Mat image(h, w, CV_8UC3, cv::Scalar(40, 40, 40));
  struct Face {
    double depth;
    std::array<cv::Point, 3> px;
    cv::Scalar colour;
  };
  std::vector<Face> faces;
  // The colour of every error level (OpenCV's jet map), looked up per face.
  static const cv::Mat jet = [] {
    cv::Mat ramp(1, 256, CV_8UC1), colours;
    for (int x = 0; x < 256; ++x) ramp.at<std::uint8_t>(0, x) = static_cast<std::uint8_t>(x);
    cv::applyColorMap(ramp, colours, cv::COLORMAP_JET);
    return colours;
  }();
  const Eigen::Vector3d eye = camera.center();
  for (const Tri& t : mesh.triangles) {
    Face f;
    bool ok = true;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = mesh.positions[t[k]].cast<double>();
      Eigen::Vector2d px;
      if (!camera.project(p, &px)) {
        ok = false;
        break;
      }
      f.px[k] = cv::Point(static_cast<int>(std::lround(px.x() * scale - 0.5)),
                          static_cast<int>(std::lround(px.y() * scale - 0.5)));
      c += p / 3;
    }
    if (!ok) continue;
    const Eigen::Vector3d a = mesh.positions[t[0]].cast<double>();
    Eigen::Vector3d n = (mesh.positions[t[1]].cast<double>() - a)
                            .cross(mesh.positions[t[2]].cast<double>() - a);
    const Eigen::Vector3d view = (eye - c).normalized();
    if (!(n.norm() > 0) || n.dot(view) <= 0) continue;  // back face
    const double shade = 0.35 + 0.65 * n.normalized().dot(view);
    const double err = (vertex_mm[t[0]] + vertex_mm[t[1]] + vertex_mm[t[2]]) / 3;
    const cv::Vec3b v = jet.at<cv::Vec3b>(
        0, cv::saturate_cast<std::uint8_t>(std::clamp(255 * err / kHeatMaxMm, 0.0, 255.0)));
    f.colour = cv::Scalar(v[0] * shade, v[1] * shade, v[2] * shade);
    f.depth = (c - eye).norm();
    faces.push_back(f);
  }
  std::sort(faces.begin(), faces.end(), [](const Face& a, const Face& b) { return a.depth > b.depth; });
  for (const Face& f : faces) cv::fillConvexPoly(image, f.px.data(), 3, f.colour, cv::LINE_8);
  const double font = std::max(0.35, 0.45 * w / 480.0);
  const cv::Point at{6, static_cast<int>(6 + 22 * font)};
  cv::putText(image, label, at, cv::FONT_HERSHEY_SIMPLEX, font, {0, 0, 0}, 3, cv::LINE_AA);
  cv::putText(image, label, at, cv::FONT_HERSHEY_SIMPLEX, font, {255, 255, 255}, 1, cv::LINE_AA);
  return image;
}

// Colour bar 0 .. kHeatMaxMm under the pictures.
cv::Mat colour_bar(int width) {
  cv::Mat ramp(1, width, CV_8UC1);
  for (int x = 0; x < width; ++x) ramp.at<std::uint8_t>(0, x) = static_cast<std::uint8_t>(255 * x / std::max(1, width - 1));
  cv::Mat bar;
  cv::applyColorMap(ramp, bar, cv::COLORMAP_JET);
  cv::resize(bar, bar, {width, 14}, 0, 0, cv::INTER_NEAREST);
  cv::Mat out(34, width, CV_8UC3, cv::Scalar(255, 255, 255));
  bar.copyTo(out(cv::Rect(0, 0, width, 14)));
  cv::putText(out, "0 mm", {4, 30}, cv::FONT_HERSHEY_SIMPLEX, 0.4, {0, 0, 0}, 1, cv::LINE_AA);
  const std::string hi = fmt::format(">= {:.0f} mm", kHeatMaxMm);
  cv::putText(out, hi, {width - 8 * static_cast<int>(hi.size()) - 4, 30}, cv::FONT_HERSHEY_SIMPLEX,
              0.4, {0, 0, 0}, 1, cv::LINE_AA);
  return out;
}

struct FrameJob {
  std::string take;
  int frame = 0;
  bool has_mesh = false, has_hull = false;
  Distances mesh, hull;
};

struct Variant {
  std::string dir;  // "reconstruct" or "reconstruct_oracle"
  InputKind input;
};

// The subject's height [mm]: the vertical extent of the true rest pose; 0 without one.
double truth_height_mm(const Session& session) {
  std::error_code ec;
  const fs::path templ = session.ground_truth_dir() / "template.ply";
  if (!fs::is_regular_file(templ, ec)) return 0;
  const Mesh mesh = read_ply(templ);
  Vec3f lo, hi;
  bounding_box(mesh, &lo, &hi);
  return mesh.positions.empty() ? 0.0 : 1000.0 * (hi.z() - lo.z());
}

// The sampled frames' meshes and hulls compared, pooled overall and per take.
struct Pooled {
  Distances all_mesh, all_hull;
  std::map<std::string, Distances> take_mesh, take_hull;
  int missing = 0, compared = 0;
};

// What validating reconstruct shares across its output folders.
struct Inputs {
  fs::path truth_dir;
  std::vector<std::string> takes;
  std::vector<Camera> cameras;
  double height_mm = 0;
};

// The checks of one output folder (reconstruct/ or reconstruct_oracle/): its metrics, tables
// and pictures added to the report.
class VariantCheck {
 public:
  VariantCheck(const ValidationContext& ctx, const Inputs& in, const Variant& variant,
               StageReport& report, std::string& details)
      : ctx_(ctx),
        in_(in),
        variant_(variant),
        out_dir_(ctx.session.root() / variant.dir),
        report_(report),
        details_(details) {}

  // Every step; returns the folder's line of the summary.
  std::string run();

 private:
  void add(const std::string& name, double value, const std::string& meaning) {
    report_.metrics.push_back({name, value, variant_.input, meaning});
  }
  void compare_frames();
  Pooled pool() const;
  Scores add_scores(const std::string& prefix, const Distances& d, const std::string& what);
  void add_take_table(const Pooled& pooled);
  int add_times();
  void add_run_record();
  void add_heat_maps();
  cv::Mat heat_map_picture(const std::string& take, const FrameJob& job) const;

  const ValidationContext& ctx_;
  const Inputs& in_;
  const Variant& variant_;
  const fs::path out_dir_;
  StageReport& report_;
  std::string& details_;
  std::vector<FrameJob> jobs_;
};

std::string VariantCheck::run() {
  compare_frames();
  const Pooled pooled = pool();
  if (pooled.compared > 0) add_scores("", pooled.all_mesh, "the final mesh");
  if (!pooled.all_hull.accuracy.empty()) add_scores("visual_hull.", pooled.all_hull, "the visual hull");
  add("frames_compared", pooled.compared, "sampled frames with a reconstructed mesh");
  add("frames_missing", pooled.missing,
      "sampled ground-truth frames without a reconstructed mesh (skipped or not run)");
  add_take_table(pooled);
  const int skipped = add_times();
  add_run_record();
  add("frames_skipped", skipped, "frames the stage reported as not reconstructable");
  const std::string summary = fmt::format("{}: {} sampled frame(s) compared, {} missing",
                                          variant_.dir, pooled.compared, pooled.missing);
  if (variant_.input == InputKind::kPipeline && !in_.cameras.empty()) add_heat_maps();
  return summary;
}

// The sampled frames of every take, their final mesh and hull compared with the truth.
void VariantCheck::compare_frames() {
  for (const std::string& take : in_.takes) {
    for (int f : sample_frames(frame_count(in_.truth_dir / take, ".ply"), ctx_.options.frames_per_take)) {
      FrameJob job;
      job.take = take;
      job.frame = f;
      jobs_.push_back(std::move(job));
    }
  }
  tbb::parallel_for(std::size_t{0}, jobs_.size(), [&](std::size_t i) {
    FrameJob& job = jobs_[i];
    const std::string file = frame_name(job.frame) + ".ply";
    const fs::path mesh_path = out_dir_ / job.take / file;
    const fs::path hull_path = out_dir_ / "visual_hull" / job.take / file;
    job.has_mesh = fs::exists(mesh_path);
    job.has_hull = fs::exists(hull_path);
    if (!job.has_mesh && !job.has_hull) return;
    const Mesh truth = read_ply(in_.truth_dir / job.take / file);
    const MeshQuery to_truth(truth);
    const unsigned seed = static_cast<unsigned>(1000 * i + 17);
    if (job.has_mesh) job.mesh = compare(read_ply(mesh_path), truth, to_truth, seed);
    if (job.has_hull) job.hull = compare(read_ply(hull_path), truth, to_truth, seed);
  });
}

// Pool the samples: overall and per take, for the final mesh and the hull.
Pooled VariantCheck::pool() const {
  Pooled p;
  for (const FrameJob& job : jobs_) {
    if (!job.has_mesh) ++p.missing;
    if (job.has_mesh) {
      ++p.compared;
      p.all_mesh.append(job.mesh);
      p.take_mesh[job.take].append(job.mesh);
    }
    if (job.has_hull) {
      p.all_hull.append(job.hull);
      p.take_hull[job.take].append(job.hull);
    }
  }
  return p;
}

// The scores of `d` as metrics named `prefix`...; returns them.
Scores VariantCheck::add_scores(const std::string& prefix, const Distances& d,
                                const std::string& what) {
  const Scores s = Scores::of(d, in_.height_mm);
  add(prefix + "accuracy_median_mm", s.accuracy_median,
      "median distance of " + what + " surface samples to the true surface [mm]");
  add(prefix + "accuracy_p90_mm", s.accuracy_p90, "90th percentile of that distance [mm]");
  add(prefix + "completeness_10mm", s.completeness,
      "fraction of true-surface samples within 10 mm of " + what);
  add(prefix + "fscore_5mm", s.fscore, "F-score of precision and recall at 5 mm (" + what + ")");
  if (in_.height_mm > 0) {
    add(prefix + "accuracy_median_pct_height", 100 * s.accuracy_median / in_.height_mm,
        "median distance of " + what + " surface samples to the true surface [% of the "
        "subject's height]");
    add(prefix + "accuracy_p90_pct_height", 100 * s.accuracy_p90 / in_.height_mm,
        "90th percentile of that distance [% of the subject's height]");
    add(prefix + "completeness_0p6pct_height", s.completeness_relative,
        "fraction of true-surface samples within 0.6 % of the subject's height of " + what);
  }
  return s;
}

// Per take: the scores as metrics and a table of final mesh / visual hull.
void VariantCheck::add_take_table(const Pooled& pooled) {
  std::string table = fmt::format(
      "{} ({}): per take, final mesh / visual hull\n\n| take | frames | accuracy median mm | "
      "accuracy p90 mm | completeness 10 mm | F-score 5 mm |\n|---|---:|---:|---:|---:|---:|\n",
      variant_.dir, variant_.input == InputKind::kOracle ? "oracle" : "pipeline");
  for (const std::string& take : in_.takes) {
    if (!pooled.take_mesh.count(take)) continue;
    const Scores m = add_scores(take + ".", pooled.take_mesh.at(take), "the final mesh");
    Scores h;
    if (pooled.take_hull.count(take)) {
      h = add_scores("visual_hull." + take + ".", pooled.take_hull.at(take), "the visual hull");
    }
    int frames = 0;
    for (const FrameJob& j : jobs_) frames += j.take == take && j.has_mesh;
    table += fmt::format("| {} | {} | {:.2f} / {:.2f} | {:.2f} / {:.2f} | {:.3f} / {:.3f} | {:.3f} / {:.3f} |\n",
                         take, frames, m.accuracy_median, h.accuracy_median, m.accuracy_p90,
                         h.accuracy_p90, m.completeness, h.completeness, m.fscore, h.fscore);
  }
  details_ += table + "\n";
}

// Time: every per-frame record of the stage (not only the sampled frames). Returns the frames
// the records say were skipped.
int VariantCheck::add_times() {
  std::error_code ec;
  double seconds = 0;
  int timed = 0, skipped = 0;
  std::map<std::string, double> steps;
  for (const std::string& take : subfolders(out_dir_)) {
    if (!fs::is_directory(out_dir_ / take, ec)) continue;
    for (const auto& e : fs::directory_iterator(out_dir_ / take)) {
      if (e.path().extension() != ".json") continue;
      nlohmann::json j;
      try {
        j = nlohmann::json::parse(read_file(e.path()));
      } catch (const std::exception&) {
        continue;
      }
      if (!j.is_object() || !j.contains("seconds_total")) continue;
      if (!j.value("reconstructed", false)) {
        ++skipped;
        continue;
      }
      seconds += j["seconds_total"].get<double>();
      ++timed;
      for (const auto& [step, s] : j["seconds"].items()) steps[step] += s.get<double>();
    }
  }
  if (timed > 0) {
    add("seconds_per_frame", seconds / timed,
        "mean time to reconstruct one frame (sum of its steps, from the per-frame records) [s]");
    std::string st = "| step | mean seconds per frame |\n|---|---:|\n";
    for (const auto& [step, s] : steps) st += fmt::format("| {} | {:.3f} |\n", step, s / timed);
    details_ += fmt::format("{}: time per step over {} frame(s)\n\n{}\n", variant_.dir, timed, st);
  }
  return skipped;
}

// What the stage's report.json says of its last run.
void VariantCheck::add_run_record() {
  try {
    const nlohmann::json run = nlohmann::json::parse(read_file(out_dir_ / "report.json")).at("run");
    add("wall_seconds_per_frame", run.at("seconds_per_frame").get<double>(),
        "wall-clock time of the last run divided by its frames (frames run in parallel) [s]");
  } catch (const std::exception&) {
  }
  try {
    const nlohmann::json summary =
        nlohmann::json::parse(read_file(out_dir_ / "report.json")).at("summary");
    add("frames_flagged", summary.at("frames_flagged").get<double>(),
        "frames whose result the stage flagged as disagreeing with their silhouettes");
    add("scale_factor", summary.at("scale_factor").get<double>(),
        "the factor the stage scaled its unset lengths by (subject size / 1.75 m)");
  } catch (const std::exception&) {
  }
}

// Heat-maps: one frame per take (the middle sampled one), final mesh and hull side by side.
void VariantCheck::add_heat_maps() {
  const int pictured = std::min<int>(ctx_.options.picture_takes, static_cast<int>(in_.takes.size()));
  for (int t = 0; t < pictured; ++t) {
    const std::string& take = in_.takes[t];
    std::vector<const FrameJob*> frames;
    for (const FrameJob& j : jobs_) {
      if (j.take == take && j.has_mesh) frames.push_back(&j);
    }
    if (frames.empty()) continue;
    const FrameJob& job = *frames[frames.size() / 2];
    const cv::Mat picture = heat_map_picture(take, job);
    Picture p;
    p.file = fmt::format("reconstruct_error_{}.png", take);
    write_image_atomic(ctx_.reports_dir / p.file, picture);
    p.caption = fmt::format(
        "reconstruct, take {} frame {}: distance to the true surface (blue 0, red >= {:.0f} mm) "
        "of the final mesh (left) and of the visual hull (right)",
        take, job.frame, kHeatMaxMm);
    report_.pictures.push_back(p);
  }
}

// The frame's final mesh and hull coloured by their distance to the truth, seen by a few
// cameras, over the colour bar.
cv::Mat VariantCheck::heat_map_picture(const std::string& take, const FrameJob& job) const {
  const std::vector<Camera>& cameras = in_.cameras;
  const std::string file = frame_name(job.frame) + ".ply";
  const Mesh truth = read_ply(in_.truth_dir / take / file);
  const MeshQuery to_truth(truth);
  std::vector<std::pair<std::string, Mesh>> meshes = {{"final mesh", read_ply(out_dir_ / take / file)}};
  if (job.has_hull) meshes.push_back({"visual hull", read_ply(out_dir_ / "visual_hull" / take / file)});
  const int count = std::min<int>(ctx_.options.picture_cameras, static_cast<int>(cameras.size()));
  const double scale =
      std::min(1.0, double(ctx_.options.panel_width) / cameras[0].intrinsics.width) *
      (cameras[0].intrinsics.width < 400 ? 1.5 : 1.0);
  std::vector<cv::Mat> rows;
  for (int i = 0; i < count; ++i) {
    const Camera& camera = cameras[static_cast<std::size_t>(i) * cameras.size() / count];
    std::vector<cv::Mat> panels;
    for (const auto& [name, surface] : meshes) {
      const Mesh& mesh = surface;  // a lambda cannot capture a structured binding (C++17)
      std::vector<double> mm(mesh.positions.size());
      tbb::parallel_for(std::size_t{0}, mm.size(),
                        [&](std::size_t v) { mm[v] = 1000 * to_truth.distance(mesh.positions[v]); });
      panels.push_back(heat_map(camera, mesh, mm, scale,
                                fmt::format("{} {} frame {}: {}", take, camera.name, job.frame, name)));
    }
    cv::Mat row;
    cv::hconcat(panels, row);
    rows.push_back(row);
  }
  rows.push_back(colour_bar(rows[0].cols));
  cv::Mat picture;
  cv::vconcat(rows, picture);
  return picture;
}

}  // namespace

StageReport validate_reconstruct(const ValidationContext& ctx) {
  const Session& session = ctx.session;
  StageReport report;
  report.stage = "reconstruct";
  Inputs in;
  in.truth_dir = session.ground_truth_dir() / "meshes";
  std::vector<Variant> variants;
  std::error_code ec;
  for (const Variant& v : {Variant{"reconstruct", InputKind::kPipeline},
                           Variant{"reconstruct_oracle", InputKind::kOracle}}) {
    if (!subfolders(session.root() / v.dir).empty()) variants.push_back(v);
  }
  if (variants.empty()) {
    report.summary = "Skipped: no reconstruct/ output.";
    return report;
  }
  in.takes = subfolders(in.truth_dir);
  if (in.takes.empty()) {
    report.summary = "Skipped: no ground_truth/meshes/ (not a synthetic session).";
    return report;
  }
  report.present = true;
  const fs::path calibration = fs::exists(session.ground_truth_dir() / "calibration" / "cameras.txt", ec)
                                   ? session.ground_truth_dir() / "calibration"
                                   : session.calibration_dir();
  in.cameras = read_colmap_model(calibration);
  in.height_mm = truth_height_mm(session);
  if (in.height_mm > 0) {
    report.metrics.push_back({"subject_height_mm", in.height_mm, InputKind::kPipeline,
                              "height of the true subject (its rest pose) [mm]"});
  }

  std::string details;
  std::vector<std::string> summaries;
  for (const Variant& variant : variants) {
    summaries.push_back(VariantCheck(ctx, in, variant, report, details).run());
  }
  report.summary = fmt::format(
      "Sampled {} frame(s) per take, {} surface samples per mesh; {}.", ctx.options.frames_per_take,
      kSamplesPerMesh, fmt::format("{}", fmt::join(summaries, "; ")));
  report.details = details;
  return report;
}

}  // namespace fourd::validate
