#pragma once
// Normal equations H dx = b over variables that are small dense blocks (poses, landmarks),
// assembled straight into CHOLMOD's input: the shared assembly of the information-form solvers
// and the graph optimiser.
#include <Eigen/Core>
#include <utility>
#include <vector>

#include "probslam/graph/sparse_cholesky.hpp"

namespace probslam {

/// A block of H named once and then accumulated into without any lookup.
struct BlockHandle {
  int id = -1;              ///< -1: a fixed variable is involved, additions are dropped
  bool transposed = false;  ///< the caller's (i, j) is stored as (j, i)
};

/// The upper triangle of H in column-compressed form with a pattern fixed at construction (from
/// the variables' sizes and the pairs of variables that share a factor), so that each
/// iteration only rewrites values and the Cholesky analysis is reused.
class BlockSystem {
 public:
  /// sizes[v] is the dimension of variable v; 0 marks a fixed variable, which gets no rows.
  /// couplings lists pairs (i, j), i != j, that share a factor (repeats are fine).
  BlockSystem(std::vector<int> sizes, const std::vector<std::pair<int, int>>& couplings);

  int dim() const { return dim_; }
  int num_variables() const { return static_cast<int>(sizes_.size()); }
  int size(int v) const { return sizes_[v]; }
  int offset(int v) const { return offsets_[v]; }

  /// The block (i, j); throws std::invalid_argument when it was not declared.
  BlockHandle block(int i, int j) const;

  void set_zero();
  /// H_ij += m (size(i) x size(j)), and so H_ji += m^T.
  void add(BlockHandle handle, const Eigen::Ref<const Eigen::MatrixXd>& m);
  /// b_v += v.
  void add_rhs(int var, const Eigen::Ref<const Eigen::VectorXd>& v);

  const SparseMatrixd& upper() const { return upper_; }
  SparseMatrixd& upper() { return upper_; }
  Eigen::VectorXd& rhs() { return rhs_; }
  const Eigen::VectorXd& rhs() const { return rhs_; }
  /// H's diagonal (a view into the matrix's values would need scattered indices: this copies).
  Eigen::VectorXd diagonal() const;
  /// H_kk += values[k] for every k (Levenberg-Marquardt damping).
  void add_to_diagonal(const Eigen::VectorXd& values);

 private:
  struct Block {
    int row_var, col_var;
    int first_column_start;  // into column_starts_: one entry per column of col_var
  };
  std::vector<int> sizes_, offsets_;
  int dim_ = 0;
  std::vector<Block> blocks_;
  std::vector<int> column_starts_;  // value index of the block's first row in each column
  std::vector<std::vector<std::pair<int, int>>> blocks_in_column_;  // (row var, block id)
  std::vector<int> diagonal_index_;
  SparseMatrixd upper_;
  Eigen::VectorXd rhs_;
};

}  // namespace probslam
