#pragma once
// Private to src/graph: the numeric supernodal Cholesky factorisation on CHOLMOD's supernodal
// symbolic analysis, with Eigen's dense kernels in place of the BLAS CHOLMOD links.
//
// Why: Debian's CHOLMOD links the reference BLAS, whose triple loops run its supernodal
// factorisation at about 1 GFlop/s here (sphere2500's 6x6-block information matrix: 4e8 flops,
// 0.3-0.45 s a factorisation, simplicial or supernodal alike). Eigen's blocked, vectorised
// kernels run the same flops several times faster, and keeping CHOLMOD's ordering, symbolic
// analysis and factor layout keeps its solves and everything built on the factor unchanged.
//
// Multifrontal: supernodes in CHOLMOD's order (a child before its parent); each assembles its
// columns of P A P^T and its children's update matrices into a dense front, factors the
// diagonal block (LLT), solves the rows below it, and hands the Schur complement of the rest
// (an update matrix) to its parent.
#include <Eigen/Core>
#include <vector>

#include "probslam/graph/sparse_cholesky.hpp"

struct cholmod_factor_struct;

namespace probslam::graph_detail {

class SupernodalNumeric {
 public:
  /// The plan for a symbolic supernodal factor (nsuper, super, pi, s, Perm) and the matrix
  /// pattern it was made for (the upper triangle of A, compressed).
  SupernodalNumeric(const cholmod_factor_struct& symbolic, const SparseMatrixd& upper);
  /// Factors A (the values of `upper`, same pattern) into `lx`, CHOLMOD's supernodal layout
  /// (each supernode's rows x columns, column-major, at px[s]). Returns the first column (of
  /// the factor's order) whose pivot is not positive, or -1 on success.
  int factorize(const SparseMatrixd& upper, double* lx) const;

 private:
  int n_ = 0;
  std::vector<int> super_, pi_, px_, rows_;  // CHOLMOD's supernodes: columns, row lists, values
  std::vector<std::vector<int>> children_;
  // P A P^T's lower triangle by permuted column: rows and where each value sits in `upper`.
  std::vector<int> a_start_, a_row_, a_value_;
};

}  // namespace probslam::graph_detail
