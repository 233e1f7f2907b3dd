#include "stages/reconstruct/reconstruct.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <fmt/ranges.h>

#include <algorithm>
#include <atomic>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <regex>
#include <set>

#include "pipeline/core/capture.h"
#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/isosurface.h"
#include "pipeline/core/log.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/geometry/components.h"
#include "pipeline/geometry/measures.h"
#include "pipeline/geometry/repair.h"
#include "stages/reconstruct/colmap_tool.h"
#include "stages/reconstruct/raycast.h"

namespace fourd::reconstruct {

namespace fs = std::filesystem;

void ReconstructOptions::check() const {
  method_of(method);
  if (remesh.mode != "relax" && remesh.mode != "isotropic") {
    throw ConfigError(fmt::format("remesh.mode '{}': expected relax or isotropic", remesh.mode));
  }
  if (guided.passes > 0 && depth.step >= guided.search_depth) {
    throw ConfigError("depth.step must be smaller than guided.search_depth");
  }
  if (fusion.band < depth.search_depth) {
    throw ConfigError("fusion.band must be at least depth.search_depth: the fused band must "
                      "cover the searched depths");
  }
}

Rig Rig::from(std::vector<Camera> calibration) {
  Rig rig;
  rig.cameras = std::move(calibration);
  for (const Camera& c : rig.cameras) {
    rig.pinholes.push_back(PinholeCamera::from(c));
    rig.undistorters.emplace_back(c);
  }
  return rig;
}

namespace {

class StepTimer {
 public:
  explicit StepTimer(FrameResult& result) : result_(result) {}
  void done(const char* step) {
    result_.seconds.emplace_back(step, timer_.seconds());
    timer_ = log::Timer();
  }

 private:
  FrameResult& result_;
  log::Timer timer_;
};

// Grey levels as float, resampled to the pinhole camera.
cv::Mat undistorted_gray(const cv::Mat& bgr, const Undistorter& undistorter) {
  cv::Mat gray, f;
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  gray.convertTo(f, CV_32F);
  return undistorter.apply(f, cv::INTER_LINEAR);
}

// Drops faces with a vertex more than `tolerance` outside the hull.
Mesh trim_to_hull(const Mesh& mesh, const VisualHull& hull, double tolerance) {
  std::vector<char> outside(mesh.positions.size());
  tbb::parallel_for(std::size_t{0}, mesh.positions.size(), [&](std::size_t i) {
    outside[i] = hull.value(mesh.positions[i].cast<double>()) > tolerance;
  });
  Mesh out;
  out.positions = mesh.positions;
  for (const Tri& t : mesh.triangles) {
    if (!outside[t[0]] && !outside[t[1]] && !outside[t[2]]) out.triangles.push_back(t);
  }
  return largest_component(out);
}

// The largest component of the field's zero level, from every `step`-th sample.
Mesh field_surface(const ScalarGrid& field, int step) {
  return largest_component(extract_isosurface(subsample(field, step), 0.0f));
}

// Step 2's state: every camera's view (undistorted grey levels, the hull's first hit per pixel)
// and depth map.
struct DepthMaps {
  std::vector<StereoView> views;
  std::vector<PinholeCamera> pinholes;
  std::vector<DepthMap> maps;
  int size() const { return static_cast<int>(views.size()); }
};

// The frame's views, undistorted, with the hull's first hit per pixel.
DepthMaps hull_views(const Rig& rig, const FrameInput& input, const Mesh& hull_mesh) {
  MeshRaycaster raycaster(hull_mesh);
  const int n = static_cast<int>(input.cameras.size());
  DepthMaps d;
  d.views.resize(n);
  d.pinholes.resize(n);
  d.maps.resize(n);
  tbb::parallel_for(0, n, [&](int i) {
    const int c = input.cameras[i];
    d.views[i].camera = d.pinholes[i] = rig.pinholes[c];
    d.views[i].gray = undistorted_gray(input.images[i], rig.undistorters[c]);
    SurfaceRender render = raycaster.render(rig.pinholes[c]);
    d.views[i].hull_depth = render.depth;
    d.views[i].roi = render.roi;
  });
  return d;
}

// The views with `guide`'s first hit per pixel in place of the hull's.
std::vector<StereoView> guided_views(const DepthMaps& d, const Mesh& guide) {
  MeshRaycaster guide_caster(guide);
  std::vector<StereoView> guided = d.views;
  tbb::parallel_for(0, d.size(), [&](int i) {
    SurfaceRender render = guide_caster.render(d.pinholes[i]);
    guided[i].hull_depth = render.depth;
    guided[i].roi = render.roi;
  });
  return guided;
}

// Depth maps of every camera against `guides` (the hull's or the guide surface's first hit
// per pixel), checked against each other.
void match_depths(DepthMaps& d, const std::vector<StereoView>& guides,
                  const DepthMapOptions& depth) {
  tbb::parallel_for(0, d.size(), [&](int i) {
    std::vector<int> neighbours =
        select_neighbours(d.pinholes, i, depth.neighbours, depth.max_angle_deg);
    d.maps[i] = estimate_depth_map(guides, i, neighbours, depth);
  });
  keep_consistent_depths(d.pinholes, d.maps, depth.consistent_views, depth.consistency_tolerance);
}

// The depth maps' holes inside `guides` filled from the depths around them.
void fill_depths(DepthMaps& d, const std::vector<StereoView>& guides,
                 const DepthMapOptions& depth, const DepthFillOptions& fill) {
  tbb::parallel_for(0, d.size(), [&](int i) {
    fill_depth_holes(guides[i].hull_depth, d.maps[i], depth.front_margin, depth.search_depth,
                     fill);
  });
}

// Fraction of the hull's pixels whose depth was matched (not filled in).
double matched_fraction(const DepthMaps& d) {
  std::size_t hull_pixels = 0, matched = 0;
  for (int i = 0; i < d.size(); ++i) {
    hull_pixels += cv::countNonZero(d.views[i].hull_depth > 0);
    cv::Mat measured = d.maps[i].depth > 0;
    if (!d.maps[i].filled.empty()) measured &= d.maps[i].filled == 0;
    matched += cv::countNonZero(measured);
  }
  return hull_pixels ? double(matched) / hull_pixels : 0.0;
}

// One frame's steps and the state they share: the visual hull, its field, the result.
class FrameSteps {
 public:
  FrameSteps(const Rig& rig, const FrameInput& input, const ReconstructOptions& options,
             FrameResult& result)
      : rig_(rig),
        input_(input),
        options_(options),
        method_(method_of(options.method)),
        result_(result),
        timer_(result),
        cameras_(frame_cameras(rig, input)),
        hull_(cameras_, input.silhouettes, options.visual_hull),  // 1. Visual hull.
        field_(hull_.grid()) {}

