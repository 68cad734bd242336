// The cluster solver's sparse block Cholesky factorisation (internal).
#pragma once

#include <Eigen/Core>
#include <Eigen/Sparse>
#include <vector>

namespace hgd {

/// Sparse Cholesky of a symmetric positive definite matrix made of dense 12x12 blocks (the
/// Gauss-Newton normal equations: one block per cluster, coupled along adjacent pairs), in
/// fixed-size block operations.
class BlockCholesky {
 public:
  using Block = Eigen::Matrix<double, 12, 12>;
  /// Symbolic analysis for the scalar pattern of `pattern` (nb*12 square, compressed, both
  /// triangles): a minimum-degree order of the blocks, the filled structure, and where each
  /// of the pattern's values goes.
  void analyze(const Eigen::SparseMatrix<double>& pattern);
  /// Factorises a matrix with the analysed pattern. False when it is not positive definite
  /// (or its pattern is not the analysed one).
  bool factorize(const Eigen::SparseMatrix<double>& matrix);
  /// x = A^-1 b.
  void solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const;

 private:
  /// Index into l_ of block (row position i, column position j), i >= j, in L's structure.
  int blockAt(int i, int j) const;

  int nb_ = 0;
  std::vector<int> order_, rank_;         ///< elimination position -> block, block -> position
  std::vector<int> col_start_, col_row_;  ///< per position j: rows (positions > j) of L's column j
  std::vector<Block> l_;                  ///< per position: diagonal block, then per row slot
  std::vector<int> diag_at_;              ///< per position: index into l_ of its diagonal block
  std::vector<int> value_to_;             ///< per pattern value: index into l_'s doubles, or -1
};

}  // namespace hgd
