#include "stages/motionspace/hybrid_build.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <map>
#include <vector>

#include "pipeline/core/error.h"
#include "stages/motionspace/nonlinear_blend.h"

namespace fourd {

namespace {

// A cell of the weight simplex. Triangles (3 inputs) keep newest-vertex-bisection order:
// corners[0] is the newest vertex and corners[1]-corners[2] the refinement edge. Segments
// (2 inputs) use corners[0..1].
struct Cell {
  std::array<int, 3> corners{-1, -1, -1};
  int depth = 0;
  double error = -1;  // max test error; < 0 while untested
  // false only for the root before its first refinement: a linear cell without midpoints.
  bool quadratic = true;
  double arc = 0;  // arc angle of a 2-input segment's shape functions (runtime/blend.h)
};

// Barycentric positions of the test weights inside a cell. A quadratic cell's nodes (corners
// and edge midpoints) are exact, so the tests sit between them, where it errs most: on a
// segment at its quarter points (the P2 error, a cubic vanishing at 0, 1/2 and 1, peaks at
// 0.21 and 0.79); in a triangle at the quarter points of its edges, its centroid and half way
// from each corner to the opposite edge's midpoint. The quarter points are where a split puts
// the new references, so their solves are not wasted. A linear cell (the root, at first) is
// also tested at its edge midpoints, where it errs most and where its references would go.
std::vector<std::array<double, 3>> test_points(int num_inputs, bool quadratic) {
  std::vector<std::array<double, 3>> points;
  if (num_inputs == 2) {
    points = {{0.75, 0.25, 0}, {0.25, 0.75, 0}};
    if (!quadratic) points.push_back({0.5, 0.5, 0});
    return points;
  }
  const double third = 1.0 / 3;
  points = {{0.75, 0.25, 0},   {0.25, 0.75, 0},   {0, 0.75, 0.25},      {0, 0.25, 0.75},
            {0.25, 0, 0.75},   {0.75, 0, 0.25},   {third, third, third}, {0.5, 0.25, 0.25},
            {0.25, 0.5, 0.25}, {0.25, 0.25, 0.5}};
  if (!quadratic) points.insert(points.end(), {{0, 0.5, 0.5}, {0.5, 0, 0.5}, {0.5, 0.5, 0}});
  return points;
}

// The working state of the bisection: the leaf cells and where every edge midpoint went.
class Refinement {
 public:
  // The root starts linear (the inputs alone: no reference); its first refinement gives it its
  // edge midpoints, which makes it quadratic, and later ones bisect.
  explicit Refinement(BlendSpace* space) : space_(space), references_(space->num_references()) {
    Cell root;
    root.corners = space->cells.front();
    root.quadratic = false;
    cells_.push_back(root);
  }

  std::vector<Cell>& cells() { return cells_; }
  const std::vector<int>& pending() const { return pending_; }
  void clear_pending() { pending_.clear(); }
  int added() const { return space_->num_references() - space_->num_inputs; }

  // Splits cell i (with its neighbour across the refinement edge, for triangles).
  void refine(int i) {
    if (!cells_[i].quadratic) {  // linear -> quadratic: the midpoints the bisection would add
      add_midpoints(cells_[i]);
      cells_[i].quadratic = true;
      cells_[i].error = -1;
      return;
    }
    if (space_->num_inputs == 2) {
      const Cell c = cells_[i];
      const int m = midpoint(c.corners[0], c.corners[1]);
      cells_[i] = Cell{{c.corners[0], m, -1}, c.depth + 1};
      cells_.push_back(Cell{{m, c.corners[1], -1}, c.depth + 1});
      add_midpoints(cells_[i]);
      add_midpoints(cells_.back());
      return;
    }
    // Newest-vertex bisection: the neighbour across the refinement edge must share it as its
    // own refinement edge before both are split; otherwise split the neighbour first.
    for (;;) {
      const int j = neighbour(i);
      if (j < 0) {
        bisect(i);
        return;
      }
      if (same_edge(cells_[j], cells_[i])) {
        bisect(j);
        bisect(i);
        return;
      }
      refine(j);
    }
  }

  // Returns to an earlier state of this refinement, dropping the references added since.
  void restore(Refinement&& earlier) {
    *this = std::move(earlier);
    truncate_references(space_, references_);
  }

  // Writes the leaf cells into the space.
  void store_cells() const {
    space_->cells.clear();
    space_->cell_arc_angles.clear();
    bool any_arc = false;
    for (const Cell& c : cells_) {
      space_->cells.push_back(c.corners);
      space_->cell_arc_angles.push_back(c.arc);
      any_arc = any_arc || c.arc != 0;
    }
    if (!any_arc) space_->cell_arc_angles.clear();
  }

