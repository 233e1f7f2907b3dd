#include "stages/graph/graph.h"

#include <fmt/format.h>

#include <algorithm>
#include <ctime>
#include <fstream>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/log.h"
#include "pipeline/core/subject.h"
#include "stages/graph/similarity.h"

namespace fourd::graph {

namespace {

namespace fs = std::filesystem;

// Process CPU time [s]: all threads, so TBB-parallel work counts fully.
double cpu_seconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

bool has_motion_space_magic(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  in.read(magic, sizeof magic);
  static constexpr char kExpected[8] = {'F', 'O', 'U', 'R', 'D', 'M', 'S', '\0'};
  return in.gcount() == sizeof magic && std::equal(magic, magic + 8, kExpected);
}

}  // namespace

MotionGraph build_motion_graph(const std::string& name, double fps, std::vector<MotionSpace> spaces,
                               std::span<const TransitionConfig> transitions,
                               const GraphOptions& options, GraphBuildReport* report) {
  options.check();
  GraphBuildReport local;
  GraphBuildReport& r = report ? *report : local;
  r = {};
  MotionGraph g;
  g.name = name;
  g.fps = fps;
  g.similarity.velocity_weight = options.velocity_weight;
  g.similarity.frame_time = 1.0 / fps;

  double start = cpu_seconds();
  for (MotionSpace& m : spaces) {
    m.check();
    GraphSpace s;
    reference_normals(m, &s.normals, &s.normal_displacements);
    s.motion = std::move(m);
    g.spaces.push_back(std::move(s));
  }
  r.normals_cpu_seconds = cpu_seconds() - start;

  auto add_edge = [&](int from, int to) {
    if (g.find_edge(from, to) >= 0) return;
    GraphEdge e;
    e.from = from;
    e.to = to;
    e.self_loop = from == to;
    EdgeBuildReport er;
    er.from = g.spaces[from].name();
    er.to = g.spaces[to].name();
    er.self_loop = e.self_loop;
    double t0 = cpu_seconds();
    e.similarity = build_edge_similarity(g.spaces[from].motion, g.spaces[to].motion, g.similarity);
    er.similarity_cpu_seconds = cpu_seconds() - t0;
    if (!e.self_loop) {  // a loop's best "transition" is staying put: nothing to precompute
      t0 = cpu_seconds();
      e.precomputed =
          precompute_transitions(g.spaces[from], g.spaces[to], g.similarity, options.precomputed);
      er.precompute_cpu_seconds = cpu_seconds() - t0;
    }
    er.max_distance = e.similarity.max_distance;
    er.precomputed = static_cast<int>(e.precomputed.size());
    r.similarity_cpu_seconds += er.similarity_cpu_seconds;
    r.precompute_cpu_seconds += er.precompute_cpu_seconds;
    r.edges.push_back(er);
    g.edges.push_back(std::move(e));
  };
  for (const TransitionConfig& t : transitions) {
    const int from = g.find_space(t.from), to = g.find_space(t.to);
    if (from < 0 || to < 0) {
      throw InputError(fmt::format("transition {} -> {}: no motion space named '{}'", t.from, t.to,
                                   from < 0 ? t.from : t.to));
    }
    add_edge(from, to);
  }
  if (options.self_loops) {
    for (int s = 0; s < static_cast<int>(g.spaces.size()); ++s) {
      if (g.spaces[s].cyclic()) add_edge(s, s);
    }
  }
  choose_default_successors(&g);
  g.check();
  return g;
}

fs::path find_motion_space_file(const fs::path& dir, const std::string& motion) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    throw InputError(fmt::format("motion spaces: folder {} does not exist (run the motionspace "
                                 "stage first)",
                                 dir.string()));
  }
  std::vector<fs::path> candidates;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.is_regular_file() && entry.path().stem() == motion &&
        has_motion_space_magic(entry.path())) {
      candidates.push_back(entry.path());
    }
  }
  if (candidates.empty()) {
    throw InputError(fmt::format("motion class '{}': no motion space file {}/{}.* (run the "
                                 "motionspace stage for it)",
                                 motion, dir.string(), motion));
  }
  std::sort(candidates.begin(), candidates.end());
  return candidates.front();
}

fs::path motion_space_dir(const Session& session, const StageArgs& args) {
  if (!args.oracle) return session.dir("motionspace");
  // The motionspace stage run on oracle inputs writes motionspace_oracle/; prepared oracle
  // inputs (oracle/motionspace/) are the fallback.
  const fs::path derived = session.dir("motionspace_oracle");
  std::error_code ec;
  return fs::is_directory(derived, ec) ? derived : stage_input_dir(session, args, "motionspace");
}

fs::path asset_path(const Session& session, bool oracle) {
  return session.dir(oracle ? "asset_oracle" : "asset") / kAssetFileName;
}

