#include "stages/timewarp/timewarp.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <regex>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/log.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/core/staged_folder.h"
#include "stages/timewarp/timewarp_io.h"

namespace fourd::timewarp {

LocalTake make_local_take(const std::string& name, std::vector<Eigen::Matrix3Xd> frames,
                          const Eigen::Matrix3Xd& template_positions,
                          const std::vector<double>& torso, int root_smoothing) {
  LocalTake take;
  take.name = name;
  take.raw_roots = estimate_roots(frames, template_positions, torso);
  take.roots = take.raw_roots;
  smooth_roots(&take.roots, root_smoothing);
  take.shapes.resize(frames.size());
  tbb::parallel_for(std::size_t{0}, frames.size(), [&](std::size_t f) {
    take.shapes[f] = remove_root(frames[f], take.roots[f]);
  });
  return take;
}

WarpedClass warp_class(const MotionClassConfig& motion, double fps, const Mesh& template_mesh,
                       std::vector<LocalTake> takes, const TimewarpOptions& options) {
  if (takes.size() < 2 || takes.size() > 3) {
    std::string names;
    for (const LocalTake& t : takes) names += (names.empty() ? "" : ", ") + t.name;
    throw InputError(fmt::format(
        "motion class {} has {} ({}); a parametric motion space blends 2 or 3 takes", motion.name,
        takes.size() == 1 ? "a single take" : fmt::format("{} takes", takes.size()), names));
  }
  const int nv = static_cast<int>(template_mesh.num_vertices());
  for (const LocalTake& t : takes) {
    if (t.num_frames() < 2) {
      throw InputError(fmt::format("motion class {}: take {} has {} frame(s); at least 2 needed",
                                   motion.name, t.name, t.num_frames()));
    }
    for (int f = 0; f < t.num_frames(); ++f) {
      if (t.shapes[f].cols() != nv) {
        throw InputError(fmt::format("motion class {}: take {} frame {} has {} vertices, the "
                                     "template has {}",
                                     motion.name, t.name, frame_name(f), t.shapes[f].cols(), nv));
      }
      if (!t.shapes[f].allFinite() || !t.roots[f].finite()) {
        throw InputError(fmt::format("motion class {}: take {} frame {} is not finite",
                                     motion.name, t.name, frame_name(f)));
      }
    }
  }

  WarpedClass out;
  out.name = motion.name;
  out.parameter = motion.parameter;
  out.cyclic = motion.cyclic;
  out.fps = fps;
  out.num_vertices = nv;
  out.triangles = template_mesh.triangles;
  out.template_positions = positions_matrix(template_mesh).cast<double>();
  out.character_height = body_height(out.template_positions);

  // Phase of every take: a closed cycle, or the whole take.
  std::vector<TakeTiming> timing(takes.size());
  std::vector<Cycle> cycles(takes.size());
  for (std::size_t k = 0; k < takes.size(); ++k) {
    if (motion.cyclic) {
      cycles[k] = find_cycle(takes[k], options.cycle());
      timing[k] = cyclic_timing(cycles[k]);
    } else {
      timing[k] = one_shot_timing(takes[k]);
    }
  }
  // Register every take to the first.
  std::vector<Warp> warps(takes.size());
  warps[0] = identity_warp(1);
  tbb::parallel_for(std::size_t{1}, takes.size(), [&](std::size_t k) {
    warps[k] = register_take(takes[0], timing[0], takes[k], timing[k], options.warp());
  });

  // Cycles are resampled on their steady roots (the per-step sway moves into the shapes); the
  // registration above compared the torso-aligned shapes, which that sway does not disturb.
  // A one-shot take's root is its real motion (a jump travels), kept as estimated.
  if (motion.cyclic) {
    tbb::parallel_for(std::size_t{0}, takes.size(), [&](std::size_t k) {
      takes[k] = steady_cycle_root(std::move(takes[k]), timing[k], options.cycle());
    });
  }

  int samples = options.samples;
  if (samples == 0) {
    double longest = 0;
    for (const TakeTiming& t : timing) longest = std::max(longest, t.length);
    // One sample per frame (a period a hair above a whole number of frames does not count).
    samples = static_cast<int>(std::ceil(longest - 0.05)) + 1;
  }
  samples = std::max(samples, 2);
  out.num_samples = samples;

  out.takes.resize(takes.size());
  tbb::parallel_for(std::size_t{0}, takes.size(), [&](std::size_t k) {
    const LocalTake& take = takes[k];
    const TakeTiming& tk = timing[k];
    const Warp& warp = warps[k];
    WarpedTake& w = out.takes[k];
    w.name = take.name;
    w.num_frames = take.num_frames();
    w.cycle = cycles[k];
    w.timing = tk;
    w.warp = warp;
    const double u0 = warp.at(0);
    const RootTransform root0 = root_at_phase(take, tk, u0);
    w.shapes.resize(static_cast<std::size_t>(samples) * nv);
    for (int i = 0; i < samples; ++i) {
      const double t = static_cast<double>(i) / (samples - 1);
      const double u = warp.at(t);
      w.sample_frames.push_back(tk.frame_at(u));
      w.seconds.push_back(tk.cyclic ? (u - u0) * tk.length / fps
                                    : (tk.frame_at(u) - tk.frame_at(u0)) / fps);
      w.roots.push_back(root_relative(root0, root_at_phase(take, tk, u)));
      // A cycle's last sample is its first: copy it, so the loop closes to the bit.
      const int source = (tk.cyclic && i == samples - 1) ? 0 : i;
      const Eigen::Matrix3Xd shape =
          source == i ? shape_at_phase(take, tk, u) : Eigen::Matrix3Xd();
      Vec3f* dst = w.shapes.data() + static_cast<std::size_t>(i) * nv;
      if (source == i) {
        for (int v = 0; v < nv; ++v) dst[v] = shape.col(v).cast<float>();
      } else {
        std::copy(w.shapes.begin(), w.shapes.begin() + nv, dst);
      }
    }
    // The class time of every captured frame.
    for (int f = 0; f < take.num_frames(); ++f) {
      if (tk.cyclic) {
        const double u = (f - tk.start) / tk.length - warp.offset;
        w.frame_t.push_back(warp.inverse(u - std::floor(u) + warp.offset));
      } else {
        w.frame_t.push_back(warp.inverse(static_cast<double>(f) / (take.num_frames() - 1)));
      }
    }
  });
  return out;
}

void run_timewarp(const Session& session, const StageArgs& args) {
  TimewarpOptions options;
  session.stage_options("timewarp", options);
  const SessionConfig& config = session.config();
  if (config.motions.empty()) {
    throw InputError(fmt::format("{}: no motion classes declared (motions:)",
                                 session.config_path().string()));
  }
  const std::filesystem::path in = stage_input_dir(session, args, "align");
  const std::filesystem::path out = stage_output_dir(session, args, "timewarp");
  log::info("reading aligned meshes from {}", in.string());
  const AlignedInput input = open_aligned_input(in);
  const Eigen::Matrix3Xd templ = positions_matrix(input.template_mesh).cast<double>();
  const std::vector<double> torso = torso_weights(templ);
  log::info("template: {} vertices, {} triangles, height {:.3f} m", templ.cols(),
            input.template_mesh.num_triangles(), body_height(templ));

  StagedFolder staged(out);
  nlohmann::json report = {{"classes", nlohmann::json::array()}};
  for (const MotionClassConfig& motion : config.motions) {
    log::Timer timer;
    std::vector<LocalTake> takes;
    for (const std::string& name : motion.takes) {
      takes.push_back(make_local_take(name, load_take(input, name), templ, torso, options.root_smoothing));
    }
    std::vector<TakeSegments> segments(takes.size());
    tbb::parallel_for(std::size_t{0}, takes.size(), [&](std::size_t k) {
      segments[k] = find_cycles(takes[k], options.cycle());
    });
    const WarpedClass warped = warp_class(motion, config.fps, input.template_mesh,
                                          std::move(takes), options);
    write_warped_class(staged.path() / (motion.name + ".twarp"), warped);
    write_file_atomic(staged.path() / (motion.name + ".json"),
                      warped_class_summary(warped).dump(1));
    for (const WarpedTake& t : warped.takes) {
      const RootTransform& end = t.roots.back();
      if (warped.cyclic) {
        log::info("{} / {}: cycle frames {:.2f}-{:.2f} ({:.2f} frames, closure {:.1f} mm, {:.0f} %), phase "
                  "offset {:.3f}, {:.2f} m/s, {:.1f} deg/s",
                  motion.name, t.name, t.cycle.start, t.cycle.start + t.cycle.period,
                  t.cycle.period, 1000 * t.cycle.closure_rms, 100 * t.cycle.closure_ratio, t.warp.offset,
                  std::hypot(end.x, end.y) / t.seconds.back(),
                  end.heading * 180 / std::numbers::pi / t.seconds.back());
      } else {
        log::info("{} / {}: {} frames, {:.2f} s, root displacement {:.3f} m", motion.name, t.name,
                  t.num_frames, t.seconds.back(), std::hypot(end.x, end.y));
      }
    }
    nlohmann::json report_class = {{"name", motion.name}, {"cyclic", motion.cyclic}};
    report_class["takes"] = nlohmann::json::array();
    for (std::size_t k = 0; k < warped.takes.size(); ++k) {
      const TakeSegments& seg = segments[k];
      report_class["takes"].push_back(take_segments_json(warped.takes[k].name,
                                                         warped.takes[k].num_frames, seg,
                                                         warped.cyclic ? &warped.takes[k].cycle
                                                                       : nullptr));
      log::info("{} / {}: period {:.2f} frames, {} cycle(s) that close, {} one-shot segment(s)",
                motion.name, warped.takes[k].name, seg.period, seg.cycles.size(),
                seg.one_shots.size());
    }
    report["classes"].push_back(std::move(report_class));
    log::info("{}: {} takes registered, {} samples ({:.1f} s)", motion.name, warped.takes.size(),
              warped.num_samples, timer.seconds());
  }
  write_file_atomic(staged.path() / "report.json", report.dump(1) + "\n");
  YAML::Emitter emitter;
  emitter << to_yaml(options);
  write_file_atomic(staged.path() / "options.yaml", std::string(emitter.c_str()) + "\n");
  staged.commit();
  log::info("wrote {}", out.string());
}

}  // namespace fourd::timewarp
