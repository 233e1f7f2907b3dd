#include "stages/align/align.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_for_each.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cctype>
#include <cmath>
#include <fmt/ranges.h>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <set>

#include "pipeline/core/binary_format.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/log.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/core/statistics.h"
#include "pipeline/core/subject.h"
#include "pipeline/geometry/measures.h"
#include "pipeline/geometry/remesh.h"
#include "pipeline/geometry/solid.h"
#include "pipeline/geometry/surface_query.h"
#include "stages/align/diagnosis.h"
#include "stages/align/shape_tree.h"

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
  out.confidence = std::move(mesh.confidence);
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
    f.status.handles = manifold.handles;
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
    const double m = median(v);
    if (m < small) small = m, small_take = take;
    if (m > large) large = m, large_take = take;
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
      log::debug("{}: heading guess {} sectors, rigid fit rms {:.1f} mm", frame_label(child.status), s,
                 1e3 * score);
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
          {"flipped_triangles", s.flipped_triangles},
          {"stretch_rms", s.stretch_rms}};
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

// ---- The tree-split jobs ---------------------------------------------------------------
//
// The stage runs as a tree job (shape histograms, tree, template, and the registration of the
// tree's top), branch jobs (each registers whole subtrees hanging off the top, independently
// of the others) and a finish job (re-parenting of what failed, the baseline, the reports).
// The jobs pass their state in <output>/.jobs/: plan.bin from the tree job, branch<K>.bin from
// each branch job. Every registration depends only on its parent's fit, so the result does not
// depend on how many branch jobs there are.

constexpr FileMagic kPlanMagic("FOURDAP");
constexpr FileMagic kBranchMagic("FOURDAB");
constexpr std::uint32_t kJobFileVersion = 2;

fs::path jobs_dir(const fs::path& out) { return out / ".jobs"; }
fs::path plan_file(const fs::path& out) { return jobs_dir(out) / "plan.bin"; }
fs::path branch_file(const fs::path& out, int branch) {
  return jobs_dir(out) / fmt::format("branch{}.bin", branch);
}

// Everything the tree job learned that the other jobs need.
struct Plan {
  std::uint64_t id = 0;      // ties branch results to the plan they were made from
  std::string options_yaml;  // the options it was made with: later jobs must see the same
  std::vector<FrameData> frames;
  std::vector<int> usable;   // database index -> frame index
  DistanceMatrix distances;  // between database frames
  ShapeTree tree;            // over database frames
  double median_edge = 0;
  int branches = 1;
  std::vector<int> job_of;   // database index -> branch job; -1: registered by the tree job
  double seconds = 0;        // the tree job's wall time
};

// The registrations of the database frames: what every attempt left.
struct Registrations {
  std::vector<Fit> fits;
  std::vector<char> aligned, attempted, has_fit;
  std::vector<int> parent_of;  // database indices, as finally registered (or best tried)
  std::vector<std::set<int>> tried;
  explicit Registrations(int n)
      : fits(n), aligned(n, 0), attempted(n, 0), has_fit(n, 0), parent_of(n, -1), tried(n) {}
};

std::string options_text(const AlignOptions& options) {
  YAML::Emitter yaml;
  yaml << to_yaml(options);
  return std::string(yaml.c_str()) + "\n";
}

void write_descriptor(BinaryWriter& w, const ShapeDescriptor& d) {
  w.write_vector(d.bins);
  w.write(d.centroid);
  w.write(d.volume);
}
ShapeDescriptor read_descriptor(BinaryReader& r) {
  ShapeDescriptor d;
  d.bins = r.read_vector<float>();
  d.centroid = r.read<Eigen::Vector3d>();
  d.volume = r.read<double>();
  return d;
}

// The registration records of database frames `ks` (those attempted).
void write_results(BinaryWriter& w, const Plan& plan, const Registrations& reg,
                   const std::vector<int>& ks) {
  std::vector<int> attempted;
  for (int k : ks) {
    if (reg.attempted[k]) attempted.push_back(k);
  }
  w.write<std::uint64_t>(attempted.size());
  for (int k : attempted) {
    w.write<int>(k);
    w.write<std::uint8_t>(reg.aligned[k]);
    w.write<std::uint8_t>(reg.has_fit[k]);
    w.write<int>(reg.parent_of[k]);
    w.write_vector(std::vector<int>(reg.tried[k].begin(), reg.tried[k].end()));
    w.write_string(plan.frames[plan.usable[k]].status.error);
    const Fit& fit = reg.fits[k];
    w.write_vector(fit.state.rotation);
    w.write_vector(fit.state.translation);
    w.write_vector(fit.state.positions);
    w.write(fit.stats);
    w.write(fit.seconds);
  }
}
void read_results(BinaryReader& r, Plan& plan, Registrations& reg, int vertices) {
  const auto count = r.read<std::uint64_t>();
  const int n = static_cast<int>(plan.usable.size());
  for (std::uint64_t i = 0; i < count; ++i) {
    const int k = r.read<int>();
    if (k < 0 || k >= n) {
      throw InputError(fmt::format("{}: frame index {} out of range", r.path().string(), k));
    }
    reg.attempted[k] = 1;
    reg.aligned[k] = r.read<std::uint8_t>();
    reg.has_fit[k] = r.read<std::uint8_t>();
    reg.parent_of[k] = r.read<int>();
    for (int p : r.read_vector<int>()) reg.tried[k].insert(p);
    plan.frames[plan.usable[k]].status.error = r.read_string();
    Fit& fit = reg.fits[k];
    fit.state.rotation = r.read_vector<Eigen::Matrix3d>();
    fit.state.translation = r.read_vector<Eigen::Vector3d>();
    fit.state.positions = r.read_vector<Vec3f>();
    fit.stats = r.read<FitStats>();
    fit.seconds = r.read<double>();
    if (reg.has_fit[k] && static_cast<int>(fit.state.positions.size()) != vertices) {
      throw InputError(fmt::format("{}: a fit of {} vertices for a template of {}",
                                   r.path().string(), fit.state.positions.size(), vertices));
    }
  }
}

void save_plan(const fs::path& file, const Plan& plan, const Registrations& reg) {
  BinaryWriter w;
  w.write(plan.id);
  w.write_string(plan.options_yaml);
  w.write<std::uint64_t>(plan.frames.size());
  for (const FrameData& f : plan.frames) {
    w.write_string(f.status.take);
    w.write<int>(f.status.frame);
    w.write_string(f.file.string());
    w.write<std::uint8_t>(f.usable);
    w.write<std::uint64_t>(f.status.flags.size());
    for (const std::string& flag : f.status.flags) w.write_string(flag);
    w.write_string(f.status.error);
    w.write<int>(f.status.handles);
    write_descriptor(w, f.descriptor);
  }
  w.write_vector(plan.usable);
  w.write_matrix(plan.distances.value);
  w.write_matrix(plan.distances.shift);
  w.write<int>(plan.tree.root);
  w.write_vector(plan.tree.parent);
  w.write_vector(plan.tree.edge_cost);
  w.write_vector(plan.tree.depth);
  w.write_vector(plan.tree.order);
  w.write(plan.median_edge);
  w.write<int>(plan.branches);
  w.write_vector(plan.job_of);
  w.write(plan.seconds);
  std::vector<int> top;
  for (int k = 0; k < static_cast<int>(plan.usable.size()); ++k) {
    if (plan.job_of[k] < 0) top.push_back(k);
  }
  write_results(w, plan, reg, top);
  w.save(file, kPlanMagic, kJobFileVersion);
}

