#include "supernodal_numeric.hpp"

#include <cholmod.h>

#include <Eigen/Cholesky>
#include <algorithm>

namespace probslam::graph_detail {

SupernodalNumeric::SupernodalNumeric(const cholmod_factor& symbolic, const SparseMatrixd& upper) {
  n_ = static_cast<int>(symbolic.n);
  const int nsuper = static_cast<int>(symbolic.nsuper);
  const int* super = static_cast<const int*>(symbolic.super);
  const int* pi = static_cast<const int*>(symbolic.pi);
  const int* px = static_cast<const int*>(symbolic.px);
  const int* s = static_cast<const int*>(symbolic.s);
  super_.assign(super, super + nsuper + 1);
  pi_.assign(pi, pi + nsuper + 1);
  px_.assign(px, px + nsuper + 1);
  rows_.assign(s, s + pi[nsuper]);
  // A supernode's parent holds its first row below its own columns.
  std::vector<int> owner(n_);
  for (int k = 0; k < nsuper; ++k)
    for (int j = super[k]; j < super[k + 1]; ++j) owner[j] = k;
  children_.assign(nsuper, {});
  for (int k = 0; k < nsuper; ++k) {
    const int below = pi[k] + (super[k + 1] - super[k]);
    if (below < pi[k + 1]) children_[owner[s[below]]].push_back(k);
  }
  // The lower triangle of P A P^T, column by column, as indices into upper's values.
  const int* perm = static_cast<const int*>(symbolic.Perm);
  std::vector<int> inverse(n_);
  for (int k = 0; k < n_; ++k) inverse[perm ? perm[k] : k] = k;
  std::vector<int> count(n_ + 1, 0);
  for (int c = 0; c < upper.cols(); ++c)
    for (int k = upper.outerIndexPtr()[c]; k < upper.outerIndexPtr()[c + 1]; ++k) {
      const int r = upper.innerIndexPtr()[k];
      if (r > c) continue;  // entries below the diagonal are ignored, as CHOLMOD does
      ++count[std::min(inverse[r], inverse[c]) + 1];
    }
  a_start_.assign(n_ + 1, 0);
  for (int j = 0; j < n_; ++j) a_start_[j + 1] = a_start_[j] + count[j + 1];
  a_row_.resize(a_start_[n_]);
  a_value_.resize(a_start_[n_]);
  std::vector<int> next(a_start_.begin(), a_start_.end() - 1);
  for (int c = 0; c < upper.cols(); ++c)
    for (int k = upper.outerIndexPtr()[c]; k < upper.outerIndexPtr()[c + 1]; ++k) {
      const int r = upper.innerIndexPtr()[k];
      if (r > c) continue;
      const int pr = inverse[r], pc = inverse[c];
      const int at = next[std::min(pr, pc)]++;
      a_row_[at] = std::max(pr, pc);
      a_value_[at] = k;
    }
}

int SupernodalNumeric::factorize(const SparseMatrixd& upper, double* lx) const {
  const int nsuper = static_cast<int>(children_.size());
  const double* values = upper.valuePtr();
  std::vector<Eigen::MatrixXd> updates(nsuper);  // each supernode's Schur complement, for its parent
  std::vector<int> local(n_, -1);                // row of the current front holding a factor row
  for (int k = 0; k < nsuper; ++k) {
    const int first = super_[k], cols = super_[k + 1] - first;
    const int* rows = rows_.data() + pi_[k];
    const int nrows = pi_[k + 1] - pi_[k], below = nrows - cols;
    for (int r = 0; r < nrows; ++r) local[rows[r]] = r;
    Eigen::MatrixXd front = Eigen::MatrixXd::Zero(nrows, nrows);  // lower triangle used
    for (int j = first; j < first + cols; ++j)
      for (int e = a_start_[j]; e < a_start_[j + 1]; ++e) front(local[a_row_[e]], j - first) += values[a_value_[e]];
    for (const int child : children_[k]) {  // extend-add: rows sorted in both, so lower stays lower
      const int* child_rows = rows_.data() + pi_[child] + (super_[child + 1] - super_[child]);
      Eigen::MatrixXd& u = updates[child];
      const int m = static_cast<int>(u.rows());
      for (int b = 0; b < m; ++b) {
        const int column = local[child_rows[b]];
        for (int a = b; a < m; ++a) front(local[child_rows[a]], column) += u(a, b);
      }
      u.resize(0, 0);
    }
    Eigen::Ref<Eigen::MatrixXd> diagonal = front.topLeftCorner(cols, cols);
    const Eigen::Index failed = Eigen::internal::llt_inplace<double, Eigen::Lower>::blocked(diagonal);
    if (failed >= 0) return first + static_cast<int>(failed);
    if (below > 0) {
      auto lower = front.bottomLeftCorner(below, cols);
      diagonal.triangularView<Eigen::Lower>().transpose().solveInPlace<Eigen::OnTheRight>(lower);
      Eigen::MatrixXd update = front.bottomRightCorner(below, below);
      update.selfadjointView<Eigen::Lower>().rankUpdate(lower, -1.0);
      updates[k] = std::move(update);
    }
    front.topLeftCorner(cols, cols).triangularView<Eigen::StrictlyUpper>().setZero();
    Eigen::Map<Eigen::MatrixXd>(lx + px_[k], nrows, cols) = front.leftCols(cols);
  }
  return -1;
}

}  // namespace probslam::graph_detail
