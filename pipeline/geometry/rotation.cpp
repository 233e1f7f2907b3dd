#include "pipeline/geometry/rotation.h"

#include <Eigen/Dense>

namespace fourd {

namespace {

Eigen::Matrix3d nearest_rotation_svd(const Eigen::Matrix3d& m) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  const Eigen::Matrix3d& v = svd.matrixV();
  Eigen::Matrix3d r = u * v.transpose();
  if (r.determinant() < 0) {
    u.col(2) *= -1;
    r = u * v.transpose();
  }
  return r;
}

}  // namespace

// With singular values s1 >= s2 >= s3, R = u1 v1^T + u2 v2^T + (u1 x u2)(v1 x v2)^T: the third
// pair is whatever makes R proper, so only v1, v2 (the two largest eigenvectors of m^T m, in
// closed form: a fraction of a Jacobi SVD's cost) and u_i = m v_i / s_i are needed. Where s1
// and s2 are close, v1 and v2 are only known as a plane, but then any orthonormal pair of it
// gives the same R. Where s2 is near 0 relative to s1, the SVD.
Eigen::Matrix3d nearest_rotation(const Eigen::Matrix3d& m) {
  using Vec3d = Eigen::Vector3d;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
  eigen.computeDirect(m.transpose() * m);  // eigenvalues in increasing order
  const Vec3d& lambda = eigen.eigenvalues();
  if (!(lambda[1] > 1e-8 * lambda[2])) return nearest_rotation_svd(m);
  const Vec3d v1 = eigen.eigenvectors().col(2).normalized();
  Vec3d v2 = eigen.eigenvectors().col(1);
  v2 = (v2 - v2.dot(v1) * v1).normalized();
  const Vec3d u1 = (m * v1).normalized();
  Vec3d u2 = m * v2;
  u2 = (u2 - u2.dot(u1) * u1).normalized();
  return u1 * v1.transpose() + u2 * v2.transpose() + u1.cross(u2) * v1.cross(v2).transpose();
}

}  // namespace fourd
