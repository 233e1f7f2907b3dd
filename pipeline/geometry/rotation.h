#pragma once
// The rotation nearest a 3x3 matrix (polar decomposition), as the as-rigid-as-possible fits
// need it for every vertex's one-ring and every graph node, many times per registration.
#include <Eigen/Core>

namespace fourd {

// The proper rotation R nearest `m` in the Frobenius norm (the R maximising trace(R^T m)): with
// m = U S V^T, U diag(1, 1, det(U V^T)) V^T. Exact up to rounding wherever m's two largest
// singular values are clear of zero (m's rank is 2 for a planar one-ring); a matrix of rank
// below about 2 (collinear edges) has no single nearest rotation and gets one of them.
Eigen::Matrix3d nearest_rotation(const Eigen::Matrix3d& m);

}  // namespace fourd