  // 1. The hull's surface (and the one written for validation); false: the frame failed.
  bool hull_surface(bool want_visual_hull);
  // 2. and 3. The fused surface of the method; nullopt: the frame failed.
  std::optional<Mesh> fused_surface(const fs::path& work_dir);
  // 4. One closed, remeshed surface, checked.
  void finish(Mesh surface);
  // The result against what the silhouettes imply (warnings only, also for a failed frame).
  void check(const Mesh& mesh);

 private:
  static std::vector<Camera> frame_cameras(const Rig& rig, const FrameInput& input) {
    std::vector<Camera> cameras;
    for (int c : input.cameras) cameras.push_back(rig.cameras[c]);
    return cameras;
  }
  DepthMaps depth_maps();
  Mesh fuse_stereo(DepthMaps& d);
  bool guided_pass(DepthMaps& d);
  std::optional<Mesh> fuse_colmap(const DepthMaps& d, const fs::path& work_dir);

  const Rig& rig_;
  const FrameInput& input_;
  const ReconstructOptions& options_;
  const Method method_;
  FrameResult& result_;
  StepTimer timer_;
  const std::vector<Camera> cameras_;
  VisualHull hull_;
  ScalarGrid field_;
  ScalarGrid depth_weight_;  // the fusion's depth votes per sample (method stereo)
  Mesh hull_mesh_;
};

bool FrameSteps::hull_surface(bool want_visual_hull) {
  if (field_.nx == 0) {
    result_.failure = "the visual hull is empty: no point of the capture volume is inside every "
                      "silhouette (check the silhouettes and the calibration)";
    return false;
  }
  hull_mesh_ = field_surface(field_, options_.isosurface_step);
  if (hull_mesh_.triangles.empty()) {
    result_.failure = "the visual hull has no surface";
    return false;
  }
  timer_.done("visual_hull");
  if (want_visual_hull) {
    // Only for validation and comparison: written as extracted, from a coarser sampling
    // (decimating or remeshing it would cost as much as the final mesh's remeshing).
    result_.visual_hull = options_.visual_hull_step == options_.isosurface_step
                              ? hull_mesh_
                              : field_surface(field_, options_.visual_hull_step);
    timer_.done("visual_hull_remesh");
  }
  return true;
}

void FrameSteps::check(const Mesh& mesh) {
  result_.plausibility = check_plausibility(cameras_, input_.silhouettes, hull_mesh_, mesh,
                                            options_.visual_hull.voxel_size, options_.checks);
  result_.warnings.insert(result_.warnings.end(), result_.plausibility.warnings.begin(),
                          result_.plausibility.warnings.end());
}

std::optional<Mesh> FrameSteps::fused_surface(const fs::path& work_dir) {
  switch (method_) {
    case Method::kVisualHull:
      return hull_mesh_;
    case Method::kStereo: {
      DepthMaps d = depth_maps();
      return fuse_stereo(d);
    }
    case Method::kColmap:
      return fuse_colmap(depth_maps(), work_dir);
  }
  return std::nullopt;
}

// 2. Depth maps, matched on undistorted images, searched behind the hull's first hit.
DepthMaps FrameSteps::depth_maps() {
  DepthMaps d = hull_views(rig_, input_, hull_mesh_);
  timer_.done("hull_depth");
  match_depths(d, d.views, options_.depth);
  result_.depth_coverage = matched_fraction(d);
  timer_.done("depth_maps");
  return d;
}

// 3. Fusion (method stereo): the filled depth maps, after the guided passes, as a TSDF.
Mesh FrameSteps::fuse_stereo(DepthMaps& d) {
  fill_depths(d, d.views, options_.depth, options_.depth_fill);
  timer_.done("depth_fill");
  for (int pass = 0; pass < options_.guided.passes; ++pass) {
    if (!guided_pass(d)) break;
  }
  fuse_depth_maps(field_, d.pinholes, d.maps, options_.depth.min_ncc, options_.fusion,
                  &depth_weight_);
  timer_.done("fusion");
  Mesh surface = field_surface(field_, options_.isosurface_step);
  timer_.done("isosurface");
  return surface;
}

// The previous pass's surface, its filled depths at full weight, guides a sweep over a
// narrower range: the matching windows follow that surface's slant rather than the hull's,
// and a neighbour's view of a point is tested against it. False: that surface is empty.
bool FrameSteps::guided_pass(DepthMaps& d) {
  ScalarGrid guide_field = field_;
  FusionOptions guide_fusion = options_.fusion;
  guide_fusion.filled_weight = options_.guided.filled_weight;
  fuse_depth_maps(guide_field, d.pinholes, d.maps, options_.depth.min_ncc, guide_fusion);
  const Mesh guide = field_surface(guide_field, options_.isosurface_step);
  if (guide.triangles.empty()) return false;
  std::vector<StereoView> guided = guided_views(d, guide);
  DepthMapOptions depth = options_.depth;
  depth.front_margin = options_.guided.front_margin;
  depth.search_depth = options_.guided.search_depth;
  depth.occlusion_margin = options_.guided.occlusion_margin;
  match_depths(d, guided, depth);
  result_.depth_coverage = matched_fraction(d);
  fill_depths(d, guided, depth, options_.depth_fill);
  timer_.done("guided_pass");
  return true;
}

// 3. Fusion (method colmap): the depth maps fused by COLMAP, meshed, trimmed to the hull.
std::optional<Mesh> FrameSteps::fuse_colmap(const DepthMaps& d, const fs::path& work_dir) {
  const std::string colmap = find_colmap(options_.colmap.executable);
  if (colmap.empty()) {
    result_.failure = fmt::format("method colmap: the COLMAP executable '{}' was not found",
                                  options_.colmap.executable);
    return std::nullopt;
  }
  std::vector<MvsView> mvs(d.size());
  tbb::parallel_for(0, d.size(), [&](int i) {
    const int c = input_.cameras[i];
    mvs[i].camera = d.pinholes[i];
    mvs[i].image = rig_.undistorters[c].apply(input_.images[i], cv::INTER_LINEAR);
    mvs[i].depth = d.maps[i].depth;
    mvs[i].normal =
        depth_map_normals(d.pinholes[i], d.maps[i].depth, options_.colmap.normal_max_jump);
  });
  Mesh surface;
  try {
    write_colmap_workspace(work_dir, mvs, options_.colmap.tie_tolerance);
    const std::size_t points = colmap_stereo_fusion(colmap, work_dir, options_.colmap);
    timer_.done("colmap_stereo_fusion");
    if (points == 0) throw SolverError("COLMAP stereo_fusion fused no point");
    surface = colmap_poisson_mesh(colmap, work_dir, options_.colmap);
    timer_.done("colmap_poisson_mesher");
  } catch (const Error& e) {
    result_.failure = e.what();
    check({});
    return std::nullopt;
  }
  if (!options_.colmap.keep_workspace) {
    std::error_code ec;
    fs::remove_all(work_dir, ec);
  }
  surface = trim_to_hull(surface, hull_, options_.colmap.hull_trim);
  timer_.done("trim");
  return surface;
}

void FrameSteps::finish(Mesh surface) {
  if (count_boundary_edges(surface) > 0) {
    int holes = fill_holes(surface);
    if (holes > 0) result_.warnings.push_back(fmt::format("filled {} hole(s)", holes));
    timer_.done("fill_holes");
  }
  result_.mesh = remesh(surface, options_.remesh);
  timer_.done("remesh");
  if (options_.project_to_field && method_ != Method::kColmap && options_.isosurface_step > 1) {
    project_to_isosurface(result_.mesh, field_, 0.0f, options_.isosurface_step * field_.voxel);
    timer_.done("project_to_field");
  }
  if (!depth_weight_.values.empty()) {
    result_.mesh.confidence = surface_confidence(result_.mesh, depth_weight_, options_.fusion);
    const auto low = std::count_if(result_.mesh.confidence.begin(),
                                   result_.mesh.confidence.end(), [](float c) { return c < 0.5f; });
    result_.low_confidence_fraction =
        result_.mesh.confidence.empty() ? 0.0 : double(low) / result_.mesh.confidence.size();
  }
  check(result_.mesh);
  timer_.done("checks");
  result_.reconstructed = true;
}

}  // namespace

Method method_of(const std::string& name) {
  if (name == "stereo") return Method::kStereo;
  if (name == "colmap") return Method::kColmap;
  if (name == "visual_hull") return Method::kVisualHull;
  throw ConfigError(fmt::format("method '{}': expected stereo, colmap or visual_hull", name));
}

FrameResult reconstruct_frame(const Rig& rig, const FrameInput& input,
                              const ReconstructOptions& options, bool want_visual_hull,
                              const fs::path& work_dir) {
  FrameResult result;
  FrameSteps steps(rig, input, options, result);
  if (!steps.hull_surface(want_visual_hull)) return result;
  std::optional<Mesh> surface = steps.fused_surface(work_dir);
  if (!surface) return result;
  if (surface->triangles.empty()) {
    result.failure = "the fused surface is empty";
    steps.check({});
    return result;
  }
  steps.finish(std::move(*surface));
  return result;
}

namespace {

struct TakeFrames {
  std::string name;
  int frames = 0;  // 0 .. frames-1 exist for at least one camera
};

// Takes and frame counts from capture/<take>/<camera>/<frame>.png. Unlike scan_capture this
// tolerates a camera missing some frames: that camera is left out of those frames (with a
// warning) instead of failing the whole session.
std::vector<TakeFrames> list_takes(const Session& session, const std::vector<Camera>& cameras) {
  static const std::regex frame_file(R"((\d{6})\.(png|jpg))");
  std::vector<TakeFrames> takes;
  std::error_code ec;
  if (!fs::is_directory(session.capture_dir(), ec)) {
    throw InputError(fmt::format("{}: no capture folder", session.capture_dir().string()));
  }
  for (const auto& entry : fs::directory_iterator(session.capture_dir())) {
    if (!entry.is_directory() || entry.path().filename().string().front() == '.') continue;
    TakeFrames take{entry.path().filename().string(), 0};
    for (const Camera& c : cameras) {
      fs::path dir = entry.path() / c.name;
      if (!fs::is_directory(dir, ec)) continue;
      for (const auto& f : fs::directory_iterator(dir)) {
        std::smatch m;
        std::string name = f.path().filename().string();
        if (std::regex_match(name, m, frame_file)) take.frames = std::max(take.frames, std::stoi(m[1]) + 1);
      }
    }
    if (take.frames > 0) takes.push_back(take);
  }
  std::sort(takes.begin(), takes.end(), [](auto& a, auto& b) { return a.name < b.name; });
  return takes;
}

// How much of the capture volume a camera sees: the fraction of a lattice of points in the
// volume that project into its image.
double volume_coverage(const Camera& camera, const VisualHullOptions& hull) {
  constexpr int kSteps = 9;
  int seen = 0, total = 0;
  for (int i = 0; i < kSteps; ++i)
    for (int j = 0; j < kSteps; ++j)
      for (int k = 0; k < kSteps; ++k) {
        Eigen::Vector3d p;
        const int idx[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
          p[a] = hull.volume_min[a] + (hull.volume_max[a] - hull.volume_min[a]) * idx[a] / (kSteps - 1);
        }
        Eigen::Vector2d px;
        seen += camera.project(p, &px) && camera.in_image(px);
        ++total;
      }
  return double(seen) / total;
}

struct Item {
  std::size_t take;
  int frame;
};

nlohmann::json frame_record(const std::string& take, int frame, const FrameResult& r,
                            const std::vector<std::string>& warnings,
                            const std::vector<std::string>& cameras_used) {
  nlohmann::json j;
  j["take"] = take;
  j["frame"] = frame;
  j["reconstructed"] = r.reconstructed;
  if (!r.reconstructed) j["skipped_because"] = r.failure;
  j["cameras_used"] = cameras_used.size();
  j["vertices"] = r.mesh.positions.size();
  j["triangles"] = r.mesh.triangles.size();
  j["depth_coverage"] = r.depth_coverage;
  j["low_confidence_fraction"] = r.low_confidence_fraction;
  nlohmann::json seconds = nlohmann::json::object();
  double total = 0;
  for (const auto& [step, s] : r.seconds) {  // a step done more than once: its total
    seconds[step] = seconds.value(step, 0.0) + s;
    total += s;
  }
  j["seconds"] = seconds;
  j["seconds_total"] = total;
  j["warnings"] = warnings;
  // Flagged: a check of the result against the silhouettes failed (plausibility.h).
  const PlausibilityReport& p = r.plausibility;
  j["flagged"] = !p.warnings.empty();
  if (!p.hull.empty()) {
    nlohmann::json checks = nlohmann::json::object();
    for (std::size_t i = 0; i < p.hull.size() && i < cameras_used.size(); ++i) {
      nlohmann::json c = {{"hull_coverage", p.hull[i].coverage}};
      if (i < p.mesh.size()) {
        c["mesh_coverage"] = p.mesh[i].coverage;
        c["mesh_spill"] = p.mesh[i].spill;
      }
      checks[cameras_used[i]] = c;
    }
    j["silhouette_checks"] = checks;
    if (!p.mesh.empty()) {
      j["mesh_to_hull_volume"] = p.volume_ratio;
      j["mesh_to_hull_extent"] = p.extent_ratio;
    }
  }
  return j;
}

// report.json from every <take>/<frame>.json present (so farm jobs that each did a range add
// up), plus this run's timing.
void write_report(const fs::path& out_dir, const std::vector<TakeFrames>& takes,
                  const nlohmann::json& run, const SubjectScale& subject) {
  nlohmann::json report;
  report["run"] = run;
  report["subject"] = subject.to_json();
  std::size_t warnings = 0, with_warnings = 0, flagged = 0;
  nlohmann::json frames = nlohmann::json::array();
  std::map<std::string, double> step_sum;
  std::size_t done = 0, skipped = 0;
  nlohmann::json skipped_list = nlohmann::json::array();
  // Every frame's warnings, named "take/frame: ...": what `fourd status` counts.
  nlohmann::json warning_list = nlohmann::json::array();
  for (const TakeFrames& t : takes) {
    for (int f = 0; f < t.frames; ++f) {
      fs::path p = out_dir / t.name / (frame_name(f) + ".json");
      std::error_code ec;
      if (!fs::exists(p, ec)) continue;
      nlohmann::json j;
      try {
        j = nlohmann::json::parse(read_file(p));
      } catch (const std::exception&) {
        continue;  // a record being written by another job right now
      }
      const std::size_t w = j.contains("warnings") ? j["warnings"].size() : 0;
      for (std::size_t k = 0; k < w; ++k) {
        const nlohmann::json& text = j["warnings"][k];
        warning_list.push_back(fmt::format("{}/{}: {}", t.name, frame_name(f),
                                           text.is_string() ? text.get<std::string>() : text.dump()));
      }
      warnings += w;
      with_warnings += w > 0;
      flagged += j.value("flagged", false);
      if (j.value("reconstructed", false)) {
        ++done;
        for (const auto& [step, s] : j["seconds"].items()) step_sum[step] += s.get<double>();
      } else {
        ++skipped;
        skipped_list.push_back({{"take", t.name}, {"frame", f},
                                {"because", j.value("skipped_because", "")}});
      }
      frames.push_back(std::move(j));
    }
  }
  nlohmann::json steps = nlohmann::json::object();
  for (const auto& [step, s] : step_sum) steps[step] = done ? s / done : 0.0;
  report["summary"] = {{"frames_reconstructed", done},
                       {"frames_skipped", skipped},
                       {"skipped", skipped_list},
                       {"mean_seconds_per_step", steps},
                       {"warnings", warnings},
                       {"frames_with_warnings", with_warnings},
                       {"frames_flagged", flagged},
                       {"subject_height_m", subject.height},
                       {"subject_size_m", subject.size},
                       {"scale_factor", subject.factor}};
  // Known only when one run did every frame; the --finish job of a split run has no wall time
  // of its jobs (the driver's completion record has it).
  if (run.contains("seconds_per_frame")) report["summary"]["seconds_per_frame"] = run["seconds_per_frame"];
  report["warnings"] = warning_list;
  report["frames"] = frames;
  write_file_atomic(out_dir / "report.json", report.dump(1) + "\n");
}

void write_options_used(const fs::path& out_dir, const ReconstructOptions& options,
                        const SubjectScale& subject, const std::vector<std::string>& scaled) {
  YAML::Emitter used;
  used << shortest_numbers(to_yaml(options));
  const std::string how =
      subject.measured
          ? fmt::format("measured on the visual hull of {} frame(s)", subject.frames_measured)
          : "given by scale.subject_size";
  write_file_atomic(
      out_dir / "options.yaml",
      fmt::format("# subject {:.4g} m (largest extent, {}; height {:.4g} m), scale factor {:.4g} "
                  "(reference {} m): {} length(s) not set in session.yaml or a preset scaled by "
                  "it\n{}\n",
                  subject.size, how, subject.height, subject.factor, kReferenceSubjectSize,
                  scaled.size(), used.c_str()));
}

void write_subject(const fs::path& out_dir, const SubjectScale& subject) {
  write_file_atomic(out_dir / kSubjectFile, subject.to_json().dump(1) + "\n");
}

// Frames spread evenly through the session (every take's frames in order).
std::vector<Item> spread_items(const std::vector<TakeFrames>& takes, int count) {
  std::vector<Item> all;
  for (std::size_t t = 0; t < takes.size(); ++t) {
    for (int f = 0; f < takes[t].frames; ++f) all.push_back({t, f});
  }
  std::vector<Item> out;
  for (std::size_t i : spread_indices(all.size(), static_cast<std::size_t>(count))) {
    out.push_back(all[i]);
  }
  return out;
}

// The subject measured on frames spread through the session: their silhouettes, of the
// cameras that have one.
SubjectScale measure_session_subject(const Rig& rig,
                                     const std::vector<TakeFrames>& takes,
                                     const ReconstructOptions& options, const Box& shared,
                                     const fs::path& segment_dir) {
  std::vector<std::vector<Camera>> cameras;
  std::vector<std::vector<cv::Mat>> silhouettes;
  if (options.scale.subject_size <= 0) {
    for (const Item& item : spread_items(takes, options.scale.sample_frames)) {
      std::vector<Camera> cams;
      std::vector<cv::Mat> sils;
      for (const Camera& cam : rig.cameras) {
        const fs::path p =
            segment_dir / takes[item.take].name / cam.name / (frame_name(item.frame) + ".png");
        std::error_code ec;
        if (!fs::is_regular_file(p, ec)) continue;
        cv::Mat s = read_image(p, cv::IMREAD_GRAYSCALE);
        if (s.cols != cam.intrinsics.width || s.rows != cam.intrinsics.height) continue;
        cams.push_back(cam);
        sils.push_back(s);
      }
      if (static_cast<int>(cams.size()) < options.min_cameras) continue;
      cameras.push_back(std::move(cams));
      silhouettes.push_back(std::move(sils));
    }
  }
  return measure_subject(cameras, silhouettes, options.visual_hull, shared, options.scale);
}

// --finish: every selected frame has its record (written last for each frame, also for a
// frame that could not be reconstructed).
void check_frame_records(const fs::path& out_dir, const std::vector<TakeFrames>& takes,
                         const std::vector<Item>& items) {
  for (const Item& item : items) {
    const fs::path p = out_dir / takes[item.take].name / (frame_name(item.frame) + ".json");
    std::error_code ec;
    if (!fs::is_regular_file(p, ec)) {
      throw InputError(fmt::format("reconstruct --finish: {} is missing (take {} frame {}): its "
                                   "job has not run or failed",
                                   p.string(), takes[item.take].name, item.frame));
    }
  }
}

// A job's upstream output: the silhouette of every camera that recorded the frame.
void check_silhouettes(const Session& session, const Rig& rig, const std::vector<TakeFrames>& takes,
                       const std::vector<Item>& items, const fs::path& segment_dir) {
  for (const Item& item : items) {
    const std::string& take = takes[item.take].name;
    for (const Camera& cam : rig.cameras) {
      std::error_code ec;
      const fs::path sil = segment_dir / take / cam.name / (frame_name(item.frame) + ".png");
      if (fs::is_regular_file(session.capture_image(take, cam.name, item.frame), ec) &&
          !fs::is_regular_file(sil, ec)) {
        throw InputError(fmt::format("{} is missing (take {} camera {} frame {}): run "
                                     "fourd-segment on these frames first",
                                     sil.string(), take, cam.name, item.frame));
      }
    }
  }
}

void run_calibration_check(const Session& session, const Rig& rig,
                           const std::vector<TakeFrames>& takes, const ReconstructOptions& options,
                           const CalibrationCheckRequest& request, const fs::path& out_dir) {
  CalibrationCheckOptions check = options.calibration_check;
  std::string take = request.take.empty() ? check.take : request.take;
  int frame = request.frame >= 0 ? request.frame : check.frame;
  if (take.empty()) take = takes.front().name;
  auto it = std::find_if(takes.begin(), takes.end(), [&](auto& t) { return t.name == take; });
  if (it == takes.end()) {
    throw InputError(fmt::format("calibration check: no take '{}' in {}", take,
                                 session.capture_dir().string()));
  }
  if (frame >= it->frames) {
    throw InputError(fmt::format("calibration check: take {} has frames 0..{}, not {}", take,
                                 it->frames - 1, frame));
  }
  // The same COLMAP as the reconstruction's (one per machine).
  const std::string colmap = find_colmap(options.colmap.executable);
  if (colmap.empty()) {
    log::warn("calibration check skipped: the COLMAP executable '{}' was not found (install "
              "colmap, or set stages.reconstruct.colmap.executable)",
              options.colmap.executable);
    return;
  }
  const bool refine = check.refine || request.refine;
  std::vector<std::pair<std::string, int>> frame_counts;
  for (const TakeFrames& t : takes) frame_counts.emplace_back(t.name, t.frames);
  // The named frame, then others spread through the session.
  std::vector<CheckFrame> checked = {{take, frame}};
  for (const CheckFrame& f : spread_frames(frame_counts, check.check_frames)) {
    if (checked.size() == static_cast<std::size_t>(check.check_frames)) break;
    if (f.take != take || f.frame != frame) checked.push_back(f);
  }
  std::vector<CheckFrame> refine_frames;
  if (refine) refine_frames = spread_frames(frame_counts, check.refine_frames);
  log::info("checking the calibration with COLMAP on take {} frame {}{}{}", take, frame,
            checked.size() > 1
                ? fmt::format(" and {} frames spread through the session", checked.size() - 1)
                : "",
            refine ? fmt::format(" (with refinement on {} frames)", refine_frames.size()) : "");
  log::Timer timer;
  CalibrationCheckResult result;
  try {
    result = check_calibration(
        colmap, rig.cameras, checked, refine_frames,
        [&](const CheckFrame& f, const Camera& c) {
          return read_capture_image(session, c, f.take, f.frame);
        },
        check, out_dir / "calibration_check");
  } catch (const Error& e) {
    log::warn("calibration check failed: {}", e.what());
    if (request.only) throw;
    return;
  }
  for (const auto& [name, e] : result.cameras) {
    std::string after;
    if (result.refined.count(name)) {
      after = fmt::format(", after refinement {:.3f} px (fitted frames)",
                          result.refined.at(name).mean_error_px);
    }
    log::info("camera {}: reprojection error median {:.3f} px, mean {:.3f} px over {} points{}",
              name, e.median_error_px, e.mean_error_px, e.observations, after);
  }
  for (const auto& w : result.warnings) log::warn("{}", w);
  if (result.fit_frames > 0) {
    log::info("refinement: fitted to {} points of {} frames; on {} held-out frames the mean "
              "reprojection error is {:.3f} px over {} points with the written calibration, "
              "{:.3f} px over {} points with the refined one",
              result.fit_points, result.fit_frames, result.held_out_frames,
              result.held_out_before.mean_error_px, result.held_out_before.points,
              result.held_out_after.mean_error_px, result.held_out_after.points);
  }
  if (!result.refined_calibration.empty()) {
    log::info("refined calibration written to {}", (out_dir / "calibration_check" / "refined").string());
  }
  log::info("calibration check: {} points triangulated, {:.1f} s", result.points, timer.seconds());
  write_file_atomic(out_dir / "calibration_check" / "report.json", result.to_json().dump(1) + "\n");
}

// The volume `cameras` share, where the subject can be carved.
Box shared_volume_of(const Session& session, const VisualHullOptions& hull,
                     const std::vector<Camera>& cameras) {
  const Box box = shared_volume(cameras, required_views(hull, static_cast<int>(cameras.size())));
  if (box.empty()) {
    throw InputError(fmt::format(
        "{}: no point is seen by the {} cameras the visual hull needs of these {} (check the "
        "calibration, or set stages.reconstruct.visual_hull.volume_min/max)",
        session.calibration_dir().string(), required_views(hull, static_cast<int>(cameras.size())),
        cameras.size()));
  }
  return box;
}

// Cameras that see nothing of the capture volume cannot help: they are left out, loudly.
std::vector<Camera> cameras_seeing_volume(const Session& session,
                                          const std::vector<Camera>& calibration,
                                          const ReconstructOptions& options) {
  std::vector<Camera> usable;
  std::vector<std::string> blind;
  for (const Camera& c : calibration) {
    double coverage = volume_coverage(c, options.visual_hull);
    if (coverage == 0) {
      blind.push_back(c.name);
      log::warn("camera {} sees nothing of the capture volume (calibration/ puts it looking "
                "elsewhere): it is left out", c.name);
    } else {
      usable.push_back(c);
    }
  }
  if (static_cast<int>(usable.size()) < options.min_cameras) {
    throw InputError(fmt::format(
        "{}: only {} camera(s) look at the capture volume, {} needed (cameras looking elsewhere: "
        "{}) — check the calibration and stages.reconstruct.visual_hull.volume_min/max",
        session.calibration_dir().string(), usable.size(), options.min_cameras,
        blind.empty() ? "none" : fmt::format("{}", fmt::join(blind, ", "))));
  }
  return usable;
}

// The cameras that see the capture volume and (unless `volume_set`: session.yaml or a preset
// sets it) the volume they share, from which the options' capture volume is derived.
std::vector<Camera> usable_cameras(const Session& session, const std::vector<Camera>& calibration,
                                   bool volume_set, ReconstructOptions& options, Box& shared) {
  if (!volume_set) {
    shared = shared_volume_of(session, options.visual_hull, calibration);
    derive_volume(options.visual_hull, shared, 1.0);  // the reference volume and the shared one
  }
  std::vector<Camera> usable = cameras_seeing_volume(session, calibration, options);
  if (!volume_set && usable.size() < calibration.size()) {
    shared = shared_volume_of(session, options.visual_hull, usable);
  }
  return usable;
}

// The rig the frames are reconstructed with: cameras of more than max_image_pixels reduced;
// nullopt when no camera is.
std::optional<Rig> reduced_rig(const Rig& rig, const ReconstructOptions& options) {
  std::vector<Camera> working = rig.cameras;
  bool reduced = false;
  for (Camera& cam : working) {
    Intrinsics& k = cam.intrinsics;
    const double pixels = static_cast<double>(k.width) * k.height;
    if (options.max_image_pixels <= 0 || pixels <= options.max_image_pixels) continue;
    const double s = std::sqrt(options.max_image_pixels / pixels);
    const int w = std::max(1, static_cast<int>(std::lround(k.width * s)));
    const int h = std::max(1, static_cast<int>(std::lround(k.height * s)));
    log::info("camera {}: {}x{} images reconstructed at {}x{} (max_image_pixels {})", cam.name,
              k.width, k.height, w, h, options.max_image_pixels);
    const double sx = static_cast<double>(w) / k.width, sy = static_cast<double>(h) / k.height;
    k.fx *= sx;
    k.cx *= sx;
    k.fy *= sy;
    k.cy *= sy;
    k.width = w;
    k.height = h;
    reduced = true;
  }
  if (!reduced) return std::nullopt;
  return Rig::from(working);
}

// The frames `sel` selects, checked against the capture.
std::vector<Item> selected_items(const std::vector<TakeFrames>& takes, const FrameSelection& sel) {
  {
    CaptureIndex index;
    for (const TakeFrames& t : takes) index.takes.push_back({t.name, t.frames, {}});
    check_frame_selection(sel, index);
  }
  std::vector<Item> items;
  for (std::size_t t = 0; t < takes.size(); ++t) {
    for (int f = 0; f < takes[t].frames; ++f) {
      if (sel.selects(takes[t].name, f)) items.push_back({t, f});
    }
  }
  if (items.empty()) {
    throw InputError(fmt::format("--take '{}' --frames {} selects no frame of the capture",
                                 sel.take, sel.frames_text()));
  }
  return items;
}

// The subject's size, and the lengths the user did not set scaled to it.
struct Scaling {
  SubjectScale subject;
  std::vector<std::string> scaled;  // the option keys scaled
};

// The subject's size, the scale factor and the capture volume that follows from them.
void log_subject(const SubjectScale& subject, const std::vector<std::string>& scaled,
                 const VisualHullOptions& hull) {
  log::info("subject: {:.3g} m largest extent, {:.3g} m high ({}); scale factor {:.4g} of the "
            "{} m reference: {} length(s) not set are scaled by it; capture volume [{:.3g}, "
            "{:.3g}, {:.3g}] .. [{:.3g}, {:.3g}, {:.3g}] m",
            subject.size, subject.height,
            subject.measured ? fmt::format("visual hull of {} frame(s)", subject.frames_measured)
                             : std::string("scale.subject_size"),
            subject.factor, kReferenceSubjectSize, scaled.size(), hull.volume_min[0],
            hull.volume_min[1], hull.volume_min[2], hull.volume_max[0], hull.volume_max[1],
            hull.volume_max[2]);
}

// The subject measured on the session (in the volume the cameras share, or the one set), the
// options' unset lengths and capture volume scaled to it, and the options checked.
Scaling scale_to_subject(const Rig& rig, const std::vector<TakeFrames>& takes,
                         const SetKeys& set_keys, bool volume_set, Box shared,
                         const fs::path& segment_dir, ReconstructOptions& options) {
  if (volume_set) {
    const VisualHullOptions& h = options.visual_hull;
    shared = {{h.volume_min[0], h.volume_min[1], h.volume_min[2]},
              {h.volume_max[0], h.volume_max[1], h.volume_max[2]}};
  }
  Scaling s;
  s.subject = measure_session_subject(rig, takes, options, shared, segment_dir);
  s.scaled = scale_unset_lengths(options, s.subject.factor, set_keys, "stages.reconstruct");
  if (!volume_set) derive_volume(options.visual_hull, shared, s.subject.factor);
  options.visual_hull.check();
  options.check();
  log_subject(s.subject, s.scaled, options.visual_hull);
  return s;
}

// What every frame of a run shares; process() reconstructs one frame and writes its files.
class FrameRun {
 public:
  FrameRun(const Session& session, const Rig& rig, const Rig& work,
           const ReconstructOptions& options, const std::vector<TakeFrames>& takes,
           const fs::path& segment_dir, const fs::path& out_dir, log::Progress& progress)
      : session_(session),
        rig_(rig),
        work_(work),
        options_(options),
        takes_(takes),
        segment_dir_(segment_dir),
        out_dir_(out_dir),
        progress_(progress) {}

