#include "stages/align/registration.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <limits>
#include <unordered_map>

#include "pipeline/core/error.h"
#include "pipeline/core/log.h"
#include "pipeline/geometry/measures.h"
#include "stages/align/mesh_tools.h"

namespace fourd::align {

Mesh fitted_mesh(const TemplateModel& model, const std::vector<Vec3f>& positions) {
  Mesh m;
  m.positions = positions;
  m.triangles = model.rest.triangles;
  return m;
}

namespace {

using Vec3d = Eigen::Vector3d;
using Mat3d = Eigen::Matrix3d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using SparseMatrix = Eigen::SparseMatrix<double>;

Mat3d skew(const Vec3d& v) {
  Mat3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

Mat3d rotation_from_vector(const Vec3d& w) {
  const double angle = w.norm();
  if (angle < 1e-12) return Mat3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

// The rotation closest to m in the Frobenius norm (polar decomposition).
Mat3d nearest_rotation(const Mat3d& m) {
  Eigen::JacobiSVD<Mat3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3d u = svd.matrixU();
  const Mat3d& v = svd.matrixV();
  Mat3d r = u * v.transpose();
  if (r.determinant() < 0) {
    u.col(2) *= -1;
    r = u * v.transpose();
  }
  return r;
}

// Cauchy weight: down-weights outliers (wrong matches, topology merges) smoothly.
double robust_weight(double residual, double scale) {
  const double x = residual / scale;
  return 1.0 / (1.0 + x * x);
}

float cos_degrees(double degrees) { return static_cast<float>(std::cos(degrees * M_PI / 180.0)); }

// A factor that is `at_zero` at confidence 0, 1 at confidence 1, linear in between.
double by_confidence(double confidence, double at_zero) {
  return at_zero + (1 - at_zero) * confidence;
}

// The weight of frame surface of `confidence` (0..1).
double confidence_weight(double confidence, const RegistrationOptions& options) {
  return by_confidence(confidence, options.unconfident_weight);
}

struct Correspondence {
  Vec3d point = Vec3d::Zero();
  Vec3d normal = Vec3d::Zero();
  double weight = 0;  // 0: no match
};

// Closest compatible surface points of every vertex, robustly weighted.
std::vector<Correspondence> find_correspondences(const std::vector<Vec3f>& positions,
                                                 const std::vector<Vec3f>& normals,
                                                 const SurfaceQuery& target, double max_distance,
                                                 double robust_scale,
                                                 const RegistrationOptions& options) {
  std::vector<Correspondence> out(positions.size());
  const float min_cos = cos_degrees(options.normal_angle);
  tbb::parallel_for(std::size_t{0}, positions.size(), [&](std::size_t i) {
    SurfaceHit hit = target.closest(positions[i], static_cast<float>(max_distance), normals[i], min_cos);
    if (!hit.found) return;
    out[i].point = hit.point.cast<double>();
    out[i].normal = hit.normal.cast<double>();
    out[i].weight =
        confidence_weight(hit.confidence, options) * robust_weight(hit.distance, robust_scale);
  });
  return out;
}

// A frame point matched to the closest point of the deformed template (a barycentric point of
// one template triangle). The forward matches only pull the template onto surface it is
// already near; these pull it onto frame surface it has not reached yet (a limb that moved
// far), which the forward matches alone would leave uncovered.
struct ReverseMatch {
  Tri triangle = Tri::Zero();     // template vertices
  Vec3d barycentric = Vec3d::Zero();
  Vec3d point = Vec3d::Zero();    // the frame point
  Vec3d normal = Vec3d::Zero();   // the frame's unit normal there
  double weight = 0;              // 0: no match
};

// The frame points the reverse matches start from: about one per template vertex, spread
// evenly over the frame's vertices, with their unit normals.
struct FrameSamples {
  std::vector<Vec3f> points;
  std::vector<Vec3f> normals;
  std::vector<float> confidence;
};

FrameSamples sample_frame(const SurfaceQuery& target, std::size_t count) {
  const std::vector<Vec3f>& positions = target.positions();
  const std::vector<Vec3f> normals = vertex_normals(positions, target.triangles());
  FrameSamples samples;
  const std::size_t stride = std::max<std::size_t>(1, positions.size() / std::max<std::size_t>(count, 1));
  for (std::size_t i = 0; i < positions.size(); i += stride) {
    if (normals[i].isZero()) continue;  // not on any triangle
    samples.points.push_back(positions[i]);
    samples.normals.push_back(normals[i]);
    samples.confidence.push_back(target.vertex_confidence(i));
  }
  return samples;
}

std::vector<ReverseMatch> find_reverse_correspondences(const TemplateModel& model,
                                                       const std::vector<Vec3f>& positions,
                                                       const FrameSamples& samples,
                                                       double max_distance, double robust_scale,
                                                       const RegistrationOptions& options) {
  const SurfaceQuery query(fitted_mesh(model, positions));
  const float min_cos = cos_degrees(options.normal_angle);
  std::vector<ReverseMatch> out(samples.points.size());
  tbb::parallel_for(std::size_t{0}, samples.points.size(), [&](std::size_t i) {
    const SurfaceHit hit = query.closest(samples.points[i], static_cast<float>(max_distance),
                                         samples.normals[i], min_cos);
    if (!hit.found) return;
    out[i].triangle = model.rest.triangles[hit.triangle];
    out[i].barycentric = hit.barycentric.cast<double>();
    out[i].point = samples.points[i].cast<double>();
    out[i].normal = samples.normals[i].cast<double>();
    out[i].weight = confidence_weight(samples.confidence[i], options) *
                    robust_weight(hit.distance, robust_scale);
  });
  return out;
}

// ---- Landmarks: the template's tips matched to the frame's -------------------------------

int nearest_vertex(const std::vector<Vec3f>& positions, const Vec3f& p) {
  int best = -1;
  float best_d = std::numeric_limits<float>::infinity();
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const float d = (positions[i] - p).squaredNorm();
    if (d < best_d) {
      best_d = d;
      best = static_cast<int>(i);
    }
  }
  return best;
}

// The frame's tips as landmarks for a fit. The tips are seen from the frame vertex nearest the
// template's centre in the fit. A covered frame tip with a template tip within anchor_distance
// anchors it; the others were missed by the fit - left uncovered, or covered without a template
// tip near (a limb that moved too far for closest points is left behind, or covered by
// stretched neighbouring surface) - and are matched to the remaining template tips.
struct TipLandmarks {
  std::vector<Landmark> landmarks;  // the anchors and the missed tips matched
  std::vector<int> frame_tips;      // the frame vertex of each landmark's point
  bool missed = false;              // a frame tip was missed and matched
  Mesh frame;                       // the frame's surface
  std::vector<std::vector<int>> frame_rings;
};

// The vertices whose distance `dist` (from a tip) is at most `length`: the tip's limb.
std::vector<int> within(const std::vector<double>& dist, double length) {
  std::vector<int> out;
  for (std::size_t v = 0; v < dist.size(); ++v) {
    if (dist[v] <= length) out.push_back(static_cast<int>(v));
  }
  return out;
}

// Where the limb of a tip attaches to the body: the centre of the surface at `length` (less
// `band`) of geodesic distance `dist` from the tip, over `positions`. A limb's root (hip,
// shoulder) hardly moves when it swings, so it tells the left limb from the right one when
// their tips have crossed (a running leg kicked back behind the other).
Vec3d limb_root(const std::vector<double>& dist, const std::vector<Vec3f>& positions, int tip,
                double length, double band) {
  Vec3d sum = Vec3d::Zero();
  int count = 0;
  for (std::size_t v = 0; v < dist.size(); ++v) {
    if (dist[v] >= length - band && dist[v] <= length) {
      sum += positions[v].cast<double>();
      ++count;
    }
  }
  return count > 0 ? Vec3d(sum / count) : Vec3d(positions[tip].cast<double>());
}

TipLandmarks tip_landmarks(const TemplateModel& model, const std::vector<Vec3f>& positions,
                           const SurfaceQuery& target, const RegistrationOptions& options) {
  const Extremities& tips = model.extremities;
  if (tips.vertices.empty()) return {};
  TipLandmarks out;
  Mesh& frame = out.frame;
  frame.positions = target.positions();
  frame.triangles = target.triangles();
  out.frame_rings = edge_neighbours(frame);
  const int centre = nearest_vertex(frame.positions, positions[tips.centre]);
  const Extremities frame_tips =
      find_extremities(frame, out.frame_rings, centre, options.extremities);
  const SurfaceQuery fitted_query(fitted_mesh(model, positions));

  // The limbs' roots, on the fit and on the frame (without limbs: the tips themselves).
  auto root_length = [&](double geodesic) { return options.limb_fraction * geodesic; };
  std::vector<Vec3d> template_root(tips.vertices.size()), frame_root(frame_tips.vertices.size());
  for (std::size_t i = 0; i < tips.vertices.size(); ++i) {
    template_root[i] = options.limb_fraction > 0
                           ? limb_root(model.tip_distance[i], positions, tips.vertices[i],
                                       root_length(tips.geodesic[i]), options.limb_band)
                           : Vec3d(positions[tips.vertices[i]].cast<double>());
  }
  for (std::size_t j = 0; j < frame_tips.vertices.size(); ++j) {
    const int tip = frame_tips.vertices[j];
    if (options.limb_fraction <= 0) {
      frame_root[j] = frame.positions[tip].cast<double>();
      continue;
    }
    const double length = root_length(frame_tips.geodesic[j]);
    std::vector<double> dist(frame.num_vertices(), std::numeric_limits<double>::infinity());
    std::vector<int> owner(frame.num_vertices(), -1);
    geodesic_update(frame, out.frame_rings, tip, 0, length, dist, owner);
    frame_root[j] = limb_root(dist, frame.positions, tip, length, options.limb_band);
  }

  std::vector<Vec3d> template_at;
  for (int v : tips.vertices) template_at.push_back(positions[v].cast<double>());
  std::vector<Landmark>& landmarks = out.landmarks;
  std::vector<int>& landmark_tips = out.frame_tips;
  std::vector<char> template_used(tips.vertices.size(), 0);
  Extremities missed;
  std::vector<Vec3d> missed_root;
  std::vector<Vec3d> missed_at;
  for (std::size_t j = 0; j < frame_tips.vertices.size(); ++j) {
    const Vec3f& p = frame.positions[frame_tips.vertices[j]];
    const bool covered =
        fitted_query.closest(p, static_cast<float>(options.coverage_distance)).found;
    const int anchor = anchored_tip(template_at, template_root, template_used, p.cast<double>(),
                                    frame_root[j], options.extremities.anchor_distance);
    if (covered && anchor >= 0) {
      template_used[anchor] = 1;
      landmarks.push_back({tips.vertices[anchor], p.cast<double>()});
      landmark_tips.push_back(frame_tips.vertices[j]);
    } else {
      missed.vertices.push_back(frame_tips.vertices[j]);
      missed.geodesic.push_back(frame_tips.geodesic[j]);
      missed_at.push_back(p.cast<double>());
      missed_root.push_back(frame_root[j]);
    }
  }
  if (missed.vertices.empty()) return out;
  // The missed tips are matched by where their limbs attach, not by where the tips are.
  Extremities free;
  std::vector<Vec3d> free_root;
  for (std::size_t i = 0; i < tips.vertices.size(); ++i) {
    if (template_used[i]) continue;
    free.vertices.push_back(tips.vertices[i]);
    free.geodesic.push_back(tips.geodesic[i]);
    free_root.push_back(template_root[i]);
  }
  const std::vector<TipMatch> matches =
      match_extremities(free, free_root, missed, missed_root, options.extremities);
  for (const TipMatch& m : matches) {
    landmarks.push_back({free.vertices[m.template_tip], missed_at[m.frame_tip]});
    landmark_tips.push_back(missed.vertices[m.frame_tip]);
  }
  log::debug("tips: {} in the frame, {} missed by the fit, {} of them matched; {} landmarks",
             frame_tips.vertices.size(), missed.vertices.size(), matches.size(), landmarks.size());
  out.missed = !matches.empty();
  return out;
}

// ---- The deformation graph ---------------------------------------------------------------

DeformationGraph build_graph(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                             int node_count, int influences) {
  const int nv = static_cast<int>(mesh.num_vertices());
  node_count = std::min(node_count, nv);
  const double inf = std::numeric_limits<double>::infinity();
  DeformationGraph graph;
  graph.influences = influences;

  // Geodesic farthest-point sampling: each new node is the vertex farthest from all nodes so
  // far; `owner` ends as the geodesic Voronoi partition.
  std::vector<double> dist(nv, inf);
  std::vector<int> owner(nv, -1);
  int next = 0;
  for (int j = 0; j < node_count; ++j) {
    graph.node_vertex.push_back(next);
    graph.node_position.push_back(mesh.positions[next].cast<double>());
    geodesic_update(mesh, rings, next, j, inf, dist, owner);
    next = static_cast<int>(std::max_element(dist.begin(), dist.end()) - dist.begin());
  }
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

// ---- Embedded deformation: Gauss-Newton --------------------------------------------------

// The block pattern of the Gauss-Newton matrix: a 6x6 block per pair of nodes that share a
// vertex or a graph edge. Fixed for the template, so the sparse Cholesky analysis is reused.
class GraphSystem {
 public:
  // With `reverse_matches`, also the blocks the reverse matches need.
  GraphSystem(const TemplateModel& model, bool reverse_matches) : model_(model) {
    const DeformationGraph& g = model.graph;
    nodes_ = static_cast<int>(g.node_vertex.size());
    for (int j = 0; j < nodes_; ++j) block_id(j, j);
    const int nv = static_cast<int>(model.rest.num_vertices()), k = g.influences;
    for (int v = 0; v < nv; ++v) {
      for (int a = 0; a < k; ++a) {
        for (int b = 0; b < k; ++b) {
          int na = g.influence_node[v * k + a], nb = g.influence_node[v * k + b];
          if (na >= 0 && nb >= 0 && na <= nb) block_id(na, nb);
        }
      }
    }
    // Reverse matches tie the nodes of a triangle's three vertices together.
    for (const Tri& t : reverse_matches ? model.rest.triangles : std::vector<Tri>{}) {
      for (int a = 0; a < 3 * k; ++a) {
        for (int b = 0; b < 3 * k; ++b) {
          const int na = g.influence_node[t[a / k] * k + a % k];
          const int nb = g.influence_node[t[b / k] * k + b % k];
          if (na >= 0 && nb >= 0 && na <= nb) block_id(na, nb);
        }
      }
    }
    for (int j = 0; j < nodes_; ++j) {
      for (int n : g.node_neighbours[j]) block_id(std::min(j, n), std::max(j, n));
    }
  }

  int unknowns() const { return 6 * nodes_; }

  // Partial sums of the matrix blocks and the gradient. The data terms are summed in a fixed
  // number of parts over fixed ranges of points, in parallel, and the parts are added in their
  // order: the result does not depend on the thread count or scheduling (runs are repeatable
  // bit for bit).
  struct Part {
    std::vector<Mat6> blocks;
    Eigen::VectorXd gradient;
  };

  // Zeroes `parts` partial sums (at least one: part 0, which add() and add_gradient() fill).
  void clear(int parts) {
    parts_.resize(std::max(parts, 1));
    for (Part& part : parts_) {
      part.blocks.assign(pairs_.size(), Mat6::Zero());  // reuses the storage
      part.gradient.setZero(6 * nodes_);
    }
  }
  Part& part(int i) { return parts_[i]; }
  // H(a, b) += m for a <= b (the lower triangle follows by symmetry). Thread-safe for distinct
  // parts.
  void add(Part& part, int a, int b, const Mat6& m) const {
    if (a <= b) {
      part.blocks[ids_.at(key(a, b))] += m;
    } else {
      part.blocks[ids_.at(key(b, a))] += m.transpose();
    }
  }
  void add(int a, int b, const Mat6& m) { add(parts_[0], a, b, m); }
  static void add_gradient(Part& part, int a, const Vec6& g) { part.gradient.segment<6>(6 * a) += g; }
  void add_gradient(int a, const Vec6& g) { add_gradient(parts_[0], a, g); }
  // Adds parts 1.. into part 0, in order. The parts stay allocated: the next clear() zeroes
  // them instead of allocating them again every Gauss-Newton step.
  void sum_parts() {
    for (std::size_t i = 1; i < parts_.size(); ++i) {
      for (std::size_t b = 0; b < pairs_.size(); ++b) parts_[0].blocks[b] += parts_[i].blocks[b];
      parts_[0].gradient += parts_[i].gradient;
    }
  }

  SparseMatrix matrix(double damping) const {
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(pairs_.size() * 72);
    for (std::size_t i = 0; i < pairs_.size(); ++i) {
      const auto [a, b] = pairs_[i];
      const Mat6& m = parts_[0].blocks[i];
      for (int r = 0; r < 6; ++r) {
        for (int c = 0; c < 6; ++c) {
          double value = m(r, c);
          if (a == b && r == c) value += damping;
          triplets.emplace_back(6 * a + r, 6 * b + c, value);
          if (a != b) triplets.emplace_back(6 * b + c, 6 * a + r, value);
        }
      }
    }
    SparseMatrix h(6 * nodes_, 6 * nodes_);
    h.setFromTriplets(triplets.begin(), triplets.end());
    return h;
  }
  const Eigen::VectorXd& gradient() const { return parts_[0].gradient; }

 private:
  std::uint64_t key(int a, int b) const { return static_cast<std::uint64_t>(a) * nodes_ + b; }
  int block_id(int a, int b) {
    auto [it, inserted] = ids_.try_emplace(key(a, b), static_cast<int>(pairs_.size()));
    if (inserted) pairs_.emplace_back(a, b);
    return it->second;
  }

  const TemplateModel& model_;
  int nodes_ = 0;
  std::unordered_map<std::uint64_t, int> ids_;
  std::vector<std::pair<int, int>> pairs_;
  std::vector<Part> parts_;
};

// The Jacobian of a deformed point with respect to one graph node's update (a rotation
// vector and a translation): J = [S, w I].
struct NodeJacobian {
  int node = -1;
  Mat3d s = Mat3d::Zero();
  double w = 0;
};

// A combination sum_e c_e x(v_e) of deformed template vertices (one vertex, or a barycentric
// point of a triangle): its position, and its Jacobian per node it depends on (at most
// 3 * influences entries). Returns the number of nodes.
int point_jacobian(const TemplateModel& model, const DeformationState& state, const int* vertices,
                   const double* coefficients, int count, Vec3d* deformed, NodeJacobian* out) {
  const DeformationGraph& g = model.graph;
  const int k = g.influences;
  int nodes = 0;
  *deformed = Vec3d::Zero();
  for (int e = 0; e < count; ++e) {
    const int v = vertices[e];
    const Vec3d rest = model.rest.positions[v].cast<double>();
    for (int a = 0; a < k; ++a) {
      const int j = g.influence_node[v * k + a];
      if (j < 0) continue;
      const double w = coefficients[e] * g.influence_weight[v * k + a];
      const Vec3d x = state.rotation[j] * (rest - g.node_position[j]);
      *deformed += w * (x + g.node_position[j] + state.translation[j]);
      int slot = 0;
      while (slot < nodes && out[slot].node != j) ++slot;
      if (slot == nodes) {
        out[nodes++] = NodeJacobian{j, Mat3d::Zero(), 0.0};
      }
      out[slot].s -= w * skew(x);
      out[slot].w += w;
    }
  }
  return nodes;
}

// Adds |P^(1/2) (point - target)|^2 for a point with the given node Jacobians, residual
// e = point - target and symmetric weight matrix P.
void add_point_term(const NodeJacobian* jac, int nodes, const Mat3d& p, const Vec3d& e,
                    const GraphSystem& system, GraphSystem::Part& part) {
  const Vec3d pe = p * e;
  for (int a = 0; a < nodes; ++a) {
    Vec6 grad;
    grad << jac[a].s.transpose() * pe, jac[a].w * pe;
    GraphSystem::add_gradient(part, jac[a].node, grad);
    const Mat3d sp = jac[a].s.transpose() * p;
    for (int b = 0; b < nodes; ++b) {
      if (jac[a].node > jac[b].node) continue;
      Mat6 block;
      block << sp * jac[b].s, jac[b].w * sp, jac[a].w * p * jac[b].s, jac[a].w * jac[b].w * p;
      system.add(part, jac[a].node, jac[b].node, block);
    }
  }
}

// One Gauss-Newton step of the graph energy; updates `state` (rotations, translations).
// Returns false when the system could not be factorised.
bool graph_gauss_newton_step(const TemplateModel& model, const std::vector<Correspondence>& matches,
                             const std::vector<ReverseMatch>& reverse,
                             const std::vector<Landmark>& landmarks, double stiffness,
                             const RegistrationOptions& options, GraphSystem& system,
                             Eigen::SimplicialLDLT<SparseMatrix>& solver, bool analyse,
                             DeformationState* state) {
  const DeformationGraph& g = model.graph;
  const int nv = static_cast<int>(model.rest.num_vertices());
  // Data weight per vertex: nodes / vertices, so that the balance with the regulariser does not
  // depend on the template's resolution.
  const double data_weight = static_cast<double>(g.node_vertex.size()) / nv;
  const double reverse_weight =
      reverse.empty() ? 0.0 : options.reverse_weight * data_weight * nv / reverse.size();
  // Every forward and reverse match adds its term to the part its index falls in.
  constexpr int kParts = 8;
  const std::size_t terms = static_cast<std::size_t>(nv) + reverse.size();
  system.clear(kParts);
  tbb::parallel_for(0, kParts, [&](int part_index) {
    GraphSystem::Part& part = system.part(part_index);
    NodeJacobian jac[3 * 8];
    Vec3d deformed;
    const std::size_t begin = terms * part_index / kParts, end = terms * (part_index + 1) / kParts;
    for (std::size_t i = begin; i < end; ++i) {
      if (i < static_cast<std::size_t>(nv)) {
        // Data: point-to-plane plus a little point-to-point, with P = c (n n^T + mu I).
        const int v = static_cast<int>(i);
        const Correspondence& m = matches[v];
        if (m.weight <= 0) continue;
        const double one = 1.0;
        const int nodes = point_jacobian(model, *state, &v, &one, 1, &deformed, jac);
        const Mat3d p = data_weight * m.weight * (m.normal * m.normal.transpose() +
                                                  options.point_to_point * Mat3d::Identity());
        add_point_term(jac, nodes, p, deformed - m.point, system, part);
      } else {
        // Reverse data: frame points pulling the template surface points closest to them.
        const ReverseMatch& m = reverse[i - nv];
        if (m.weight <= 0) continue;
        const int nodes = point_jacobian(model, *state, m.triangle.data(), m.barycentric.data(),
                                         3, &deformed, jac);
        const Mat3d p = reverse_weight * m.weight * (m.normal * m.normal.transpose() +
                                                     options.point_to_point * Mat3d::Identity());
        add_point_term(jac, nodes, p, deformed - m.point, system, part);
      }
    }
  });
  system.sum_parts();

  // Landmarks: point-to-point, each weighing as much as landmark_weight vertices.
  for (const Landmark& l : landmarks) {
    NodeJacobian jac[8];
    Vec3d deformed;
    const double one = 1.0;
    const int nodes = point_jacobian(model, *state, &l.vertex, &one, 1, &deformed, jac);
    add_point_term(jac, nodes, options.landmark_weight * data_weight * Mat3d::Identity(),
                   deformed - l.point, system, system.part(0));
  }

  // Regulariser: each node predicts its neighbours' positions as rigidly as possible.
  for (std::size_t j = 0; j < g.node_vertex.size(); ++j) {
    for (int n : g.node_neighbours[j]) {
      const Vec3d d = g.node_position[n] - g.node_position[j];
      const Vec3d rd = state->rotation[j] * d;
      const Vec3d r = rd + g.node_position[j] + state->translation[j] - g.node_position[n] -
                      state->translation[n];
      const double w = stiffness * std::min(model.node_softness[j], model.node_softness[n]);
      Eigen::Matrix<double, 3, 6> jj, jn;
      jj << -skew(rd), Mat3d::Identity();
      jn << Mat3d::Zero(), -Mat3d::Identity();
      system.add_gradient(static_cast<int>(j), w * jj.transpose() * r);
      system.add_gradient(n, w * jn.transpose() * r);
      system.add(static_cast<int>(j), static_cast<int>(j), w * jj.transpose() * jj);
      system.add(n, n, w * jn.transpose() * jn);
      system.add(static_cast<int>(j), n, w * jj.transpose() * jn);
    }
  }

  SparseMatrix h = system.matrix(1e-6 * std::max(stiffness, 1e-3));
  if (analyse) solver.analyzePattern(h);
  solver.factorize(h);
  if (solver.info() != Eigen::Success) return false;
  const Eigen::VectorXd delta = solver.solve(-system.gradient());
  if (solver.info() != Eigen::Success || !delta.allFinite()) return false;
  for (std::size_t j = 0; j < g.node_vertex.size(); ++j) {
    state->rotation[j] = nearest_rotation(rotation_from_vector(delta.segment<3>(6 * j)) * state->rotation[j]);
    state->translation[j] += delta.segment<3>(6 * j + 3);
  }
  return true;
}

// ---- Vertex-level ARAP refinement ------------------------------------------------------

// Per-vertex rotations best mapping the template's one-rings onto `positions`.
std::vector<Mat3d> local_rotations(const TemplateModel& model, const std::vector<Vec3f>& positions) {
  const std::size_t nv = positions.size();
  std::vector<Mat3d> rotations(nv);
  tbb::parallel_for(std::size_t{0}, nv, [&](std::size_t i) {
    Mat3d cov = Mat3d::Zero();
    for (std::size_t k = 0; k < model.rings[i].size(); ++k) {
      const int j = model.rings[i][k];
      const Vec3d e = (positions[i] - positions[j]).cast<double>();
      const Vec3d e0 = (model.rest.positions[i] - model.rest.positions[j]).cast<double>();
      cov += model.ring_weights[i][k] * e * e0.transpose();
    }
    rotations[i] = nearest_rotation(cov);
  });
  return rotations;
}

SparseMatrix laplacian(const TemplateModel& model) {
  const int nv = static_cast<int>(model.rest.num_vertices());
  std::vector<Eigen::Triplet<double>> triplets;
  for (int i = 0; i < nv; ++i) {
    double diagonal = 0;
    for (std::size_t k = 0; k < model.rings[i].size(); ++k) {
      // Symmetrised: the edge (i, j) appears in both rings with the same cotangent weight.
      const double w = model.ring_weights[i][k];
      triplets.emplace_back(i, model.rings[i][k], -w);
      diagonal += w;
    }
    triplets.emplace_back(i, i, diagonal);
  }
  SparseMatrix l(nv, nv);
  l.setFromTriplets(triplets.begin(), triplets.end());
  return l;
}

}  // namespace

std::vector<int> folded_triangles(const TemplateModel& model, const std::vector<Vec3f>& positions) {
  const std::vector<Mat3d> rotations = local_rotations(model, positions);
  const auto& r = model.rest.positions;
  std::vector<int> out;
  for (std::size_t i = 0; i < model.rest.triangles.size(); ++i) {
    const Tri& t = model.rest.triangles[i];
    const Vec3d rest_normal = (r[t[1]] - r[t[0]]).cross(r[t[2]] - r[t[0]]).cast<double>();
    const Vec3d expected = (rotations[t[0]] + rotations[t[1]] + rotations[t[2]]) * rest_normal;
    const Vec3d now =
        (positions[t[1]] - positions[t[0]]).cross(positions[t[2]] - positions[t[0]]).cast<double>();
    if (now.dot(expected) <= 0) out.push_back(static_cast<int>(i));
  }
  return out;
}

void unfold(const TemplateModel& model, const std::vector<Vec3f>& graph_positions, int rings,
            std::vector<Vec3f>* positions) {
  if (rings < 0) return;
  const std::vector<int> folds = folded_triangles(model, *positions);
  if (folds.empty()) return;
  const int nv = static_cast<int>(positions->size());
  std::vector<int> index(nv, -1), patch;
  auto take = [&](int v) {
    if (index[v] < 0) {
      index[v] = static_cast<int>(patch.size());
      patch.push_back(v);
    }
  };
  for (int t : folds) {
    for (int v : model.rest.triangles[t]) take(v);
  }
  for (int r = 0; r < rings; ++r) {
    const std::size_t end = patch.size();
    for (std::size_t k = 0; k < end; ++k) {
      for (int w : model.rings[patch[k]]) take(w);
    }
  }
  // (L d)_i = 0 for the patch's vertices, d = x - graph position; d is the refinement's outside
  // the patch. L is symmetric: column i holds row i.
  const SparseMatrix l = laplacian(model);
  const int n = static_cast<int>(patch.size());
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, 3);
  for (int k = 0; k < n; ++k) {
    for (SparseMatrix::InnerIterator it(l, patch[k]); it; ++it) {
      const int j = static_cast<int>(it.row());
      if (index[j] >= 0) {
        triplets.emplace_back(k, index[j], it.value() + (j == patch[k] ? 1e-9 : 0.0));
      } else {
        rhs.row(k) -= it.value() * ((*positions)[j] - graph_positions[j]).cast<double>().transpose();
      }
    }
  }
  SparseMatrix a(n, n);
  a.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<SparseMatrix> solver(a);
  if (solver.info() != Eigen::Success) return;
  const Eigen::MatrixXd d = solver.solve(rhs);
  if (solver.info() != Eigen::Success || !d.allFinite()) return;
  std::vector<Vec3f> patched = *positions;
  for (int k = 0; k < n; ++k) {
    patched[patch[k]] = graph_positions[patch[k]] + d.row(k).transpose().cast<float>();
  }
  if (folded_triangles(model, patched).size() < folds.size()) *positions = std::move(patched);
}

namespace {

void refine_vertices(const TemplateModel& model, const SurfaceQuery& target,
                     const RegistrationOptions& options, std::vector<Vec3f>* positions) {
  const int nv = static_cast<int>(positions->size());
  const SparseMatrix l = laplacian(model);
  Eigen::SimplicialLDLT<SparseMatrix> solver;
  // A weak pull to the current positions keeps the system definite where nothing matches.
  const double anchor = 1e-4;
  const FrameSamples samples =
      options.reverse_weight > 0 ? sample_frame(target, model.rest.num_vertices()) : FrameSamples{};
  for (int it = 0; it < options.refine_iterations; ++it) {
    const std::vector<Vec3f> normals = vertex_normals(*positions, model.rest.triangles);
    const std::vector<Correspondence> matches =
        find_correspondences(*positions, normals, target, options.final_max_distance,
                             options.robust_scale, options);
    const std::vector<Mat3d> rotations = local_rotations(model, *positions);
    SparseMatrix a = l;
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nv, 3);
    if (!samples.points.empty()) {
      // Frame points pull the template's closest surface points (a triangle's barycentric
      // combination): c |sum_k b_k x_k - q|^2 couples the triangle's vertices, which the
      // Laplacian's pattern already does.
      const std::vector<ReverseMatch> reverse = find_reverse_correspondences(
          model, *positions, samples, options.final_max_distance, options.robust_scale, options);
      const double scale = options.refine_weight * options.reverse_weight * nv / reverse.size();
      for (const ReverseMatch& m : reverse) {
        if (m.weight <= 0) continue;
        const double c = scale * m.weight;
        for (int r = 0; r < 3; ++r) {
          for (int q = 0; q < 3; ++q) {
            a.coeffRef(m.triangle[r], m.triangle[q]) += c * m.barycentric[r] * m.barycentric[q];
          }
          rhs.row(m.triangle[r]) += c * m.barycentric[r] * m.point.transpose();
        }
      }
    }
    for (int i = 0; i < nv; ++i) {
      Vec3d b = rhs.row(i).transpose();
      for (std::size_t k = 0; k < model.rings[i].size(); ++k) {
        const int j = model.rings[i][k];
        const Vec3d e0 = (model.rest.positions[i] - model.rest.positions[j]).cast<double>();
        b += model.ring_weights[i][k] * 0.5 * (rotations[i] + rotations[j]) * e0;
      }
      const double c = options.refine_weight * matches[i].weight + anchor;
      a.coeffRef(i, i) += c;
      const Vec3d target_point = matches[i].weight > 0
                                     ? Vec3d(options.refine_weight * matches[i].weight * matches[i].point)
                                     : Vec3d::Zero();
      b += target_point + anchor * (*positions)[i].cast<double>();
      rhs.row(i) = b.transpose();
    }
    if (it == 0) solver.analyzePattern(a);
    solver.factorize(a);
    if (solver.info() != Eigen::Success) {
      throw SolverError("registration: the refinement system could not be factorised");
    }
    const Eigen::MatrixXd x = solver.solve(rhs);
    if (!x.allFinite()) throw SolverError("registration: the refinement diverged");
    for (int i = 0; i < nv; ++i) (*positions)[i] = x.row(i).transpose().cast<float>();
  }
}

}  // namespace

void RegistrationOptions::check() const {
  if (stiffness.empty()) throw ConfigError("stiffness: needs at least one level");
  if (final_max_distance > max_distance) {
    throw ConfigError(fmt::format("final_max_distance ({}) exceeds max_distance ({})",
                                  final_max_distance, max_distance));
  }
}

std::vector<Vec3f> vertex_normals(const std::vector<Vec3f>& positions,
                                  const std::vector<Tri>& triangles) {
  std::vector<Vec3f> normals(positions.size(), Vec3f::Zero());
  for (const Tri& t : triangles) {
    const Vec3f n = (positions[t[1]] - positions[t[0]]).cross(positions[t[2]] - positions[t[0]]);
    for (int k = 0; k < 3; ++k) normals[t[k]] += n;
  }
  for (Vec3f& n : normals) {
    const float len = n.norm();
    if (len > 0) n /= len;
  }
  return normals;
}

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

Eigen::Isometry3d rigid_icp(const std::vector<Vec3f>& points, const std::vector<Vec3f>& normals,
                            const SurfaceQuery& target, int iterations, double max_distance,
                            const RegistrationOptions& options) {
  Eigen::Isometry3d total = Eigen::Isometry3d::Identity();
  std::vector<Vec3f> current = points, current_normals = normals;
  for (int it = 0; it < iterations; ++it) {
    const std::vector<Correspondence> matches =
        find_correspondences(current, current_normals, target, max_distance,
                             std::max(options.robust_scale, max_distance / 3), options);
    Vec3d centroid = Vec3d::Zero();
    double weight_sum = 0;
    int matched = 0;
    for (std::size_t i = 0; i < current.size(); ++i) {
      if (matches[i].weight <= 0) continue;
      centroid += matches[i].weight * current[i].cast<double>();
      weight_sum += matches[i].weight;
      ++matched;
    }
    if (matched < 6) break;
    centroid /= weight_sum;
    // Linearised about the centroid (better conditioned): x -> x + w x (x - c) + t.
    Mat6 a = Mat6::Zero();
    Vec6 b = Vec6::Zero();
    for (std::size_t i = 0; i < current.size(); ++i) {
      const Correspondence& m = matches[i];
      if (m.weight <= 0) continue;
      const Vec3d p = current[i].cast<double>() - centroid;
      const Vec3d e = current[i].cast<double>() - m.point;
      Eigen::Matrix<double, 3, 6> j;
      j << -skew(p), Mat3d::Identity();
      const Mat3d w = m.weight * (m.normal * m.normal.transpose() +
                                  options.point_to_point * Mat3d::Identity());
      a += j.transpose() * w * j;
      b += j.transpose() * w * e;
    }
    a.diagonal().array() += 1e-9 * (1.0 + a.diagonal().maxCoeff());
    const Vec6 x = a.ldlt().solve(-b);
    if (!x.allFinite()) break;
    const Mat3d r = rotation_from_vector(x.head<3>());
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    step.linear() = r;
    step.translation() = centroid + x.tail<3>() - r * centroid;
    for (std::size_t i = 0; i < current.size(); ++i) {
      current[i] = (step * current[i].cast<double>()).cast<float>();
      current_normals[i] = (r * current_normals[i].cast<double>()).cast<float>();
    }
    total = step * total;
    if (x.head<3>().norm() < 1e-7 && x.tail<3>().norm() < 1e-8) break;
  }
  return total;
}

namespace {

// One registration from `start`, the landmarks pulling the coarse levels. It begins at level
// `first_level`: the coarse levels' stiff regulariser undoes a start's bends (it pulls the graph
// towards one rigid motion), so a start that already bends the limbs skips them.
DeformationState register_pass(const TemplateModel& model, const DeformationState& start,
                               const SurfaceQuery& target, const RegistrationOptions& options,
                               const std::vector<Landmark>& landmarks, int first_level = 0) {
  DeformationState state = start;
  std::vector<Vec3f> positions = deform_with_graph(model, state);
  if (options.rigid_iterations > 0) {
    const Eigen::Isometry3d motion =
        rigid_icp(positions, vertex_normals(positions, model.rest.triangles), target,
                  options.rigid_iterations, options.max_distance, options);
    apply_rigid(model, motion, &state);
  }

  const FrameSamples samples =
      options.reverse_weight > 0 ? sample_frame(target, model.rest.num_vertices()) : FrameSamples{};
  GraphSystem system(model, options.reverse_weight > 0);
  Eigen::SimplicialLDLT<SparseMatrix> solver;
  bool analysed = false;
  const int levels = static_cast<int>(options.stiffness.size());
  for (int level = std::min(first_level, levels - 1); level < levels; ++level) {
    // The matching distance shrinks geometrically from max_distance to final_max_distance.
    const double t = levels > 1 ? static_cast<double>(level) / (levels - 1) : 1.0;
    const double max_distance =
        options.max_distance * std::pow(options.final_max_distance / options.max_distance, t);
    const double robust_scale = std::max(options.robust_scale, max_distance / 3);
    for (int it = 0; it < options.iterations_per_level; ++it) {
      positions = deform_with_graph(model, state);
      const std::vector<Correspondence> matches = find_correspondences(
          positions, vertex_normals(positions, model.rest.triangles), target, max_distance,
          robust_scale, options);
      const std::vector<ReverseMatch> reverse =
          options.reverse_weight > 0
              ? find_reverse_correspondences(model, positions, samples, max_distance, robust_scale,
                                             options)
              : std::vector<ReverseMatch>{};
      const bool coarse = level < options.landmark_levels;
      if (!graph_gauss_newton_step(model, matches, reverse,
                                   coarse ? landmarks : std::vector<Landmark>{},
                                   options.stiffness[level], options,
                                   system, solver, !analysed, &state)) {
        throw SolverError("registration: the deformation graph system could not be solved");
      }
      analysed = true;
    }
  }
  state.positions = deform_with_graph(model, state);
  const std::vector<Vec3f> graph_positions = state.positions;
  refine_vertices(model, target, options, &state.positions);
  unfold(model, graph_positions, options.unfold_rings, &state.positions);
  return state;
}

}  // namespace

double two_sided_rms(const FitStats& s) {
  return std::sqrt(s.surface_rms * s.surface_rms + s.reverse_rms * s.reverse_rms);
}

std::size_t least_stretched_close_fit(const std::vector<FitStats>& fits, double stretch_tolerance,
                                      double stretch_margin) {
  std::size_t closest = 0;
  for (std::size_t i = 1; i < fits.size(); ++i) {
    if (two_sided_rms(fits[i]) < two_sided_rms(fits[closest])) closest = i;
  }
  std::size_t chosen = closest;
  for (std::size_t i = 0; i < fits.size(); ++i) {
    if (two_sided_rms(fits[i]) > stretch_tolerance * two_sided_rms(fits[closest])) continue;
    if (fits[i].stretch_rms < stretch_margin * fits[closest].stretch_rms &&
        fits[i].stretch_rms < fits[chosen].stretch_rms) {
      chosen = i;
    }
  }
  return chosen;
}

DeformationState turn_limbs_to_tips(const TemplateModel& model, const DeformationState& start,
                                    const std::vector<Landmark>& landmarks, double limb_fraction,
                                    double blend) {
  const Extremities& tips = model.extremities;
  const std::vector<Vec3f> at = deform_with_graph(model, start);
  DeformationState out = start;
  for (const Landmark& l : landmarks) {
    const auto tip = std::find(tips.vertices.begin(), tips.vertices.end(), l.vertex);
    if (tip == tips.vertices.end()) continue;
    const double length = limb_fraction * tips.geodesic[tip - tips.vertices.begin()];
    const std::vector<double>& dist = model.tip_distance[tip - tips.vertices.begin()];
    const std::vector<int> limb = within(dist, length);
    Vec3d joint = Vec3d::Zero();
    int border = 0;
    for (int v : limb) {
      for (int w : model.rings[v]) {
        if (dist[w] > length) {
          joint += at[v].cast<double>();
          ++border;
          break;
        }
      }
    }
    if (border == 0) continue;  // the whole template: not a limb
    joint /= border;
    const Vec3d from = at[l.vertex].cast<double>() - joint, to = l.point - joint;
    if (from.norm() < 1e-6 || to.norm() < 1e-6) continue;
    const Eigen::Quaterniond turn = Eigen::Quaterniond::FromTwoVectors(from, to);
    log::debug("limb of tip {}: {} vertices, {} on its border, turned {:.0f} deg", l.vertex,
               limb.size(), border, Eigen::AngleAxisd(turn).angle() * 180 / M_PI);
    const DeformationGraph& graph = model.graph;
    for (std::size_t k = 0; k < graph.node_vertex.size(); ++k) {
      const double d = dist[graph.node_vertex[k]];
      if (!(d <= length)) continue;
      const double w = blend > 0 ? std::clamp((length - d) / blend, 0.0, 1.0) : 1.0;
      const Mat3d r = Eigen::Quaterniond::Identity().slerp(w, turn).toRotationMatrix();
      // x -> r (y - joint) + joint after the node's own motion y = R (x - g) + g + t.
      const Vec3d& g = graph.node_position[k];
      out.rotation[k] = r * out.rotation[k];
      out.translation[k] = r * (g + out.translation[k] - joint) + joint - g;
    }
  }
  out.positions = deform_with_graph(model, out);
  return out;
}

DeformationState bend_limbs_along_frame(const TemplateModel& model, const DeformationState& start,
                                        const std::vector<Landmark>& landmarks,
                                        const std::vector<int>& frame_tips, const Mesh& frame,
                                        const std::vector<std::vector<int>>& frame_rings,
                                        double limb_fraction, double band) {
  const Extremities& tips = model.extremities;
  const std::vector<Vec3f> at = deform_with_graph(model, start);
  const double inf = std::numeric_limits<double>::infinity();
  DeformationState out = start;
  std::vector<double> frame_dist(frame.num_vertices(), inf);
  std::vector<int> frame_owner(frame.num_vertices(), -1);
  for (std::size_t l = 0; l < landmarks.size() && l < frame_tips.size(); ++l) {
    const auto tip = std::find(tips.vertices.begin(), tips.vertices.end(), landmarks[l].vertex);
    if (tip == tips.vertices.end()) continue;
    const double length = limb_fraction * tips.geodesic[tip - tips.vertices.begin()];
    const int bands = static_cast<int>(std::ceil(length / band));
    if (bands < 3) continue;
    const std::vector<double>& dist = model.tip_distance[tip - tips.vertices.begin()];
    const std::vector<int> limb = within(dist, length);
    const std::vector<int> reached = geodesic_update(frame, frame_rings, frame_tips[l], 0, length,
                                                     frame_dist, frame_owner);
    // The rings of equal geodesic distance from the tip, on the template and on the frame:
    // their centres are the limb's axis, whatever the limb's pose.
    struct Ring {
      Vec3d centre = Vec3d::Zero();
      double spread = 0;  // mean distance of its vertices from the centre
      int count = 0;
    };
    auto rings_of = [&](const std::vector<int>& vertices, const std::vector<double>& d,
                        auto position) {
      std::vector<Ring> r(bands);
      for (int v : vertices) {
        const int b = std::min(bands - 1, static_cast<int>(d[v] / band));
        r[b].centre += position(v);
        ++r[b].count;
      }
      for (Ring& x : r) {
        if (x.count > 0) x.centre /= x.count;
      }
      for (int v : vertices) {
        const int b = std::min(bands - 1, static_cast<int>(d[v] / band));
        r[b].spread += (position(v) - r[b].centre).norm() / r[b].count;
      }
      return r;
    };
    const std::vector<Ring> t_rings =
        rings_of(limb, dist, [&](int v) { return Vec3d(at[v].cast<double>()); });
    const std::vector<Ring> f_rings = rings_of(
        reached, frame_dist, [&](int v) { return Vec3d(frame.positions[v].cast<double>()); });
    for (int v : reached) frame_dist[v] = inf;
    // The limb is followed as far as the frame's rings look like the template's: a ring much
    // wider on the frame has run into the body (a hand resting on the hip).
    int valid = 0;
    while (valid < bands && t_rings[valid].count >= 3 && f_rings[valid].count >= 3 &&
           f_rings[valid].spread <= 1.5 * t_rings[valid].spread + 0.02) {
      ++valid;
    }
    if (valid < 3) continue;
    // Per ring: the turn of the limb's axis there and the move of its centre.
    std::vector<Mat3d> turn(valid);
    for (int b = 0; b < valid; ++b) {
      const int lo = std::max(0, b - 2), hi = std::min(valid - 1, b + 2);
      const Vec3d from = t_rings[hi].centre - t_rings[lo].centre;
      const Vec3d to = f_rings[hi].centre - f_rings[lo].centre;
      turn[b] = from.norm() > 1e-6 && to.norm() > 1e-6
                    ? Eigen::Quaterniond::FromTwoVectors(from, to).toRotationMatrix()
                    : Mat3d::Identity();
    }
    const double followed = std::min(length, valid * band);
    log::debug("limb of tip {}: followed along the frame over {:.2f} of {:.2f} m",
               landmarks[l].vertex, followed, length);
    const DeformationGraph& graph = model.graph;
    for (std::size_t k = 0; k < graph.node_vertex.size(); ++k) {
      const double d = dist[graph.node_vertex[k]];
      if (!(d <= length)) continue;
      const int b = std::min(valid - 1, static_cast<int>(d / band));
      // Beyond the followed part the last ring's motion fades out towards the limb's border.
      const double w = d < followed || length <= followed
                           ? 1.0
                           : std::clamp((length - d) / (length - followed), 0.0, 1.0);
      const Mat3d r = Eigen::Quaterniond::Identity()
                          .slerp(w, Eigen::Quaterniond(turn[b]))
                          .toRotationMatrix();
      const Vec3d shift = w * (f_rings[b].centre - t_rings[b].centre);
      // The node's moved position y = g + t turns about its ring's centre and moves with it.
      const Vec3d& g = graph.node_position[k];
      const Vec3d y = g + out.translation[k];
      out.rotation[k] = r * out.rotation[k];
      out.translation[k] = r * (y - t_rings[b].centre) + t_rings[b].centre + shift - g;
    }
  }
  out.positions = deform_with_graph(model, out);
  return out;
}

DeformationState register_to_surface(const TemplateModel& model, const DeformationState& start,
                                     const SurfaceQuery& target,
                                     const RegistrationOptions& options) {
  DeformationState fit = register_pass(model, start, target, options, {});
  if (options.landmark_weight <= 0) return fit;
  // A fit that covers the whole frame has followed every limb; the tips are looked for only
  // when part of the frame is left over.
  const FitStats first = evaluate_fit(model, fit.positions, target, options);
  if (first.uncovered_fraction <= options.landmark_uncovered) return fit;
  const TipLandmarks tips = tip_landmarks(model, fit.positions, target, options);
  if (tips.landmarks.empty()) return fit;
  struct Candidate {
    DeformationState state;
    FitStats stats;
  };
  std::vector<Candidate> candidates;
  candidates.push_back({std::move(fit), first});
  auto attempt = [&](const DeformationState& from, const char* what, int first_level = 0) {
    DeformationState retry =
        register_pass(model, from, target, options, tips.landmarks, first_level);
    const FitStats stats = evaluate_fit(model, retry.positions, target, options);
    log::debug("{}: both-ways rms {:.1f} mm -> {:.1f} mm, stretch {:.3f} -> {:.3f}", what,
               1e3 * two_sided_rms(first), 1e3 * two_sided_rms(stats), first.stretch_rms,
               stats.stretch_rms);
    candidates.push_back({std::move(retry), stats});
  };
  // A tip was missed: register again from the same start, pulled by the tips.
  if (tips.missed) attempt(start, "tip landmarks");
  // The limbs turned about their joints towards the tips first (the tips may all be covered
  // by a limb bent at the wrong joint).
  if (options.limb_fraction > 0) {
    attempt(turn_limbs_to_tips(model, start, tips.landmarks, options.limb_fraction,
                               options.limb_blend),
            "limbs turned to the tips");
    attempt(bend_limbs_along_frame(model, start, tips.landmarks, tips.frame_tips, tips.frame,
                                   tips.frame_rings, options.limb_fraction, options.limb_band),
            "limbs bent along the frame", options.bent_first_level);
  }
  // A retry must fit clearly closer than the first fit (a tip matched to the wrong limb, a
  // foot to the other foot, can still fit a little closer); of those, the least stretched of
  // the about closest wins.
  std::vector<std::size_t> closer;
  std::vector<FitStats> closer_stats;
  for (std::size_t i = 1; i < candidates.size(); ++i) {
    if (two_sided_rms(candidates[i].stats) < options.landmark_gain * two_sided_rms(first)) {
      closer.push_back(i);
      closer_stats.push_back(candidates[i].stats);
    }
  }
  if (closer.empty()) return std::move(candidates[0].state);
  const std::size_t chosen =
      least_stretched_close_fit(closer_stats, options.stretch_tolerance, options.stretch_margin);
  return std::move(candidates[closer[chosen]].state);
}

FitStats evaluate_fit(const TemplateModel& model, const std::vector<Vec3f>& positions,
                      const SurfaceQuery& target, const RegistrationOptions& options) {
  FitStats stats;
  const std::size_t nv = positions.size();
  std::vector<double> forward(nv, 0.0), forward_weight(nv, 1.0);
  tbb::parallel_for(std::size_t{0}, nv, [&](std::size_t i) {
    SurfaceHit hit = target.closest(positions[i], std::numeric_limits<float>::max());
    forward[i] = hit.found ? hit.distance : std::numeric_limits<double>::infinity();
    forward_weight[i] = confidence_weight(hit.confidence, options);
  });
  // The rms weights the frame's surface as the registration does: a fit that keeps away from
  // a membrane of low confidence is not a worse fit.
  double sum = 0, weights = 0;
  for (std::size_t i = 0; i < nv; ++i) {
    sum += forward_weight[i] * forward[i] * forward[i];
    weights += forward_weight[i];
  }
  stats.surface_rms = weights > 0 ? std::sqrt(sum / weights) : 0.0;
  if (nv) {
    std::vector<double> sorted = forward;
    const std::size_t k = std::min(nv - 1, static_cast<std::size_t>(0.95 * nv));
    std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
    stats.surface_p95 = sorted[k];
    stats.surface_max = *std::max_element(forward.begin(), forward.end());
  }

  // Reverse: does the fit cover the whole frame (a limb left behind shows up here only)?
  const SurfaceQuery fitted_query(fitted_mesh(model, positions));
  const std::vector<Vec3f>& frame_points = target.positions();
  const std::size_t stride = std::max<std::size_t>(1, frame_points.size() / 20000);
  const std::size_t samples = (frame_points.size() + stride - 1) / stride;
  std::vector<double> reverse(samples, 0.0);
  tbb::parallel_for(std::size_t{0}, samples, [&](std::size_t s) {
    SurfaceHit hit = fitted_query.closest(frame_points[s * stride], std::numeric_limits<float>::max());
    reverse[s] = hit.found ? hit.distance : std::numeric_limits<double>::infinity();
  });
  // Frame surface of low confidence counts for less.
  double reverse_sum = 0, uncovered = 0, total = 0;
  for (std::size_t s = 0; s < samples; ++s) {
    const double c = confidence_weight(target.vertex_confidence(s * stride), options);
    reverse_sum += c * reverse[s] * reverse[s];
    if (reverse[s] > options.coverage_distance) uncovered += c;
    total += c;
  }
  if (total > 0) {
    stats.reverse_rms = std::sqrt(reverse_sum / total);
    stats.uncovered_fraction = uncovered / total;
  }

  // Stretch: how far the fit is from an isometry of the template (edge lengths).
  double stretch_sum = 0;
  std::size_t edges = 0;
  for (std::size_t v = 0; v < nv; ++v) {
    for (int w : model.rings[v]) {
      if (static_cast<std::size_t>(w) <= v) continue;
      const double rest = (model.rest.positions[v] - model.rest.positions[w]).norm();
      if (rest <= 0) continue;
      const double change = (positions[v] - positions[w]).norm() / rest - 1;
      stretch_sum += change * change;
      ++edges;
    }
  }
  stats.stretch_rms = edges ? std::sqrt(stretch_sum / edges) : 0.0;

  stats.flipped_triangles = static_cast<int>(folded_triangles(model, positions).size());
  return stats;
}

}  // namespace fourd::align
