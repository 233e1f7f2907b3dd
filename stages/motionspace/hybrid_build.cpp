#include "stages/motionspace/hybrid_build.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
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
};

// Barycentric positions of the test weights inside a cell.
std::vector<std::array<double, 3>> test_points(int num_inputs) {
  if (num_inputs == 2) return {{0.75, 0.25, 0}, {0.5, 0.5, 0}, {0.25, 0.75, 0}};
  const double third = 1.0 / 3, sixth = 1.0 / 6;
  return {{0, 0.5, 0.5},
          {0.5, 0, 0.5},
          {0.5, 0.5, 0},
          {third, third, third},
          {2 * third, sixth, sixth},
          {sixth, 2 * third, sixth},
          {sixth, sixth, 2 * third}};
}

// The working state of the bisection: the leaf cells and where every edge midpoint went.
class Refinement {
 public:
  explicit Refinement(BlendSpace* space) : space_(space), references_(space->num_references()) {
    Cell root;
    root.corners = space->cells.front();
    cells_.push_back(root);
  }

  std::vector<Cell>& cells() { return cells_; }
  const std::vector<int>& pending() const { return pending_; }
  void clear_pending() { pending_.clear(); }
  int added() const { return space_->num_references() - space_->num_inputs; }

  // Splits cell i (with its neighbour across the refinement edge, for triangles).
  void refine(int i) {
    if (space_->num_inputs == 2) {
      const Cell c = cells_[i];
      const int m = midpoint(c.corners[0], c.corners[1]);
      cells_[i] = Cell{{c.corners[0], m, -1}, c.depth + 1};
      cells_.push_back(Cell{{m, c.corners[1], -1}, c.depth + 1});
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
    space_->reference_weights.resize(static_cast<std::size_t>(references_) * space_->num_inputs);
    space_->frames.resize(static_cast<std::size_t>(references_) * space_->num_frames *
                          space_->frame_stride());
  }

  // Writes the leaf cells into the space.
  void store_cells() const {
    space_->cells.clear();
    for (const Cell& c : cells_) space_->cells.push_back(c.corners);
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

Eigen::Matrix3Xd frame_positions(const BlendSpace& space, int reference, int f) {
  const float* p = space.frame(reference, f);
  const std::size_t stride = space.plane_stride;
  Eigen::Matrix3Xd x(3, space.num_vertices);
  for (int v = 0; v < space.num_vertices; ++v) x.col(v) << p[v], p[stride + v], p[2 * stride + v];
  return x;
}

void store_frame(const Eigen::Matrix3Xd& x, int reference, int f, BlendSpace* space) {
  float* p = space->frame(reference, f);
  const std::size_t stride = space->plane_stride;
  for (int v = 0; v < space->num_vertices; ++v) {
    p[v] = static_cast<float>(x(0, v));
    p[stride + v] = static_cast<float>(x(1, v));
    p[2 * stride + v] = static_cast<float>(x(2, v));
  }
}

// Largest vertex distance between x and sum_k g_k * frame(corners[k], f).
double max_distance(const Eigen::Matrix3Xd& x, const BlendSpace& space,
                    const std::array<int, 3>& corners, const std::array<double, 3>& g, int f) {
  const std::size_t stride = space.plane_stride;
  Eigen::Matrix3Xd blend = Eigen::Matrix3Xd::Zero(3, space.num_vertices);
  for (int k = 0; k < space.num_inputs; ++k) {
    if (g[k] == 0) continue;
    const float* p = space.frame(corners[k], f);
    for (int v = 0; v < space.num_vertices; ++v) {
      blend.col(v) += g[k] * Eigen::Vector3d(p[v], p[stride + v], p[2 * stride + v]);
    }
  }
  return (x - blend).colwise().norm().maxCoeff();
}

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
    for (const auto& g : test_points(n)) {
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

// For every frame: the non-linear blend at the pending references (stored in the space), then
// at the test weights, compared with the hybrid and the linear blend. Returns per test its
// largest error over the frames; raises *linear_error to the linear blend's largest error.
// Frames run in parallel; each writes only its own frames and its own row of errors.
std::vector<double> solve_frames(const NonlinearBlendData& data, const TestSet& set,
                                 const std::vector<int>& pending, const std::vector<Cell>& cells,
                                 BlendSpace* space, double* linear_error) {
  const int n = space->num_inputs;
  const int nt = static_cast<int>(set.tests.size());
  std::vector<double> errors(static_cast<std::size_t>(space->num_frames) * nt, 0.0);
  std::vector<double> linear_errors(space->num_frames, 0.0);
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
    for (int wi = 0; wi < static_cast<int>(set.weights.size()); ++wi) {
      nonlinear_blend_solve(data, prepared, set.weights[wi], &x);
      const Eigen::Matrix3Xd linear = linear_blend(inputs, set.weights[wi]);
      linear_errors[f] = std::max(linear_errors[f], (x - linear).colwise().norm().maxCoeff());
      for (int ti = 0; ti < nt; ++ti) {
        const Test& test = set.tests[ti];
        if (test.weight != wi) continue;
        errors[static_cast<std::size_t>(f) * nt + ti] =
            max_distance(x, *space, cells[test.cell].corners, test.g, f);
      }
    }
  });
  std::vector<double> worst(nt, 0.0);
  for (int f = 0; f < space->num_frames; ++f) {
    *linear_error = std::max(*linear_error, linear_errors[f]);
    for (int ti = 0; ti < nt; ++ti) {
      worst[ti] = std::max(worst[ti], errors[static_cast<std::size_t>(f) * nt + ti]);
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
    if (cells[c].error > options.epsilon && cells[c].depth < options.max_depth) {
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
    const TestSet set = collect_tests(*space, refinement.cells());
    const std::vector<double> errors = solve_frames(
        data, set, refinement.pending(), refinement.cells(), space, &report.linear_max_error);
    report.nonlinear_solves +=
        space->num_frames * static_cast<int>(refinement.pending().size() + set.weights.size());
    refinement.clear_pending();
    for (std::size_t ti = 0; ti < set.tests.size(); ++ti) {
      Cell& cell = refinement.cells()[set.tests[ti].cell];
      cell.error = std::max({cell.error, 0.0, errors[ti]});
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
  space->cells.clear();
  int previous = 0;
  for (int r : refs) {
    space->cells.push_back({previous, r, -1});
    previous = r;
  }
  space->cells.push_back({previous, 1, -1});
  space->check();
}

}  // namespace fourd
