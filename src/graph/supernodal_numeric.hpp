#pragma once
// Private to src/graph: the numeric supernodal Cholesky factorisation on CHOLMOD's supernodal
// symbolic analysis, with Eigen's dense kernels (supernodal_kernels.hpp) in place of the BLAS
// CHOLMOD links.
//
// Why: Debian's CHOLMOD links the reference BLAS, whose triple loops run its supernodal
// factorisation at about 1 GFlop/s here (sphere2500's 6x6-block information matrix: 3.4e8 flops,
// 0.3-0.45 s a factorisation, simplicial or supernodal alike); Eigen's blocked, vectorised
// kernels run the same flops 10-20 times faster. Keeping CHOLMOD's ordering, symbolic analysis
// and factor layout keeps everything built on the factor (the sparse inverse) unchanged.
#include <Eigen/Core>
#include <vector>

#include "probslam/graph/sparse_cholesky.hpp"
#include "supernodal_kernels.hpp"

struct cholmod_factor_struct;

namespace probslam::graph_detail {

class SupernodalNumeric {
 public:
  /// The plan for a symbolic supernodal factor (nsuper, super, pi, px, s, Perm) and the matrix
  /// pattern it was made for (the upper triangle of A, compressed); the kernels for this CPU
  /// (the environment variable PROBSLAM_SUPERNODAL_KERNELS=generic forces the baseline ones:
  /// the tests run both on a CPU with AVX2).
  SupernodalNumeric(const cholmod_factor_struct& symbolic, const SparseMatrixd& upper);
  /// Factors A (the values of `upper`, same pattern) into `lx`, CHOLMOD's supernodal layout
  /// (each supernode's rows x columns, column-major, at px[s]). Returns the first column (of
  /// the factor's order) whose pivot is not positive, or -1 on success.
  int factorize(const SparseMatrixd& upper, double* lx) const;
  /// b <- A^-1 b with the factor in `lx` (one right-hand side a column): the triangular solves
  /// by supernode with Eigen's kernels, not CHOLMOD's through the reference BLAS.
  void solve(const double* lx, Eigen::MatrixXd& b) const;
  /// Whether the AVX2 + FMA kernels run (this CPU has both, and the build made them).
  bool avx2() const { return avx2_; }

 private:
  SupernodalPlanView view() const;

  int n_ = 0;
  std::vector<int> perm_;  // L L^T = P A P^T: row i of P A P^T is row perm_[i] of A
  std::vector<int> super_, pi_, px_, rows_;  // CHOLMOD's supernodes: columns, row lists, values
  std::vector<int> child_start_, child_list_;
  // P A P^T's lower triangle by permuted column: rows and where each value sits in `upper`.
  std::vector<int> a_start_, a_row_, a_value_;
  bool avx2_ = false;
  SupernodalFactorize factorize_ = nullptr;
  SupernodalSolve solve_ = nullptr;
};

}  // namespace probslam::graph_detail