// Reads the plan, the tree job's registrations and the template; checks the plan against the
// options in force.
Plan load_plan(const fs::path& out, const AlignOptions& options, Registrations* reg,
               Mesh* template_mesh) {
  const fs::path file = plan_file(out);
  if (!fs::is_regular_file(file)) {
    throw InputError(fmt::format("{}: no plan (run the --tree job first)", file.string()));
  }
  BinaryReader r = BinaryReader::open(file, kPlanMagic, {kJobFileVersion});
  Plan plan;
  plan.id = r.read<std::uint64_t>();
  plan.options_yaml = r.read_string();
  if (plan.options_yaml != options_text(options)) {
    throw InputError(fmt::format("{}: made with other align options than session.yaml's now: "
                                 "rerun the --tree job",
                                 file.string()));
  }
  plan.frames.resize(r.read<std::uint64_t>());
  for (FrameData& f : plan.frames) {
    f.status.take = r.read_string();
    f.status.frame = r.read<int>();
    f.file = r.read_string();
    f.usable = r.read<std::uint8_t>();
    f.status.flags.resize(r.read<std::uint64_t>());
    for (std::string& flag : f.status.flags) flag = r.read_string();
    f.status.error = r.read_string();
    f.status.handles = r.read<int>();
    f.descriptor = read_descriptor(r);
  }
  plan.usable = r.read_vector<int>();
  plan.distances.value = r.read_matrix<Eigen::MatrixXd>();
  plan.distances.shift = r.read_matrix<Eigen::MatrixXi>();
  plan.tree.root = r.read<int>();
  plan.tree.parent = r.read_vector<int>();
  plan.tree.edge_cost = r.read_vector<double>();
  plan.tree.depth = r.read_vector<int>();
  plan.tree.order = r.read_vector<int>();
  plan.median_edge = r.read<double>();
  plan.branches = r.read<int>();
  plan.job_of = r.read_vector<int>();
  plan.seconds = r.read<double>();
  const std::size_t n = plan.usable.size();
  bool consistent = n > 0 && plan.distances.value.rows() == static_cast<Eigen::Index>(n) &&
                    plan.distances.value.cols() == static_cast<Eigen::Index>(n) &&
                    plan.distances.shift.rows() == static_cast<Eigen::Index>(n) &&
                    plan.distances.shift.cols() == static_cast<Eigen::Index>(n) &&
                    plan.tree.parent.size() == n && plan.tree.edge_cost.size() == n &&
                    plan.tree.depth.size() == n && plan.job_of.size() == n &&
                    plan.tree.root >= 0 && plan.tree.root < static_cast<int>(n) &&
                    plan.branches >= 1;
  for (int i : plan.usable) consistent = consistent && i >= 0 && i < static_cast<int>(plan.frames.size());
  for (std::size_t k = 0; consistent && k < n; ++k) {
    const int p = plan.tree.parent[k];
    consistent = p >= -1 && p < static_cast<int>(n) && plan.job_of[k] >= -1 &&
                 plan.job_of[k] < plan.branches;
  }
  if (!consistent) throw InputError(fmt::format("{}: inconsistent plan", file.string()));
  plan.tree.children.assign(n, {});
  for (std::size_t k = 0; k < n; ++k) {
    if (plan.tree.parent[k] >= 0) plan.tree.children[plan.tree.parent[k]].push_back(static_cast<int>(k));
  }
  *template_mesh = read_ply(out / "template.ply");
  *reg = Registrations(static_cast<int>(n));
  read_results(r, plan, *reg, static_cast<int>(template_mesh->num_vertices()));
  r.expect_end();
  return plan;
}

// Cuts the tree into `branches` jobs of whole subtrees. The top of the tree (the root, and
// nodes split further while there are fewer subtrees than jobs or one subtree is much larger
// than a job's share, at most a tenth of the frames) is registered by the tree job; its
// subtrees go to the least loaded job, largest first.
std::vector<int> assign_branches(const ShapeTree& tree, int branches) {
  const int n = static_cast<int>(tree.parent.size());
  std::vector<int> size(n, 1);
  for (auto it = tree.order.rbegin(); it != tree.order.rend(); ++it) {
    if (tree.parent[*it] >= 0) size[tree.parent[*it]] += size[*it];
  }
  std::vector<int> job_of(n, -1);
  std::vector<int> frontier = tree.children[tree.root];
  int top = 1;
  const int top_budget = std::max(1, n / 10);
  const double share = static_cast<double>(n) / branches;
  while (top < top_budget && !frontier.empty()) {
    auto largest = std::max_element(frontier.begin(), frontier.end(),
                                    [&](int a, int b) { return size[a] < size[b]; });
    const bool too_few = static_cast<int>(frontier.size()) < branches;
    if (size[*largest] <= 1 || (!too_few && size[*largest] <= 1.5 * share)) break;
    const int node = *largest;
    frontier.erase(largest);
    ++top;
    frontier.insert(frontier.end(), tree.children[node].begin(), tree.children[node].end());
  }
  std::sort(frontier.begin(), frontier.end(), [&](int a, int b) {
    return size[a] != size[b] ? size[a] > size[b] : a < b;
  });
  std::vector<int> load(branches, 0);
  for (int s : frontier) {
    const int job = static_cast<int>(std::min_element(load.begin(), load.end()) - load.begin());
    load[job] += size[s];
    // The whole subtree of s.
    std::vector<int> stack{s};
    while (!stack.empty()) {
      const int k = stack.back();
      stack.pop_back();
      job_of[k] = job;
      stack.insert(stack.end(), tree.children[k].begin(), tree.children[k].end());
    }
  }
  return job_of;
}

// Registers frames along the tree and keeps what happened (attempt) in `reg`.
class TreeRegistration {
 public:
  TreeRegistration(const TemplateModel& model, Plan& plan, Registrations& reg,
                   const AlignOptions& options, fs::path out)
      : model_(model), plan_(plan), reg_(reg), options_(options), out_(std::move(out)) {}

  fs::path frame_file(int k) const {
    const FrameStatus& s = plan_.frames[plan_.usable[k]].status;
    return out_ / s.take / (frame_name(s.frame) + ".ply");
  }
  void write_frame(int k) const {
    write_ply(frame_file(k), fitted_mesh(model_, reg_.fits[k].state.positions));
  }

  // Registers database frame k from database frame p (-1: the template at rest); writes its
  // mesh when the fit passes.
  bool attempt(int k, int p) {
    FrameData& f = plan_.frames[plan_.usable[k]];
    reg_.attempted[k] = 1;
    reg_.tried[k].insert(p);
    Fit fit;
    try {
      fit = fit_from(k, p);
    } catch (const SolverError& e) {
      f.status.error = e.what();
      return false;
    }
    const std::string failure = fit_failure(fit.stats, options_);
    if (!failure.empty()) {
      // Keep the best of the failed attempts (it may be kept, flagged, at the end).
      if (!reg_.has_fit[k] || fit.stats.surface_rms < reg_.fits[k].stats.surface_rms) {
        reg_.fits[k] = std::move(fit);
        reg_.parent_of[k] = p;
        reg_.has_fit[k] = 1;
      }
      f.status.error = failure;
      return false;
    }
    reg_.fits[k] = std::move(fit);
    reg_.has_fit[k] = 1;
    reg_.parent_of[k] = p;
    reg_.aligned[k] = 1;
    f.status.error.clear();
    write_frame(k);
    return true;
  }

