#pragma once
// The 4D parametric motion graph (paper section 3.2): parametric motion spaces as nodes, the
// transitions session.yaml allows as edges (plus a self-loop for each cyclic space), and per
// edge the precomputed similarity matrices S^{st}_{ij}(u, v) between every input sequence i of
// the source space and every input sequence j of the target space.
//
// Frame distance (section 3.2.1), with root motion factored out (shapes in their root frame,
// velocities expressed in the root frame of the later frame and per capture frame):
//   d(M_a, M_b) = (1 / N_v) (|X_a - X_b|^2 + velocity_weight |V_a - V_b|^2)        [m^2]
//   s(M_a, M_b) = 1 - d / d_max,    d_max the largest d over the edge's matrices.
// Lower bound of Eq. 3: for blends with convex weights w^s, w^t, Jensen's inequality on the
// squared norm gives d(M^s(w^s), M^t(w^t)) <= sum_ij w^s_i w^t_j d(M^s_i, M^t_j), i.e.
//   s(M^s(t_s, w^s), M^t(t_t, w^t)) >= w^s S(t_s, t_t) (w^t)^T.
// At continuous times S is interpolated bilinearly in the sample positions, which keeps the
// bound valid for blends that interpolate linearly between samples (the runtime's blend does).
//
// The graph is plain data (struct of arrays); everything here is allocation-free once built,
// except route(), which is called per request, not per frame.
#include <array>
#include <span>
#include <string>
#include <vector>

#include "runtime/blend.h"
#include "runtime/motion_space.h"
#include "runtime/textures.h"

namespace fourd {

// A node: one motion space plus per-vertex normals of every reference frame, stored like the
// positions (space.blend.frames and .displacements: the inputs' normals in float, the other
// references' as fp16 displacements from the linear blend of the inputs' normals), so they
// blend with the same coefficients as the positions.
struct GraphSpace {
  MotionSpace motion;
  AlignedFloats normals;              // N x F x (x | y | z planes), like motion.blend.frames
  AlignedHalfs normal_displacements;  // (#R - N) x F x planes, like motion.blend.displacements
  // Empty, or normal_displacements decoded to float, like motion.blend.displacement_floats.
  AlignedFloats normal_displacement_floats;
  // Where this space goes on when it ends with nothing requested (a one-shot space): the index
  // of another space it has an edge to, or -1 (a cyclic space loops; a one-shot space with -1
  // holds its last pose). The graph stage chooses it (choose_default_successor) and the asset
  // stores it (version 5); older assets get the same rule at load.
  int default_successor = -1;

  const std::string& name() const { return motion.name; }
  bool cyclic() const { return motion.cyclic; }
  int num_inputs() const { return motion.num_inputs(); }
  int num_samples() const { return motion.num_samples(); }
  double parameter_min() const { return motion.parameter_map.min_value(); }
  double parameter_max() const { return motion.parameter_map.max_value(); }
  // The normals frame that sits where `position_frame` (a pointer into motion.blend.frames, or
  // into motion.blend.displacements) sits among the positions.
  const float* normals_for(const float* position_frame) const {
    return normals.data() + (position_frame - motion.blend.frames.data());
  }
  const std::uint16_t* normals_for(const std::uint16_t* position_displacement) const {
    return normal_displacements.data() +
           (position_displacement - motion.blend.displacements.data());
  }
  // The decoded normal displacements where a decoded position displacement sits, or null.
  const float* normal_displacement_float(const float* position_displacement) const {
    return position_displacement == nullptr || normal_displacement_floats.empty()
               ? nullptr
               : normal_displacement_floats.data() +
                     (position_displacement - motion.blend.displacement_floats.data());
  }
  // Decodes the position and normal displacements to float (BlendSpace::displacement_floats).
  void decode_displacements() {
    fourd::decode_displacements(&motion.blend);
    fourd::decode_displacements(normal_displacements, &normal_displacement_floats);
  }
};

// S^{st}_{ij}(u, v) for one edge: similarity of sample u of source input i and sample v of
// target input j, all in [0, 1].
struct EdgeSimilarity {
  int source_inputs = 0;   // N_s
  int target_inputs = 0;   // N_t
  int source_samples = 0;  // F_s
  int target_samples = 0;  // F_t
  double max_distance = 0;  // d_max [m^2]
  // F_s x F_t x N_s x N_t, at ((u * F_t + v) * N_s + i) * N_t + j: for a pair of samples the
  // N_s x N_t matrix is contiguous (row-major), which is what an evaluation reads.
  std::vector<float> values;

