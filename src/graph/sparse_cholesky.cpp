#include "probslam/graph/sparse_cholesky.hpp"

#include <cholmod.h>

#include <algorithm>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>

#include "probslam/core/check.hpp"
#include "supernodal_numeric.hpp"

namespace probslam {
namespace {

// A pivot of the factor (the Schur complement left of a diagonal entry once the variables before
// it are eliminated) is computed with a rounding error of about (entries summed) x epsilon x the
// diagonal entry itself. A pivot below this multiple of epsilon times its own diagonal entry is
// rounding noise: that direction of the system is singular to working precision (a variable
// constrained in fewer directions than it has, or two variables tied so rigidly that their
// common motion is lost in the rounding of the tie). The test is per variable and so invariant
// to the scale of each one: information from 1e-12 to 1e12 in one system passes, which a cut on
// the reciprocal condition number (the ratio of the smallest to the largest pivot) refuses.
constexpr double kMinRelativePivot = 1e4 * std::numeric_limits<double>::epsilon();

// The diagonal of the factor L (L L^T = P A P^T), simplicial or supernodal.
std::vector<double> factor_diagonal(const cholmod_factor* f) {
  std::vector<double> d(f->n);
  const double* x = static_cast<const double*>(f->x);
  if (!f->is_super) {
    const int* p = static_cast<const int*>(f->p);
    for (size_t j = 0; j < f->n; ++j) d[j] = x[p[j]];  // the diagonal leads each column
    return d;
  }
  const int* super = static_cast<const int*>(f->super);
  const int* pi = static_cast<const int*>(f->pi);
  const int* px = static_cast<const int*>(f->px);
  for (size_t s = 0; s < f->nsuper; ++s) {
    const int rows = pi[s + 1] - pi[s];
    for (int k = 0; k < super[s + 1] - super[s]; ++k) d[super[s] + k] = x[px[s] + k + k * rows];
  }
  return d;
}

// The diagonal of the symmetric matrix whose upper triangle `upper` holds.
std::vector<double> matrix_diagonal(const SparseMatrixd& upper) {
  std::vector<double> d(upper.cols(), 0.0);
  for (int j = 0; j < upper.cols(); ++j)
    for (SparseMatrixd::InnerIterator it(upper, j); it; ++it)
      if (it.row() == j) d[j] = it.value();
  return d;
}

// The first column (of the factor's order) whose pivot is rounding noise, or -1.
int first_negligible_pivot(const cholmod_factor* f, const SparseMatrixd& upper) {
  const std::vector<double> l = factor_diagonal(f), a = matrix_diagonal(upper);
  const int* perm = static_cast<const int*>(f->Perm);
  for (size_t j = 0; j < f->n; ++j) {
    const double diagonal = a[perm ? perm[j] : j];
    if (!(l[j] * l[j] > kMinRelativePivot * diagonal)) return static_cast<int>(j);
  }
  return -1;
}

}  // namespace

struct SparseCholesky::Impl {
  SparseCholeskyOptions options;
  cholmod_common common{};
  cholmod_factor* factor = nullptr;
  // Pattern of the matrix the analysis was made for, to detect a change.
  std::vector<int> outer, inner;
  bool reused = false;
  int singular_column = -1;  // of A, when the last factorize() failed there
  // A supernodal factor's numbers come from Eigen's kernels (supernodal_numeric.hpp).
  std::unique_ptr<graph_detail::SupernodalNumeric> numeric;

  // Sparse inverse on the pattern of L (computed on demand, dropped at each factorisation).
  mutable bool have_inverse = false;
  mutable std::vector<int> z_outer, z_inner;  // column-compressed lower triangle, rows sorted
  mutable std::vector<double> z_values;
  mutable std::vector<int> inverse_permutation;

  explicit Impl(SparseCholeskyOptions o) : options(o) {
    cholmod_start(&common);
    common.print = 0;
    common.error_handler = nullptr;
    common.supernodal = options.method == FactorMethod::kSimplicial   ? CHOLMOD_SIMPLICIAL
                        : options.method == FactorMethod::kSupernodal ? CHOLMOD_SUPERNODAL
                                                                      : CHOLMOD_AUTO;
    common.nmethods = 1;
    // kDefault here (no problem that names its own) is AMD.
    common.method[0].ordering =
        options.ordering == FillOrdering::kMetis ? CHOLMOD_METIS : CHOLMOD_AMD;
    common.postorder = 1;
    common.final_ll = 1;  // LL' keeps the sparse-inverse recurrence simple
  }
  ~Impl() {
    if (factor) cholmod_free_factor(&factor, &common);
    cholmod_finish(&common);
  }