  // Registers aligned frame k again, from each of the aligned frames `parents`; of its fit and
  // the new ones that pass, keeps least_stretched_close_fit's choice. Returns whether that is a
  // new fit.
  bool refit(int k, const std::vector<int>& parents) {
    for (int p : parents) reg_.tried[k].insert(p);
    std::vector<std::optional<Fit>> tries(parents.size());
    tbb::parallel_for(std::size_t{0}, parents.size(), [&](std::size_t i) {
      try {
        tries[i] = fit_from(k, parents[i]);
      } catch (const SolverError&) {
      }
    });
    std::vector<FitStats> stats{reg_.fits[k].stats};
    std::vector<std::size_t> passed;  // stats[j + 1] is tries[passed[j]]'s
    for (std::size_t i = 0; i < parents.size(); ++i) {
      if (!tries[i]) continue;
      const bool ok = fit_failure(tries[i]->stats, options_).empty();
      log::debug("{} registered again from {}: rms {:.1f} mm, stretch {:.3f}{}",
                 frame_label(plan_.frames[plan_.usable[k]].status),
                 frame_label(plan_.frames[plan_.usable[parents[i]]].status),
                 1e3 * tries[i]->stats.surface_rms, tries[i]->stats.stretch_rms,
                 ok ? "" : " (failed)");
      if (!ok) continue;
      stats.push_back(tries[i]->stats);
      passed.push_back(i);
    }
    const std::size_t chosen =
        least_stretched_close_fit(stats, options_.registration.stretch_tolerance,
                                  options_.registration.stretch_margin);
    if (chosen == 0) return false;
    const std::size_t i = passed[chosen - 1];
    reg_.fits[k] = std::move(*tries[i]);
    reg_.parent_of[k] = parents[i];
    write_frame(k);
    return true;
  }

  // Fits of aligned frame k from each of the aligned frames `parents` that pass (in parallel;
  // recorded as tried), with the parent each came from.
  std::vector<std::pair<int, Fit>> passing_fits(int k, const std::vector<int>& parents) {
    for (int p : parents) reg_.tried[k].insert(p);
    std::vector<std::optional<Fit>> tries(parents.size());
    tbb::parallel_for(std::size_t{0}, parents.size(), [&](std::size_t i) {
      try {
        tries[i] = fit_from(k, parents[i]);
      } catch (const SolverError&) {
      }
    });
    std::vector<std::pair<int, Fit>> out;
    for (std::size_t i = 0; i < parents.size(); ++i) {
      if (tries[i] && fit_failure(tries[i]->stats, options_).empty()) {
        out.emplace_back(parents[i], std::move(*tries[i]));
      }
    }
    return out;
  }

  // Frame k takes `fit`, registered from p, and its mesh is written again.
  void adopt(int k, Fit fit, int p) {
    reg_.fits[k] = std::move(fit);
    reg_.parent_of[k] = p;
    write_frame(k);
  }

  // Registers the subtrees hanging from `starts` whose nodes belong to job `job`, each from
  // its tree parent, independent subtrees in parallel; a failed frame's subtree is left to
  // re-parenting (not attempted).
  void register_subtrees(const std::vector<int>& starts, int job, log::Progress& progress) {
    std::vector<int> start;
    for (int k : starts) {
      const int p = plan_.tree.parent[k];
      if (p < 0 || reg_.aligned[p]) start.push_back(k);
    }
    tbb::parallel_for_each(start.begin(), start.end(), [&](int k, tbb::feeder<int>& feeder) {
      if (attempt(k, plan_.tree.parent[k])) {
        for (int c : plan_.tree.children[k]) {
          if (plan_.job_of[c] == job) feeder.add(c);
        }
      }
      progress.step();
    });
  }

 private:
  // The fit of database frame k started from database frame p's (-1: the template at rest).
  // The caller records p in reg_.tried[k].
  Fit fit_from(int k, int p) {
    const FrameData& f = plan_.frames[plan_.usable[k]];
    if (p < 0) return register_frame(model_, rest_state(model_), nullptr, f, 0, options_);
    return register_frame(model_, reg_.fits[p].state, &plan_.frames[plan_.usable[p]].descriptor, f,
                          plan_.distances.shift(k, p), options_);
  }

  const TemplateModel& model_;
  Plan& plan_;
  Registrations& reg_;
  const AlignOptions& options_;
  fs::path out_;
};

std::uint64_t new_plan_id() {
  std::random_device device;
  return (static_cast<std::uint64_t>(device()) << 32) ^ device() ^
         static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
}

