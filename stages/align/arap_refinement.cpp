// The vertex-level as-rigid-as-possible refinement (Sorkine & Alexa 2007) after the graph fit,
// and the folds it may leave, found and given back the graph's shape.
#include "stages/align/registration_internal.h"

#include <tbb/parallel_for.h>

#include <Eigen/SparseCholesky>

#include "pipeline/core/error.h"

namespace fourd::align {

using namespace detail;

namespace detail {

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

namespace {

// Per template vertex, a search start: the graph match of the data vertex nearest it in edges
// (breadth first from all data vertices at once; a data vertex its own).
std::vector<Correspondence> matches_near(const TemplateModel& model,
                                         const std::vector<Correspondence>& graph_matches) {
  std::vector<Correspondence> out(model.rest.num_vertices());
  if (graph_matches.size() != model.data_vertices.size()) return out;
  std::vector<int> queue;
  std::vector<char> seen(out.size(), 0);
  for (std::size_t i = 0; i < graph_matches.size(); ++i) {
    const int v = model.data_vertices[i];
    out[v].triangle = graph_matches[i].triangle;
    seen[v] = 1;
    queue.push_back(v);
  }
  for (std::size_t head = 0; head < queue.size(); ++head) {
    const int v = queue[head];
    for (int w : model.rings[v]) {
      if (seen[w]) continue;
      seen[w] = 1;
      out[w].triangle = out[v].triangle;
      queue.push_back(w);
    }
  }
  return out;
}

// Per sample of `samples`, a search start: the graph's reverse match of the last graph sample at
// or before its frame vertex (both are spread over the frame's vertices in order).
std::vector<ReverseMatch> reverse_near(const FrameSamples& samples,
                                       const FrameSamples& graph_samples,
                                       const std::vector<ReverseMatch>& graph_reverse) {
  std::vector<ReverseMatch> out(samples.points.size());
  if (graph_reverse.size() != graph_samples.vertices.size()) return out;
  std::size_t g = 0;
  for (std::size_t i = 0; i < samples.vertices.size(); ++i) {
    while (g + 1 < graph_samples.vertices.size() &&
           graph_samples.vertices[g + 1] <= samples.vertices[i]) {
      ++g;
    }
    if (g < graph_reverse.size()) out[i].face = graph_reverse[g].face;
  }
  return out;
}

}  // namespace

void refine_vertices(const TemplateModel& model, const SurfaceQuery& target,
                     const RegistrationOptions& options,
                     const std::vector<Correspondence>& graph_matches,
                     const FrameSamples& graph_samples,
                     const std::vector<ReverseMatch>& graph_reverse,
                     std::vector<Vec3f>* positions) {
  const int nv = static_cast<int>(positions->size());
  const SparseMatrix l = laplacian(model);
  Eigen::SimplicialLDLT<SparseMatrix> solver;
  // A weak pull to the current positions keeps the system definite where nothing matches.
  const double anchor = 1e-4;
  const FrameSamples samples =
      options.reverse_weight > 0 ? sample_frame(target, model.rest.num_vertices()) : FrameSamples{};
  FittedSurface fitted;
  // The latest matches both ways: the next search starts from them (the first from the graph
  // fit's).
  std::vector<Correspondence> matches = matches_near(model, graph_matches);
  std::vector<ReverseMatch> reverse = reverse_near(samples, graph_samples, graph_reverse);
  for (int it = 0; it < options.refine_iterations; ++it) {
    const std::vector<Vec3f> normals = vertex_normals(*positions, model.rest.triangles);
    matches = find_correspondences(*positions, normals, target, options.final_max_distance,
                                   options.robust_scale, options, &matches);
    const std::vector<Mat3d> rotations = local_rotations(model, *positions);
    SparseMatrix a = l;
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nv, 3);
    if (!samples.points.empty()) {
      // Frame points pull the template's closest surface points (a triangle's barycentric
      // combination): c |sum_k b_k x_k - q|^2 couples the triangle's vertices, which the
      // Laplacian's pattern already does.
      reverse = find_reverse_correspondences(model, *positions, samples,
                                             options.final_max_distance, options.robust_scale,
                                             options, &fitted, &reverse);
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

}  // namespace detail

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

}  // namespace fourd::align
