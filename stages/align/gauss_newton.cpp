// Gauss-Newton on the embedded deformation graph: per step, the data terms (both ways), the
// landmarks and the as-rigid-as-possible regulariser summed into a block-sparse system.
#include "stages/align/registration_internal.h"

#include "stages/align/block_cholesky.h"

#include <tbb/parallel_for.h>

#include <algorithm>

namespace fourd::align::detail {

namespace {

// The block pattern of the Gauss-Newton matrix: a 6x6 block per pair of nodes that share a
// vertex or a graph edge. Fixed for the template, so the block Cholesky's ordering and pattern
// are computed once and every step factorises the blocks' values.
class GraphSystem {
 public:
  // With `reverse_matches`, also the blocks the reverse matches need.
  GraphSystem(const TemplateModel& model, bool reverse_matches) {
    const DeformationGraph& g = model.graph;
    nodes_ = static_cast<int>(g.node_vertex.size());
    // Per node a, the nodes b >= a it shares a block with.
    std::vector<std::vector<int>> rows(nodes_);
    auto pair = [&](int a, int b) {
      if (a >= 0 && b >= 0) rows[std::min(a, b)].push_back(std::max(a, b));
    };
    for (int j = 0; j < nodes_; ++j) pair(j, j);
    const int nv = static_cast<int>(model.rest.num_vertices()), k = g.influences;
    for (int v = 0; v < nv; ++v) {
      for (int a = 0; a < k; ++a) {
        for (int b = a; b < k; ++b) pair(g.influence_node[v * k + a], g.influence_node[v * k + b]);
      }
    }
    // Reverse matches tie the nodes of a triangle's three vertices together (each node once:
    // the three mostly share theirs).
    std::vector<int> tied;
    for (const Tri& t : reverse_matches ? model.rest.triangles : std::vector<Tri>{}) {
      tied.clear();
      for (int a = 0; a < 3 * k; ++a) tied.push_back(g.influence_node[t[a / k] * k + a % k]);
      std::sort(tied.begin(), tied.end());
      tied.erase(std::unique(tied.begin(), tied.end()), tied.end());
      for (std::size_t a = 0; a < tied.size(); ++a) {
        for (std::size_t b = a; b < tied.size(); ++b) pair(tied[a], tied[b]);
      }
    }
    for (int j = 0; j < nodes_; ++j) {
      for (int n : g.node_neighbours[j]) pair(j, n);
    }
    row_start_.assign(1, 0);
    for (int a = 0; a < nodes_; ++a) {
      std::sort(rows[a].begin(), rows[a].end());
      rows[a].erase(std::unique(rows[a].begin(), rows[a].end()), rows[a].end());
      for (int b : rows[a]) pairs_.emplace_back(a, b);
      cols_.insert(cols_.end(), rows[a].begin(), rows[a].end());
      row_start_.push_back(static_cast<int>(cols_.size()));
    }
    // A graph of up to kDenseNodes nodes looks its blocks up in a table (at most 4 MB; 250 KB
    // at the default 250 nodes) instead of searching the row: every data term looks up 10 to
    // 80 blocks, and the search's mispredicted branches were a quarter of their assembly.
    if (nodes_ <= kDenseNodes) {
      dense_.assign(static_cast<std::size_t>(nodes_) * nodes_, -1);
      for (std::size_t i = 0; i < pairs_.size(); ++i) {
        dense_[static_cast<std::size_t>(pairs_[i].first) * nodes_ + pairs_[i].second] =
            static_cast<int>(i);
      }
    }
    cholesky_ = std::make_unique<BlockCholesky>(nodes_, pairs_);
  }

  int unknowns() const { return 6 * nodes_; }

  // Partial sums of the matrix blocks and the gradient. The data terms are summed in a fixed
  // number of parts over fixed ranges of points, in parallel, and the parts are added in their
  // order: the result does not depend on the thread count or scheduling (runs are repeatable
  // bit for bit). A part's points (neighbours on the surface) touch a small share of the
  // blocks: the parts but the first remember which, and only those are added and zeroed again
  // (all of them would be ~2 MB per part, every step).
  struct Part {
    std::vector<Mat6> blocks;
    Eigen::VectorXd gradient;
    std::vector<int> touched;         // the blocks written since the last clear()
    std::vector<char> is_touched;     // per block
  };

  // Zeroes `parts` partial sums (at least one: part 0, which add() and add_gradient() fill).
  // The parts stay allocated: zeroed instead of allocated again every Gauss-Newton step.
  void clear(int parts) {
    parts_.resize(std::max(parts, 1));
    for (std::size_t i = 0; i < parts_.size(); ++i) {
      Part& part = parts_[i];
      if (i == 0 || part.blocks.size() != pairs_.size()) {
        part.blocks.assign(pairs_.size(), Mat6::Zero());  // reuses the storage
        part.is_touched.assign(pairs_.size(), 0);
      } else {
        for (int b : part.touched) {
          part.blocks[b].setZero();
          part.is_touched[b] = 0;
        }
      }
      part.touched.clear();
      part.gradient.setZero(6 * nodes_);
    }
  }
  Part& part(int i) { return parts_[i]; }
  // The block H(a, b), a <= b, of a part, to add to. Thread-safe for distinct parts.
  Mat6& block_of(Part& part, int a, int b) const {
    const int index = block(a, b);
    if (!part.is_touched[index]) {
      part.is_touched[index] = 1;
      part.touched.push_back(index);
    }
    return part.blocks[index];
  }
  // H(a, b) += m (the lower triangle follows by symmetry). Thread-safe for distinct parts.
  void add(Part& part, int a, int b, const Mat6& m) const {
    if (a <= b) {
      block_of(part, a, b) += m;
    } else {
      block_of(part, b, a) += m.transpose();
    }
  }
  void add(int a, int b, const Mat6& m) { add(parts_[0], a, b, m); }
  static void add_gradient(Part& part, int a, const Vec6& g) { part.gradient.segment<6>(6 * a) += g; }
  void add_gradient(int a, const Vec6& g) { add_gradient(parts_[0], a, g); }
  // Adds parts 1.. into part 0, in order (a block a part did not touch is zero in it).
  void sum_parts() {
    for (std::size_t i = 1; i < parts_.size(); ++i) {
      for (int b : parts_[i].touched) parts_[0].blocks[b] += parts_[i].blocks[b];
      parts_[0].gradient += parts_[i].gradient;
    }
  }

