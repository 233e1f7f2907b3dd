#include "pipeline/geometry/rotation.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <random>

namespace fourd {
namespace {

using Mat3 = Eigen::Matrix3d;

// The reference: U diag(1, 1, det(U V^T)) V^T from a full SVD.
Mat3 by_svd(const Mat3& m) {
  Eigen::JacobiSVD<Mat3> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d d(1, 1, (svd.matrixU() * svd.matrixV().transpose()).determinant());
  return svd.matrixU() * d.asDiagonal() * svd.matrixV().transpose();
}

Mat3 random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> g;
  return Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized().toRotationMatrix();
}

void expect_rotation(const Mat3& r) {
  EXPECT_LT((r.transpose() * r - Mat3::Identity()).norm(), 1e-12);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
}

// The matrices the fits hand it: general ones (either sign of determinant), one-ring
// covariances (rotated planar rings: rank 2 up to the ring's bend), rotations a rounding away
// from orthogonal, scaled rotations (equal singular values), and two singular values equal.
TEST(Rotation, TheNearestRotationIsTheSvds) {
  std::mt19937 rng(3);
  std::normal_distribution<double> g;
  std::uniform_real_distribution<double> unit(0, 1);
  for (int i = 0; i < 2000; ++i) {
    Mat3 m;
    switch (i % 5) {
      case 0:
        m = Mat3::NullaryExpr([&] { return g(rng); });
        break;
      case 1: {
        // A ring of 6 edges in the plane z = 0, bent by up to 1e-3 out of it, deformed a little
        // and turned: sum e e0^T.
        const Mat3 turn = random_rotation(rng);
        const Mat3 strain = Mat3::Identity() + 0.2 * Mat3::NullaryExpr([&] { return g(rng); });
        const double bend = 1e-3 * unit(rng);
        m.setZero();
        for (int k = 0; k < 6; ++k) {
          const double a = k * M_PI / 3 + 0.2 * g(rng);
          const Eigen::Vector3d e0(std::cos(a), std::sin(a), bend * g(rng));
          m += (turn * strain * e0) * e0.transpose();
        }
        break;
      }
      case 2:
        m = random_rotation(rng) * (Mat3::Identity() + 1e-15 * Mat3::NullaryExpr([&] { return g(rng); }));
        break;
      case 3:
        m = (0.1 + unit(rng)) * random_rotation(rng) * (unit(rng) < 0.5 ? 1.0 : -1.0);
        break;
      default:
        m = random_rotation(rng) * Eigen::Vector3d(2, 1 + unit(rng), 1 + unit(rng)).asDiagonal() *
            random_rotation(rng);
        if (i % 2) m.col(0) *= -1;
        break;
    }
    const Mat3 r = nearest_rotation(m);
    expect_rotation(r);
    if (i % 5 == 3 && m.determinant() < 0) {
      // -s R (s > 0) is a reflection: a half turn of R about any axis is as near.
      continue;
    }
    EXPECT_LT((r - by_svd(m)).norm(), 1e-9) << "case " << i % 5 << "\n" << m;
  }
}

// Rank 1 (edges all along one line) has no single nearest rotation: a proper rotation that
// turns the line's direction onto m's still comes back.
TEST(Rotation, RankOneGivesARotationOfTheLine) {
  const Eigen::Vector3d u = Eigen::Vector3d(1, 2, 3).normalized(), v = Eigen::Vector3d(0, 1, 0);
  const Mat3 r = nearest_rotation(2.0 * u * v.transpose());
  expect_rotation(r);
  EXPECT_LT((r * v - u).norm(), 1e-12);
}

}  // namespace
}  // namespace fourd