  float at(int u, int v, int i, int j) const {
    return values[((static_cast<std::size_t>(u) * target_samples + v) * source_inputs + i) *
                      target_inputs +
                  j];
  }
  const float* block(int u, int v) const {
    return values.data() +
           (static_cast<std::size_t>(u) * target_samples + v) * source_inputs * target_inputs;
  }
  // Throws InputError if sizes disagree or a value is outside [0, 1].
  void check() const;
};

// The N_s x N_t matrix S at continuous times t_s, t_t in [0, 1] (bilinear between samples),
// row-major into out[0 .. N_s N_t).
void similarity_matrix_at(const EdgeSimilarity& s, double t_source, double t_target, float* out);
// The lower bound w_s S(t_s, t_t) w_t^T of Eq. 3 (weights projected onto the simplex).
double similarity_lower_bound(const EdgeSimilarity& s, double t_source,
                              std::span<const float> w_source, double t_target,
                              std::span<const float> w_target);

// One of the n best transitions of an edge precomputed offline (the baseline of Table 2,
// after Heck & Gleicher 2007): switch from (source_t, source_p) to (target_t, target_p).
struct PrecomputedTransition {
  float source_t = 0;
  float source_p = 0;
  float target_t = 0;
  float target_p = 0;
  float distance = 0;  // d between the two blended frames [m^2] (computed on the played blends)
};

struct GraphEdge {
  int from = -1;  // space index
  int to = -1;
  bool self_loop = false;  // a cyclic space's loop onto itself
  EdgeSimilarity similarity;
  std::vector<PrecomputedTransition> precomputed;  // best first (lowest distance)
};

// How the similarity matrices were made; stored with the graph so evaluations use the same.
struct SimilarityDefinition {
  double velocity_weight = 5.0;  // weight of |V_a - V_b|^2 in d
  double frame_time = 0.04;      // [s] velocities are per this time step (1 / capture fps)
};

struct MotionGraph {
  std::string name;                 // session name
  double fps = 25;                  // capture frame rate [frames/s]; latency counts these frames
  SimilarityDefinition similarity;  // how edge matrices were computed
  std::vector<GraphSpace> spaces;
  std::vector<GraphEdge> edges;
  // The captured appearance (runtime/textures.h): atlas UVs and key textures per space; empty
  // when the session had no textures.
  AssetTextures textures;

  double frame_time() const { return 1.0 / fps; }
  int num_vertices() const {
    return spaces.empty() ? 0 : spaces.front().motion.blend.num_vertices;
  }
  // -1 when absent.
  int find_space(const std::string& name) const;
  int find_edge(int from, int to) const;
  // The space's stored default successor (GraphSpace::default_successor); -1 for an index
  // out of range.
  int default_successor(int space) const;
  // Every space's topology, edge indices and matrix sizes; throws InputError naming what is wrong.
  void check() const;
};

// The graph's rule for a default successor: the target of the space's first edge (in the order
// session.yaml lists the transitions) into a cyclic space, else of its first edge to another
// space; -1 for a cyclic space or one with no way out (it holds its last pose).
int choose_default_successor(const MotionGraph& graph, int space);
// Sets every space's default_successor by that rule.
void choose_default_successors(MotionGraph* graph);

// Shortest route (fewest edges) from space `from` to `to` as the list of spaces after `from`,
// ending with `to`; empty if there is none or from == to. Allocates (called per request).
std::vector<int> shortest_route(const MotionGraph& graph, int from, int to);

// Parameter -> weights for one space (weights_for_parameter on its map); w has 3 entries, the
// unused ones zero.
ParameterLookup space_weights(const GraphSpace& space, double p, std::array<float, 3>* w);
// Blended duration [s] of one pass through the space at parameter p.
double space_duration(const GraphSpace& space, double p);

// Root at "unwrapped" time t: for a cyclic space t may leave [0, 1] (t = 1 + x is x into the
// next cycle: root(1) * root(x)); a one-shot space clamps t to [0, 1]. Relative to t = 0.
RootPose space_root(const MotionSpace& space, double t, std::span<const float> w);

}  // namespace fourd