 private:
  // Reference at the midpoint of edge (a, b), created on first use (its frames are pending).
  int midpoint(int a, int b) {
    const auto key = std::minmax(a, b);
    if (auto it = midpoints_.find(key); it != midpoints_.end()) return it->second;
    const int n = space_->num_inputs;
    std::vector<double> w(n);
    for (int k = 0; k < n; ++k) {
      w[k] = 0.5 * (space_->reference_weights[a * n + k] + space_->reference_weights[b * n + k]);
    }
    const int m = add_reference(space_, w);
    references_ = space_->num_references();
    midpoints_[key] = m;
    pending_.push_back(m);
    return m;
  }

  static bool same_edge(const Cell& a, const Cell& b) {
    return std::minmax(a.corners[1], a.corners[2]) == std::minmax(b.corners[1], b.corners[2]);
  }

  // The other leaf triangle holding cell i's refinement edge, or -1 on the simplex boundary.
  int neighbour(int i) const {
    const int a = cells_[i].corners[1], b = cells_[i].corners[2];
    for (int j = 0; j < static_cast<int>(cells_.size()); ++j) {
      const auto& c = cells_[j].corners;
      if (j != i && std::count(c.begin(), c.end(), a) && std::count(c.begin(), c.end(), b))
        return j;
    }
    return -1;
  }

  void bisect(int i) {
    const Cell c = cells_[i];
    const int m = midpoint(c.corners[1], c.corners[2]);
    cells_[i] = Cell{{m, c.corners[0], c.corners[1]}, c.depth + 1};
    cells_.push_back(Cell{{m, c.corners[2], c.corners[0]}, c.depth + 1});
    add_midpoints(cells_[i]);
    add_midpoints(cells_.back());
  }

  // Every leaf cell is quadratic: its edges' midpoint references (the nodes the runtime's
  // cell_midpoints finds by weight), created on first use.
  void add_midpoints(const Cell& c) {
    const int n = space_->num_inputs;
    if (n == 2) {
      midpoint(c.corners[0], c.corners[1]);
    } else if (n == 3) {
      for (int k = 0; k < 3; ++k) midpoint(c.corners[k], c.corners[(k + 1) % 3]);
    }
  }