// The tree job: pass 1 over every frame, the tree, the template, the plan of branch jobs, and
// the registration of the tree's top.
void run_tree_job(const fs::path& in, const fs::path& out, const StageArgs& args,
                  const AlignOptions& options) {
  log::Timer timer;
  Plan plan;
  plan.id = new_plan_id();
  plan.options_yaml = options_text(options);
  plan.branches = args.branches;
  plan.frames = list_frames(in, args.selection);
  std::vector<FrameData>& frames = plan.frames;
  log::info("align: {} frames from {}", frames.size(), in.string());
  inspect_frames(frames, options);
  for (const FrameData& f : frames) {
    if (!f.status.error.empty()) {
      log::warn("{}: {}{}", frame_label(f.status), f.status.error,
                f.usable ? " (used anyway: exclude_non_manifold is off)" : " - excluded");
    }
  }
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (frames[i].usable) plan.usable.push_back(static_cast<int>(i));
  }
  if (plan.usable.empty()) throw InputError(fmt::format("{}: no usable frame to align", in.string()));
  check_one_character(frames, options.max_volume_ratio);

  // 1. Shape similarity and the tree.
  std::vector<ShapeDescriptor> descriptors;
  for (int i : plan.usable) descriptors.push_back(frames[i].descriptor);
  log::Timer tree_timer;
  plan.distances = pairwise_shape_distances(descriptors, options.descriptor);
  std::vector<int> handles;
  for (int i : plan.usable) handles.push_back(frames[i].status.handles);
  const int tree_root = options.root.empty()
                            ? central_frame(plan.distances.value, handles, options.root_tolerance)
                            : find_root(frames, plan.usable, options.root);
  plan.tree = minimum_spanning_tree(plan.distances.value, tree_root);
  const ShapeTree& tree = plan.tree;
  const int root = plan.usable[tree.root];
  log::info("shape tree over {} frames in {:.1f} s: root {} ({}, {} handles), depth {}",
            plan.usable.size(), tree_timer.seconds(), frame_label(frames[root].status),
            options.root.empty() ? "most central" : "chosen", frames[root].status.handles,
            *std::max_element(tree.depth.begin(), tree.depth.end()));
  std::vector<double> edges;
  for (std::size_t k = 0; k < tree.parent.size(); ++k) {
    if (tree.parent[k] >= 0) edges.push_back(tree.edge_cost[k]);
  }
  plan.median_edge = median(edges);
  plan.job_of = assign_branches(tree, plan.branches);

  // 2. The template.
  log::Timer template_timer;
  const Mesh root_frame = load_frame(frames[root]);
  Mesh root_mesh = root_frame;
  if (options.handle_voxel > 0) {
    const int before = frames[root].status.handles;  // counted by inspect_frames
    root_mesh = remove_small_handles(root_mesh, options.handle_voxel, options.handle_radius);
    const int after = check_manifold(root_mesh).handles;
    if (after != before) log::info("template: handles of the root frame {} -> {}", before, after);
  }
  Mesh template_mesh = remesh_to_vertex_count(root_mesh, options.template_vertices,
                                              options.remesh_iterations);
  if (!root_frame.confidence.empty()) {
    // The template keeps its frame's confidence: low where the root frame is a membrane.
    const SurfaceQuery root_surface(root_frame);
    template_mesh.confidence.resize(template_mesh.num_vertices());
    for (std::size_t i = 0; i < template_mesh.num_vertices(); ++i) {
      template_mesh.confidence[i] =
          root_surface.closest(template_mesh.positions[i], std::numeric_limits<float>::max())
              .confidence;
    }
  }
  ensure_directory(out);
  write_ply(out / "template.ply", template_mesh);
  // Every aligned frame is the template's topology: its file's size once per frame.
  require_free_space(out, fs::file_size(out / "template.ply") * frames.size(),
                     fmt::format("align's {} frames", frames.size()));
  const TemplateModel model = build_template_model(template_mesh, options.registration);
  const auto creased = std::count_if(model.node_softness.begin(), model.node_softness.end(),
                                     [](double s) { return s < 0.5; });
  log::info("template: {} vertices, {} triangles, {} graph nodes ({} in creases, regulariser "
            "below half) ({:.1f} s)",
            template_mesh.num_vertices(), template_mesh.num_triangles(),
            model.graph.node_vertex.size(), creased, template_timer.seconds());

  // 3. The top of the tree.
  const int n = static_cast<int>(plan.usable.size());
  int top = 0;
  for (int j : plan.job_of) top += j < 0;
  Registrations reg(n);
  TreeRegistration registration(model, plan, reg, options, out);
  {
    log::Progress progress("registering the top of the tree", top);
    registration.register_subtrees({tree.root}, -1, progress);
  }
  std::vector<int> load(plan.branches, 0);
  for (int j : plan.job_of) {
    if (j >= 0) ++load[j];
  }
  log::info("{} frames registered here; branch jobs: {} frames", top, fmt::join(load, ", "));
  plan.seconds = timer.seconds();
  save_plan(plan_file(out), plan, reg);
}

// Branch job `branch`: registers its subtrees from the top's fits.
void run_branch_job(const fs::path& out, int branch, const AlignOptions& options) {
  log::Timer timer;
  Registrations reg(0);
  Mesh template_mesh;
  Plan plan = load_plan(out, options, &reg, &template_mesh);
  if (branch >= plan.branches) {
    throw UsageError(fmt::format("--branch {}: the plan has {} branch jobs (0 to {})", branch,
                                 plan.branches, plan.branches - 1));
  }
  const TemplateModel model = build_template_model(template_mesh, options.registration);
  std::vector<int> starts, mine;
  const int n = static_cast<int>(plan.usable.size());
  for (int k = 0; k < n; ++k) {
    if (plan.job_of[k] != branch) continue;
    mine.push_back(k);
    const int p = plan.tree.parent[k];
    if (p >= 0 && plan.job_of[p] != branch) starts.push_back(k);
  }
  TreeRegistration registration(model, plan, reg, options, out);
  {
    log::Progress progress(fmt::format("branch job {} of {}", branch, plan.branches), mine.size());
    registration.register_subtrees(starts, branch, progress);
  }
  BinaryWriter w;
  w.write(plan.id);
  w.write<int>(branch);
  w.write(timer.seconds());
  write_results(w, plan, reg, mine);
  w.save(branch_file(out, branch), kBranchMagic, kJobFileVersion);
}

// True when a's parent chain (in `reg`) passes through k.
bool descends_from(const Registrations& reg, int a, int k) {
  const int n = static_cast<int>(reg.parent_of.size());
  for (int p = reg.parent_of[a], steps = 0; p >= 0 && steps <= n; p = reg.parent_of[p], ++steps) {
    if (p == k) return true;
  }
  return false;
}

// Outlier fits: an aligned frame whose rms is more than outlier_rms_factor x the median of the
// aligned frames' passed, but is most likely a wrong fit (a leg on the other leg, an arm slid
// along itself). It is registered again from its neighbours in time and from the most similar
// other aligned frames (not its own descendants, which started from its fit); of its fits, the
// least stretched of the about closest is kept (least_stretched_close_fit), and the frames
// registered from a refitted frame are registered again from its new fit, each keeping the same
// rule's choice of its two fits.
// Parents to register frame k from again: its neighbours in time first, then the `similar` most
// similar frames by shape distance; each aligned, not k's descendant and `eligible`.
std::vector<int> retry_parents(const Plan& plan, const Registrations& reg, int k, int similar_count,
                               const std::function<bool(int)>& eligible) {
  const int n = static_cast<int>(plan.usable.size());
  const FrameStatus& s = plan.frames[plan.usable[k]].status;
  std::vector<int> candidates;
  std::vector<std::pair<double, int>> similar;
  for (int p = 0; p < n; ++p) {
    if (p == k || !reg.aligned[p] || !eligible(p) || descends_from(reg, p, k)) continue;
    const FrameStatus& o = plan.frames[plan.usable[p]].status;
    if (o.take == s.take && std::abs(o.frame - s.frame) == 1) {
      candidates.push_back(p);
    } else {
      similar.push_back({plan.distances.value(k, p), p});
    }
  }
  std::sort(similar.begin(), similar.end());
  for (int i = 0; i < similar_count && i < static_cast<int>(similar.size()); ++i) {
    candidates.push_back(similar[i].second);
  }
  return candidates;
}

