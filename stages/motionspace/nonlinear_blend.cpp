#include "stages/motionspace/nonlinear_blend.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <Eigen/SparseCore>
#include <cmath>

#include "pipeline/core/error.h"
#include "pipeline/geometry/union_find.h"

namespace fourd {

namespace {

// Edge matrix of a triangle's tetrahedron: [p1 - p0, p2 - p0, n / sqrt|n|] with n the
// unnormalised normal; the scaled normal makes the 4th edge change length with the area.
Eigen::Matrix3d edge_matrix(const Eigen::Matrix3Xd& x, const Tri& t) {
  const Eigen::Vector3d p0 = x.col(t[0]);
  const Eigen::Vector3d e1 = x.col(t[1]) - p0;
  const Eigen::Vector3d e2 = x.col(t[2]) - p0;
  const Eigen::Vector3d n = e1.cross(e2);
  Eigen::Matrix3d e;
  e << e1, e2, n / std::sqrt(n.norm());
  return e;
}

// Polar decomposition T = R S with R a rotation (det +1) and S symmetric, via the SVD
// T = U diag(s) V^T: R = U D V^T, S = V D diag(s) V^T with D flipping the last axis when
// U V^T is a reflection (an inverted element keeps a proper rotation).
// (GCC 12 reports a false -Wmaybe-uninitialized inside Eigen's fixed-size JacobiSVD.)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
void polar_decomposition(const Eigen::Matrix3d& t, Eigen::Matrix3d* r, Eigen::Matrix3d* s) {
  Eigen::JacobiSVD<Eigen::Matrix3d, Eigen::NoQRPreconditioner> svd(
      t, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d d(1, 1, (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1 : 1);
  *r = svd.matrixU() * d.asDiagonal() * svd.matrixV().transpose();
  *s = svd.matrixV() * (d.cwiseProduct(svd.singularValues())).asDiagonal() *
       svd.matrixV().transpose();
}
#pragma GCC diagnostic pop

Eigen::Vector3d rotation_log(const Eigen::Matrix3d& r) {
  const Eigen::AngleAxisd aa(r);  // angle in [0, pi]
  return aa.angle() * aa.axis();
}

Eigen::Matrix3d rotation_exp(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

// Normalised copy of the weights; throws InputError for a wrong count or bad values.
std::vector<double> checked_weights(std::span<const double> w, int num_inputs) {
  if (static_cast<int>(w.size()) != num_inputs) {
    throw InputError(
        fmt::format("non-linear blend: {} weights for {} inputs", w.size(), num_inputs));
  }
  double sum = 0;
  for (double wi : w) {
    if (!(wi >= 0) || !std::isfinite(wi)) {
      throw InputError(fmt::format("non-linear blend: weight {} is not a non-negative number", wi));
    }
    sum += wi;
  }
  if (!(sum > 0)) throw InputError("non-linear blend: weights sum to zero");
  std::vector<double> out(w.begin(), w.end());
  for (double& wi : out) wi /= sum;
  return out;
}

}  // namespace

void nonlinear_blend_precompute(const Eigen::Matrix3Xd& reference, std::span<const Tri> triangles,
                                NonlinearBlendData* data) {
  const int nv = static_cast<int>(reference.cols());
  const int nf = static_cast<int>(triangles.size());
  if (nv == 0 || nf == 0) throw InputError("non-linear blend: empty reference mesh");
  if (!reference.allFinite())
    throw InputError("non-linear blend: reference has non-finite positions");
  NonlinearBlendData& d = *data;
  d = NonlinearBlendData{};
  d.num_vertices = nv;
  d.triangles.assign(triangles.begin(), triangles.end());
  d.inverse_edges.resize(nf);
  d.areas.resize(nf);
  d.hat_gradients.resize(nf);

  // Connected components (union-find), one pinned vertex each: the Laplacian's null space is
  // one translation per component, so pinning makes the system positive definite.
  UnionFind sets(nv);
  for (int f = 0; f < nf; ++f) {
    const Tri& t = triangles[f];
    for (int k = 0; k < 3; ++k) {
      if (t[k] < 0 || t[k] >= nv) {
        throw InputError(
            fmt::format("non-linear blend: triangle {} has vertex index {} (mesh has {} vertices)",
                        f, t[k], nv));
      }
    }
    const Eigen::Vector3d p0 = reference.col(t[0]), p1 = reference.col(t[1]),
                          p2 = reference.col(t[2]);
    const Eigen::Vector3d n = (p1 - p0).cross(p2 - p0);
    const double twice_area = n.norm();
    const double scale =
        (p1 - p0).squaredNorm() + (p2 - p0).squaredNorm() + (p2 - p1).squaredNorm();
    if (!(twice_area > 1e-10 * scale)) {
      throw InputError(
          fmt::format("non-linear blend: reference triangle {} ({}, {}, {}) is degenerate", f, t[0],
                      t[1], t[2]));
    }
    d.areas[f] = 0.5 * twice_area;
    d.inverse_edges[f] = edge_matrix(reference, t).inverse();
    // Gradient of the hat function of corner i: the opposite edge turned 90 degrees in the
    // triangle's plane, divided by twice the area.
    const Eigen::Vector3d nh = n / twice_area;
    d.hat_gradients[f].col(0) = nh.cross(p2 - p1) / twice_area;
    d.hat_gradients[f].col(1) = nh.cross(p0 - p2) / twice_area;
    d.hat_gradients[f].col(2) = nh.cross(p1 - p0) / twice_area;
    sets.unite(t[0], t[1]);
    sets.unite(t[0], t[2]);
  }
  d.component.assign(nv, -1);
  d.unknown.assign(nv, -1);
  std::vector<int> component_of_root(nv, -1);
  int num_unknowns = 0;
  for (int v = 0; v < nv; ++v) {
    const int root = sets.find(v);
    if (component_of_root[root] < 0) {
      component_of_root[root] = static_cast<int>(d.pinned.size());
      d.pinned.push_back(v);  // the first vertex of each component stays fixed
    } else {
      d.unknown[v] = num_unknowns++;
    }
    d.component[v] = component_of_root[root];
  }

  // L_ij = sum_t area_t grad_i . grad_j (the cotangent Laplacian), pinned rows/columns dropped.
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<std::size_t>(nf) * 9);
  for (int f = 0; f < nf; ++f) {
    const Eigen::Matrix3d gram = d.areas[f] * d.hat_gradients[f].transpose() * d.hat_gradients[f];
    for (int i = 0; i < 3; ++i) {
      const int ri = d.unknown[triangles[f][i]];
      if (ri < 0) continue;
      for (int j = 0; j < 3; ++j) {
        const int rj = d.unknown[triangles[f][j]];
        if (rj >= 0) entries.emplace_back(ri, rj, gram(i, j));
      }
    }
  }
  if (num_unknowns == 0) return;  // only single-vertex components: nothing to solve
  Eigen::SparseMatrix<double> laplacian(num_unknowns, num_unknowns);
  laplacian.setFromTriplets(entries.begin(), entries.end());
  d.solver = std::make_unique<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>>();
  d.solver->compute(laplacian);
  if (d.solver->info() != Eigen::Success) {
    throw SolverError(fmt::format("non-linear blend: factorising the {}x{} Laplacian failed",
                                  num_unknowns, num_unknowns));
  }
}

void nonlinear_blend_prepare(const NonlinearBlendData& data,
                             std::span<const Eigen::Matrix3Xd> inputs,
                             NonlinearBlendInputs* prepared) {
  const int n = static_cast<int>(inputs.size());
  const int nf = static_cast<int>(data.triangles.size());
  if (n == 0) throw InputError("non-linear blend: no inputs");
  for (int k = 0; k < n; ++k) {
    if (inputs[k].cols() != data.num_vertices) {
      throw InputError(
          fmt::format("non-linear blend: input {} has {} vertices, the reference has {}", k,
                      inputs[k].cols(), data.num_vertices));
    }
    if (!inputs[k].allFinite()) {
      throw InputError(fmt::format("non-linear blend: input {} has non-finite positions", k));
    }
  }
  NonlinearBlendInputs& p = *prepared;
  p.num_inputs = n;
  p.anchor_rotations.resize(nf);
  p.log_rotations.resize(static_cast<std::size_t>(nf) * n);
  p.stretches.resize(static_cast<std::size_t>(nf) * n);
  for (int f = 0; f < nf; ++f) {
    const Tri& t = data.triangles[f];
    Eigen::Matrix3d r;
    for (int k = 0; k < n; ++k) {
      const Eigen::Matrix3d grad = edge_matrix(inputs[k], t) * data.inverse_edges[f];
      polar_decomposition(grad, &r, &p.stretches[f * n + k]);
      if (k == 0) p.anchor_rotations[f] = r;
      // Relative to input 0, so the log map only sees the rotation between the inputs (under
      // 180 degrees for any sensible pair) and not the rotation away from the reference.
      p.log_rotations[f * n + k] =
          k == 0 ? Eigen::Vector3d::Zero() : rotation_log(r * p.anchor_rotations[f].transpose());
    }
  }
  const int nc = static_cast<int>(data.pinned.size());
  p.centroids.setZero(3, static_cast<Eigen::Index>(nc) * n);
  std::vector<int> count(nc, 0);
  for (int v = 0; v < data.num_vertices; ++v) ++count[data.component[v]];
  for (int k = 0; k < n; ++k) {
    for (int v = 0; v < data.num_vertices; ++v) {
      p.centroids.col(data.component[v] * n + k) += inputs[k].col(v) / count[data.component[v]];
    }
  }
}

void nonlinear_blend_solve(const NonlinearBlendData& data, const NonlinearBlendInputs& prepared,
                           std::span<const double> weights, Eigen::Matrix3Xd* out) {
  const int n = prepared.num_inputs;
  const std::vector<double> w = checked_weights(weights, n);
  const int nf = static_cast<int>(data.triangles.size());
  const int nv = data.num_vertices;
  const Eigen::Index num_unknowns = data.solver ? data.solver->rows() : 0;

  // Right-hand side b_i = sum_t area_t T_t grad_i(t) of the blended gradients T = R S.
  Eigen::MatrixX3d rhs = Eigen::MatrixX3d::Zero(num_unknowns, 3);
  for (int f = 0; f < nf; ++f) {
    Eigen::Vector3d log_r = Eigen::Vector3d::Zero();
    Eigen::Matrix3d s = Eigen::Matrix3d::Zero();
    for (int k = 0; k < n; ++k) {
      log_r += w[k] * prepared.log_rotations[f * n + k];
      s += w[k] * prepared.stretches[f * n + k];
    }
    const Eigen::Matrix3d target = rotation_exp(log_r) * prepared.anchor_rotations[f] * s;
    const Eigen::Matrix3d contribution = data.areas[f] * target * data.hat_gradients[f];
    for (int i = 0; i < 3; ++i) {
      const int row = data.unknown[data.triangles[f][i]];
      if (row >= 0) rhs.row(row) += contribution.col(i).transpose();
    }
  }
  Eigen::MatrixX3d x;
  if (num_unknowns > 0) {
    x = data.solver->solve(rhs);
    if (data.solver->info() != Eigen::Success) {
      throw SolverError("non-linear blend: back-substitution failed");
    }
  }

  out->resize(3, nv);
  for (int v = 0; v < nv; ++v) {
    const int row = data.unknown[v];
    out->col(v) = row >= 0 ? Eigen::Vector3d(x.row(row).transpose()) : Eigen::Vector3d::Zero();
  }
  // Translation per component: match the centroid of the linear blend.
  const int nc = static_cast<int>(data.pinned.size());
  Eigen::Matrix3Xd shift = Eigen::Matrix3Xd::Zero(3, nc);
  std::vector<int> count(nc, 0);
  for (int v = 0; v < nv; ++v) {
    shift.col(data.component[v]) -= out->col(v);
    ++count[data.component[v]];
  }
  for (int c = 0; c < nc; ++c) {
    shift.col(c) /= count[c];
    for (int k = 0; k < n; ++k) shift.col(c) += w[k] * prepared.centroids.col(c * n + k);
  }
  for (int v = 0; v < nv; ++v) out->col(v) += shift.col(data.component[v]);
}

Eigen::Matrix3Xd nonlinear_blend(const Eigen::Matrix3Xd& reference, std::span<const Tri> triangles,
                                 std::span<const Eigen::Matrix3Xd> inputs,
                                 std::span<const double> w) {
  NonlinearBlendData data;
  nonlinear_blend_precompute(reference, triangles, &data);
  NonlinearBlendInputs prepared;
  nonlinear_blend_prepare(data, inputs, &prepared);
  Eigen::Matrix3Xd out;
  nonlinear_blend_solve(data, prepared, w, &out);
  return out;
}

Eigen::Matrix3Xd linear_blend(std::span<const Eigen::Matrix3Xd> inputs,
                              std::span<const double> weights) {
  const std::vector<double> w = checked_weights(weights, static_cast<int>(inputs.size()));
  Eigen::Matrix3Xd out = Eigen::Matrix3Xd::Zero(3, inputs[0].cols());
  for (std::size_t k = 0; k < inputs.size(); ++k) {
    if (inputs[k].cols() != out.cols()) {
      throw InputError(fmt::format("linear blend: input {} has {} vertices, input 0 has {}", k,
                                   inputs[k].cols(), out.cols()));
    }
    out += w[k] * inputs[k];
  }
  return out;
}

}  // namespace fourd
