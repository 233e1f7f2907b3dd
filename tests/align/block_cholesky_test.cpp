#include "stages/align/block_cholesky.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <random>

namespace fourd::align::detail {
namespace {

// A random symmetric positive definite matrix of 40 x 40 blocks on a ring with random chords
// (so the factor fills in), solved against a dense factorisation of the same matrix.
TEST(BlockCholesky, SolvesASparseBlockSystemAsADenseFactorisationDoes) {
  const int n = 40;
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> node(0, n - 1);
  std::vector<std::pair<int, int>> upper;
  for (int a = 0; a < n; ++a) {
    upper.emplace_back(a, a);
    upper.emplace_back(std::min(a, (a + 1) % n), std::max(a, (a + 1) % n));
  }
  for (int c = 0; c < 15; ++c) {
    const int a = node(rng), b = node(rng);
    if (a != b) upper.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(upper.begin(), upper.end());
  upper.erase(std::unique(upper.begin(), upper.end()), upper.end());
  // H = sum over the pairs of J^T J for random 6x12 J on the two blocks: positive
  // semi-definite with exactly this pattern; the damping makes it definite.
  std::vector<BlockCholesky::Block> blocks(upper.size(), BlockCholesky::Block::Zero());
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(6 * n, 6 * n);
  for (std::size_t p = 0; p < upper.size(); ++p) {
    const auto [a, b] = upper[p];
    const Eigen::Matrix<double, 6, 6> ja = Eigen::Matrix<double, 6, 6>::Random();
    const Eigen::Matrix<double, 6, 6> jb = Eigen::Matrix<double, 6, 6>::Random();
    if (a == b) {
      blocks[p] += ja.transpose() * ja;
      dense.block<6, 6>(6 * a, 6 * a) += ja.transpose() * ja;
      continue;
    }
    // The pair's own term adds to both diagonal blocks and to (a, b).
    const auto diag_a = std::find(upper.begin(), upper.end(), std::make_pair(a, a)) - upper.begin();
    const auto diag_b = std::find(upper.begin(), upper.end(), std::make_pair(b, b)) - upper.begin();
    blocks[diag_a] += ja.transpose() * ja;
    blocks[diag_b] += jb.transpose() * jb;
    blocks[p] += ja.transpose() * jb;
    dense.block<6, 6>(6 * a, 6 * a) += ja.transpose() * ja;
    dense.block<6, 6>(6 * b, 6 * b) += jb.transpose() * jb;
    dense.block<6, 6>(6 * a, 6 * b) += ja.transpose() * jb;
    dense.block<6, 6>(6 * b, 6 * a) += jb.transpose() * ja;
  }
  const double damping = 1e-3;
  dense.diagonal().array() += damping;
  const Eigen::VectorXd rhs = Eigen::VectorXd::Random(6 * n);

  BlockCholesky cholesky(n, upper);
  ASSERT_TRUE(cholesky.factorize(blocks, damping));
  const Eigen::VectorXd x = cholesky.solve(rhs);
  const Eigen::VectorXd expected = dense.ldlt().solve(rhs);
  EXPECT_LT((dense * x - rhs).norm(), 1e-9 * rhs.norm());
  EXPECT_LT((x - expected).norm(), 1e-8 * expected.norm());

  // Factorised again with other values (the same pattern): the new solution.
  for (auto& block : blocks) block *= 2;
  ASSERT_TRUE(cholesky.factorize(blocks, 2 * damping));
  EXPECT_LT((cholesky.solve(rhs) - 0.5 * expected).norm(), 1e-8 * expected.norm());

  // Not positive definite: refused.
  blocks[0] = -BlockCholesky::Block::Identity();
  EXPECT_FALSE(cholesky.factorize(blocks, 0.0));
}

}  // namespace
}  // namespace fourd::align::detail
