#pragma once
// Sparse Cholesky factorisation of symmetric positive-definite systems through SuiteSparse
// CHOLMOD: the one solve path of the information-form solvers and the graph optimiser.
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>
#include <vector>

#include "probslam/core/options_description.hpp"

namespace probslam {

using SparseMatrixd = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

enum class FactorMethod {
  kSimplicial,  ///< column by column (CHOLMOD's own numbers)
  kSupernodal,  ///< dense blocks, factored with Eigen's kernels on CHOLMOD's analysis
  kAuto,        ///< CHOLMOD's choice from the flop count per nonzero
};

enum class FillOrdering {
  kAmd,      ///< approximate minimum degree
  kMetis,    ///< nested dissection (METIS)
  kDefault,  ///< the problem's own: METIS for a 3-D pose graph, AMD otherwise
};

// Supernodal by default: with Eigen's kernels it is the faster one on every pose graph measured,
// 2-D and 3-D (docs/pose_graphs.md: w10000 36 against 71 ms an iteration, M3500 5.2 against 7.6).
template <>
struct OptionEnum<FactorMethod> {
  static constexpr std::array<const char*, 3> names{"simplicial", "supernodal", "auto"};
};
template <>
struct OptionEnum<FillOrdering> {
  static constexpr std::array<const char*, 3> names{"amd", "metis", "default"};
};

struct SparseCholeskyOptions {
  FactorMethod method = FactorMethod::kSupernodal;
  FillOrdering ordering = FillOrdering::kDefault;
  void validate() const {}  // every value of the enums is valid
  /// These options with kDefault replaced by `fallback` (the problem's own ordering).
  SparseCholeskyOptions resolved(FillOrdering fallback) const {
    SparseCholeskyOptions o = *this;
    if (o.ordering == FillOrdering::kDefault) o.ordering = fallback;
    return o;
  }
  template <class V>
  static void describe(V& v) {
    v("method", &SparseCholeskyOptions::method, "", "\"supernodal\", \"simplicial\" or \"auto\" (CHOLMOD's choice)");
    v("ordering", &SparseCholeskyOptions::ordering, "", "fill-reducing ordering: \"amd\", \"metis\" (nested dissection) or \"default\" (metis for a 3-D pose graph, amd otherwise)");
  }
};

/// A block of the inverse: rows [row, row + rows) and columns [col, col + cols).
struct InverseBlock {
  int row = 0, rows = 0, col = 0, cols = 0;
};

/// Factorises A = P^T L L^T P. The symbolic analysis (ordering and factor pattern) is reused
/// for as long as the pattern of A does not change, so iterating solvers pay for it once.
class SparseCholesky {
 public:
  explicit SparseCholesky(SparseCholeskyOptions options = {});
  ~SparseCholesky();
  SparseCholesky(SparseCholesky&&) noexcept;
  SparseCholesky& operator=(SparseCholesky&&) noexcept;
  SparseCholesky(const SparseCholesky&) = delete;
  SparseCholesky& operator=(const SparseCholesky&) = delete;

  /// Factorises the symmetric matrix whose upper triangle (diagonal included) `upper` holds;
  /// entries below the diagonal are ignored. Throws std::invalid_argument when the matrix is
  /// not square, holds a non-finite value, or is not positive definite: CHOLMOD meets a pivot
  /// <= 0, or a pivot is rounding noise next to its own diagonal entry (a test per variable,
  /// invariant to each variable's scale; no cut on the condition number).
  void factorize(const SparseMatrixd& upper);
  /// The column of A at which the last factorize() failed, or -1.
  int singular_column() const;

  /// A^-1 b for one or several right-hand sides.
  Eigen::VectorXd solve(const Eigen::VectorXd& b) const;
  Eigen::MatrixXd solve(const Eigen::MatrixXd& b) const;

  /// Blocks of A^-1 (marginal covariances when A is an information matrix), never forming the
  /// dense inverse: entries inside the factor's pattern come from the sparse-inverse
  /// (Takahashi) recurrence, the others from solves against unit columns.
  std::vector<Eigen::MatrixXd> inverse_blocks(const std::vector<InverseBlock>& blocks) const;

  int rows() const;
  bool factorized() const;
  /// Nonzeros of the factor L, and whether the last factorize() reused the analysis.
  long factor_nonzeros() const;
  bool analysis_reused() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace probslam
