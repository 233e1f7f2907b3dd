// The embedded deformation graph of the template (Sumner et al. 2007): its nodes, edges and
// influences, the template model built around it, and deforming the template with it.
#include "stages/align/registration_internal.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "pipeline/core/error.h"
#include "pipeline/geometry/geodesic.h"
#include "pipeline/geometry/measures.h"

namespace fourd::align {

using namespace detail;

namespace {

// Per vertex, 1 / (1 + H / crease_curvature) where the template is concave with mean curvature
// H [1/m], 1 elsewhere (and everywhere when crease_curvature is 0). H is estimated over the
// two-ring: the mean of 2 n.(p_j - p_i) / |p_j - p_i|^2, positive where the neighbours rise
// above the tangent plane. Concave creases are where parts of the body meet (armpits, crotch)
// and, in a template that merged them, where skin must stretch when the joint opens.
std::vector<double> crease_softness(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                                    double crease_curvature) {
  const std::size_t nv = mesh.num_vertices();
  std::vector<double> softness(nv, 1.0);
  if (crease_curvature <= 0) return softness;
  const std::vector<Vec3f> normals = vertex_normals(mesh.positions, mesh.triangles);
  tbb::parallel_for(std::size_t{0}, nv, [&](std::size_t i) {
    std::vector<int> near;
    for (int j : rings[i]) {
      near.push_back(j);
      for (int k : rings[j]) near.push_back(k);
    }
    std::sort(near.begin(), near.end());
    near.erase(std::unique(near.begin(), near.end()), near.end());
    double sum = 0;
    int count = 0;
    for (int j : near) {
      if (j == static_cast<int>(i)) continue;
      const Vec3d d = (mesh.positions[j] - mesh.positions[i]).cast<double>();
      const double d2 = d.squaredNorm();
      if (d2 <= 0) continue;
      sum += 2.0 * normals[i].cast<double>().dot(d) / d2;
      ++count;
    }
    const double h = count > 0 ? sum / count : 0.0;
    softness[i] = 1.0 / (1.0 + std::max(h, 0.0) / crease_curvature);
  });
  return softness;
}

}  // namespace

namespace detail {

std::vector<int> farthest_point_samples(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                                        int count, std::vector<double>* dist,
                                        std::vector<int>* owner) {
  const int nv = static_cast<int>(mesh.num_vertices());
  const double inf = std::numeric_limits<double>::infinity();
  dist->assign(nv, inf);
  owner->assign(nv, -1);
  std::vector<int> samples;
  int next = 0;
  for (int j = 0; j < std::min(count, nv); ++j) {
    samples.push_back(next);
    geodesic_update(mesh, rings, next, j, inf, *dist, *owner);
    next = static_cast<int>(std::max_element(dist->begin(), dist->end()) - dist->begin());
  }
  return samples;
}

DeformationGraph build_graph(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                             int node_count, int influences) {
  const int nv = static_cast<int>(mesh.num_vertices());
  node_count = std::min(node_count, nv);
  const double inf = std::numeric_limits<double>::infinity();
  DeformationGraph graph;
  graph.influences = influences;

  // Geodesic farthest-point nodes; `owner` is the geodesic Voronoi partition.
  std::vector<double> dist;
  std::vector<int> owner;
  graph.node_vertex = farthest_point_samples(mesh, rings, node_count, &dist, &owner);
  for (int v : graph.node_vertex) graph.node_position.push_back(mesh.positions[v].cast<double>());
  const double cover_radius = *std::max_element(dist.begin(), dist.end());
  if (!std::isfinite(cover_radius)) {
    throw InputError("template: the mesh is not connected (deformation graph cannot reach it all)");
  }

  // Graph edges between nodes whose Voronoi cells touch.
  graph.node_neighbours.assign(node_count, {});
  for (int v = 0; v < nv; ++v) {
    for (int w : rings[v]) {
      if (owner[v] != owner[w]) graph.node_neighbours[owner[v]].push_back(owner[w]);
    }
  }
  for (auto& n : graph.node_neighbours) {
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
  }

  // Each vertex blends its K nearest nodes (geodesically), w = (1 - d / d_{K+1})^2
  // (Sumner et al. 2007), normalised.
  const double radius = 3.0 * cover_radius;
  std::vector<std::vector<std::pair<double, int>>> near(nv);
  std::vector<double> local(nv, inf);
  std::vector<int> local_owner(nv, -1);
  for (int j = 0; j < node_count; ++j) {
    std::vector<int> reached =
        geodesic_update(mesh, rings, graph.node_vertex[j], j, radius, local, local_owner);
    for (int v : reached) {
      near[v].emplace_back(local[v], j);
      local[v] = inf;
    }
  }
  graph.influence_node.assign(static_cast<std::size_t>(nv) * influences, -1);
  graph.influence_weight.assign(static_cast<std::size_t>(nv) * influences, 0.0);
  for (int v = 0; v < nv; ++v) {
    auto& list = near[v];
    std::sort(list.begin(), list.end());
    const int k = std::min<int>(influences, static_cast<int>(list.size()));
    const double d_max = static_cast<int>(list.size()) > influences ? list[influences].first : radius;
    double sum = 0;
    for (int i = 0; i < k; ++i) {
      double w = 1.0 - list[i].first / std::max(d_max, 1e-12);
      w = std::max(w, 1e-4);  // the nearest nodes always count a little
      w *= w;
      graph.influence_node[static_cast<std::size_t>(v) * influences + i] = list[i].second;
      graph.influence_weight[static_cast<std::size_t>(v) * influences + i] = w;
      sum += w;
    }
    for (int i = 0; i < k; ++i) graph.influence_weight[static_cast<std::size_t>(v) * influences + i] /= sum;
  }
  return graph;
}

// Cotangent weights of every one-ring edge, clamped positive (the template is remeshed
// isotropically, so few angles are obtuse).
std::vector<std::vector<double>> cotangent_weights(const Mesh& mesh,
                                                   const std::vector<std::vector<int>>& rings) {
  std::vector<std::vector<double>> weights(rings.size());
  for (std::size_t v = 0; v < rings.size(); ++v) weights[v].assign(rings[v].size(), 0.0);
  auto add = [&](int i, int j, double w) {
    auto it = std::find(rings[i].begin(), rings[i].end(), j);
    if (it != rings[i].end()) weights[i][it - rings[i].begin()] += w;
  };
  for (const Tri& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const int i = t[(k + 1) % 3], j = t[(k + 2) % 3];
      const Vec3d a = (mesh.positions[i] - mesh.positions[t[k]]).cast<double>();
      const Vec3d b = (mesh.positions[j] - mesh.positions[t[k]]).cast<double>();
      const double cross = a.cross(b).norm();
      const double cot = cross > 1e-20 ? a.dot(b) / cross : 0.0;
      add(i, j, 0.5 * cot);
      add(j, i, 0.5 * cot);
    }
  }
  for (auto& ring : weights) {
    for (double& w : ring) w = std::clamp(w, 1e-3, 1e3);
  }
  return weights;
}

// Fills the model's softness (per vertex; per graph node, the smallest of the vertices it is
// nearest to, its own included) and softens the refinement's ring weights with it, to no less
// than crease_refine_floor. Needs the rings, their weights and the graph.
void soften_creases(const RegistrationOptions& options, TemplateModel* model) {
  model->vertex_softness = crease_softness(model->rest, model->rings, options.crease_curvature);
  const std::vector<float>& confidence = model->rest.confidence;
  for (std::size_t i = 0; i < confidence.size(); ++i) {
    model->vertex_softness[i] *= by_confidence(confidence[i], options.unconfident_stiffness);
  }
  const std::vector<double>& soft = model->vertex_softness;
  for (std::size_t i = 0; i < model->rings.size(); ++i) {
    for (std::size_t k = 0; k < model->rings[i].size(); ++k) {
      const double s = std::min(soft[i], soft[model->rings[i][k]]);
      model->ring_weights[i][k] *= std::max(s, options.crease_refine_floor);
    }
  }
  const DeformationGraph& g = model->graph;
  model->node_softness.assign(g.node_vertex.size(), 1.0);
  for (std::size_t v = 0; v < soft.size(); ++v) {
    const int nearest = g.influence_node[v * g.influences];
    if (nearest >= 0) {
      model->node_softness[nearest] = std::min(model->node_softness[nearest], soft[v]);
    }
  }
}

}  // namespace detail

