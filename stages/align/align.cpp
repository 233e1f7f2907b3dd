#include "stages/align/align.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_for_each.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/log.h"
#include "pipeline/core/mesh_io.h"
#include "stages/align/mesh_tools.h"
#include "stages/align/shape_tree.h"
#include "stages/align/surface_query.h"

namespace fourd::align {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// One input frame and what pass 1 learned about it.
struct FrameData {
  FrameStatus status;
  fs::path file;
  bool usable = false;  // readable, non-empty and (if required) manifold
  ShapeDescriptor descriptor;
};

bool parse_frame_number(const std::string& stem, int* frame) {
  if (stem.empty() || stem.size() > 9) return false;
  for (char c : stem) {
    if (!std::isdigit(static_cast<unsigned char>(c))) return false;
  }
  *frame = std::stoi(stem);
  return true;
}

// <dir>/<take>/<frame>.ply for every take folder, frames in numeric order.
std::vector<FrameData> list_frames(const fs::path& dir, const FrameSelection& selection) {
  if (!fs::is_directory(dir)) {
    throw InputError(fmt::format("{}: no such folder (run the reconstruct stage first)", dir.string()));
  }
  std::vector<fs::path> takes;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.is_directory()) takes.push_back(entry.path());
  }
  std::sort(takes.begin(), takes.end());
  std::vector<FrameData> frames;
  for (const fs::path& take_dir : takes) {
    const std::string take = take_dir.filename().string();
    std::vector<std::pair<int, fs::path>> files;
    for (const auto& entry : fs::directory_iterator(take_dir)) {
      int frame = 0;
      if (entry.is_regular_file() && entry.path().extension() == ".ply" &&
          parse_frame_number(entry.path().stem().string(), &frame) && selection.selects(take, frame)) {
        files.emplace_back(frame, entry.path());
      }
    }
    std::sort(files.begin(), files.end());
    for (const auto& [frame, file] : files) {
      FrameData f;
      f.status.take = take;
      f.status.frame = frame;
      f.file = file;
      frames.push_back(std::move(f));
    }
  }
  if (frames.empty()) {
    throw InputError(fmt::format("{}: no <take>/<frame>.ply meshes to align", dir.string()));
  }
  return frames;
}

std::string frame_label(const FrameStatus& s) { return s.take + "/" + frame_name(s.frame); }

Mesh load_frame(const FrameData& f) {
  Mesh mesh = read_ply(f.file);
  mesh.check(f.file.string());
  Mesh out;
  out.positions = std::move(mesh.positions);
  out.triangles = std::move(mesh.triangles);
  return out;
}

// Pass 1: reads every frame, flags the ones that cannot be used, and computes the shape
// histograms of the others.
void inspect_frames(std::vector<FrameData>& frames, const AlignOptions& options) {
  log::Progress progress("shape histograms", frames.size());
  tbb::parallel_for(std::size_t{0}, frames.size(), [&](std::size_t i) {
    FrameData& f = frames[i];
    Mesh mesh;
    try {
      mesh = load_frame(f);
    } catch (const Error& e) {
      f.status.flags.push_back("unreadable");
      f.status.error = e.what();
      progress.step();
      return;
    }
    if (mesh.empty()) {
      f.status.flags.push_back("empty");
      f.status.error = "the mesh has no triangles (failed reconstruction?)";
      progress.step();
      return;
    }
    const ManifoldReport manifold = check_manifold(mesh);
    bool usable = true;
    if (!manifold.manifold()) {
      f.status.flags.push_back("non_manifold");
      f.status.error = fmt::format("not manifold: {} edges shared by more than two triangles, {} "
                                   "triangles a halfedge mesh cannot hold",
                                   manifold.non_manifold_edges, manifold.rejected_faces);
      usable = !options.exclude_non_manifold;
    }
    f.descriptor = compute_shape_descriptor(mesh, options.descriptor);
    if (f.descriptor.volume <= 0) {
      f.status.flags.push_back("empty");
      f.status.error = "the mesh encloses no volume (open or degenerate surface)";
      usable = false;
    }
    f.usable = usable;
    progress.step();
  });
}