  // Factorises the summed matrix with `damping` added to its diagonal; false when it is not
  // positive definite.
  bool factorize(double damping) { return cholesky_->factorize(parts_[0].blocks, damping); }
  // The solution of the factorised system with right-hand side b.
  Eigen::VectorXd solve(const Eigen::VectorXd& b) const { return cholesky_->solve(b); }
  const Eigen::VectorXd& gradient() const { return parts_[0].gradient; }

 private:
  // The block of nodes a <= b.
  int block(int a, int b) const {
    if (!dense_.empty()) return dense_[static_cast<std::size_t>(a) * nodes_ + b];
    const auto begin = cols_.begin() + row_start_[a], end = cols_.begin() + row_start_[a + 1];
    return static_cast<int>(std::lower_bound(begin, end, b) - cols_.begin());
  }

  int nodes_ = 0;
  static constexpr int kDenseNodes = 1024;
  std::vector<int> row_start_, cols_;  // per node a, the nodes b >= a of its blocks, sorted
  std::vector<int> dense_;  // block of nodes a <= b at a * nodes_ + b (small graphs only)
  std::vector<std::pair<int, int>> pairs_;  // block i is pairs_[i] = (a, b), a <= b
  std::vector<Part> parts_;
  std::unique_ptr<BlockCholesky> cholesky_;
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
// e = point - target and symmetric weight matrix P. With J_a = [S_a, w_a I], the block of nodes
// a <= b is J_a^T P J_b = [(P S_a)^T S_b, w_b (P S_a)^T; w_a P S_b, w_a w_b P]: P S_a once per
// node, not per pair.
void add_point_term(const NodeJacobian* jac, int nodes, const Mat3d& p, const Vec3d& e,
                    const GraphSystem& system, GraphSystem::Part& part) {
  const Vec3d pe = p * e;
  Mat3d ps[3 * 8];
  for (int a = 0; a < nodes; ++a) ps[a] = p * jac[a].s;
  for (int a = 0; a < nodes; ++a) {
    Vec6 grad;
    grad << jac[a].s.transpose() * pe, jac[a].w * pe;
    GraphSystem::add_gradient(part, jac[a].node, grad);
    for (int b = 0; b < nodes; ++b) {
      if (jac[a].node > jac[b].node) continue;
      Mat6& block = system.block_of(part, jac[a].node, jac[b].node);
      block.topLeftCorner<3, 3>().noalias() += ps[a].transpose() * jac[b].s;
      block.topRightCorner<3, 3>() += jac[b].w * ps[a].transpose();
      block.bottomLeftCorner<3, 3>() += jac[a].w * ps[b];
      block.bottomRightCorner<3, 3>() += (jac[a].w * jac[b].w) * p;
    }
  }
}

// One Gauss-Newton step of the graph energy; updates `state` (rotations, translations).
// Returns false when the system could not be factorised.
bool graph_gauss_newton_step(const TemplateModel& model, const std::vector<Correspondence>& matches,
                             const std::vector<ReverseMatch>& reverse,
                             const std::vector<Landmark>& landmarks, double stiffness,
                             const RegistrationOptions& options, GraphSystem& system,
                             DeformationState* state) {
  const DeformationGraph& g = model.graph;
  const std::vector<int>& data_vertices = model.data_vertices;
  const int nv = static_cast<int>(data_vertices.size());
  // Data weight per vertex: nodes / data vertices, so that the balance with the regulariser does
  // not depend on the template's resolution.
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
        const int v = data_vertices[i];
        const Correspondence& m = matches[i];
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

  if (!system.factorize(1e-6 * std::max(stiffness, 1e-3))) return false;
  const Eigen::VectorXd delta = system.solve(-system.gradient());
  if (!delta.allFinite()) return false;
  for (std::size_t j = 0; j < g.node_vertex.size(); ++j) {
    state->rotation[j] = nearest_rotation(rotation_from_vector(delta.segment<3>(6 * j)) * state->rotation[j]);
    state->translation[j] += delta.segment<3>(6 * j + 3);
  }
  return true;
}

}  // namespace

struct GraphGaussNewton::Impl {
  Impl(const TemplateModel& model, bool reverse_matches) : model(model), system(model, reverse_matches) {}
  const TemplateModel& model;
  GraphSystem system;
};

GraphGaussNewton::GraphGaussNewton(const TemplateModel& model, bool reverse_matches)
    : impl_(std::make_unique<Impl>(model, reverse_matches)) {}

GraphGaussNewton::~GraphGaussNewton() = default;

bool GraphGaussNewton::step(const std::vector<Correspondence>& matches,
                            const std::vector<ReverseMatch>& reverse,
                            const std::vector<Landmark>& landmarks, double stiffness,
                            const RegistrationOptions& options, DeformationState* state) {
  return graph_gauss_newton_step(impl_->model, matches, reverse, landmarks, stiffness, options,
                                 impl_->system, state);
}

}  // namespace fourd::align::detail