void refit_outliers(Plan& plan, Registrations& reg, TreeRegistration& registration,
                    const AlignOptions& options) {
  const int n = static_cast<int>(plan.usable.size());
  auto status = [&](int k) -> FrameStatus& { return plan.frames[plan.usable[k]].status; };
  std::vector<double> rms;
  for (int k = 0; k < n; ++k) {
    if (reg.aligned[k]) rms.push_back(reg.fits[k].stats.surface_rms);
  }
  const double limit = options.outlier_rms_factor * median(rms);
  std::vector<int> outliers;
  for (int k = 0; k < n; ++k) {
    if (reg.aligned[k] && reg.fits[k].stats.surface_rms > limit) outliers.push_back(k);
  }
  std::sort(outliers.begin(), outliers.end(), [&](int a, int b) {
    return reg.fits[a].stats.surface_rms > reg.fits[b].stats.surface_rms;
  });
  for (int k : outliers) {
    FrameStatus& s = status(k);
    const FitStats first = reg.fits[k].stats;
    const double before = first.surface_rms;
    const std::vector<int> candidates = retry_parents(
        plan, reg, k, options.reparent_attempts, [&](int p) { return !reg.tried[k].count(p); });
    if (!registration.refit(k, candidates)) {
      s.flags.push_back("outlier_fit");
      log::warn("{}: fit rms {:.1f} mm, over the outlier limit {:.1f} mm; no fit from another "
                "parent is better (closer, or about as close and less stretched)",
                frame_label(s), 1e3 * before, 1e3 * limit);
      continue;
    }
    s.flags.push_back("refitted");
    log::info("{}: fit rms {:.1f} mm, over the outlier limit {:.1f} mm; refitted from {}: rms "
              "{:.1f} mm, stretch {:.3f} -> {:.3f}",
              frame_label(s), 1e3 * before, 1e3 * limit, frame_label(status(reg.parent_of[k])),
              1e3 * reg.fits[k].stats.surface_rms, first.stretch_rms,
              reg.fits[k].stats.stretch_rms);
    // The frames registered from k, and from those in turn, again from the new fits.
    std::vector<int> redo{k};
    while (!redo.empty()) {
      const int p = redo.back();
      redo.pop_back();
      for (int c = 0; c < n; ++c) {
        if (!reg.aligned[c] || reg.parent_of[c] != p || c == k) continue;
        const double old_rms = reg.fits[c].stats.surface_rms;
        if (registration.refit(c, {p})) {
          status(c).flags.push_back("refitted");
          log::info("{}: registered again from the new fit of {}: rms {:.1f} -> {:.1f} mm",
                    frame_label(status(c)), frame_label(status(p)), 1e3 * old_rms,
                    1e3 * reg.fits[c].stats.surface_rms);
          redo.push_back(c);
        }
      }
    }
  }
}

// Patches the template is cut into for the self-diagnosis: about a limb segment each on a
// human (a forearm, a shin), small enough that one wrong patch stands out of its frame.
constexpr int kDiagnosisRegions = 24;

// The largest side of the mesh's bounding box [m] (a quadruped's length, a performer's height).
double size_of(const Mesh& mesh) {
  Vec3f lo, hi;
  bounding_box(mesh, &lo, &hi);
  return mesh.positions.empty() ? 0.0 : static_cast<double>((hi - lo).maxCoeff());
}

// The self-diagnosis of one aligned frame.
struct FrameDiagnosis {
  bool done = false;
  std::vector<RegionCues> cues;
  std::vector<RegionVerdict> verdicts;  // patches over a limit, worst first; empty: fine
  bool retried = false;                 // registered again from other parents after a verdict
};

// Diagnoses the frames with a fit (aligned, or kept despite a failed fit): the surface cues
// from the frame's input mesh, the jump cue from its take neighbours' fits (frames f-1 and
// f+1, both with a fit) over the take's median jump of the patch.
class Diagnoser {
 public:
  Diagnoser(const TemplateModel& model, const Plan& plan, const Registrations& reg,
            const std::vector<char>& has_result, const AlignOptions& options)
      : model_(model),
        regions_(make_regions(model, kDiagnosisRegions)),
        limits_(diagnosis_limits(size_of(model.rest))),
        plan_(plan),
        reg_(reg),
        options_(options),
        out_(plan.usable.size()) {
    const int n = static_cast<int>(plan.usable.size());
    log::Progress progress("self-diagnosis", n);
    tbb::parallel_for(0, n, [&](int k) {
      if (has_result[k]) {
        out_[k].cues = surface_cues(k, reg.fits[k].state.positions);
        out_[k].done = true;
      }
      progress.step();
    });
    for (int k = 0; k < n; ++k) {
      if (out_[k].done) index_[{status(k).take, status(k).frame}] = k;
    }
    std::map<std::string, std::vector<std::vector<double>>> take_jumps;  // take, patch -> jumps
    for (int k = 0; k < n; ++k) {
      if (!out_[k].done) continue;
      add_jumps(k, reg.fits[k].state.positions, &out_[k].cues);
      auto& per_patch = take_jumps[status(k).take];
      per_patch.resize(out_[k].cues.size());
      for (std::size_t r = 0; r < out_[k].cues.size(); ++r) {
        if (out_[k].cues[r].jump >= 0) per_patch[r].push_back(out_[k].cues[r].jump);
      }
    }
    for (auto& [take, per_patch] : take_jumps) {
      for (auto& jumps : per_patch) take_median_[take].push_back(median(jumps));
    }
    for (int k = 0; k < n; ++k) {
      if (!out_[k].done) continue;
      add_ratios(k, &out_[k].cues);
      out_[k].verdicts = judge(out_[k].cues, limits_);
    }
  }

  const TemplateRegions& regions() const { return regions_; }
  const DiagnosisLimits& limits() const { return limits_; }
  const FrameDiagnosis& operator[](int k) const { return out_[k]; }
  int size() const { return static_cast<int>(out_.size()); }

  // The cues of frame k were its fit `positions` (its neighbours' fits as they are now).
  std::vector<RegionCues> cues_of(int k, const std::vector<Vec3f>& positions) const {
    std::vector<RegionCues> cues = surface_cues(k, positions);
    add_jumps(k, positions, &cues);
    add_ratios(k, &cues);
    return cues;
  }
  // Frame k now has the fit `positions` (a retry's); its take neighbours' jumps change with it.
  void update(int k, const std::vector<Vec3f>& positions) {
    out_[k].cues = cues_of(k, positions);
    out_[k].verdicts = judge(out_[k].cues, limits_);
    out_[k].retried = true;
    const FrameStatus& s = status(k);
    for (int step : {-1, 1}) {
      const auto o = index_.find({s.take, s.frame + step});
      if (o == index_.end()) continue;
      FrameDiagnosis& d = out_[o->second];
      const std::vector<Vec3f>& fit = reg_.fits[o->second].state.positions;
      for (RegionCues& c : d.cues) c.jump = -1, c.jump_ratio = 0;
      add_jumps(o->second, fit, &d.cues);
      add_ratios(o->second, &d.cues);
      d.verdicts = judge(d.cues, limits_);
    }
  }
  void mark_retried(int k) { out_[k].retried = true; }

 private:
  const FrameStatus& status(int k) const { return plan_.frames[plan_.usable[k]].status; }
  std::vector<RegionCues> surface_cues(int k, const std::vector<Vec3f>& positions) const {
    const Mesh mesh = load_frame(plan_.frames[plan_.usable[k]]);
    const SurfaceQuery target(mesh);
    return region_cues(model_, regions_, positions, target, options_.registration.coverage_distance);
  }
  void add_jumps(int k, const std::vector<Vec3f>& positions, std::vector<RegionCues>* cues) const {
    const FrameStatus& s = status(k);
    const auto before = index_.find({s.take, s.frame - 1});
    const auto after = index_.find({s.take, s.frame + 1});
    if (before == index_.end() || after == index_.end()) return;
    const std::vector<double> jumps =
        region_jumps(regions_, positions, reg_.fits[before->second].state.positions,
                     reg_.fits[after->second].state.positions);
    for (std::size_t r = 0; r < jumps.size(); ++r) (*cues)[r].jump = jumps[r];
  }
  void add_ratios(int k, std::vector<RegionCues>* cues) const {
    const auto m = take_median_.find(status(k).take);
    if (m == take_median_.end()) return;
    for (std::size_t r = 0; r < cues->size(); ++r) {
      RegionCues& c = (*cues)[r];
      if (c.jump >= 0 && m->second[r] > 0) c.jump_ratio = c.jump / m->second[r];
    }
  }