// Takes of different characters cannot share a template: their volumes give them away.
void check_one_character(const std::vector<FrameData>& frames, double max_ratio) {
  std::map<std::string, std::vector<double>> volumes;
  for (const FrameData& f : frames) {
    if (f.usable) volumes[f.status.take].push_back(f.descriptor.volume);
  }
  std::string small_take, large_take;
  double small = std::numeric_limits<double>::infinity(), large = 0;
  for (auto& [take, v] : volumes) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    const double median = v[v.size() / 2];
    if (median < small) small = median, small_take = take;
    if (median > large) large = median, large_take = take;
  }
  if (volumes.size() > 1 && large > max_ratio * small) {
    throw InputError(fmt::format(
        "takes '{}' (median volume {:.4f} m^3) and '{}' ({:.4f} m^3) differ by a factor of {:.2f}: "
        "they look like different characters, which cannot share one template. Align each "
        "character in its own session (or raise stages.align.max_volume_ratio, now {}).",
        large_take, large, small_take, small, large / small, max_ratio));
  }
}

// Rotation about the up axis by `shift` histogram sectors, taking `from`'s centroid to `to`'s.
Eigen::Isometry3d heading_motion(const ShapeDescriptor& from, const ShapeDescriptor& to, int shift,
                                 const DescriptorOptions& d) {
  const double angle = 2 * M_PI * shift / d.sectors;
  const Eigen::Vector3d axis = Eigen::Vector3d::Unit(d.up_axis);
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.translate(to.centroid);
  m.rotate(Eigen::AngleAxisd(angle, axis));
  m.translate(-from.centroid);
  return m;
}

struct Fit {
  DeformationState state;
  FitStats stats;
  double seconds = 0;
};

// Root-mean-square distance of (a subset of) points to the target, truncated at `cap`.
double truncated_rms(const std::vector<Vec3f>& points, const SurfaceQuery& target, float cap) {
  double sum = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < points.size(); i += 4, ++n) {
    SurfaceHit hit = target.closest(points[i], cap);
    const double d = hit.found ? hit.distance : cap;
    sum += d * d;
  }
  return n ? std::sqrt(sum / n) : 0.0;
}

// Registers the template to `child`, starting from `parent_state` (the parent's fit) moved
// by the better of two rigid guesses: the heading change the shape histograms found, and
// none (histograms of near-symmetric poses can mistake front for back).
Fit register_frame(const TemplateModel& model, const DeformationState& parent_state,
                   const ShapeDescriptor* parent_descriptor, const FrameData& child, int shift,
                   const AlignOptions& options) {
  log::Timer timer;
  const Mesh mesh = load_frame(child);
  const SurfaceQuery target(mesh);
  const RegistrationOptions& reg = options.registration;

  DeformationState start = parent_state;
  if (parent_descriptor) {
    std::vector<int> shifts{shift};
    if (shift != 0) shifts.push_back(0);
    double best_score = std::numeric_limits<double>::infinity();
    for (int s : shifts) {
      DeformationState candidate = parent_state;
      apply_rigid(model, heading_motion(*parent_descriptor, child.descriptor, s, options.descriptor),
                  &candidate);
      const Eigen::Isometry3d refine =
          rigid_icp(candidate.positions, vertex_normals(candidate.positions, model.rest.triangles),
                    target, reg.rigid_iterations, reg.max_distance, reg);
      apply_rigid(model, refine, &candidate);
      const double score = truncated_rms(candidate.positions, target, static_cast<float>(reg.max_distance));
      if (score < best_score) {
        best_score = score;
        start = std::move(candidate);
      }
    }
  }
  RegistrationOptions no_rigid = reg;
  no_rigid.rigid_iterations = 0;  // done above
  Fit fit;
  fit.state = register_to_surface(model, start, target, no_rigid);
  fit.stats = evaluate_fit(model, fit.state.positions, target, reg);
  fit.seconds = timer.seconds();
  return fit;
}