  void process(const Item& item);
  std::size_t failed() const { return failed_.load(); }
  std::size_t flagged() const { return flagged_.load(); }

 private:
  FrameInput read_input(const std::string& take, int frame,
                        std::vector<std::string>& warnings) const;
  void write_meshes(const std::string& take, int frame, const FrameResult& result);
  void log_frame(const std::string& take, int frame, const FrameResult& result,
                 const std::vector<std::string>& warnings);

  const Session& session_;
  const Rig& rig_;
  const Rig& work_;
  const ReconstructOptions& options_;
  const std::vector<TakeFrames>& takes_;
  const fs::path& segment_dir_;
  const fs::path& out_dir_;
  log::Progress& progress_;
  std::atomic<std::size_t> failed_{0}, flagged_{0};
  std::mutex log_mutex_;
};

void FrameRun::process(const Item& item) {
  const std::string& take = takes_[item.take].name;
  const int frame = item.frame;
  std::vector<std::string> warnings;
  const FrameInput input = read_input(take, frame, warnings);
  FrameResult result;
  if (static_cast<int>(input.cameras.size()) < options_.min_cameras) {
    result.failure = fmt::format("only {} usable camera(s), {} needed", input.cameras.size(),
                                 options_.min_cameras);
  } else {
    result = reconstruct_frame(work_, input, options_, options_.write_visual_hull,
                               out_dir_ / "work" / take / frame_name(frame));
  }
  warnings.insert(warnings.end(), result.warnings.begin(), result.warnings.end());
  if (!result.plausibility.warnings.empty()) ++flagged_;
  write_meshes(take, frame, result);
  std::vector<std::string> used_names;
  for (int c : input.cameras) used_names.push_back(rig_.cameras[c].name);
  write_file_atomic(out_dir_ / take / (frame_name(frame) + ".json"),
                    frame_record(take, frame, result, warnings, used_names).dump(1) + "\n");
  log_frame(take, frame, result, warnings);
  progress_.step();
}

// The frame's images and silhouettes, at the working rig's size; a camera without a sensible
// pair is left out with a warning.
FrameInput FrameRun::read_input(const std::string& take, int frame,
                                std::vector<std::string>& warnings) const {
  FrameInput input;
  for (std::size_t c = 0; c < rig_.cameras.size(); ++c) {
    const Camera& cam = rig_.cameras[c];
    cv::Mat image, silhouette;
    const fs::path sil_path = segment_dir_ / take / cam.name / (frame_name(frame) + ".png");
    try {
      image = read_capture_image(session_, cam, take, frame);
      silhouette = read_image(sil_path, cv::IMREAD_GRAYSCALE);
    } catch (const Error& e) {
      warnings.push_back(fmt::format("camera {} left out: {}", cam.name, e.what()));
      continue;
    }
    if (silhouette.size() != image.size()) {
      warnings.push_back(fmt::format("camera {} left out: silhouette {} is {}x{}, the image "
                                     "{}x{}", cam.name, sil_path.string(), silhouette.cols,
                                     silhouette.rows, image.cols, image.rows));
      continue;
    }
    const int fg = cv::countNonZero(silhouette);
    if (fg == 0) {
      warnings.push_back(fmt::format("camera {} left out: its silhouette {} is empty (it would "
                                     "carve away everything)", cam.name, sil_path.string()));
      continue;
    }
    if (fg == static_cast<int>(silhouette.total())) {
      warnings.push_back(fmt::format("camera {} left out: its silhouette {} is full (the whole "
                                     "image is foreground)", cam.name, sil_path.string()));
      continue;
    }
    const Intrinsics& k = work_.cameras[c].intrinsics;
    if (k.width != image.cols || k.height != image.rows) {
      cv::resize(image, image, cv::Size(k.width, k.height), 0, 0, cv::INTER_AREA);
      cv::resize(silhouette, silhouette, cv::Size(k.width, k.height), 0, 0, cv::INTER_AREA);
      cv::threshold(silhouette, silhouette, 127, 255, cv::THRESH_BINARY);
    }
    input.cameras.push_back(static_cast<int>(c));
    input.images.push_back(image);
    input.silhouettes.push_back(silhouette);
  }
  return input;
}

// The frame's mesh (and visual hull); a failed frame is counted, and its meshes of an earlier
// run are removed.
void FrameRun::write_meshes(const std::string& take, int frame, const FrameResult& result) {
  const fs::path mesh_path = out_dir_ / take / (frame_name(frame) + ".ply");
  const fs::path hull_path = out_dir_ / "visual_hull" / take / (frame_name(frame) + ".ply");
  ensure_directory(mesh_path.parent_path());
  std::error_code ec;
  if (result.reconstructed) {
    write_ply(mesh_path, result.mesh);
    if (options_.write_visual_hull && !result.visual_hull.empty()) {
      ensure_directory(hull_path.parent_path());
      write_ply(hull_path, result.visual_hull);
    }
  } else {
    // Never leave an earlier run's mesh standing in for a frame that failed now.
    fs::remove(mesh_path, ec);
    fs::remove(hull_path, ec);
    ++failed_;
  }
}

// The frame's warnings and outcome, one frame's lines together.
void FrameRun::log_frame(const std::string& take, int frame, const FrameResult& result,
                         const std::vector<std::string>& warnings) {
  std::lock_guard lock(log_mutex_);
  for (const auto& w : warnings) log::warn("take {} frame {}: {}", take, frame, w);
  if (!result.reconstructed) {
    log::warn("take {} frame {}: skipped — {}", take, frame, result.failure);
  } else {
    std::string steps;
    for (const auto& [s, t] : result.seconds) steps += fmt::format(" {} {:.2f}", s, t);
    log::debug("take {} frame {}: {} vertices, depth coverage {:.0f}%, seconds:{}", take, frame,
               result.mesh.positions.size(), 100 * result.depth_coverage, steps);
  }
}

// Every item through `run`, frames_in_parallel of them at once.
void process_items(FrameRun& run, const std::vector<Item>& items, int frames_in_parallel) {
  if (frames_in_parallel == 1) {
    for (const Item& item : items) run.process(item);
  } else {
    const int concurrency = frames_in_parallel > 0 ? frames_in_parallel
                                                   : tbb::this_task_arena::max_concurrency();
    tbb::task_arena arena(concurrency);
    arena.execute([&] {
      tbb::parallel_for(std::size_t{0}, items.size(), [&](std::size_t i) { run.process(items[i]); },
                        tbb::simple_partitioner());
    });
  }
}

// This job's work folders (other jobs may be running beside it), and work/ when empty.
void remove_work_folders(const fs::path& out_dir, const std::vector<TakeFrames>& takes,
                         const std::vector<Item>& items) {
  std::error_code ec;
  for (const Item& item : items) {
    fs::remove_all(out_dir / "work" / takes[item.take].name / frame_name(item.frame), ec);
  }
  for (const TakeFrames& t : takes) fs::remove(out_dir / "work" / t.name, ec);  // when empty
  fs::remove(out_dir / "work", ec);
}

// The run's outcome: frames done, skipped and flagged; throws when no frame could be done.
void log_outcome(const fs::path& out_dir, std::size_t items, const FrameRun& run,
                 double seconds) {
  log::info("reconstructed {} of {} frame(s) in {:.1f} s ({:.2f} s per frame)",
            items - run.failed(), items, seconds, seconds / items);
  if (run.failed() == items) {
    throw InputError(fmt::format("no frame could be reconstructed ({} tried); see {}", items,
                                 (out_dir / "report.json").string()));
  }
  if (run.failed() > 0) {
    log::warn("{} frame(s) could not be reconstructed and were skipped: see {}", run.failed(),
              (out_dir / "report.json").string());
  }
  if (run.flagged() > 0) {
    log::warn("{} frame(s) flagged: their result disagrees with what the silhouettes imply (the "
              "warnings above, and \"flagged\" in their records)",
              run.flagged());
  }
}

}  // namespace

void run_reconstruct(const Session& session, const StageArgs& args,
                     const CalibrationCheckRequest& request) {
  ReconstructOptions options;
  SetKeys set_keys;
  session.stage_options("reconstruct", options, &set_keys);
  const std::vector<Camera> calibration = read_colmap_model(session.calibration_dir());
  const fs::path out_dir = stage_output_dir(session, args, "reconstruct");
  const fs::path segment_dir = stage_input_dir(session, args, "segment");
  ensure_directory(out_dir);

  // The volume the cameras share, where the subject can be carved: the capture volume unless
  // session.yaml or a preset sets one.
  const bool volume_set = set_keys.count("stages.reconstruct.visual_hull.volume_min") ||
                          set_keys.count("stages.reconstruct.visual_hull.volume_max");
  Box shared;
  const Rig rig = Rig::from(usable_cameras(session, calibration, volume_set, options, shared));
  const std::optional<Rig> reduced = reduced_rig(rig, options);
  const Rig& work = reduced ? *reduced : rig;
  const std::vector<TakeFrames> takes = list_takes(session, rig.cameras);
  if (takes.empty()) {
    throw InputError(fmt::format("{}: no take with frames of the calibrated cameras",
                                 session.capture_dir().string()));
  }

  // The frames of this job and their inputs, checked before any work.
  const FrameSelection& sel = args.selection;
  const std::vector<Item> items = selected_items(takes, sel);
  if (args.finish) {
    check_frame_records(out_dir, takes, items);
  } else if (!request.only) {
    check_silhouettes(session, rig, takes, items, segment_dir);
  }

  if (request.only || (options.calibration_check.enabled && sel.whole())) {
    run_calibration_check(session, rig, takes, options, request, out_dir);
  }
  if (request.only) return;

  const Scaling scaling =
      scale_to_subject(rig, takes, set_keys, volume_set, shared, segment_dir, options);
  const SubjectScale& subject = scaling.subject;
  const std::vector<std::string>& scaled = scaling.scaled;
  write_subject(out_dir, subject);
  if (args.finish) {
    // The jobs' frames are all there: the report adds up their per-frame records.
    write_report(out_dir, takes, {{"frames", items.size()}, {"split_into_jobs", true}}, subject);
    write_options_used(out_dir, options, subject, scaled);
    log::info("reconstruct: report over {} frame(s) written to {}", items.size(),
              (out_dir / "report.json").string());
    return;
  }
  log::info("reconstructing {} frame(s) of {} take(s) from {} cameras, method {}", items.size(),
            takes.size(), rig.cameras.size(), options.method);

  log::Progress progress("reconstructing frames", items.size());
  log::Timer wall;
  FrameRun run(session, rig, work, options, takes, segment_dir, out_dir, progress);
  process_items(run, items, options.frames_in_parallel);
  remove_work_folders(out_dir, takes, items);

  const double seconds = wall.seconds();
  nlohmann::json record = {{"frames", items.size()},
                           {"frames_skipped", run.failed()},
                           {"wall_seconds", seconds},
                           {"seconds_per_frame", seconds / items.size()},
                           {"threads", tbb::this_task_arena::max_concurrency()},
                           {"method", options.method}};
  if (sel.whole()) {
    write_report(out_dir, takes, record, subject);
    write_options_used(out_dir, options, subject, scaled);
  } else {
    log::info("a job of a split run: reconstruct/report.json is left to `fourd-reconstruct "
              "--finish`");
  }
  log_outcome(out_dir, items.size(), run, seconds);
}

}  // namespace fourd::reconstruct