  const TemplateModel& model_;
  TemplateRegions regions_;
  DiagnosisLimits limits_;
  const Plan& plan_;
  const Registrations& reg_;
  const AlignOptions& options_;
  std::vector<FrameDiagnosis> out_;
  std::map<std::pair<std::string, int>, int> index_;
  std::map<std::string, std::vector<double>> take_median_;
};

// Frames the self-diagnosis finds wrong, worst first, registered again from their neighbours
// in time and the most similar frames (each aligned, not fitted from the frame, `eligible`): the
// fit with the least badness is kept when its badness is under `keep_below` x the frame's, and
// the frame's take neighbours are diagnosed again (their jump cue measures against it).
void retry_frames(Plan& plan, Registrations& reg, TreeRegistration& registration,
                  Diagnoser& diagnoses, const AlignOptions& options, const char* what,
                  const std::function<bool(const FrameDiagnosis&)>& wrong_enough,
                  const std::function<bool(const FrameDiagnosis&)>& eligible, double keep_below) {
  const int n = diagnoses.size();
  auto status = [&](int k) -> FrameStatus& { return plan.frames[plan.usable[k]].status; };
  std::vector<std::pair<double, int>> wrong;
  for (int k = 0; k < n; ++k) {
    if (!reg.aligned[k] || !diagnoses[k].done || !wrong_enough(diagnoses[k])) continue;
    wrong.emplace_back(badness(diagnoses[k].cues, diagnoses.limits()), k);
  }
  std::sort(wrong.rbegin(), wrong.rend());
  if (!wrong.empty()) log::info("self-diagnosis: {} frames {}, registering them again", wrong.size(), what);
  for (const std::pair<double, int>& worst_first : wrong) {
    const int k = worst_first.second;
    const FrameStatus& s = status(k);
    // An earlier retry may have changed this frame's cues (a neighbour's new fit).
    const double before = badness(diagnoses[k].cues, diagnoses.limits());
    if (!wrong_enough(diagnoses[k])) continue;
    const int old_parent = reg.parent_of[k];
    const std::vector<int> candidates =
        retry_parents(plan, reg, k, options.reparent_attempts,
                      [&](int p) { return old_parent != p && eligible(diagnoses[p]); });
    diagnoses.mark_retried(k);
    std::vector<std::pair<int, Fit>> fits = registration.passing_fits(k, candidates);
    double best = keep_below * before;
    int chosen = -1;
    for (std::size_t i = 0; i < fits.size(); ++i) {
      const double b = badness(diagnoses.cues_of(k, fits[i].second.state.positions), diagnoses.limits());
      if (b < best) {
        best = b;
        chosen = static_cast<int>(i);
      }
    }
    if (chosen < 0) {
      log::debug("{}: no fit from {} other frames is less wrong", frame_label(s), candidates.size());
      continue;
    }
    const int parent = fits[chosen].first;
    log::info("{}: registered again from {}: badness {:.2f} -> {:.2f}", frame_label(s),
              frame_label(status(parent)), before, best);
    registration.adopt(k, std::move(fits[chosen].second), parent);
    std::vector<std::string>& flags = status(k).flags;
    if (std::find(flags.begin(), flags.end(), "refitted") == flags.end()) flags.push_back("refitted");
    diagnoses.update(k, reg.fits[k].state.positions);
  }
}

bool wrong_on_surface(const FrameDiagnosis& d) {
  return std::any_of(d.verdicts.begin(), d.verdicts.end(),
                     [](const RegionVerdict& r) { return r.cue != "jump"; });
}

// Every aligned frame diagnosed wrong on its surface (residual, uncovered, stretch or folds) is
// registered again from frames diagnosed fine. A frame wrong by its jump alone is not: on the
// default sample the jump named 395 of 407 patch verdicts of the oracle run, of frames mostly
// right (precision 0.23), and registering all 95 again changed 3 verdicts at 2.5x the stage's
// time.
void retry_wrong_frames(Plan& plan, Registrations& reg, TreeRegistration& registration,
                        Diagnoser& diagnoses, const AlignOptions& options) {
  retry_frames(plan, reg, registration, diagnoses, options, "wrong on their surface",
               wrong_on_surface, [](const FrameDiagnosis& d) { return d.verdicts.empty(); }, 1.0);
}

// A jump retry's fit replaces the frame's only when it is this much less bad: the retry is for a
// gross error (a limb on the other one: 13.4 -> 1.5 on second_body's walk_slow/11), and a fast
// limb's fits from other parents differ by a percent (fps_6's jump_long/7: 12.42 -> 12.39).
constexpr double kJumpRetryGain = 0.8;

// Every aligned frame with a patch that jumps from its take neighbours by more than
// `retry_jump_factor` x the jump limit is registered again from frames right on their surface
// (a neighbour's own jump cue is off when this frame is wrong). A limb fitted to the other
// one (second_body's walk_slow/11: both feet 0.3 m off, 13x the limit) is far beyond what the
// motion between two frames explains; a fast hand is not (at most 4-5x at 12 fps).
void retry_jumped_frames(Plan& plan, Registrations& reg, TreeRegistration& registration,
                         Diagnoser& diagnoses, const AlignOptions& options) {
  retry_frames(
      plan, reg, registration, diagnoses, options, "far from their neighbours in time",
      [&](const FrameDiagnosis& d) {
        return jumps_far(d.cues, diagnoses.limits(), options.retry_jump_factor);
      },
      [](const FrameDiagnosis& d) { return !wrong_on_surface(d); }, kJumpRetryGain);
}

json diagnosis_json(const FrameDiagnosis& d, const TemplateRegions& regions) {
  json wrong = json::array();
  for (const RegionVerdict& v : d.verdicts) {
    wrong.push_back({{"region", regions.names[v.region]}, {"cue", v.cue}, {"value", v.value},
                     {"limit", v.limit}});
  }
  json cues = json::array();
  for (const RegionCues& c : d.cues) {
    cues.push_back({1e3 * c.residual_p90, c.uncovered, c.stretch_rms, c.flipped,
                    c.jump < 0 ? -1.0 : 1e3 * c.jump, c.jump_ratio});
  }
  return {{"verdict", d.verdicts.empty() ? "ok" : "wrong"},
          {"retried", d.retried},
          {"wrong", wrong},
          {"cues", cues}};
}

// The branch jobs' results read into `reg` (and their frames' errors into `plan`). Returns the
// jobs' wall time, the tree job's included.
double read_branch_results(const fs::path& out, Plan& plan, Registrations& reg,
                           const Mesh& template_mesh) {
  double job_seconds = plan.seconds;
  for (int b = 0; b < plan.branches; ++b) {
    const fs::path file = branch_file(out, b);
    if (!fs::is_regular_file(file)) {
      throw InputError(fmt::format("{}: missing (run branch job {} first)", file.string(), b));
    }
    BinaryReader r = BinaryReader::open(file, kBranchMagic, {kJobFileVersion});
    if (r.read<std::uint64_t>() != plan.id || r.read<int>() != b) {
      throw InputError(fmt::format("{}: made from another plan than {} (rerun branch job {})",
                                   file.string(), plan_file(out).string(), b));
    }
    job_seconds += r.read<double>();
    read_results(r, plan, reg, static_cast<int>(template_mesh.num_vertices()));
    r.expect_end();
  }
  return job_seconds;
}

