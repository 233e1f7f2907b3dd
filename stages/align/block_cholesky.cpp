#include "stages/align/block_cholesky.h"

#include <Eigen/Cholesky>
#include <Eigen/OrderingMethods>
#include <Eigen/SparseCore>
#include <algorithm>

namespace fourd::align::detail {

namespace {
using Vec6 = Eigen::Matrix<double, 6, 1>;
}  // namespace

BlockCholesky::BlockCholesky(int n, const std::vector<std::pair<int, int>>& upper) : n_(n) {
  // A fill-reducing ordering of the blocks (AMD on their pattern).
  std::vector<Eigen::Triplet<double>> triplets;
  for (int i = 0; i < n; ++i) triplets.emplace_back(i, i, 1.0);
  for (const auto& [a, b] : upper) {
    triplets.emplace_back(a, b, 1.0);
    triplets.emplace_back(b, a, 1.0);
  }
  Eigen::SparseMatrix<double> pattern(n, n);
  pattern.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> permutation;
  Eigen::AMDOrdering<int>()(pattern, permutation);
  old_of_.assign(permutation.indices().data(), permutation.indices().data() + n);
  std::vector<int> new_of(n);
  for (int i = 0; i < n; ++i) new_of[old_of_[i]] = i;

  // The factor's pattern, column by column along the elimination tree: column j holds the
  // matrix's rows below j and its children's rows but j; its parent is its first row.
  std::vector<std::vector<int>> columns(n), children(n);
  for (const auto& [a, b] : upper) {
    if (a == b) continue;
    const int i = std::max(new_of[a], new_of[b]), j = std::min(new_of[a], new_of[b]);
    columns[j].push_back(i);
  }
  for (int j = 0; j < n; ++j) {
    std::vector<int>& column = columns[j];
    for (int c : children[j]) {
      for (int i : columns[c]) {
        if (i != j) column.push_back(i);
      }
    }
    std::sort(column.begin(), column.end());
    column.erase(std::unique(column.begin(), column.end()), column.end());
    if (!column.empty()) children[column.front()].push_back(j);
  }
  column_start_.assign(1, 0);
  for (const std::vector<int>& column : columns) {
    rows_.insert(rows_.end(), column.begin(), column.end());
    column_start_.push_back(static_cast<int>(rows_.size()));
  }
  values_.resize(rows_.size());
  diagonal_.resize(n);

  // Its rows: per row j, the columns k < j with a block there, in increasing order.
  row_start_.assign(n + 1, 0);
  for (int i : rows_) ++row_start_[i + 1];
  for (int i = 0; i < n; ++i) row_start_[i + 1] += row_start_[i];
  row_columns_.resize(rows_.size());
  row_slots_.resize(rows_.size());
  std::vector<int> fill(row_start_.begin(), row_start_.end() - 1);
  for (int k = 0; k < n; ++k) {
    for (int s = column_start_[k]; s < column_start_[k + 1]; ++s) {
      const int r = fill[rows_[s]]++;
      row_columns_[r] = k;
      row_slots_[r] = s;
    }
  }

  // Where the caller's blocks go: H(a, b) is the factor's block (i, j), i > j, as it is when
  // a comes after b in the new order, else transposed.
  auto slot = [&](int i, int j) {
    const auto begin = rows_.begin() + column_start_[j], end = rows_.begin() + column_start_[j + 1];
    return static_cast<int>(std::lower_bound(begin, end, i) - rows_.begin());
  };
  for (const auto& [a, b] : upper) {
    Place& place = places_.emplace_back();
    if (a == b) {
      place.column = new_of[a];
    } else if (new_of[a] > new_of[b]) {
      place.slot = slot(new_of[a], new_of[b]);
    } else {
      place.slot = slot(new_of[b], new_of[a]);
      place.transposed = true;
    }
  }
}

bool BlockCholesky::factorize(const std::vector<Block>& blocks, double damping) {
  std::fill(values_.begin(), values_.end(), Block::Zero());
  std::fill(diagonal_.begin(), diagonal_.end(), Block::Zero());
  for (std::size_t p = 0; p < places_.size(); ++p) {
    const Place& place = places_[p];
    if (place.slot < 0) {
      diagonal_[place.column] += blocks[p];
    } else if (place.transposed) {
      values_[place.slot] += blocks[p].transpose();
    } else {
      values_[place.slot] += blocks[p];
    }
  }
  // Left-looking: column j takes the updates of the columns k < j with a block in row j, then
  // is divided by its diagonal block's factor.
  std::vector<int> where(n_, -1);  // row i's slot in the current column
  for (int j = 0; j < n_; ++j) {
    for (int s = column_start_[j]; s < column_start_[j + 1]; ++s) where[rows_[s]] = s;
    Block& d = diagonal_[j];
    d.diagonal().array() += damping;
    for (int r = row_start_[j]; r < row_start_[j + 1]; ++r) {
      const int k = row_columns_[r], s = row_slots_[r];
      const Block ljk_t = values_[s].transpose();
      d.noalias() -= values_[s] * ljk_t;
      for (int q = s + 1; q < column_start_[k + 1]; ++q) {
        values_[where[rows_[q]]].noalias() -= values_[q] * ljk_t;
      }
    }
    const Eigen::LLT<Block> llt(d);
    if (llt.info() != Eigen::Success) return false;
    d = llt.matrixL();
    for (int s = column_start_[j]; s < column_start_[j + 1]; ++s) {
      // L_ij L_jj^T = B_ij.
      d.transpose().triangularView<Eigen::Upper>().solveInPlace<Eigen::OnTheRight>(values_[s]);
    }
  }
  return true;
}

Eigen::VectorXd BlockCholesky::solve(const Eigen::VectorXd& b) const {
  std::vector<Vec6> y(n_);
  for (int j = 0; j < n_; ++j) y[j] = b.segment<6>(6 * old_of_[j]);
  for (int j = 0; j < n_; ++j) {
    diagonal_[j].triangularView<Eigen::Lower>().solveInPlace(y[j]);
    for (int s = column_start_[j]; s < column_start_[j + 1]; ++s) y[rows_[s]] -= values_[s] * y[j];
  }
  for (int j = n_ - 1; j >= 0; --j) {
    for (int s = column_start_[j]; s < column_start_[j + 1]; ++s) {
      y[j] -= values_[s].transpose() * y[rows_[s]];
    }
    diagonal_[j].transpose().triangularView<Eigen::Upper>().solveInPlace(y[j]);
  }
  Eigen::VectorXd x(6 * n_);
  for (int j = 0; j < n_; ++j) x.segment<6>(6 * old_of_[j]) = y[j];
  return x;
}

}  // namespace fourd::align::detail