nlohmann::json graph_summary(const MotionGraph& graph, const GraphBuildReport& report) {
  nlohmann::json j;
  j["name"] = graph.name;
  j["fps"] = graph.fps;
  j["vertices"] = graph.num_vertices();
  j["velocity_weight"] = graph.similarity.velocity_weight;
  j["frame_time_s"] = graph.similarity.frame_time;
  j["normals_cpu_s"] = report.normals_cpu_seconds;
  j["similarity_cpu_s"] = report.similarity_cpu_seconds;
  j["precompute_cpu_s"] = report.precompute_cpu_seconds;
  for (const GraphSpace& s : graph.spaces) {
    const ParameterMap& m = s.motion.parameter_map;
    j["nodes"].push_back({{"name", s.name()},
                          {"cyclic", s.cyclic()},
                          {"takes", s.motion.takes},
                          {"samples", s.num_samples()},
                          {"references", s.motion.blend.num_references()},
                          {"parameter", m.parameter},
                          {"unit", m.unit},
                          {"parameter_min", m.min_value()},
                          {"parameter_max", m.max_value()}});
  }
  for (std::size_t k = 0; k < graph.edges.size(); ++k) {
    const GraphEdge& e = graph.edges[k];
    nlohmann::json je = {{"from", graph.spaces[e.from].name()},
                         {"to", graph.spaces[e.to].name()},
                         {"self_loop", e.self_loop},
                         {"max_distance_m2", e.similarity.max_distance},
                         {"matrix", {e.similarity.source_samples, e.similarity.target_samples,
                                     e.similarity.source_inputs, e.similarity.target_inputs}}};
    if (k < report.edges.size()) {
      je["similarity_cpu_s"] = report.edges[k].similarity_cpu_seconds;
      je["precompute_cpu_s"] = report.edges[k].precompute_cpu_seconds;
    }
    for (const PrecomputedTransition& p : e.precomputed) {
      je["precomputed"].push_back({{"source_t", p.source_t},
                                   {"source_p", p.source_p},
                                   {"target_t", p.target_t},
                                   {"target_p", p.target_p},
                                   {"distance_m2", p.distance}});
    }
    j["edges"].push_back(je);
  }
  return j;
}

namespace {

// The session's motion spaces, in session.yaml's order, checked against its declarations.
std::vector<MotionSpace> load_spaces(const SessionConfig& config, const fs::path& in_dir) {
  std::vector<MotionSpace> spaces;
  for (const MotionClassConfig& motion : config.motions) {
    const fs::path file = find_motion_space_file(in_dir, motion.name);
    log::info("reading motion space '{}' from {}", motion.name, file.string());
    spaces.push_back(load_motion_space(file));
    if (spaces.back().cyclic != motion.cyclic) {
      throw InputError(fmt::format("{}: motion space is {} but session.yaml declares '{}' {}",
                                   file.string(), spaces.back().cyclic ? "cyclic" : "one-shot",
                                   motion.name, motion.cyclic ? "cyclic" : "one-shot"));
    }
  }
  return spaces;
}

// The key textures of the asset, when the texture stage made an atlas and options want them.
void add_key_textures(const Session& session, const StageArgs& args, const GraphOptions& options,
                      Asset& asset) {
  const fs::path texture_dir = stage_input_dir(session, args, "texture");
  if (options.textures.keys == 0) {
    log::info("no key textures (textures.keys: 0)");
  } else if (!has_textures(texture_dir)) {
    log::info("no textures in the asset: {} has no atlas.ply", texture_dir.string());
  } else {
    log::Timer tt;
    asset.graph.textures = build_key_textures(asset.graph, texture_dir,
                                              stage_input_dir(session, args, "timewarp"),
                                              options.textures);
    asset.graph.check();
    log::info("{} key textures of {} x {} texels from {} in {:.1f} s",
              asset.graph.textures.images.size(), asset.graph.textures.width,
              asset.graph.textures.height, texture_dir.string(), tt.seconds());
  }
}

// Where each one-shot space goes when it ends with no request (stored in the asset:
// GraphSpace::default_successor, chosen by choose_default_successor), logged.
nlohmann::json default_successors(const MotionGraph& graph) {
  nlohmann::json successors = nlohmann::json::object();
  for (int k = 0; k < static_cast<int>(graph.spaces.size()); ++k) {
    if (graph.spaces[k].cyclic()) continue;
    const int next = graph.default_successor(k);
    successors[graph.spaces[k].name()] =
        next >= 0 ? nlohmann::json(graph.spaces[next].name()) : nlohmann::json(nullptr);
    log::info("{}: ends into {} when nothing is requested", graph.spaces[k].name(),
              next >= 0 ? graph.spaces[next].name() : "its last pose (no way out)");
  }
  return successors;
}

// graph.json: the graph's summary, the asset file, its textures and the default successors.
void write_graph_json(const Session& session, const fs::path& graph_dir, const fs::path& asset_file,
                      const Asset& asset, const GraphBuildReport& report,
                      const GraphOptions& options) {
  nlohmann::json summary = graph_summary(asset.graph, report);
  summary["asset"] = fs::relative(asset_file, session.root()).generic_string();
  summary["asset_bytes"] = fs::file_size(asset_file);
  const AssetTextures& textures = asset.graph.textures;
  summary["textures"] = {{"images", textures.images.size()},
                         {"width", textures.width},
                         {"height", textures.height},
                         {"keys", textures.empty() ? 0 : options.textures.keys},
                         {"jpeg_quality", textures.jpeg_quality}};
  summary["default_successors"] = default_successors(asset.graph);
  write_file_atomic(graph_dir / "graph.json", summary.dump(1));
}

// Table 2 compares transition methods between two different spaces; a graph of one motion
// class (self-loops only) has none, unless the session lists spaces (then it is an error).
void run_table2(const fs::path& graph_dir, const MotionGraph& graph, const GraphOptions& options,
                const GraphBuildReport& report) {
  const bool between_spaces = std::any_of(graph.edges.begin(), graph.edges.end(),
                                          [](const GraphEdge& e) { return !e.self_loop; });
  if (options.table2.transitions > 0 && !between_spaces && options.table2.spaces.empty()) {
    log::info("Table 2: skipped, the graph has no transition between two different spaces");
  }
  if (options.table2.transitions > 0 && (between_spaces || !options.table2.spaces.empty())) {
    log::Timer t2;
    const Table2 table = evaluate_table2(graph, options.transitions, options.table2,
                                         report.similarity_cpu_seconds,
                                         report.precompute_cpu_seconds);
    for (const Table2Row& r : table.rows) {
      log::info("Table 2, {:<18} E_S {:8.2f} (played {:8.2f})  lambda E_L {:7.2f}  latency "
                "{:.3f} s  online {:.2e} s  offline {:.2f} s  ({}/{} answered)",
                r.method, r.similarity_cost, r.played_similarity_cost, r.latency_cost,
                r.latency_s, r.online_cpu_s, r.offline_cpu_s, r.answered, table.requests);
    }
    log::info("Table 2, transitions played: worst per-frame vertex jump {:.1f} mm, {:.2f} (worst) "
              "/ {:.2f} (median) x the motions' 99th percentile ({}/{} played)",
              table.jumps.worst_displacement_mm, table.jumps.worst_ratio,
              table.jumps.median_ratio, table.jumps.played, table.requests);
    write_file_atomic(graph_dir / "table2.json", table2_json(table).dump(1));
    log::info("Table 2: {} requests over {} edge(s) in {:.1f} s", table.requests,
              table.edges.size(), t2.seconds());
  } else {
    std::error_code ec;
    fs::remove(graph_dir / "table2.json", ec);  // not from an earlier run with other options
  }
}

}  // namespace