  // A non-owning CHOLMOD view of an Eigen column-compressed matrix (upper triangle stored).
  static cholmod_sparse view(const SparseMatrixd& a) {
    cholmod_sparse s{};
    s.nrow = static_cast<size_t>(a.rows());
    s.ncol = static_cast<size_t>(a.cols());
    s.nzmax = static_cast<size_t>(a.nonZeros());
    s.p = const_cast<int*>(a.outerIndexPtr());
    s.i = const_cast<int*>(a.innerIndexPtr());
    s.nz = a.isCompressed() ? nullptr : const_cast<int*>(a.innerNonZeroPtr());
    s.x = const_cast<double*>(a.valuePtr());
    s.stype = 1;
    s.itype = CHOLMOD_INT;
    s.xtype = CHOLMOD_REAL;
    s.dtype = CHOLMOD_DOUBLE;
    s.sorted = 1;
    s.packed = a.isCompressed() ? 1 : 0;
    return s;
  }

  bool same_pattern(const SparseMatrixd& a) const {
    if (!factor || static_cast<int>(outer.size()) != a.cols() + 1) return false;
    if (!std::equal(outer.begin(), outer.end(), a.outerIndexPtr())) return false;
    return std::equal(inner.begin(), inner.end(), a.innerIndexPtr());
  }