// The tree's outcome flagged on every frame; throws when the template does not fit its own
// frame (the root).
void flag_tree_outcome(Plan& plan, const Registrations& reg, const AlignOptions& options) {
  const ShapeTree& tree = plan.tree;
  const int n = static_cast<int>(plan.usable.size());
  for (int k = 0; k < n; ++k) {
    FrameStatus& s = plan.frames[plan.usable[k]].status;
    if (tree.parent[k] >= 0 && tree.edge_cost[k] > options.far_edge_factor * plan.median_edge) {
      s.flags.push_back("far_from_parent");
    }
    if (reg.attempted[k] && !reg.aligned[k]) s.flags.push_back("registration_failed");
    if (!reg.attempted[k]) s.flags.push_back("orphaned");
  }
  if (!reg.aligned[tree.root]) {
    const FrameStatus& root = plan.frames[plan.usable[tree.root]].status;
    throw SolverError(fmt::format("align: the template does not fit its own frame {}: {}",
                                  frame_label(root), root.error));
  }
}

// 4. Re-parenting: every frame not aligned yet (its fit failed, or its parent's did) is
//    registered from the most similar aligned frame it has not tried, best pairs first.
void reparent_unaligned(Plan& plan, const Registrations& reg, TreeRegistration& registration,
                        const AlignOptions& options) {
  const int n = static_cast<int>(plan.usable.size());
  for (;;) {
    int best_k = -1, best_p = -1;
    double best = std::numeric_limits<double>::infinity();
    for (int k = 0; k < n; ++k) {
      if (reg.aligned[k]) continue;
      const int failures = static_cast<int>(reg.tried[k].size());
      if (failures > options.reparent_attempts) continue;
      for (int p = 0; p < n; ++p) {
        if (reg.aligned[p] && !reg.tried[k].count(p) && plan.distances.value(k, p) < best) {
          best = plan.distances.value(k, p);
          best_k = k;
          best_p = p;
        }
      }
    }
    if (best_k < 0) break;
    FrameStatus& s = plan.frames[plan.usable[best_k]].status;
    if (registration.attempt(best_k, best_p)) {
      s.flags.push_back("reparented");
      log::info("{}: re-parented to {}", frame_label(s),
                frame_label(plan.frames[plan.usable[best_p]].status));
    }
  }
}

// 5. Frames whose every attempt failed: by default their best fit is kept and flagged (the
//    motion stays complete for the stages after this one, and the report and validation show
//    the frame's error); with keep_failed_fits off they are excluded. Fills `kept` (per
//    database frame) and returns the frame files written.
std::set<fs::path> keep_failed_fits(Plan& plan, const Registrations& reg,
                                    TreeRegistration& registration, const AlignOptions& options,
                                    std::vector<char>& kept) {
  const int n = static_cast<int>(plan.usable.size());
  kept.assign(n, 0);
  std::set<fs::path> written;
  for (int k = 0; k < n; ++k) {
    if (reg.aligned[k]) {
      written.insert(registration.frame_file(k));
    } else if (options.keep_failed_fits && reg.has_fit[k]) {
      kept[k] = 1;
      plan.frames[plan.usable[k]].status.flags.push_back("kept_failed_fit");
      registration.write_frame(k);
      written.insert(registration.frame_file(k));
    }
  }
  return written;
}

// Every database frame's status for the report: aligned (or kept), its fit and its parent.
void set_statuses(Plan& plan, const Registrations& reg, const std::vector<char>& kept) {
  const int n = static_cast<int>(plan.usable.size());
  for (int k = 0; k < n; ++k) {
    FrameStatus& s = plan.frames[plan.usable[k]].status;
    s.aligned = reg.aligned[k] || kept[k];
    s.fit = reg.fits[k].stats;
    s.seconds = reg.fits[k].seconds;
    if (s.aligned) {
      const int p = reg.parent_of[k];
      s.parent = p >= 0 ? plan.usable[p] : -1;
      s.parent_distance = p >= 0 ? plan.distances.value(k, p) : 0.0;
    } else if (s.error.empty()) {
      s.error = "its parent could not be aligned and no other parent fitted";
    }
  }
}

// The frames diagnosed wrong flagged, each with a warning naming its worst patch. Returns
// how many.
int flag_diagnosed(Plan& plan, const Diagnoser& diagnoses) {
  const TemplateRegions& regions = diagnoses.regions();
  const int n = static_cast<int>(plan.usable.size());
  int diagnosed_wrong = 0;
  for (int k = 0; k < n; ++k) {
    const FrameDiagnosis& d = diagnoses[k];
    if (!d.done || d.verdicts.empty()) continue;
    FrameStatus& s = plan.frames[plan.usable[k]].status;
    s.flags.push_back("diagnosed_wrong");
    ++diagnosed_wrong;
    const RegionVerdict& v = d.verdicts.front();
    log::warn("{}: diagnosed wrong{} - {} {}: {:.3g} over the limit {:.3g}{}", frame_label(s),
              d.retried ? " (also after registering it again from other frames)" : "",
              regions.names[v.region], v.cue, v.value, v.limit,
              d.verdicts.size() > 1 ? fmt::format(" (and {} more)", d.verdicts.size() - 1) : "");
  }
  return diagnosed_wrong;
}

