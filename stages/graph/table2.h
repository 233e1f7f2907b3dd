#pragma once
// The paper's Table 2 on our graph: random transition requests between motion spaces, each
// answered by the online trellis search (several depths) and by the precomputed baseline
// (n best transitions per edge; once with the parameter rate limit the online trellis obeys, once
// letting the parameter jump to a stored transition's at once), with the columns of the paper: E_S(P_opt), lambda E_L(P_opt),
// latency [s], online CPU per transition [s] and offline CPU [s].
//
// E_S is reported two ways: as each method scores it (the online search uses the lower bound
// of Eq. 3, the baseline the distance it stored), and measured the same way for both on the
// frames actually played at the switch (cost_unit x d between the hybrid blends), so that the
// methods are compared on what the viewer sees. The requests are also played by a runtime
// character, measuring the worst per-frame vertex jump of each transition (Table2Jumps).
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "runtime/character.h"
#include "runtime/motion_graph.h"
#include "runtime/transition.h"

namespace fourd::graph {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/graph.md, "Advanced").
struct Table2Options {
  int transitions = 50;
  std::vector<std::string> spaces;
  std::vector<int> depths = {3, 5, 8, 10, 12, 16};  // online trellis depths evaluated
  std::vector<int> precomputed = {1, 5, 10};        // n of the baseline
  std::uint64_t seed = 2012;                        // of the random requests
  int timing_repeats = 20;                          // searches per request timed

  template <class V>
  void visit(V& v) {
    v("transitions", transitions, "random transition requests (0: skip Table 2)",
      Range{0, 100000});
    v("spaces", spaces, "evaluate edges between these motion spaces (empty: all edges)");
  }
};

struct Table2Row {
  std::string method;  // "online, depth 12", "10 precomputed"
  int depth = 0;       // online only
  int n = 0;           // precomputed only
  bool rate_limited = true;  // precomputed: the parameter moves at most dp per trellis step
  int answered = 0;    // requests the method found a path for
  double similarity_cost = 0;         // mean E_S as the method scores it
  double played_similarity_cost = 0;  // mean E_S measured on the played frames
  double latency_cost = 0;            // mean lambda E_L
  double latency_s = 0;               // mean latency [s]
  double online_cpu_s = 0;            // mean CPU per transition search [s]
  double offline_cpu_s = 0;           // precomputation the method needs [s]
};

// The requests played by a runtime character (the asset's search options, default character
// options) at the capture frame rate: how far a vertex moves in one frame while each
// transition plays, against the two motions' own speeds (runtime/transition_jump.h).
struct Table2Jumps {
  int depth = 0;                    // the online search's (the asset's)
  int played = 0;                   // requests played to the end
  std::vector<double> ratios;       // per played request, worst displacement / max p99
  std::vector<double> worst_mm;     // per played request [mm]
  double worst_ratio = 0, median_ratio = 0;
  double worst_displacement_mm = 0;
};

struct Table2 {
  int requests = 0;
  std::vector<std::string> edges;  // "from -> to" evaluated
  std::vector<Table2Row> rows;     // online depths first, then the baseline
  Table2Jumps jumps;
};

// `similarity_cpu_s`: offline CPU of the similarity matrices (what the online method needs);
// `precompute_cpu_s`: of the baseline's n best transitions (it needs the matrices' features too,
// so its offline time is the sum). Throws ConfigError for a space name the graph lacks or no
// edge between the listed spaces.
// `character`: how the requests are played (Table2Jumps).
Table2 evaluate_table2(const MotionGraph& graph, const TransitionOptions& transitions,
                       const Table2Options& options, double similarity_cpu_s,
                       double precompute_cpu_s, const CharacterOptions& character = {});

nlohmann::json table2_json(const Table2& table);

}  // namespace fourd::graph
