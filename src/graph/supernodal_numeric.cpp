#include "supernodal_numeric.hpp"

#include <cholmod.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>

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
  std::vector<int> parent(nsuper, -1);
  child_start_.assign(nsuper + 1, 0);
  for (int k = 0; k < nsuper; ++k) {
    const int below = pi[k] + (super[k + 1] - super[k]);
    if (below < pi[k + 1]) ++child_start_[(parent[k] = owner[s[below]]) + 1];
  }
  for (int k = 0; k < nsuper; ++k) child_start_[k + 1] += child_start_[k];
  child_list_.resize(child_start_[nsuper]);
  std::vector<int> next_child(child_start_.begin(), child_start_.end() - 1);
  for (int k = 0; k < nsuper; ++k)  // children in increasing order, as they are factored
    if (parent[k] >= 0) child_list_[next_child[parent[k]]++] = k;
#ifdef PROBSLAM_AVX2_KERNELS
  const char* forced = std::getenv("PROBSLAM_SUPERNODAL_KERNELS");
  avx2_ = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
          !(forced && std::strcmp(forced, "generic") == 0);
#endif
  factorize_ = kernels_generic::factorize;
  solve_ = kernels_generic::solve;
#ifdef PROBSLAM_AVX2_KERNELS
  if (avx2_) {
    factorize_ = kernels_avx2::factorize;
    solve_ = kernels_avx2::solve;
  }
#endif
  // The lower triangle of P A P^T, column by column, as indices into upper's values.
  const int* perm = static_cast<const int*>(symbolic.Perm);
  perm_.resize(n_);
  for (int k = 0; k < n_; ++k) perm_[k] = perm ? perm[k] : k;
  std::vector<int> inverse(n_);
  for (int k = 0; k < n_; ++k) inverse[perm_[k]] = k;
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

SupernodalPlanView SupernodalNumeric::view() const {
  SupernodalPlanView v;
  v.n = n_;
  v.nsuper = static_cast<int>(super_.size()) - 1;
  v.perm = perm_.data();
  v.super = super_.data();
  v.pi = pi_.data();
  v.px = px_.data();
  v.rows = rows_.data();
  v.child_start = child_start_.data();
  v.child_list = child_list_.data();
  v.a_start = a_start_.data();
  v.a_row = a_row_.data();
  v.a_value = a_value_.data();
  return v;
}

int SupernodalNumeric::factorize(const SparseMatrixd& upper, double* lx) const {
  return factorize_(view(), upper.valuePtr(), lx);
}

void SupernodalNumeric::solve(const double* lx, Eigen::MatrixXd& b) const {
  solve_(view(), lx, b.data(), static_cast<int>(b.cols()));
}

}  // namespace probslam::graph_detail
