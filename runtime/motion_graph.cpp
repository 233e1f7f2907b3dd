#include "runtime/motion_graph.h"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <deque>

#include "pipeline/core/error.h"
#include "pipeline/core/se2.h"

namespace fourd {

namespace {

// Continuous sample position of t in [0, 1] over `samples` samples: index and fraction.
inline void sample_position(double t, int samples, int* i, float* f) {
  if (samples < 2) {
    *i = 0;
    *f = 0;
    return;
  }
  const double pos = std::clamp(t, 0.0, 1.0) * (samples - 1);
  *i = std::min(static_cast<int>(pos), samples - 2);
  *f = static_cast<float>(pos - *i);
}

std::array<float, 3> simplex(std::span<const float> w, int n) {
  std::array<float, 3> p{};
  float sum = 0;
  for (int i = 0; i < n; ++i) sum += (p[i] = std::max(0.f, w[i]));
  for (int i = 0; i < n; ++i) p[i] = sum > 0 ? p[i] / sum : 1.f / n;
  return p;
}

}  // namespace

void EdgeSimilarity::check() const {
  if (source_inputs < 1 || source_inputs > 3 || target_inputs < 1 || target_inputs > 3 ||
      source_samples < 1 || target_samples < 1) {
    throw InputError(fmt::format("similarity matrix: bad sizes ({} x {} inputs, {} x {} samples)",
                                 source_inputs, target_inputs, source_samples, target_samples));
  }
  const std::size_t expected = static_cast<std::size_t>(source_samples) * target_samples *
                               source_inputs * target_inputs;
  if (values.size() != expected) {
    throw InputError(
        fmt::format("similarity matrix: {} values, expected {}", values.size(), expected));
  }
  if (!(max_distance > 0) || !std::isfinite(max_distance)) {
    throw InputError(fmt::format("similarity matrix: maximum distance {} is not positive",
                                 max_distance));
  }
  for (std::size_t k = 0; k < values.size(); ++k) {
    if (!(values[k] >= 0.f && values[k] <= 1.f)) {
      throw InputError(fmt::format("similarity matrix: value {} at {} is outside [0, 1]",
                                   values[k], k));
    }
  }
}

void similarity_matrix_at(const EdgeSimilarity& s, double t_source, double t_target, float* out) {
  int u = 0, v = 0;
  float fu = 0, fv = 0;
  sample_position(t_source, s.source_samples, &u, &fu);
  sample_position(t_target, s.target_samples, &v, &fv);
  const int u1 = std::min(u + 1, s.source_samples - 1), v1 = std::min(v + 1, s.target_samples - 1);
  const float* a = s.block(u, v);
  const float* b = s.block(u, v1);
  const float* c = s.block(u1, v);
  const float* d = s.block(u1, v1);
  const float ca = (1 - fu) * (1 - fv), cb = (1 - fu) * fv, cc = fu * (1 - fv), cd = fu * fv;
  const int n = s.source_inputs * s.target_inputs;
  for (int k = 0; k < n; ++k) out[k] = ca * a[k] + cb * b[k] + cc * c[k] + cd * d[k];
}

double similarity_lower_bound(const EdgeSimilarity& s, double t_source,
                              std::span<const float> w_source, double t_target,
                              std::span<const float> w_target) {
  std::array<float, 9> m{};
  similarity_matrix_at(s, t_source, t_target, m.data());
  const std::array<float, 3> ws = simplex(w_source, s.source_inputs);
  const std::array<float, 3> wt = simplex(w_target, s.target_inputs);
  double lb = 0;
  for (int i = 0; i < s.source_inputs; ++i) {
    for (int j = 0; j < s.target_inputs; ++j) {
      lb += static_cast<double>(ws[i]) * wt[j] * m[i * s.target_inputs + j];
    }
  }
  return lb;
}

int MotionGraph::find_space(const std::string& space_name) const {
  for (std::size_t k = 0; k < spaces.size(); ++k) {
    if (spaces[k].name() == space_name) return static_cast<int>(k);
  }
  return -1;
}

int MotionGraph::find_edge(int from, int to) const {
  for (std::size_t k = 0; k < edges.size(); ++k) {
    if (edges[k].from == from && edges[k].to == to) return static_cast<int>(k);
  }
  return -1;
}

int MotionGraph::default_successor(int space) const {
  if (space < 0 || space >= static_cast<int>(spaces.size())) return -1;
  return spaces[space].default_successor;
}

int choose_default_successor(const MotionGraph& graph, int space) {
  if (space < 0 || space >= static_cast<int>(graph.spaces.size()) || graph.spaces[space].cyclic()) {
    return -1;
  }
  int any = -1;
  for (const GraphEdge& e : graph.edges) {
    if (e.from != space || e.to == space) continue;
    if (graph.spaces[e.to].cyclic()) return e.to;
    if (any < 0) any = e.to;
  }
  return any;
}

void choose_default_successors(MotionGraph* graph) {
  for (int k = 0; k < static_cast<int>(graph->spaces.size()); ++k) {
    graph->spaces[k].default_successor = choose_default_successor(*graph, k);
  }
}

void MotionGraph::check() const {
  if (!(fps > 0) || !std::isfinite(fps)) {
    throw InputError(fmt::format("motion graph '{}': frame rate {} is not positive", name, fps));
  }
  if (spaces.empty()) throw InputError(fmt::format("motion graph '{}': no motion spaces", name));
  const int nv = num_vertices();
  for (const GraphSpace& s : spaces) {
    s.motion.check();
    if (s.motion.blend.num_vertices != nv || s.motion.triangles != spaces.front().motion.triangles) {
      throw InputError(fmt::format(
          "motion graph '{}': space '{}' has another topology than '{}' ({} vs {} vertices)", name,
          s.name(), spaces.front().name(), s.motion.blend.num_vertices, nv));
    }
    if (s.normals.size() != s.motion.blend.frames.size() ||
        s.normal_displacements.size() != s.motion.blend.displacements.size()) {
      throw InputError(
          fmt::format("motion graph '{}': space '{}' has {} + {} normal values for "
                      "{} + {} position values",
                      name, s.name(), s.normals.size(), s.normal_displacements.size(),
                      s.motion.blend.frames.size(), s.motion.blend.displacements.size()));
    }
    if (find_space(s.name()) != &s - spaces.data()) {
      throw InputError(fmt::format("motion graph '{}': two spaces named '{}'", name, s.name()));
    }
  }
  if (!textures.empty()) {
    std::vector<int> inputs;
    for (const GraphSpace& s : spaces) inputs.push_back(s.num_inputs());
    try {
      textures.check(inputs, spaces.front().motion.triangles.size());
    } catch (const InputError& err) {
      throw InputError(fmt::format("motion graph '{}': {}", name, err.what()));
    }
  }
  for (const GraphEdge& e : edges) {
    const int n = static_cast<int>(spaces.size());
    if (e.from < 0 || e.from >= n || e.to < 0 || e.to >= n) {
      throw InputError(fmt::format("motion graph '{}': edge {} -> {} names a space past {}", name,
                                   e.from, e.to, n));
    }
    const std::string label =
        fmt::format("motion graph '{}': edge {} -> {}", name, spaces[e.from].name(),
                    spaces[e.to].name());
    if (find_edge(e.from, e.to) != &e - edges.data()) {
      throw InputError(label + " appears twice");
    }
    if (e.self_loop != (e.from == e.to)) throw InputError(label + ": self-loop flag disagrees");
    try {
      e.similarity.check();
    } catch (const InputError& err) {
      throw InputError(fmt::format("{}: {}", label, err.what()));
    }
    const MotionSpace& a = spaces[e.from].motion;
    const MotionSpace& b = spaces[e.to].motion;
    if (e.similarity.source_inputs != a.num_inputs() || e.similarity.target_inputs != b.num_inputs() ||
        e.similarity.source_samples != a.num_samples() ||
        e.similarity.target_samples != b.num_samples()) {
      throw InputError(label + ": similarity matrix sizes do not match the spaces");
    }
    for (const PrecomputedTransition& p : e.precomputed) {
      if (!(p.source_t >= 0 && p.source_t <= 1 && p.target_t >= 0 && p.target_t <= 1 &&
            std::isfinite(p.source_p) && std::isfinite(p.target_p) && p.distance >= 0)) {
        throw InputError(label + ": a precomputed transition is out of range");
      }
    }
  }
  // A default successor is reached by a transition: an edge to another space, from a one-shot
  // space (a cyclic one loops).
  for (const GraphSpace& s : spaces) {
    const int next = s.default_successor;
    if (next == -1) continue;
    const int k = static_cast<int>(&s - spaces.data());
    if (s.cyclic() || next == k || find_edge(k, next) < 0) {
      throw InputError(fmt::format(
          "motion graph '{}': space '{}' names {} as its default successor, but {}", name,
          s.name(), next,
          s.cyclic() ? "it is cyclic (it loops)"
                     : "it has no transition to that space"));
    }
  }
}

std::vector<int> shortest_route(const MotionGraph& graph, int from, int to) {
  const int n = static_cast<int>(graph.spaces.size());
  if (from < 0 || from >= n || to < 0 || to >= n || from == to) return {};
  std::vector<int> previous(n, -1);
  std::deque<int> queue{from};
  previous[from] = from;
  while (!queue.empty() && previous[to] < 0) {
    const int s = queue.front();
    queue.pop_front();
    // Edges in file order, so ties go to the transition session.yaml lists first.
    for (const GraphEdge& e : graph.edges) {
      if (e.from == s && previous[e.to] < 0) {
        previous[e.to] = s;
        queue.push_back(e.to);
      }
    }
  }
  if (previous[to] < 0) return {};
  std::vector<int> route;
  for (int s = to; s != from; s = previous[s]) route.push_back(s);
  std::reverse(route.begin(), route.end());
  return route;
}

ParameterLookup space_weights(const GraphSpace& space, double p, std::array<float, 3>* w) {
  *w = {0.f, 0.f, 0.f};
  return weights_for_parameter(space.motion.parameter_map, p,
                               std::span<float>(w->data(), space.num_inputs()));
}

double space_duration(const GraphSpace& space, double p) {
  std::array<float, 3> w{};
  space_weights(space, p, &w);
  return blended_duration(space.motion, std::span<const float>(w.data(), space.num_inputs()));
}

RootPose space_root(const MotionSpace& space, double t, std::span<const float> w) {
  if (!space.cyclic) return blended_root(space, std::clamp(t, 0.0, 1.0), w);
  const double cycles = std::floor(t);
  RootPose r = blended_root(space, t - cycles, w);
  if (cycles == 0) return r;
  const RootPose one = blended_root(space, 1.0, w);
  const RootPose step = cycles > 0 ? one : root_inverse(one);
  for (int k = 0; k < static_cast<int>(std::abs(cycles)); ++k) r = root_compose(step, r);
  return r;
}

}  // namespace fourd
