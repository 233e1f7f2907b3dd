#include "stages/reconstruct/reconstruct.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <fmt/ranges.h>

#include <algorithm>
#include <atomic>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
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
  if (method != "stereo" && method != "colmap" && method != "visual_hull") {
    throw ConfigError(fmt::format("method '{}': expected stereo, colmap or visual_hull", method));
  }
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

}  // namespace

FrameResult reconstruct_frame(const Rig& rig, const FrameInput& input,
                              const ReconstructOptions& options, bool want_visual_hull,
                              const fs::path& work_dir) {
  FrameResult result;
  StepTimer timer(result);
  std::vector<Camera> cameras;
  for (int c : input.cameras) cameras.push_back(rig.cameras[c]);

  // 1. Visual hull.
  VisualHull hull(cameras, input.silhouettes, options.visual_hull);
  ScalarGrid field = hull.grid();
  ScalarGrid depth_weight;  // the fusion's depth votes per sample (method stereo)
  if (field.nx == 0) {
    result.failure = "the visual hull is empty: no point of the capture volume is inside every "
                     "silhouette (check the silhouettes and the calibration)";
    return result;
  }
  Mesh hull_mesh =
      largest_component(extract_isosurface(subsample(field, options.isosurface_step), 0.0f));
  if (hull_mesh.triangles.empty()) {
    result.failure = "the visual hull has no surface";
    return result;
  }
  timer.done("visual_hull");
  if (want_visual_hull) {
    // Only for validation and comparison: written as extracted, from a coarser sampling
    // (decimating or remeshing it would cost as much as the final mesh's remeshing).
    result.visual_hull = options.visual_hull_step == options.isosurface_step
                             ? hull_mesh
                             : largest_component(extract_isosurface(
                                   subsample(field, options.visual_hull_step), 0.0f));
    timer.done("visual_hull_remesh");
  }

  // The result against what the silhouettes imply (warnings only, also for a failed frame).
  auto check = [&](const Mesh& mesh) {
    result.plausibility = check_plausibility(cameras, input.silhouettes, hull_mesh, mesh,
                                             options.visual_hull.voxel_size, options.checks);
    result.warnings.insert(result.warnings.end(), result.plausibility.warnings.begin(),
                           result.plausibility.warnings.end());
  };
  Mesh surface;
  if (options.method == "visual_hull") {
    surface = hull_mesh;
  } else {
    // 2. Depth maps, matched on undistorted images, searched behind the hull's first hit.
    MeshRaycaster raycaster(hull_mesh);
    const int n = static_cast<int>(cameras.size());
    std::vector<StereoView> views(n);
    std::vector<PinholeCamera> pinholes(n);
    tbb::parallel_for(0, n, [&](int i) {
      const int c = input.cameras[i];
      views[i].camera = pinholes[i] = rig.pinholes[c];
      views[i].gray = undistorted_gray(input.images[i], rig.undistorters[c]);
      SurfaceRender render = raycaster.render(rig.pinholes[c]);
      views[i].hull_depth = render.depth;
      views[i].roi = render.roi;
    });
    timer.done("hull_depth");
    // Depth maps of every camera against `guides` (the hull's or the guide surface's first hit
    // per pixel), checked against each other.
    std::vector<DepthMap> depth_maps(n);
    auto match = [&](const std::vector<StereoView>& guides, const DepthMapOptions& depth) {
      tbb::parallel_for(0, n, [&](int i) {
        std::vector<int> neighbours =
            select_neighbours(pinholes, i, depth.neighbours, depth.max_angle_deg);
        depth_maps[i] = estimate_depth_map(guides, i, neighbours, depth);
      });
      keep_consistent_depths(pinholes, depth_maps, depth.consistent_views,
                             depth.consistency_tolerance);
    };
    auto fill = [&](const std::vector<StereoView>& guides, const DepthMapOptions& depth) {
      tbb::parallel_for(0, n, [&](int i) {
        fill_depth_holes(guides[i].hull_depth, depth_maps[i], depth.front_margin,
                         depth.search_depth, options.depth_fill);
      });
    };
    // Fraction of the hull's pixels whose depth was matched (not filled in).
    auto measure_coverage = [&] {
      std::size_t hull_pixels = 0, matched = 0;
      for (int i = 0; i < n; ++i) {
        hull_pixels += cv::countNonZero(views[i].hull_depth > 0);
        cv::Mat measured = depth_maps[i].depth > 0;
        if (!depth_maps[i].filled.empty()) measured &= depth_maps[i].filled == 0;
        matched += cv::countNonZero(measured);
      }
      result.depth_coverage = hull_pixels ? double(matched) / hull_pixels : 0.0;
    };
    match(views, options.depth);
    measure_coverage();
    timer.done("depth_maps");

    // 3. Fusion.
    if (options.method == "stereo") {
      fill(views, options.depth);
      timer.done("depth_fill");
      for (int pass = 0; pass < options.guided.passes; ++pass) {
        // The previous pass's surface, its filled depths at full weight, guides a sweep over a
        // narrower range: the matching windows follow that surface's slant rather than the
        // hull's, and a neighbour's view of a point is tested against it.
        ScalarGrid guide_field = field;
        FusionOptions guide_fusion = options.fusion;
        guide_fusion.filled_weight = options.guided.filled_weight;
        fuse_depth_maps(guide_field, pinholes, depth_maps, options.depth.min_ncc, guide_fusion);
        const Mesh guide = largest_component(
            extract_isosurface(subsample(guide_field, options.isosurface_step), 0.0f));
        if (guide.triangles.empty()) break;
        MeshRaycaster guide_caster(guide);
        std::vector<StereoView> guided = views;
        tbb::parallel_for(0, n, [&](int i) {
          SurfaceRender render = guide_caster.render(pinholes[i]);
          guided[i].hull_depth = render.depth;
          guided[i].roi = render.roi;
        });
        DepthMapOptions depth = options.depth;
        depth.front_margin = options.guided.front_margin;
        depth.search_depth = options.guided.search_depth;
        depth.occlusion_margin = options.guided.occlusion_margin;
        match(guided, depth);
        measure_coverage();
        fill(guided, depth);
        timer.done("guided_pass");
      }
      fuse_depth_maps(field, pinholes, depth_maps, options.depth.min_ncc, options.fusion,
                      &depth_weight);
      timer.done("fusion");
      surface = largest_component(
          extract_isosurface(subsample(field, options.isosurface_step), 0.0f));
      timer.done("isosurface");
    } else {
      const std::string colmap = find_colmap(options.colmap.executable);
      if (colmap.empty()) {
        result.failure = fmt::format("method colmap: the COLMAP executable '{}' was not found",
                                     options.colmap.executable);
        return result;
      }
      std::vector<MvsView> mvs(n);
      tbb::parallel_for(0, n, [&](int i) {
        const int c = input.cameras[i];
        mvs[i].camera = pinholes[i];
        mvs[i].image = rig.undistorters[c].apply(input.images[i], cv::INTER_LINEAR);
        mvs[i].depth = depth_maps[i].depth;
        mvs[i].normal =
            depth_map_normals(pinholes[i], depth_maps[i].depth, options.colmap.normal_max_jump);
      });
      try {
        write_colmap_workspace(work_dir, mvs, options.colmap.tie_tolerance);
        const std::size_t points = colmap_stereo_fusion(colmap, work_dir, options.colmap);
        timer.done("colmap_stereo_fusion");
        if (points == 0) throw SolverError("COLMAP stereo_fusion fused no point");
        surface = colmap_poisson_mesh(colmap, work_dir, options.colmap);
        timer.done("colmap_poisson_mesher");
      } catch (const Error& e) {
        result.failure = e.what();
        check({});
        return result;
      }
      if (!options.colmap.keep_workspace) {
        std::error_code ec;
        fs::remove_all(work_dir, ec);
      }
      surface = trim_to_hull(surface, hull, options.colmap.hull_trim);
      timer.done("trim");
    }
  }
  if (surface.triangles.empty()) {
    result.failure = "the fused surface is empty";
    check({});
    return result;
  }

  // 4. One closed, remeshed surface.
  if (count_boundary_edges(surface) > 0) {
    int holes = fill_holes(surface);
    if (holes > 0) result.warnings.push_back(fmt::format("filled {} hole(s)", holes));
    timer.done("fill_holes");
  }
  result.mesh = remesh(surface, options.remesh);
  timer.done("remesh");
  if (options.project_to_field && options.method != "colmap" && options.isosurface_step > 1) {
    project_to_isosurface(result.mesh, field, 0.0f, options.isosurface_step * field.voxel);
    timer.done("project_to_field");
  }
  if (!depth_weight.values.empty()) {
    result.mesh.confidence = surface_confidence(result.mesh, depth_weight, options.fusion);
    const auto low = std::count_if(result.mesh.confidence.begin(), result.mesh.confidence.end(),
                                   [](float c) { return c < 0.5f; });
    result.low_confidence_fraction =
        result.mesh.confidence.empty() ? 0.0 : double(low) / result.mesh.confidence.size();
  }
  check(result.mesh);
  timer.done("checks");
  result.reconstructed = true;
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
  auto shared_of = [&](const std::vector<Camera>& cameras) {
    const Box box = shared_volume(
        cameras, required_views(options.visual_hull, static_cast<int>(cameras.size())));
    if (box.empty()) {
      throw InputError(fmt::format(
          "{}: no point is seen by the {} cameras the visual hull needs of these {} (check the "
          "calibration, or set stages.reconstruct.visual_hull.volume_min/max)",
          session.calibration_dir().string(),
          required_views(options.visual_hull, static_cast<int>(cameras.size())), cameras.size()));
    }
    return box;
  };
  Box shared;
  if (!volume_set) {
    shared = shared_of(calibration);
    derive_volume(options.visual_hull, shared, 1.0);  // the reference volume and the shared one
  }

  // Cameras that see nothing of the capture volume cannot help: leave them out, loudly.
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
  if (!volume_set && !blind.empty()) shared = shared_of(usable);
  const Rig rig = Rig::from(usable);
  // The rig the frames are reconstructed with: cameras of more than max_image_pixels reduced.
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
  const Rig work_rig = reduced ? Rig::from(working) : Rig{};
  const Rig& work = reduced ? work_rig : rig;
  const std::vector<TakeFrames> takes = list_takes(session, rig.cameras);
  if (takes.empty()) {
    throw InputError(fmt::format("{}: no take with frames of the calibrated cameras",
                                 session.capture_dir().string()));
  }

  // The frames of this job and their inputs, checked before any work.
  const FrameSelection& sel = args.selection;
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
  if (args.finish) {
    check_frame_records(out_dir, takes, items);
  } else if (!request.only) {
    check_silhouettes(session, rig, takes, items, segment_dir);
  }

  if (request.only || (options.calibration_check.enabled && sel.whole())) {
    run_calibration_check(session, rig, takes, options, request, out_dir);
  }
  if (request.only) return;

  // The subject's size, and the lengths the user did not set scaled to it.
  if (volume_set) {
    const VisualHullOptions& h = options.visual_hull;
    shared = {{h.volume_min[0], h.volume_min[1], h.volume_min[2]},
              {h.volume_max[0], h.volume_max[1], h.volume_max[2]}};
  }
  const SubjectScale subject =
      measure_session_subject(rig, takes, options, shared, segment_dir);
  const std::vector<std::string> scaled =
      scale_unset_lengths(options, subject.factor, set_keys, "stages.reconstruct");
  if (!volume_set) derive_volume(options.visual_hull, shared, subject.factor);
  options.visual_hull.check();
  options.check();
  log::info("subject: {:.3g} m largest extent, {:.3g} m high ({}); scale factor {:.4g} of the "
            "{} m reference: {} length(s) not set are scaled by it; capture volume [{:.3g}, "
            "{:.3g}, {:.3g}] .. [{:.3g}, {:.3g}, {:.3g}] m",
            subject.size, subject.height,
            subject.measured ? fmt::format("visual hull of {} frame(s)", subject.frames_measured)
                             : std::string("scale.subject_size"),
            subject.factor, kReferenceSubjectSize, scaled.size(),
            options.visual_hull.volume_min[0], options.visual_hull.volume_min[1],
            options.visual_hull.volume_min[2], options.visual_hull.volume_max[0],
            options.visual_hull.volume_max[1], options.visual_hull.volume_max[2]);
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

  std::atomic<std::size_t> failed{0}, flagged{0};
  std::mutex log_mutex;
  log::Progress progress("reconstructing frames", items.size());
  log::Timer wall;
  auto process = [&](const Item& item) {
    const std::string& take = takes[item.take].name;
    const int frame = item.frame;
    FrameInput input;
    std::vector<std::string> warnings;
    for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
      const Camera& cam = rig.cameras[c];
      cv::Mat image, silhouette;
      const fs::path sil_path = segment_dir / take / cam.name / (frame_name(frame) + ".png");
      try {
        image = read_capture_image(session, cam, take, frame);
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
      const Intrinsics& k = work.cameras[c].intrinsics;
      if (k.width != image.cols || k.height != image.rows) {
        cv::resize(image, image, cv::Size(k.width, k.height), 0, 0, cv::INTER_AREA);
        cv::resize(silhouette, silhouette, cv::Size(k.width, k.height), 0, 0, cv::INTER_AREA);
        cv::threshold(silhouette, silhouette, 127, 255, cv::THRESH_BINARY);
      }
      input.cameras.push_back(static_cast<int>(c));
      input.images.push_back(image);
      input.silhouettes.push_back(silhouette);
    }
    FrameResult result;
    if (static_cast<int>(input.cameras.size()) < options.min_cameras) {
      result.failure = fmt::format("only {} usable camera(s), {} needed", input.cameras.size(),
                                   options.min_cameras);
    } else {
      result = reconstruct_frame(work, input, options, options.write_visual_hull,
                                 out_dir / "work" / take / frame_name(frame));
    }
    warnings.insert(warnings.end(), result.warnings.begin(), result.warnings.end());
    if (!result.plausibility.warnings.empty()) ++flagged;
    const fs::path mesh_path = out_dir / take / (frame_name(frame) + ".ply");
    const fs::path hull_path = out_dir / "visual_hull" / take / (frame_name(frame) + ".ply");
    ensure_directory(mesh_path.parent_path());
    std::error_code ec;
    if (result.reconstructed) {
      write_ply(mesh_path, result.mesh);
      if (options.write_visual_hull && !result.visual_hull.empty()) {
        ensure_directory(hull_path.parent_path());
        write_ply(hull_path, result.visual_hull);
      }
    } else {
      // Never leave an earlier run's mesh standing in for a frame that failed now.
      fs::remove(mesh_path, ec);
      fs::remove(hull_path, ec);
      ++failed;
    }
    std::vector<std::string> used_names;
    for (int c : input.cameras) used_names.push_back(rig.cameras[c].name);
    write_file_atomic(out_dir / take / (frame_name(frame) + ".json"),
                      frame_record(take, frame, result, warnings, used_names).dump(1) + "\n");
    {
      std::lock_guard lock(log_mutex);
      for (const auto& w : warnings) log::warn("take {} frame {}: {}", take, frame, w);
      if (!result.reconstructed) {
        log::warn("take {} frame {}: skipped — {}", take, frame, result.failure);
      } else {
        std::string steps;
        for (const auto& [s, t] : result.seconds) steps += fmt::format(" {} {:.2f}", s, t);
        log::debug("take {} frame {}: {} vertices, depth coverage {:.0f}%, seconds:{}", take,
                   frame, result.mesh.positions.size(), 100 * result.depth_coverage, steps);
      }
    }
    progress.step();
  };
  if (options.frames_in_parallel == 1) {
    for (const Item& item : items) process(item);
  } else {
    const int concurrency = options.frames_in_parallel > 0 ? options.frames_in_parallel
                                                           : tbb::this_task_arena::max_concurrency();
    tbb::task_arena arena(concurrency);
    arena.execute([&] {
      tbb::parallel_for(std::size_t{0}, items.size(), [&](std::size_t i) { process(items[i]); },
                        tbb::simple_partitioner());
    });
  }
  // Only this job's work folders: other jobs may be running beside it.
  std::error_code ec;
  for (const Item& item : items) {
    fs::remove_all(out_dir / "work" / takes[item.take].name / frame_name(item.frame), ec);
  }
  for (const TakeFrames& t : takes) fs::remove(out_dir / "work" / t.name, ec);  // when empty
  fs::remove(out_dir / "work", ec);

  const double seconds = wall.seconds();
  nlohmann::json run = {{"frames", items.size()},
                        {"frames_skipped", failed.load()},
                        {"wall_seconds", seconds},
                        {"seconds_per_frame", seconds / items.size()},
                        {"threads", tbb::this_task_arena::max_concurrency()},
                        {"method", options.method}};
  if (sel.whole()) {
    write_report(out_dir, takes, run, subject);
    write_options_used(out_dir, options, subject, scaled);
  } else {
    log::info("a job of a split run: reconstruct/report.json is left to `fourd-reconstruct "
              "--finish`");
  }
  log::info("reconstructed {} of {} frame(s) in {:.1f} s ({:.2f} s per frame)",
            items.size() - failed.load(), items.size(), seconds, seconds / items.size());
  if (failed.load() == items.size()) {
    throw InputError(fmt::format("no frame could be reconstructed ({} tried); see {}",
                                 items.size(), (out_dir / "report.json").string()));
  }
  if (failed.load() > 0) {
    log::warn("{} frame(s) could not be reconstructed and were skipped: see {}", failed.load(),
              (out_dir / "report.json").string());
  }
  if (flagged.load() > 0) {
    log::warn("{} frame(s) flagged: their result disagrees with what the silhouettes imply (the "
              "warnings above, and \"flagged\" in their records)",
              flagged.load());
  }
}

}  // namespace fourd::reconstruct