  BlendSpace* space_;
  int references_;  // references in the space in this state (restore() truncates to it)
  std::vector<Cell> cells_;
  std::map<std::pair<int, int>, int> midpoints_;
  std::vector<int> pending_;
};

// One test: a weight inside a cell, with its coordinates in that cell.
struct Test {
  int cell;
  std::array<double, 3> g;
  int weight;  // index into the unique test weights
};

// The mesh of a reference at frame f (runtime/blend.h: an input's frame, or the linear blend
// plus the stored displacement).
Eigen::Matrix3Xd frame_positions(const BlendSpace& space, int reference, int f) {
  std::vector<float> p(space.frame_stride());
  reference_frame(space, reference, f, p.data());
  const std::size_t stride = space.plane_stride;
  Eigen::Matrix3Xd x(3, space.num_vertices);
  for (int v = 0; v < space.num_vertices; ++v) x.col(v) << p[v], p[stride + v], p[2 * stride + v];
  return x;
}

void store_frame(const Eigen::Matrix3Xd& x, int reference, int f, BlendSpace* space) {
  std::vector<Vec3f> p(space->num_vertices);
  for (int v = 0; v < space->num_vertices; ++v) p[v] = x.col(v).cast<float>();
  set_frame(space, reference, f, p);
}

// Largest vertex distance between x and the runtime's blend inside `cell` at barycentric
// coordinates g (Eq. 1 with the cell's quadratic shape functions), at frame f.
double max_distance(const Eigen::Matrix3Xd& x, const BlendSpace& space,
                    const std::array<int, 3>& corners, const std::array<double, 3>& g, double arc,
                    int f) {
  CellNodes nodes;
  cell_shape_functions(space, corners, cell_midpoints(space, corners), g, arc, &nodes);
  Eigen::Matrix3Xd blend = Eigen::Matrix3Xd::Zero(3, space.num_vertices);
  for (int k = 0; k < nodes.count; ++k) {
    blend += nodes.g[k] * frame_positions(space, nodes.references[k], f);
  }
  return (x - blend).colwise().norm().maxCoeff();
}

}  // namespace

double segment_arc_angle(const BlendSpace& space, int a, int m, int b) {
  if (m < 0) return 0;
  double num = 0, den = 0;
  for (int f = 0; f < space.num_frames; ++f) {
    const Eigen::Matrix3Xd pa = frame_positions(space, a, f);
    const Eigen::Matrix3Xd pm = frame_positions(space, m, f);
    const Eigen::Matrix3Xd pb = frame_positions(space, b, f);
    for (int v = 0; v < space.num_vertices; ++v) {
      const Eigen::Vector3d xa = pa.col(v), xm = pm.col(v), xb = pb.col(v);
      const Eigen::Vector3d u = xa - xm, w = xb - xm;
      const double sagitta2 = (xm - 0.5 * (xa + xb)).squaredNorm();
      const double nu = u.norm(), nw = w.norm();
      if (!(sagitta2 > 0) || !(nu > 0) || !(nw > 0)) continue;
      // The inscribed angle at the midpoint node is pi - theta / 2.
      const double inscribed = std::acos(std::clamp(u.dot(w) / (nu * nw), -1.0, 1.0));
      num += sagitta2 * 2 * (std::numbers::pi - inscribed);
      den += sagitta2;
    }
  }
  return den > 0 ? std::clamp(num / den, 0.0, std::numbers::pi) : 0.0;
}

namespace {

void check_space(const BlendSpace& space, const Eigen::Matrix3Xd& reference) {
  space.check();
  if (space.num_references() != space.num_inputs || space.cells.size() != 1) {
    throw InputError(
        fmt::format("hybrid build: the blend space already has {} references and {} cells; "
                    "expected only its {} inputs",
                    space.num_references(), space.cells.size(), space.num_inputs));
  }
  if (reference.cols() != space.num_vertices) {
    throw InputError(fmt::format("hybrid build: reference mesh has {} vertices, the inputs have {}",
                                 reference.cols(), space.num_vertices));
  }
}

// The test weights of every untested cell; a weight shared by two cells (an edge midpoint)
// is solved once.
struct TestSet {
  std::vector<Test> tests;
  std::vector<std::vector<double>> weights;
};

TestSet collect_tests(const BlendSpace& space, const std::vector<Cell>& cells) {
  const int n = space.num_inputs;
  TestSet set;
  std::map<std::array<long long, 3>, int> weight_index;
  for (int c = 0; c < static_cast<int>(cells.size()); ++c) {
    if (cells[c].error >= 0) continue;
    for (const auto& g : test_points(n, cells[c].quadratic)) {
      std::vector<double> w(n, 0.0);
      for (int k = 0; k < n; ++k) {
        for (int i = 0; i < n; ++i) {
          w[i] += g[k] * space.reference_weights[cells[c].corners[k] * n + i];
        }
      }
      std::array<long long, 3> key{};
      for (int i = 0; i < n; ++i) key[i] = std::llround(w[i] * 1e9);
      auto [it, inserted] = weight_index.emplace(key, static_cast<int>(set.weights.size()));
      if (inserted) set.weights.push_back(w);
      set.tests.push_back({c, g, it->second});
    }
  }
  return set;
}

// The non-linear blend at the pending references, stored in the space at every frame. Frames
// run in parallel; each writes only its own frames.
void solve_pending(const NonlinearBlendData& data, const std::vector<int>& pending,
                   BlendSpace* space) {
  if (pending.empty()) return;
  const int n = space->num_inputs;
  tbb::parallel_for(0, space->num_frames, [&](int f) {
    std::vector<Eigen::Matrix3Xd> inputs(n);
    for (int k = 0; k < n; ++k) inputs[k] = frame_positions(*space, k, f);
    NonlinearBlendInputs prepared;
    nonlinear_blend_prepare(data, inputs, &prepared);
    Eigen::Matrix3Xd x;
    for (int r : pending) {
      const std::span<const double> w(space->reference_weights.data() + r * n, n);
      nonlinear_blend_solve(data, prepared, w, &x);
      store_frame(x, r, f, space);
    }
  });
}

// For every frame: the non-linear blend at the test weights, compared with the hybrid (for
// each of its cell's candidate arc angles) and the linear blend. Returns per test and candidate
// its largest error over the frames; raises *linear_error to the linear blend's largest error.
// Frames run in parallel; each writes only its own row of errors.
std::vector<std::array<double, 2>> test_frames(
    const NonlinearBlendData& data, const TestSet& set, const std::vector<Cell>& cells,
    const std::vector<std::array<double, 2>>& candidates, const BlendSpace& space,
    double* linear_error) {
  const int n = space.num_inputs;
  const int nt = static_cast<int>(set.tests.size());
  std::vector<std::array<double, 2>> errors(static_cast<std::size_t>(space.num_frames) * nt,
                                            {0.0, 0.0});
  std::vector<double> linear_errors(space.num_frames, 0.0);
  tbb::parallel_for(0, space.num_frames, [&](int f) {
    std::vector<Eigen::Matrix3Xd> inputs(n);
    for (int k = 0; k < n; ++k) inputs[k] = frame_positions(space, k, f);
    NonlinearBlendInputs prepared;
    nonlinear_blend_prepare(data, inputs, &prepared);
    Eigen::Matrix3Xd x;
    for (int wi = 0; wi < static_cast<int>(set.weights.size()); ++wi) {
      nonlinear_blend_solve(data, prepared, set.weights[wi], &x);
      const Eigen::Matrix3Xd linear = linear_blend(inputs, set.weights[wi]);
      linear_errors[f] = std::max(linear_errors[f], (x - linear).colwise().norm().maxCoeff());
      for (int ti = 0; ti < nt; ++ti) {
        const Test& test = set.tests[ti];
        if (test.weight != wi) continue;
        auto& e = errors[static_cast<std::size_t>(f) * nt + ti];
        for (int k = 0; k < 2; ++k) {
          const double arc = candidates[test.cell][k];
          e[k] = k > 0 && arc == candidates[test.cell][0]
                     ? e[0]
                     : max_distance(x, space, cells[test.cell].corners, test.g, arc, f);
        }
      }
    }
  });
  std::vector<std::array<double, 2>> worst(nt, {0.0, 0.0});
  for (int f = 0; f < space.num_frames; ++f) {
    *linear_error = std::max(*linear_error, linear_errors[f]);
    for (int ti = 0; ti < nt; ++ti) {
      for (int k = 0; k < 2; ++k) {
        worst[ti][k] = std::max(worst[ti][k], errors[static_cast<std::size_t>(f) * nt + ti][k]);
      }
    }
  }
  return worst;
}

// Bisects the cells above epsilon, worst first, while depth and the reference budget allow.
// Closure may split more cells than the one marked, so a split that would overrun the budget
// is undone. Returns whether anything was split.
bool refine_worst(const HybridBuildOptions& options, Refinement* refinement) {
  const std::vector<Cell>& cells = refinement->cells();
  std::vector<int> marked;
  for (int c = 0; c < static_cast<int>(cells.size()); ++c) {
    if (cells[c].error > options.epsilon &&
        (cells[c].depth < options.max_depth || !cells[c].quadratic)) {
      marked.push_back(c);
    }
  }
  std::sort(marked.begin(), marked.end(),
            [&](int a, int b) { return cells[a].error > cells[b].error; });
  // Refining replaces a cell by a child in place and appends the rest, so the indices of marked
  // cells stay valid; a cell already split by another's closure is untested (error < 0).
  bool any = false;
  for (int c : marked) {
    if (refinement->cells()[c].error < 0) continue;
    Refinement before = *refinement;
    refinement->refine(c);
    if (refinement->added() > options.max_references) {
      refinement->restore(std::move(before));
      break;
    }
    any = true;
  }
  return any;
}

}  // namespace

void HybridBuildOptions::check() const {
  if (!(epsilon > 0)) throw ConfigError(fmt::format("epsilon: must be > 0 (got {})", epsilon));
  if (max_depth < 0) throw ConfigError(fmt::format("max_depth: must be >= 0 (got {})", max_depth));
  if (max_references < 0) {
    throw ConfigError(fmt::format("max_references: must be >= 0 (got {})", max_references));
  }
}

HybridBuildReport build_hybrid_references(const HybridBuildOptions& options,
                                          const Eigen::Matrix3Xd& reference,
                                          std::span<const Tri> triangles, BlendSpace* space) {
  options.check();
  check_space(*space, reference);
  HybridBuildReport report;
  if (space->num_inputs == 1) {  // a single input: the hybrid is the input, exactly
    report.cells = 1;
    report.converged = true;
    return report;
  }
  NonlinearBlendData data;
  nonlinear_blend_precompute(reference, triangles, &data);

  Refinement refinement(space);
  do {
    solve_pending(data, refinement.pending(), space);
    const TestSet set = collect_tests(*space, refinement.cells());
    // Candidate shape functions of each untested cell: quadratic, and for a 2-input segment
    // the arc basis with the angle its nodes draw; the cell keeps the better at its tests.
    std::vector<Cell>& cells = refinement.cells();
    std::vector<std::array<double, 2>> candidates(cells.size(), {0.0, 0.0});
    for (std::size_t c = 0; c < cells.size(); ++c) {
      if (cells[c].error >= 0 || !cells[c].quadratic || space->num_inputs != 2) continue;
      const int m = cell_midpoints(*space, cells[c].corners)[0];
      candidates[c][1] = segment_arc_angle(*space, cells[c].corners[0], m, cells[c].corners[1]);
    }
    const std::vector<std::array<double, 2>> errors =
        test_frames(data, set, cells, candidates, *space, &report.linear_max_error);
    report.nonlinear_solves +=
        space->num_frames * static_cast<int>(refinement.pending().size() + set.weights.size());
    refinement.clear_pending();
    std::vector<std::array<double, 2>> cell_errors(cells.size(), {-1.0, -1.0});
    for (std::size_t ti = 0; ti < set.tests.size(); ++ti) {
      auto& e = cell_errors[set.tests[ti].cell];
      for (int k = 0; k < 2; ++k) e[k] = std::max({e[k], 0.0, errors[ti][k]});
    }
    for (std::size_t c = 0; c < cells.size(); ++c) {
      if (cell_errors[c][0] < 0) continue;  // tested earlier
      const int k = cell_errors[c][1] < cell_errors[c][0] ? 1 : 0;
      cells[c].arc = candidates[c][k];
      cells[c].error = cell_errors[c][k];
    }
  } while (refine_worst(options, &refinement));

  refinement.store_cells();
  report.references_added = refinement.added();
  report.cells = static_cast<int>(refinement.cells().size());
  for (const Cell& c : refinement.cells()) {
    report.max_depth = std::max(report.max_depth, c.depth);
    report.max_error = std::max(report.max_error, c.error);
  }
  report.converged = report.max_error <= options.epsilon;
  space->check();
  return report;
}

void add_line_references(const Eigen::Matrix3Xd& reference, std::span<const Tri> triangles,
                         std::span<const double> s, BlendSpace* space) {
  check_space(*space, reference);
  if (space->num_inputs != 2) {
    throw InputError(fmt::format("line references: the space has {} inputs, expected 2",
                                 space->num_inputs));
  }
  for (std::size_t j = 0; j < s.size(); ++j) {
    if (!(s[j] > 0 && s[j] < 1) || (j > 0 && !(s[j] > s[j - 1]))) {
      throw InputError(fmt::format("line references: weights must increase strictly inside (0, 1) "
                                   "(reference {} at {})",
                                   j, s[j]));
    }
  }
  std::vector<int> refs;
  for (double sj : s) refs.push_back(add_reference(space, std::array<double, 2>{1 - sj, sj}));
  NonlinearBlendData data;
  nonlinear_blend_precompute(reference, triangles, &data);
  tbb::parallel_for(0, space->num_frames, [&](int f) {
    std::vector<Eigen::Matrix3Xd> inputs{frame_positions(*space, 0, f),
                                         frame_positions(*space, 1, f)};
    NonlinearBlendInputs prepared;
    nonlinear_blend_prepare(data, inputs, &prepared);
    Eigen::Matrix3Xd x;
    for (std::size_t j = 0; j < refs.size(); ++j) {
      nonlinear_blend_solve(data, prepared, std::array<double, 2>{1 - s[j], s[j]}, &x);
      store_frame(x, refs[j], f, space);
    }
  });
  // Nodes along the line: input 0, the references, input 1. A node exactly half way between
  // its neighbours is the midpoint of a quadratic segment; otherwise the segment is linear.
  std::vector<int> nodes{0};
  nodes.insert(nodes.end(), refs.begin(), refs.end());
  nodes.push_back(1);
  auto at = [&](int r) { return space->reference_weights[r * 2 + 1]; };
  space->cells.clear();
  space->cell_arc_angles.clear();
  for (std::size_t i = 0; i + 1 < nodes.size();) {
    const bool quadratic =
        i + 2 < nodes.size() &&
        std::abs(at(nodes[i + 1]) - 0.5 * (at(nodes[i]) + at(nodes[i + 2]))) <= 1e-12;
    const std::size_t end = i + (quadratic ? 2 : 1);
    space->cells.push_back({nodes[i], nodes[end], -1});
    space->cell_arc_angles.push_back(
        quadratic ? segment_arc_angle(*space, nodes[i], nodes[i + 1], nodes[end]) : 0.0);
    i = end;
  }
  space->check();
}

}  // namespace fourd
