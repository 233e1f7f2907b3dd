#pragma once
// The graph stage (paper section 3.2): builds the 4D parametric motion graph from the motion
// spaces of session.yaml and writes the runtime asset.
//
// Nodes: the motion classes of session.yaml (Session::config().motions), each read from the
// motionspace stage's output (<class>.* with the motion-space magic, runtime/motion_space.h).
// Edges: the transitions session.yaml lists, plus a self-loop for every cyclic class. Per edge:
// the similarity matrices S^{st}_{ij}(u, v) (similarity.h) and the n best precomputed
// transitions of the baseline (precomputed.h); per node: the normals of every reference frame,
// so the runtime blends normals instead of recomputing them, and, when the session has
// textures (texture/), the atlas UVs and each input take's key textures (key_textures.h; the
// time warps of timewarp/ say which captured frame each key phase shows).
//
// Also evaluates the paper's Table 2 on the built graph (table2.h) into graph/table2.json.
// Writes graph/graph.json (nodes, edges, sizes, d_max, precomputed transitions, offline CPU
// times), graph/options.yaml, and asset/motion_graph.fourd (runtime/asset.h). In oracle mode it
// reads motionspace_oracle/ (the motionspace stage run on oracle inputs) and writes
// graph_oracle/ and asset_oracle/.
#include <filesystem>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/session.h"
#include "runtime/asset.h"
#include "stages/common/stage.h"
#include "stages/graph/key_textures.h"
#include "stages/graph/precomputed.h"
#include "stages/graph/table2.h"

namespace fourd::graph {

inline constexpr const char* kAssetFileName = "motion_graph.fourd";

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/graph.md, "Advanced").
struct GraphOptions {
  double velocity_weight = 5.0;  // weight of |V_a - V_b|^2 (the velocity term) in the frame
                                 // distance
  bool self_loops = true;
  PrecomputeOptions precomputed;
  TransitionOptions transitions;  // defaults stored in the asset for the runtime
  Table2Options table2;           // the paper's Table 2 on this graph (graph/table2.json)
  KeyTextureOptions textures;     // key textures in the asset (when the session has texture/)

  template <class V>
  void visit(V& v) {
    v("self_loops", self_loops, "add a loop edge to every cyclic motion space");
    v("precomputed", precomputed, "baseline: n best transitions per edge");
    v("transitions", transitions, "online transition search defaults, stored in the asset");
    v("table2", table2, "Table 2: random transitions, online vs precomputed");
    v("textures", textures, "key textures of the asset (from texture/, when present)");
  }
  void check() const { transitions.check(); }
};

struct EdgeBuildReport {
  std::string from, to;
  bool self_loop = false;
  double max_distance = 0;         // d_max [m^2]
  double similarity_cpu_seconds = 0;  // S matrices (what the online method needs)
  double precompute_cpu_seconds = 0;  // the baseline's n best transitions
  int precomputed = 0;
};

struct GraphBuildReport {
  double normals_cpu_seconds = 0;
  double similarity_cpu_seconds = 0;
  double precompute_cpu_seconds = 0;
  std::vector<EdgeBuildReport> edges;
};

// The graph over `spaces` (in this order) with the edges `transitions` names (space names) and
// self-loops. Throws InputError for a transition naming an unknown space, spaces of different
// topologies, or spaces that fail MotionSpace::check.
MotionGraph build_motion_graph(const std::string& name, double fps, std::vector<MotionSpace> spaces,
                               std::span<const TransitionConfig> transitions,
                               const GraphOptions& options, GraphBuildReport* report);

// The motion space file of `motion` in `dir`: a file named <motion>.<anything> that carries the
// motion-space magic. Throws InputError naming the folder and class when there is none.
std::filesystem::path find_motion_space_file(const std::filesystem::path& dir,
                                             const std::string& motion);

// Folders the stage reads and writes.
std::filesystem::path motion_space_dir(const Session& session, const StageArgs& args);
std::filesystem::path asset_path(const Session& session, bool oracle);

nlohmann::json graph_summary(const MotionGraph& graph, const GraphBuildReport& report);

void run_graph(const Session& session, const StageArgs& args);

}  // namespace fourd::graph
