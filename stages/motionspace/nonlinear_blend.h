#pragma once
// Non-linear mesh blending M_NL(w) (paper section 3.1, offline only).
//
// Every input is described per triangle by its deformation gradient T_k relative to a
// reference mesh (Sumner & Popovic 2004: a tetrahedron per triangle, the 4th vertex along the
// normal). T_k = R_k S_k is split by polar decomposition; rotations are blended in the log
// space relative to input 0 (R = exp(sum_k w_k log(R_k R_0^T)) R_0, so two inputs follow the
// geodesic and rotations up to just below 180 degrees blend correctly), stretches linearly
// (S = sum_k w_k S_k). Vertex positions then solve the Poisson system of gradient-domain
// deformation (Sorkine 2006; Botsch & Sorkine 2008):
//
//   minimise sum_t area_t |grad_t(x) - T_t|_F^2   (grad_t measured on the reference mesh),
//
// i.e. L x = b with L the cotangent Laplacian of the reference: factorised once per topology.
// The Laplacian leaves one translation per connected component free; each component is
// placed so that its vertex centroid equals that of the linear blend.
//
// Precompute/solve split (libigl style):
//   nonlinear_blend_precompute(reference, triangles, &data)     once per topology
//   nonlinear_blend_prepare(data, inputs, &prepared)            once per set of input poses
//   nonlinear_blend_solve(data, prepared, w, &out)              per weight vector: one sparse
//                                                               back-substitution, 3 columns
#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <memory>
#include <span>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

struct NonlinearBlendData {
  int num_vertices = 0;
  std::vector<Tri> triangles;  // #F
  // Per triangle: inverse of the reference edge matrix [e1 e2 n/sqrt|n|] (3x3), area, and
  // the gradients of its three hat functions (3 x 3, one column per corner).
  std::vector<Eigen::Matrix3d> inverse_edges;
  std::vector<double> areas;
  std::vector<Eigen::Matrix3d> hat_gradients;
  // Connected components: per vertex its component; per component the pinned vertex.
  std::vector<int> component;
  std::vector<int> pinned;
  std::vector<int> unknown;  // per vertex: row in the reduced system, -1 if pinned
  // Cholesky factor of the cotangent Laplacian without the pinned rows/columns.
  std::unique_ptr<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>> solver;
};

// Builds the gradient operator and factorises the Laplacian of `reference` (3 x #V, any pose
// of the topology, e.g. the template). Throws InputError for an index out of range or a
// degenerate reference triangle (naming it), SolverError if factorisation fails.
void nonlinear_blend_precompute(const Eigen::Matrix3Xd& reference, std::span<const Tri> triangles,
                                NonlinearBlendData* data);

// The inputs analysed once, so that many weight vectors can be blended cheaply.
struct NonlinearBlendInputs {
  int num_inputs = 0;
  // Per triangle: rotation of input 0 (3x3); per triangle and input: log(R_k R_0^T) as an
  // axis * angle vector and the symmetric stretch S_k.
  std::vector<Eigen::Matrix3d> anchor_rotations;  // #F
  std::vector<Eigen::Vector3d> log_rotations;     // #F x N (triangle-major)
  std::vector<Eigen::Matrix3d> stretches;         // #F x N (triangle-major)
  Eigen::MatrixXd centroids;  // 3 x (#components * N): input k, component c at c * N + k
};

// Decomposes the deformation gradients of every input (each 3 x #V, same topology as the
// reference). Throws InputError if an input has the wrong vertex count or is not finite.
void nonlinear_blend_prepare(const NonlinearBlendData& data,
                             std::span<const Eigen::Matrix3Xd> inputs,
                             NonlinearBlendInputs* prepared);

// M_NL(w) into `out` (3 x #V). `w` has one non-negative weight per input, summing to a
// positive value (it is normalised). Throws InputError for bad weights, SolverError if the
// back-substitution fails.
void nonlinear_blend_solve(const NonlinearBlendData& data, const NonlinearBlendInputs& prepared,
                           std::span<const double> w, Eigen::Matrix3Xd* out);

// All three steps at once, for a single blend.
Eigen::Matrix3Xd nonlinear_blend(const Eigen::Matrix3Xd& reference, std::span<const Tri> triangles,
                                 std::span<const Eigen::Matrix3Xd> inputs,
                                 std::span<const double> w);

// M_L(w) = sum_k w_k M_k / sum_k w_k, in double (offline reference for the runtime's float blend).
Eigen::Matrix3Xd linear_blend(std::span<const Eigen::Matrix3Xd> inputs, std::span<const double> w);

}  // namespace fourd