// Every aligned frame's depth along the parents actually used; the excluded and flagged
// frames logged.
void set_depths(std::vector<FrameData>& frames, const std::vector<int>& usable) {
  const int n = static_cast<int>(usable.size());
  for (int k = 0; k < n; ++k) {
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
}

// The per-frame tables of tree.json and report.json, and their totals.
struct FrameTables {
  int aligned = 0, flagged = 0, flipped = 0;
  double rms_sum = 0;
  json nodes = json::array(), per_frame = json::array(), excluded = json::array();
};

FrameTables frame_tables(const Plan& plan, const Diagnoser& diagnoses) {
  const std::vector<FrameData>& frames = plan.frames;
  std::vector<int> database_index(frames.size(), -1);
  for (int k = 0; k < static_cast<int>(plan.usable.size()); ++k) database_index[plan.usable[k]] = k;
  FrameTables t;
  for (const FrameData& f : frames) {
    const FrameStatus& s = f.status;
    json node = {{"take", s.take},     {"frame", s.frame},   {"aligned", s.aligned},
                 {"parent", s.parent}, {"depth", s.depth},   {"distance", s.parent_distance},
                 {"flags", s.flags}, {"handles", s.handles}};
    if (s.aligned) {
      node["residual_mm"] = 1e3 * s.fit.surface_rms;
      ++t.aligned;
      t.rms_sum += s.fit.surface_rms * s.fit.surface_rms;
      t.flipped += s.fit.flipped_triangles;
      json entry = fit_json(s.fit);
      entry["take"] = s.take;
      entry["frame"] = s.frame;
      entry["seconds"] = s.seconds;
      entry["flags"] = s.flags;
      if (!s.error.empty()) {
        entry["error"] = s.error;
        ++t.flagged;
      }
      const int k = database_index[&f - frames.data()];
      if (k >= 0 && diagnoses[k].done) {
        entry["diagnosis"] = diagnosis_json(diagnoses[k], diagnoses.regions());
      }
      t.per_frame.push_back(entry);
    } else {
      t.excluded.push_back(
          {{"take", s.take}, {"frame", s.frame}, {"reason", s.error}, {"flags", s.flags}});
    }
    t.nodes.push_back(node);
  }
  return t;
}

// tree.json: the template and every frame's node in the tree, as finally registered.
void write_tree_json(const fs::path& out, int root, const Mesh& template_mesh, const json& nodes) {
  json tree_json = {{"version", 1},
                    {"root", root},
                    {"template", "template.ply"},
                    {"template_vertices", template_mesh.num_vertices()},
                    {"descriptor", "volumetric shape histogram, L2 distance minimised over rotation "
                                   "about the up axis"},
                    {"nodes", nodes}};
  write_file_atomic(out / "tree.json", tree_json.dump(1) + "\n");
}

// report.json's diagnosis section: how many frames are wrong, the patches, the cues' limits.
json diagnosis_summary(const Diagnoser& diagnoses, int diagnosed_wrong) {
  const DiagnosisLimits& limits = diagnoses.limits();
  return {{"wrong_frames", diagnosed_wrong},
          {"regions", diagnoses.regions().names},
          {"cue_columns", {"residual_p90_mm", "uncovered", "stretch_rms", "flipped", "jump_mm",
                           "jump_ratio"}},
          {"limits", {{"residual_p90_mm", 1e3 * limits.residual},
                      {"uncovered", limits.uncovered},
                      {"stretch_rms", limits.stretch},
                      {"flipped", limits.flipped},
                      {"jump_mm", 1e3 * limits.jump},
                      {"jump_ratio", limits.jump_ratio}}}};
}

// The finish job: merges the branch jobs' results, re-parents and keeps what failed, runs the
// baseline and writes the reports.
void run_finish_job(const fs::path& out, const StageArgs& args, const AlignOptions& options,
                    const std::string& options_header) {
  log::Timer timer;
  Registrations reg(0);
  Mesh template_mesh;
  Plan plan = load_plan(out, options, &reg, &template_mesh);
  const double job_seconds = read_branch_results(out, plan, reg, template_mesh);
  const TemplateModel model = build_template_model(template_mesh, options.registration);
  std::vector<FrameData>& frames = plan.frames;
  const int n = static_cast<int>(plan.usable.size());
  const int root = plan.usable[plan.tree.root];
  flag_tree_outcome(plan, reg, options);

  TreeRegistration registration(model, plan, reg, options, out);
  reparent_unaligned(plan, reg, registration, options);
  // 4b. Outlier fits.
  if (options.outlier_rms_factor > 0) refit_outliers(plan, reg, registration, options);
  std::vector<char> kept;
  const std::set<fs::path> written = keep_failed_fits(plan, reg, registration, options, kept);
  set_statuses(plan, reg, kept);

  // 5b. Self-diagnosis: every fit measured patch by patch; a frame with a patch over a limit is
  //     registered again from other parents, and if still wrong flagged, the patch named.
  std::vector<char> has_result(n, 0);
  for (int k = 0; k < n; ++k) has_result[k] = reg.aligned[k] || kept[k];
  Diagnoser diagnoses(model, plan, reg, has_result, options);
  if (options.retry_diagnosed) retry_wrong_frames(plan, reg, registration, diagnoses, options);
  if (options.retry_jump_factor > 0) retry_jumped_frames(plan, reg, registration, diagnoses, options);
  const int diagnosed_wrong = flag_diagnosed(plan, diagnoses);
  set_depths(frames, plan.usable);

  // 6. The baseline.
  json sequential;
  if (options.sequential_baseline) {
    sequential = run_sequential(model, frames[root].descriptor, frames, options, out / "sequential");
  }

  // Outputs.
  remove_stale_frames(out, written);
  const double seconds = job_seconds + timer.seconds();
  const FrameTables t = frame_tables(plan, diagnoses);
  write_tree_json(out, root, template_mesh, t.nodes);
  json report = {{"version", 1},
                 {"input", args.oracle ? "oracle" : "pipeline"},
                 {"frames", frames.size()},
                 {"aligned", t.aligned},
                 {"flagged", t.flagged},
                 {"excluded", t.excluded},
                 {"template_vertices", template_mesh.num_vertices()},
                 {"surface_rms_mm", t.aligned ? 1e3 * std::sqrt(t.rms_sum / t.aligned) : 0.0},
                 {"flipped_triangles", t.flipped},
                 {"branch_jobs", plan.branches},
                 {"seconds", seconds},
                 {"seconds_per_frame", seconds / static_cast<double>(frames.size())},
                 {"diagnosis", diagnosis_summary(diagnoses, diagnosed_wrong)},
                 {"per_frame", t.per_frame}};
  if (options.sequential_baseline) report["sequential"] = sequential;
  write_file_atomic(out / "report.json", report.dump(1) + "\n");
  write_file_atomic(out / "options.yaml", options_header + options_text(options));
  log::info("aligned {} of {} frames ({} of them kept despite a failed fit, flagged; {} diagnosed "
            "wrong somewhere), surface rms {:.2f} mm, {} flipped triangles, {:.2f} s per frame",
            t.aligned, frames.size(), t.flagged, diagnosed_wrong,
            report["surface_rms_mm"].get<double>(), t.flipped,
            seconds / static_cast<double>(frames.size()));
}

}  // namespace

void run_align(const Session& session, const StageArgs& args,
               const std::function<void(AlignOptions&)>& adjust) {
  const fs::path in = stage_input_dir(session, args, "reconstruct");
  const fs::path out = stage_output_dir(session, args, "align");
  // The subject the lengths scale to: reconstruct's, or measured on a few input meshes when
  // reconstruct/ was imported. Every job of the stage derives the same options.
  const Subject subject = stage_subject(session, in, [&] {
    const std::vector<FrameData> frames = list_frames(in, FrameSelection{});
    std::vector<Mesh> meshes;
    for (std::size_t i : spread_indices(frames.size(), 5)) {
      try {
        meshes.push_back(load_frame(frames[i]));
      } catch (const Error&) {  // an unreadable frame is excluded, with its reason, later
      }
    }
    return measure_subject(meshes, in.string());
  });
  AlignOptions options;
  std::size_t scaled = subject_stage_options(session, "align", subject, options).size();
  // The creases' curvature threshold is an inverse length.
  options.registration.crease_curvature /= subject.factor;
  ++scaled;
  if (adjust) adjust(options);
  const std::string header = subject_comment(subject, scaled);
  if (args.tree) {
    run_tree_job(in, out, args, options);
  } else if (args.branch >= 0) {
    run_branch_job(out, args.branch, options);
  } else if (args.finish) {
    run_finish_job(out, args, options, header);
  } else {
    // The whole stage in one process: the same jobs, one after the other.
    StageArgs whole = args;
    whole.branches = 1;
    run_tree_job(in, out, whole, options);
    run_branch_job(out, 0, options);
    run_finish_job(out, args, options, header);
  }
}

}  // namespace fourd::align