std::string fit_failure(const FitStats& s, const AlignOptions& options) {
  if (!(s.surface_rms <= options.max_surface_rms)) {
    return fmt::format("fit rms {:.1f} mm exceeds {:.1f} mm", 1e3 * s.surface_rms,
                       1e3 * options.max_surface_rms);
  }
  if (!(s.uncovered_fraction <= options.max_uncovered_fraction)) {
    return fmt::format("{:.1f}% of the frame is farther than {:.0f} mm from the fit (limit {:.1f}%)",
                       100 * s.uncovered_fraction, 1e3 * options.registration.coverage_distance,
                       100 * options.max_uncovered_fraction);
  }
  return {};
}

Mesh fitted_mesh(const TemplateModel& model, const std::vector<Vec3f>& positions) {
  Mesh m;
  m.positions = positions;
  m.triangles = model.rest.triangles;
  return m;
}

int find_root(const std::vector<FrameData>& frames, const std::vector<int>& usable,
              const std::string& name) {
  for (std::size_t k = 0; k < usable.size(); ++k) {
    const FrameStatus& s = frames[usable[k]].status;
    if (frame_label(s) == name || s.take + "/" + std::to_string(s.frame) == name) {
      return static_cast<int>(k);
    }
  }
  throw ConfigError(fmt::format(
      "stages.align.root: '{}' is not a usable input frame (expected <take>/<frame>)", name));
}

json fit_json(const FitStats& s) {
  return {{"surface_rms_mm", 1e3 * s.surface_rms},
          {"surface_p95_mm", 1e3 * s.surface_p95},
          {"surface_max_mm", 1e3 * s.surface_max},
          {"reverse_rms_mm", 1e3 * s.reverse_rms},
          {"uncovered_fraction", s.uncovered_fraction},
          {"flipped_triangles", s.flipped_triangles}};
}

// Deletes <out>/<take>/*.ply files this run did not write (frames excluded now, takes gone).
void remove_stale_frames(const fs::path& out, const std::set<fs::path>& written) {
  if (!fs::is_directory(out)) return;
  for (const auto& take : fs::directory_iterator(out)) {
    if (!take.is_directory() || take.path().filename() == "sequential") continue;
    for (const auto& file : fs::directory_iterator(take.path())) {
      if (file.path().extension() == ".ply" && !written.count(file.path())) fs::remove(file.path());
    }
  }
}

// The frame-to-frame baseline: each take registered in time order, each frame from the one
// before (the first from the template, moved by the histograms' rigid guess).
json run_sequential(const TemplateModel& model, const ShapeDescriptor& root_descriptor,
                    const std::vector<FrameData>& frames, const AlignOptions& options,
                    const fs::path& out) {
  std::map<std::string, std::vector<int>> takes;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (frames[i].usable) takes[frames[i].status.take].push_back(static_cast<int>(i));
  }
  std::vector<std::string> names;
  for (const auto& [take, list] : takes) names.push_back(take);
  std::vector<json> per_take(names.size());
  log::Progress progress("sequential baseline", frames.size());
  tbb::parallel_for(std::size_t{0}, names.size(), [&](std::size_t t) {
    json list = json::array();
    DeformationState state = rest_state(model);
    const ShapeDescriptor* previous = &root_descriptor;
    for (int i : takes[names[t]]) {
      const FrameData& f = frames[i];
      const int shift = shape_distance(f.descriptor, *previous, options.descriptor).shift;
      Fit fit;
      try {
        fit = register_frame(model, state, previous, f, shift, options);
      } catch (const SolverError& e) {
        list.push_back({{"take", f.status.take}, {"frame", f.status.frame}, {"error", e.what()}});
        progress.step();
        continue;
      }
      write_ply(out / f.status.take / (frame_name(f.status.frame) + ".ply"),
                fitted_mesh(model, fit.state.positions));
      json entry = fit_json(fit.stats);
      entry["take"] = f.status.take;
      entry["frame"] = f.status.frame;
      list.push_back(entry);
      state = std::move(fit.state);
      previous = &f.descriptor;
      progress.step();
    }
    per_take[t] = std::move(list);
  });
  json result = json::object();
  for (std::size_t t = 0; t < names.size(); ++t) result[names[t]] = per_take[t];
  return result;
}

}  // namespace