TemplateModel build_template_model(const Mesh& template_mesh, const RegistrationOptions& options) {
  if (template_mesh.empty()) throw InputError("template: empty mesh");
  TemplateModel model;
  model.rest.positions = template_mesh.positions;
  model.rest.triangles = template_mesh.triangles;
  model.rest.confidence = template_mesh.confidence;
  model.rings = vertex_neighbours(model.rest);
  model.ring_weights = cotangent_weights(model.rest, model.rings);
  model.graph = build_graph(model.rest, model.rings, options.graph_nodes, options.node_influences);
  soften_creases(options, &model);
  if (static_cast<int>(model.rest.num_vertices()) <= options.graph_samples) {
    model.data_vertices.resize(model.rest.num_vertices());
    std::iota(model.data_vertices.begin(), model.data_vertices.end(), 0);
  } else {
    std::vector<double> dist;
    std::vector<int> owner;
    model.data_vertices =
        farthest_point_samples(model.rest, model.rings, options.graph_samples, &dist, &owner);
    std::sort(model.data_vertices.begin(), model.data_vertices.end());
  }
  Vec3f centroid = Vec3f::Zero();
  for (const Vec3f& p : model.rest.positions) centroid += p;
  centroid /= static_cast<float>(model.rest.num_vertices());
  model.extremities = find_extremities(model.rest, model.rings,
                                       nearest_vertex(model.rest.positions, centroid),
                                       options.extremities);
  for (int tip : model.extremities.vertices) {
    std::vector<double>& dist = model.tip_distance.emplace_back(
        model.rest.num_vertices(), std::numeric_limits<double>::infinity());
    std::vector<int> owner(model.rest.num_vertices(), -1);
    geodesic_update(model.rest, model.rings, tip, 0, std::numeric_limits<double>::infinity(), dist,
                    owner);
  }
  return model;
}

