#include "stages/graph/table2.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <random>

#include "pipeline/core/error.h"
#include "runtime/transition_jump.h"
#include "stages/graph/similarity.h"

namespace fourd::graph {
namespace {

struct Request {
  int edge = -1;
  MotionState from;
  TransitionTarget to;
};

std::vector<int> table_edges(const MotionGraph& graph, const Table2Options& options) {
  std::vector<int> wanted;
  for (const std::string& name : options.spaces) {
    const int s = graph.find_space(name);
    if (s < 0) throw ConfigError(fmt::format("table2.spaces: no motion space named '{}'", name));
    wanted.push_back(s);
  }
  auto listed = [&](int s) {
    return wanted.empty() || std::find(wanted.begin(), wanted.end(), s) != wanted.end();
  };
  std::vector<int> edges;
  for (int e = 0; e < static_cast<int>(graph.edges.size()); ++e) {
    const GraphEdge& edge = graph.edges[e];
    if (!edge.self_loop && listed(edge.from) && listed(edge.to)) edges.push_back(e);
  }
  if (edges.empty()) {
    throw ConfigError("table2.spaces: the graph has no transition between the listed spaces");
  }
  return edges;
}

double uniform_parameter(const GraphSpace& space, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(space.parameter_min(), space.parameter_max());
  return space.parameter_max() > space.parameter_min() ? u(rng) : space.parameter_min();
}

// E_S on the frames played at the switch: the hybrid blends at the path's exit and entry.
double played_similarity_cost(const MotionGraph& graph, const TransitionPath& path,
                              const TransitionOptions& options, MotionSample* source_scratch,
                              MotionSample* target_scratch) {
  const GraphSpace& src = graph.spaces[path.exit.space];
  const GraphSpace& dst = graph.spaces[path.entry.space];
  std::array<float, 3> ws{}, wt{};
  space_weights(src, path.exit.p, &ws);
  space_weights(dst, path.entry.p, &wt);
  const Eigen::VectorXf a = played_state_features(
      src.motion, path.exit.t, std::span<const float>(ws.data(), src.num_inputs()),
      graph.similarity, source_scratch);
  const Eigen::VectorXf b = played_state_features(
      dst.motion, path.entry.t, std::span<const float>(wt.data(), dst.num_inputs()),
      graph.similarity, target_scratch);
  return options.cost_unit * feature_distance(a, b);
}

}  // namespace

Table2 evaluate_table2(const MotionGraph& graph, const TransitionOptions& transitions,
                       const Table2Options& options, double similarity_cpu_s,
                       double precompute_cpu_s, const CharacterOptions& character_options) {
  Table2 table;
  if (options.transitions <= 0) return table;
  const std::vector<int> edges = table_edges(graph, options);
  for (int e : edges) {
    table.edges.push_back(fmt::format("{} -> {}", graph.spaces[graph.edges[e].from].name(),
                                      graph.spaces[graph.edges[e].to].name()));
  }
  // Random requests: a uniform edge, source state uniform in time and parameter, target
  // parameter uniform, target time left to the search (any phase of a cyclic target, the
  // configured time of a one-shot one), as in the paper's experiment.
  std::mt19937_64 rng(options.seed);
  std::uniform_int_distribution<std::size_t> pick(0, edges.size() - 1);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Request> requests(static_cast<std::size_t>(options.transitions));
  for (Request& r : requests) {
    r.edge = edges[pick(rng)];
    const GraphEdge& e = graph.edges[r.edge];
    r.from = {e.from, unit(rng), uniform_parameter(graph.spaces[e.from], rng)};
    r.to = {e.to, uniform_parameter(graph.spaces[e.to], rng), -1};
  }
  table.requests = static_cast<int>(requests.size());

  std::vector<MotionSample> scratch;
  for (const GraphSpace& s : graph.spaces) scratch.push_back(make_motion_sample(s.motion));
  TransitionSearch search;
  using Clock = std::chrono::steady_clock;
  auto run_method = [&](Table2Row row, auto&& answer) {
    double cpu = 0;
    for (const Request& r : requests) {
      TransitionPath path = answer(r);
      const auto t0 = Clock::now();
      for (int k = 0; k < options.timing_repeats; ++k) path = answer(r);
      cpu += std::chrono::duration<double>(Clock::now() - t0).count() / options.timing_repeats;
      if (!path.found) continue;
      ++row.answered;
      row.similarity_cost += path.similarity_cost;
      // Self-loops are not evaluated, so the two spaces' scratches are distinct.
      row.played_similarity_cost += played_similarity_cost(
          graph, path, transitions, &scratch[static_cast<std::size_t>(path.exit.space)],
          &scratch[static_cast<std::size_t>(path.entry.space)]);
      row.latency_cost += transitions.lambda * path.latency_frames;
      row.latency_s += path.latency_frames * graph.frame_time();
    }
    if (row.answered > 0) {
      row.similarity_cost /= row.answered;
      row.played_similarity_cost /= row.answered;
      row.latency_cost /= row.answered;
      row.latency_s /= row.answered;
    }
    row.online_cpu_s = cpu / static_cast<double>(requests.size());
    table.rows.push_back(row);
  };
  for (int depth : options.depths) {
    TransitionOptions o = transitions;
    o.depth = depth;
    Table2Row row;
    row.method = fmt::format("online, depth {}", depth);
    row.depth = depth;
    row.offline_cpu_s = similarity_cpu_s;
    run_method(row, [&](const Request& r) { return search.search(graph, r.edge, r.from, r.to, o); });
  }
  for (const bool limited : {true, false}) {
    for (int n : options.precomputed) {
      Table2Row row;
      row.method = fmt::format("{} precomputed{}", n, limited ? "" : ", instant parameter");
      row.n = n;
      row.rate_limited = limited;
      row.offline_cpu_s = similarity_cpu_s + precompute_cpu_s;
      run_method(row, [&](const Request& r) {
        return select_precomputed_transition(graph, r.edge, n, r.from, r.to, transitions, limited);
      });
    }
  }
  // The requests played, as the runtime plays them.
  Character character(graph, transitions, character_options);
  table.jumps.depth = transitions.depth;
  for (const Request& r : requests) {
    const TransitionJump jump =
        measure_transition_jump(character, r.from, r.to, graph.frame_time());
    if (!jump.played) continue;
    ++table.jumps.played;
    table.jumps.ratios.push_back(jump.ratio());
    table.jumps.worst_mm.push_back(1000 * jump.worst_m);
    table.jumps.worst_ratio = std::max(table.jumps.worst_ratio, jump.ratio());
    table.jumps.worst_displacement_mm = std::max(table.jumps.worst_displacement_mm, 1000 * jump.worst_m);
  }
  if (!table.jumps.ratios.empty()) {
    std::vector<double> sorted = table.jumps.ratios;
    std::sort(sorted.begin(), sorted.end());
    const std::size_t n = sorted.size();
    table.jumps.median_ratio = n % 2 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
  }
  return table;
}

nlohmann::json table2_json(const Table2& table) {
  nlohmann::json j;
  j["requests"] = table.requests;
  j["edges"] = table.edges;
  j["rows"] = nlohmann::json::array();
  for (const Table2Row& r : table.rows) {
    j["rows"].push_back({{"method", r.method},
                         {"depth", r.depth},
                         {"precomputed", r.n},
                         {"rate_limited", r.rate_limited},
                         {"answered", r.answered},
                         {"similarity_cost", r.similarity_cost},
                         {"played_similarity_cost", r.played_similarity_cost},
                         {"latency_cost", r.latency_cost},
                         {"latency_s", r.latency_s},
                         {"online_cpu_s", r.online_cpu_s},
                         {"offline_cpu_s", r.offline_cpu_s}});
  }
  const Table2Jumps& k = table.jumps;
  j["transition_jump"] = {{"depth", k.depth},
                          {"played", k.played},
                          {"worst_ratio", k.worst_ratio},
                          {"median_ratio", k.median_ratio},
                          {"worst_displacement_mm", k.worst_displacement_mm},
                          {"ratios", k.ratios},
                          {"worst_mm", k.worst_mm}};
  return j;
}

}  // namespace fourd::graph