void run_align(const Session& session, const StageArgs& args) {
  AlignOptions options;
  session.stage_options("align", options);
  const fs::path in = stage_input_dir(session, args, "reconstruct");
  const fs::path out = stage_output_dir(session, args, "align");
  log::Timer total_timer;

  std::vector<FrameData> frames = list_frames(in, args.selection);
  log::info("align: {} frames from {}", frames.size(), in.string());
  inspect_frames(frames, options);
  for (const FrameData& f : frames) {
    if (!f.status.error.empty()) {
      log::warn("{}: {}{}", frame_label(f.status), f.status.error,
                f.usable ? " (used anyway: exclude_non_manifold is off)" : " - excluded");
    }
  }
  std::vector<int> usable;  // database index -> frame index
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (frames[i].usable) usable.push_back(static_cast<int>(i));
  }
  if (usable.empty()) throw InputError(fmt::format("{}: no usable frame to align", in.string()));
  check_one_character(frames, options.max_volume_ratio);

  // 1. Shape similarity and the tree.
  std::vector<ShapeDescriptor> descriptors;
  for (int i : usable) descriptors.push_back(frames[i].descriptor);
  log::Timer tree_timer;
  const DistanceMatrix distances = pairwise_shape_distances(descriptors, options.descriptor);
  const int forced_root = options.root.empty() ? -1 : find_root(frames, usable, options.root);
  const ShapeTree tree = minimum_spanning_tree(distances.value, forced_root);
  const int root = usable[tree.root];
  log::info("shape tree over {} frames in {:.1f} s: root {}, depth {}", usable.size(),
            tree_timer.seconds(), frame_label(frames[root].status),
            *std::max_element(tree.depth.begin(), tree.depth.end()));
  std::vector<double> edges;
  for (std::size_t k = 0; k < tree.parent.size(); ++k) {
    if (tree.parent[k] >= 0) edges.push_back(tree.edge_cost[k]);
  }
  double median_edge = 0;
  if (!edges.empty()) {
    std::nth_element(edges.begin(), edges.begin() + edges.size() / 2, edges.end());
    median_edge = edges[edges.size() / 2];
  }

  // 2. The template.
  log::Timer template_timer;
  const Mesh template_mesh =
      remesh_to_vertex_count(load_frame(frames[root]), options.template_vertices, options.remesh_iterations);
  ensure_directory(out);
  write_ply(out / "template.ply", template_mesh);
  // Every aligned frame is the template's topology: its file's size once per frame.
  require_free_space(out, fs::file_size(out / "template.ply") * frames.size(),
                     fmt::format("align's {} frames", frames.size()));
  const TemplateModel model = build_template_model(template_mesh, options.registration);
  log::info("template: {} vertices, {} triangles, {} graph nodes ({:.1f} s)",
            template_mesh.num_vertices(), template_mesh.num_triangles(),
            model.graph.node_vertex.size(), template_timer.seconds());

  // 3. Registration along the tree, independent branches in parallel.
  const int n = static_cast<int>(usable.size());
  std::vector<Fit> fits(n);
  std::vector<char> aligned(n, 0), attempted(n, 0), has_fit(n, 0);
  std::vector<int> parent_of(n, -1);  // database indices, as finally registered (or best tried)
  std::vector<std::set<int>> tried(n);
  std::set<fs::path> written;
  std::mutex written_mutex;
  auto write_frame = [&](int k) {
    const FrameStatus& s = frames[usable[k]].status;
    const fs::path file = out / s.take / (frame_name(s.frame) + ".ply");
    write_ply(file, fitted_mesh(model, fits[k].state.positions));
    std::lock_guard<std::mutex> lock(written_mutex);
    written.insert(file);
  };
  // Registers database frame k from database frame p (-1: the template at rest).
  auto attempt = [&](int k, int p) -> bool {
    FrameData& f = frames[usable[k]];
    tried[k].insert(p);
    attempted[k] = 1;
    Fit fit;
    try {
      if (p < 0) {
        fit = register_frame(model, rest_state(model), nullptr, f, 0, options);
      } else {
        fit = register_frame(model, fits[p].state, &descriptors[p], f, distances.shift(k, p), options);
      }
    } catch (const SolverError& e) {
      f.status.error = e.what();
      return false;
    }
    const std::string failure = fit_failure(fit.stats, options);
    if (!failure.empty()) {
      // Keep the best of the failed attempts (it may be kept, flagged, at the end).
      if (!has_fit[k] || fit.stats.surface_rms < fits[k].stats.surface_rms) {
        fits[k] = std::move(fit);
        parent_of[k] = p;
        has_fit[k] = 1;
      }
      f.status.error = failure;
      return false;
    }
    fits[k] = std::move(fit);
    has_fit[k] = 1;
    parent_of[k] = p;
    aligned[k] = 1;
    write_frame(k);
    return true;
  };

  {
    log::Progress progress("registering along the tree", n);
    std::vector<int> start{tree.root};
    tbb::parallel_for_each(start.begin(), start.end(), [&](int k, tbb::feeder<int>& feeder) {
      if (attempt(k, tree.parent[k])) {
        for (int c : tree.children[k]) feeder.add(c);
      }
      progress.step();
    });
  }
  for (int k = 0; k < n; ++k) {
    FrameStatus& s = frames[usable[k]].status;
    if (tree.parent[k] >= 0 && tree.edge_cost[k] > options.far_edge_factor * median_edge) {
      s.flags.push_back("far_from_parent");
    }
    if (attempted[k] && !aligned[k]) s.flags.push_back("registration_failed");
    if (!attempted[k]) s.flags.push_back("orphaned");
  }
  if (!aligned[tree.root]) {
    throw SolverError(fmt::format("align: the template does not fit its own frame {}: {}",
                                  frame_label(frames[root].status), frames[root].status.error));
  }

  // 4. Re-parenting: every frame not aligned yet (its fit failed, or its parent's did) is
  //    registered from the most similar aligned frame it has not tried, best pairs first.
  for (;;) {
    int best_k = -1, best_p = -1;
    double best = std::numeric_limits<double>::infinity();
    for (int k = 0; k < n; ++k) {
      if (aligned[k]) continue;
      const int failures = static_cast<int>(tried[k].size());
      if (failures > options.reparent_attempts) continue;
      for (int p = 0; p < n; ++p) {
        if (aligned[p] && !tried[k].count(p) && distances.value(k, p) < best) {
          best = distances.value(k, p);
          best_k = k;
          best_p = p;
        }
      }
    }
    if (best_k < 0) break;
    FrameStatus& s = frames[usable[best_k]].status;
    if (attempt(best_k, best_p)) {
      s.error.clear();
      s.flags.push_back("reparented");
      log::info("{}: re-parented to {}", frame_label(s), frame_label(frames[usable[best_p]].status));
    }
  }

  // 5. Frames whose every attempt failed: by default their best fit is kept and flagged (the
  //    motion stays complete for the stages after this one, and the report and validation show
  //    the frame's error); with keep_failed_fits off they are excluded.
  std::vector<char> kept(n, 0);
  if (options.keep_failed_fits) {
    for (int k = 0; k < n; ++k) {
      if (aligned[k] || !has_fit[k]) continue;
      kept[k] = 1;
      frames[usable[k]].status.flags.push_back("kept_failed_fit");
      write_frame(k);
    }
  }

  // Statuses for the report.
  for (int k = 0; k < n; ++k) {
    FrameStatus& s = frames[usable[k]].status;
    s.aligned = aligned[k] || kept[k];
    s.fit = fits[k].stats;
    s.seconds = fits[k].seconds;
    if (aligned[k] || kept[k]) {
      const int p = parent_of[k];
      s.parent = p >= 0 ? usable[p] : -1;
      s.parent_distance = p >= 0 ? distances.value(k, p) : 0.0;
    } else if (s.error.empty()) {
      s.error = "its parent could not be aligned and no other parent fitted";
    }
  }
  for (int k = 0; k < n; ++k) {  // depth along the parents actually used
    FrameStatus& s = frames[usable[k]].status;
    int depth = 0;
    for (int p = s.parent; p >= 0 && depth <= n; p = frames[p].status.parent) ++depth;
    if (s.aligned) s.depth = depth;
  }
  for (FrameData& f : frames) {
    if (!f.status.aligned) {
      log::warn("{}: excluded - {}", frame_label(f.status), f.status.error);
    } else if (!f.status.error.empty()) {
      log::warn("{}: kept, flagged - {}", frame_label(f.status), f.status.error);
    }
  }

  // 5. The baseline.
  json sequential;
  if (options.sequential_baseline) {
    sequential = run_sequential(model, frames[root].descriptor, frames, options, out / "sequential");
  }

  // Outputs.
  remove_stale_frames(out, written);
  const double seconds = total_timer.seconds();
  int aligned_count = 0, flagged_count = 0;
  double rms_sum = 0;
  int flipped = 0;
  json nodes = json::array(), per_frame = json::array(), excluded = json::array();
  for (const FrameData& f : frames) {
    const FrameStatus& s = f.status;
    json node = {{"take", s.take},     {"frame", s.frame},   {"aligned", s.aligned},
                 {"parent", s.parent}, {"depth", s.depth},   {"distance", s.parent_distance},
                 {"flags", s.flags}};
    if (s.aligned) {
      node["residual_mm"] = 1e3 * s.fit.surface_rms;
      ++aligned_count;
      rms_sum += s.fit.surface_rms * s.fit.surface_rms;
      flipped += s.fit.flipped_triangles;
      json entry = fit_json(s.fit);
      entry["take"] = s.take;
      entry["frame"] = s.frame;
      entry["seconds"] = s.seconds;
      entry["flags"] = s.flags;
      if (!s.error.empty()) {
        entry["error"] = s.error;
        ++flagged_count;
      }
      per_frame.push_back(entry);
    } else {
      excluded.push_back({{"take", s.take}, {"frame", s.frame}, {"reason", s.error}, {"flags", s.flags}});
    }
    nodes.push_back(node);
  }
  json tree_json = {{"version", 1},
                    {"root", root},
                    {"template", "template.ply"},
                    {"template_vertices", template_mesh.num_vertices()},
                    {"descriptor", "volumetric shape histogram, L2 distance minimised over rotation "
                                   "about the up axis"},
                    {"nodes", nodes}};
  write_file_atomic(out / "tree.json", tree_json.dump(1) + "\n");
  json report = {{"version", 1},
                 {"input", args.oracle ? "oracle" : "pipeline"},
                 {"frames", frames.size()},
                 {"aligned", aligned_count},
                 {"flagged", flagged_count},
                 {"excluded", excluded},
                 {"template_vertices", template_mesh.num_vertices()},
                 {"surface_rms_mm", aligned_count ? 1e3 * std::sqrt(rms_sum / aligned_count) : 0.0},
                 {"flipped_triangles", flipped},
                 {"seconds", seconds},
                 {"seconds_per_frame", seconds / static_cast<double>(frames.size())},
                 {"per_frame", per_frame}};
  if (options.sequential_baseline) report["sequential"] = sequential;
  write_file_atomic(out / "report.json", report.dump(1) + "\n");
  YAML::Emitter yaml;
  yaml << to_yaml(options);
  write_file_atomic(out / "options.yaml", std::string(yaml.c_str()) + "\n");
  log::info("aligned {} of {} frames ({} of them kept despite a failed fit, flagged), surface rms "
            "{:.2f} mm, {} flipped triangles, {:.2f} s per frame",
            aligned_count, frames.size(), flagged_count, report["surface_rms_mm"].get<double>(), flipped,
            seconds / static_cast<double>(frames.size()));
}

}  // namespace fourd::align