  void compute_inverse() const;
  double inverse_entry(int r, int c) const;  // permuted indices; NaN when outside the pattern
};

SparseCholesky::SparseCholesky(SparseCholeskyOptions options)
    : impl_(std::make_unique<Impl>(options)) {}
SparseCholesky::~SparseCholesky() = default;
SparseCholesky::SparseCholesky(SparseCholesky&&) noexcept = default;
SparseCholesky& SparseCholesky::operator=(SparseCholesky&&) noexcept = default;

int SparseCholesky::rows() const {
  return impl_->factor ? static_cast<int>(impl_->factor->n) : 0;
}
bool SparseCholesky::factorized() const { return impl_->factor && impl_->factor->minor == impl_->factor->n; }
bool SparseCholesky::analysis_reused() const { return impl_->reused; }

long SparseCholesky::factor_nonzeros() const {
  const cholmod_factor* f = impl_->factor;
  if (!f) return 0;
  if (f->is_super) {
    long n = 0;
    const int* super = static_cast<const int*>(f->super);
    const int* pi = static_cast<const int*>(f->pi);
    for (size_t s = 0; s < f->nsuper; ++s) {
      const long cols = super[s + 1] - super[s], rows = pi[s + 1] - pi[s];
      n += cols * rows - cols * (cols - 1) / 2;
    }
    return n;
  }
  const int* nz = static_cast<const int*>(f->nz);
  long n = 0;
  for (size_t j = 0; j < f->n; ++j) n += nz[j];
  return n;
}

void SparseCholesky::factorize(const SparseMatrixd& upper) {
  Impl& m = *impl_;
  require(upper.rows() == upper.cols(), "matrix", "must be square");
  require(upper.rows() > 0, "matrix", "must not be empty");
  const Eigen::Map<const Eigen::VectorXd> values(upper.valuePtr(), upper.nonZeros());
  require(upper.isCompressed(), "matrix", "must be compressed (call makeCompressed())");
  require_all_finite(values, "matrix");
  m.have_inverse = false;
  cholmod_sparse a = Impl::view(upper);
  m.reused = m.same_pattern(upper);
  if (!m.reused) {
    if (m.factor) cholmod_free_factor(&m.factor, &m.common);
    m.factor = cholmod_analyze(&a, &m.common);
    if (!m.factor) throw std::runtime_error("CHOLMOD analysis failed (out of memory?)");
    m.outer.assign(upper.outerIndexPtr(), upper.outerIndexPtr() + upper.cols() + 1);
    m.inner.assign(upper.innerIndexPtr(), upper.innerIndexPtr() + upper.nonZeros());
    m.numeric.reset();
    if (m.factor->is_super) m.numeric = std::make_unique<graph_detail::SupernodalNumeric>(*m.factor, upper);
  }
  m.singular_column = -1;
  bool done = false;
  if (m.numeric) {
    if (m.factor->xtype == CHOLMOD_PATTERN &&
        !cholmod_change_factor(CHOLMOD_REAL, /*to_ll=*/1, /*to_super=*/1, /*to_packed=*/1, /*to_monotonic=*/1,
                               m.factor, &m.common))
      throw std::runtime_error("CHOLMOD factor allocation failed (out of memory?)");
    // A pivot that is not positive: CHOLMOD's own factorisation below then reports where, as
    // the simplicial path does, so both paths fail alike.
    done = m.numeric->factorize(upper, static_cast<double*>(m.factor->x)) < 0;
    if (done) {
      m.factor->is_ll = 1;
      m.factor->minor = m.factor->n;
      m.common.status = CHOLMOD_OK;
    }
  }
  if (!done) cholmod_factorize(&a, m.factor, &m.common);
  const bool not_positive = m.common.status == CHOLMOD_NOT_POSDEF || m.factor->minor < m.factor->n;
  const int pivot = not_positive ? static_cast<int>(m.factor->minor) : first_negligible_pivot(m.factor, upper);
  if (pivot >= 0) {
    const int* perm = static_cast<const int*>(m.factor->Perm);
    m.singular_column = perm && pivot < static_cast<int>(m.factor->n) ? perm[pivot] : pivot;
    // The analysis stays valid; the next factorize() with this pattern may succeed.
    m.factor->minor = 0;
    throw_invalid_argument("matrix", "is singular or not positive definite (column " +
                                         std::to_string(m.singular_column) + " of " +
                                         std::to_string(m.factor->n) +
                                         "): is every variable anchored and connected?");
  }
}

int SparseCholesky::singular_column() const { return impl_->singular_column; }

Eigen::MatrixXd SparseCholesky::solve(const Eigen::MatrixXd& b) const {
  Impl& m = *impl_;
  require(factorized(), "solve", "needs a successful factorize() first");
  require(b.rows() == rows(), "b", "must have as many rows as the matrix");
  if (m.numeric && m.factor->is_super) {
    Eigen::MatrixXd x = b;
    m.numeric->solve(static_cast<const double*>(m.factor->x), x);
    return x;
  }
  cholmod_dense rhs{};
  rhs.nrow = static_cast<size_t>(b.rows());
  rhs.ncol = static_cast<size_t>(b.cols());
  rhs.nzmax = rhs.nrow * rhs.ncol;
  rhs.d = rhs.nrow;
  rhs.x = const_cast<double*>(b.data());
  rhs.xtype = CHOLMOD_REAL;
  rhs.dtype = CHOLMOD_DOUBLE;
  cholmod_dense* x = cholmod_solve(CHOLMOD_A, m.factor, &rhs, &m.common);
  if (!x) throw std::runtime_error("CHOLMOD solve failed (out of memory?)");
  Eigen::MatrixXd out = Eigen::Map<const Eigen::MatrixXd>(static_cast<const double*>(x->x),
                                                          b.rows(), b.cols());
  cholmod_free_dense(&x, &m.common);
  return out;
}

Eigen::VectorXd SparseCholesky::solve(const Eigen::VectorXd& b) const {
  return solve(Eigen::MatrixXd(b));
}

// Takahashi's recurrence on L L^T = P A P^T: Z = (L L^T)^-1 on the pattern of L, from the last
// column to the first, each entry needing only entries of later columns on that pattern.
void SparseCholesky::Impl::compute_inverse() const {
  cholmod_factor* copy = cholmod_copy_factor(factor, const_cast<cholmod_common*>(&common));
  if (!copy) throw std::runtime_error("CHOLMOD copy failed (out of memory?)");
  auto* cm = const_cast<cholmod_common*>(&common);
  cholmod_change_factor(CHOLMOD_REAL, /*to_ll=*/1, /*to_super=*/0, /*to_packed=*/1,
                        /*to_monotonic=*/1, copy, cm);
  const int n = static_cast<int>(copy->n);
  const int* lp = static_cast<const int*>(copy->p);
  const int* li = static_cast<const int*>(copy->i);
  const int* lnz = static_cast<const int*>(copy->nz);
  const double* lx = static_cast<const double*>(copy->x);

  // Sorted copy of L; z shares its pattern.
  z_outer.assign(n + 1, 0);
  for (int j = 0; j < n; ++j) z_outer[j + 1] = z_outer[j] + lnz[j];
  z_inner.resize(z_outer[n]);
  std::vector<double> l_values(z_outer[n]);
  std::vector<std::pair<int, double>> column;
  for (int j = 0; j < n; ++j) {
    column.clear();
    for (int k = lp[j]; k < lp[j] + lnz[j]; ++k) column.emplace_back(li[k], lx[k]);
    std::sort(column.begin(), column.end());
    for (size_t k = 0; k < column.size(); ++k) {
      z_inner[z_outer[j] + k] = column[k].first;
      l_values[z_outer[j] + k] = column[k].second;
    }
  }
  inverse_permutation.assign(n, 0);
  const int* perm = static_cast<const int*>(copy->Perm);
  for (int k = 0; k < n; ++k) inverse_permutation[perm[k]] = k;
  cholmod_free_factor(&copy, cm);

  // Column j needs S_i = sum_k L_kj Z(i, k) over i, k in its pattern. Every such Z(i, k) sits in
  // the pattern of L (fill is chordal), in column min(i, k), so one sweep over the columns c of
  // the pattern covers each pair once, with a scatter array instead of a search per entry.
  z_values.assign(z_outer[n], 0.0);
  std::vector<double> l_at(n, 0.0), sum_at(n, 0.0);
  std::vector<int> stamp(n, -1);
  for (int j = n - 1; j >= 0; --j) {
    const int begin = z_outer[j], end = z_outer[j + 1];  // begin holds the diagonal
    for (int b = begin + 1; b < end; ++b) {
      stamp[z_inner[b]] = j;
      l_at[z_inner[b]] = l_values[b];
      sum_at[z_inner[b]] = 0.0;
    }
    for (int b = begin + 1; b < end; ++b) {
      const int c = z_inner[b];
      for (int e = z_outer[c]; e < z_outer[c + 1]; ++e) {
        const int r = z_inner[e];
        if (stamp[r] != j) continue;
        sum_at[c] += l_at[r] * z_values[e];
        if (r != c) sum_at[r] += l_at[c] * z_values[e];
      }
    }
    const double diag = l_values[begin];
    double diag_sum = 0.0;
    for (int b = begin + 1; b < end; ++b) {
      z_values[b] = -sum_at[z_inner[b]] / diag;
      diag_sum += l_values[b] * z_values[b];
    }
    z_values[begin] = 1.0 / (diag * diag) - diag_sum / diag;
  }
  have_inverse = true;
}

double SparseCholesky::Impl::inverse_entry(int r, int c) const {
  if (r < c) std::swap(r, c);
  const auto first = z_inner.begin() + z_outer[c], last = z_inner.begin() + z_outer[c + 1];
  const auto it = std::lower_bound(first, last, r);
  if (it == last || *it != r) return std::numeric_limits<double>::quiet_NaN();
  return z_values[it - z_inner.begin()];
}

std::vector<Eigen::MatrixXd> SparseCholesky::inverse_blocks(
    const std::vector<InverseBlock>& blocks) const {
  const Impl& m = *impl_;
  require(factorized(), "inverse_blocks", "needs a successful factorize() first");
  const int n = rows();
  for (const InverseBlock& b : blocks)
    require(b.row >= 0 && b.col >= 0 && b.rows >= 0 && b.cols >= 0 && b.row + b.rows <= n &&
                b.col + b.cols <= n,
            "blocks", "must lie inside the matrix");
  if (!m.have_inverse) m.compute_inverse();

  std::vector<Eigen::MatrixXd> out;
  out.reserve(blocks.size());
  // Entries outside the pattern of L come from solves against unit columns: gathered by column
  // first, then solved kSolveChunk columns at a time (one supernodal sweep serves them all, and
  // the memory stays n * kSolveChunk whatever the number of columns).
  struct Pending {
    size_t block;
    int r, c;
  };
  std::map<int, std::vector<Pending>> pending;  // original column -> the entries it serves
  for (const InverseBlock& b : blocks) {
    Eigen::MatrixXd block(b.rows, b.cols);
    for (int c = 0; c < b.cols; ++c) {
      for (int r = 0; r < b.rows; ++r) {
        const int orig_r = b.row + r, orig_c = b.col + c;
        block(r, c) = m.inverse_entry(m.inverse_permutation[orig_r], m.inverse_permutation[orig_c]);
        if (std::isnan(block(r, c))) pending[orig_c].push_back({out.size(), r, c});
      }
    }
    out.push_back(std::move(block));
  }
  constexpr int kSolveChunk = 64;
  std::vector<int> columns;
  columns.reserve(pending.size());
  for (const auto& entry : pending) columns.push_back(entry.first);
  for (size_t start = 0; start < columns.size(); start += kSolveChunk) {
    const int count = static_cast<int>(std::min<size_t>(kSolveChunk, columns.size() - start));
    Eigen::MatrixXd units = Eigen::MatrixXd::Zero(n, count);
    for (int k = 0; k < count; ++k) units(columns[start + k], k) = 1.0;
    const Eigen::MatrixXd solved = solve(units);
    for (int k = 0; k < count; ++k)
      for (const Pending& p : pending[columns[start + k]])
        out[p.block](p.r, p.c) = solved(blocks[p.block].row + p.r, k);
  }
  return out;
}

}  // namespace probslam