DeformationState rest_state(const TemplateModel& model) {
  DeformationState state;
  const std::size_t m = model.graph.node_vertex.size();
  state.rotation.assign(m, Mat3d::Identity());
  state.translation.assign(m, Vec3d::Zero());
  state.positions = model.rest.positions;
  return state;
}

std::vector<Vec3f> deform_with_graph(const TemplateModel& model, const DeformationState& state) {
  const DeformationGraph& g = model.graph;
  const int nv = static_cast<int>(model.rest.num_vertices()), k = g.influences;
  std::vector<Vec3f> out(nv);
  tbb::parallel_for(0, nv, [&](int v) {
    const Vec3d rest = model.rest.positions[v].cast<double>();
    Vec3d p = Vec3d::Zero();
    for (int a = 0; a < k; ++a) {
      const int j = g.influence_node[v * k + a];
      if (j < 0) continue;
      p += g.influence_weight[v * k + a] *
           (state.rotation[j] * (rest - g.node_position[j]) + g.node_position[j] + state.translation[j]);
    }
    out[v] = p.cast<float>();
  });
  return out;
}

void apply_rigid(const TemplateModel& model, const Eigen::Isometry3d& motion,
                 DeformationState* state) {
  const Mat3d r = motion.linear();
  // motion(R_j (x - g_j) + g_j + t_j) = (r R_j)(x - g_j) + g_j + [motion(g_j + t_j) - g_j].
  for (std::size_t j = 0; j < state->rotation.size(); ++j) {
    const Vec3d& g = model.graph.node_position[j];
    state->rotation[j] = r * state->rotation[j];
    state->translation[j] = motion * (g + state->translation[j]) - g;
  }
  for (Vec3f& p : state->positions) p = (motion * p.cast<double>()).cast<float>();
}

}  // namespace fourd::align