void run_graph(const Session& session, const StageArgs& args) {
  GraphOptions options;
  session.stage_options("graph", options);
  options.check();
  const SessionConfig& config = session.config();
  std::vector<MotionSpace> spaces = load_spaces(config, motion_space_dir(session, args));
  // E_S is a squared distance: cost_unit (per m^2) scales with the subject as 1 / factor^2, so
  // that lambda weighs latency against the same relative dissimilarity for a subject of any
  // size (reconstruct's subject, else the motion spaces' character height).
  const Subject subject = stage_subject(session, session.dir("reconstruct"), [&] {
    Subject s;
    s.size = s.height = spaces.front().character_height;
    s.factor = subject_scale_factor(s.size);
    s.source = "the motion spaces' character height";
    return s;
  });
  options.transitions.cost_unit /= subject.factor * subject.factor;
  log_subject("graph", subject, 1);
  log::Timer timer;
  GraphBuildReport report;
  Asset asset;
  asset.graph =
      build_motion_graph(config.name, config.fps, std::move(spaces), config.transitions, options,
                         &report);
  asset.transitions = options.transitions;
  add_key_textures(session, args, options, asset);
  for (const EdgeBuildReport& e : report.edges) {
    log::info("edge {} -> {}{}: d_max {:.4g} m^2, similarity {:.2f} s CPU, {} precomputed "
              "transitions in {:.2f} s CPU",
              e.from, e.to, e.self_loop ? " (loop)" : "", e.max_distance,
              e.similarity_cpu_seconds, e.precomputed, e.precompute_cpu_seconds);
  }
  log::info("graph: {} spaces, {} edges in {:.1f} s", asset.graph.spaces.size(),
            asset.graph.edges.size(), timer.seconds());

  const fs::path graph_dir = stage_output_dir(session, args, "graph");
  ensure_directory(graph_dir);
  const fs::path asset_file = asset_path(session, args.oracle);
  ensure_directory(asset_file.parent_path());
  save_asset(asset_file, asset);
  write_graph_json(session, graph_dir, asset_file, asset, report, options);
  run_table2(graph_dir, asset.graph, options, report);
  YAML::Emitter yaml;
  yaml << to_yaml(options);
  write_file_atomic(graph_dir / "options.yaml", std::string(yaml.c_str()) + "\n");
  log::info("wrote {} ({:.1f} MB) and {}", asset_file.string(),
            fs::file_size(asset_file) / 1e6, (graph_dir / "graph.json").string());
}

}  // namespace fourd::graph
