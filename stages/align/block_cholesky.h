#pragma once
// Sparse Cholesky factorisation (L L^T) of a symmetric positive definite matrix made of 6x6
// blocks: the Gauss-Newton matrix of the deformation graph, a block per pair of nodes that
// share data or a graph edge. The ordering (AMD on the blocks) and the factor's pattern are
// computed once by the constructor; factorize() then works on dense 6x6 blocks, several times
// faster than a scalar sparse Cholesky on the same matrix.
#include <Eigen/Core>
#include <utility>
#include <vector>

namespace fourd::align::detail {

class BlockCholesky {
 public:
  using Block = Eigen::Matrix<double, 6, 6>;

  // A matrix of n x n blocks whose non-zero blocks (a, b), a <= b, are `upper` (the diagonal
  // ones among them; H(b, a) = H(a, b)^T).
  BlockCholesky(int n, const std::vector<std::pair<int, int>>& upper);

  // Factorises the matrix whose block upper[i] is blocks[i], with `damping` added to its
  // diagonal. False when it is not positive definite.
  bool factorize(const std::vector<Block>& blocks, double damping);

  // x with H x = b (after a successful factorize).
  Eigen::VectorXd solve(const Eigen::VectorXd& b) const;

 private:
  int n_ = 0;
  std::vector<int> old_of_;  // new block index -> the caller's
  // The factor, by block column j (new indices): the rows i > j of its blocks, sorted, from
  // column_start_[j]; their values; and the diagonal block's lower triangle.
  std::vector<int> column_start_, rows_;
  std::vector<Block> values_, diagonal_;
  // Per block column j, the columns k < j whose row j is a block of the factor, with where it
  // stands among column k's blocks.
  std::vector<int> row_start_, row_columns_, row_slots_;
  // Where each of the caller's blocks goes: a slot of values_ (transposed or not), or the
  // diagonal of a column.
  struct Place {
    int slot = -1;      // index into values_, or -1 for a diagonal block
    int column = 0;     // the diagonal block's column (slot -1)
    bool transposed = false;
  };
  std::vector<Place> places_;
};

}  // namespace fourd::align::detail
