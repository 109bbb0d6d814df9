#include "probslam/graph/block_system.hpp"

#include <algorithm>

#include "probslam/core/check.hpp"

namespace probslam {

BlockSystem::BlockSystem(std::vector<int> sizes, const std::vector<std::pair<int, int>>& couplings)
    : sizes_(std::move(sizes)) {
  const int n = num_variables();
  offsets_.assign(n + 1, 0);
  for (int v = 0; v < n; ++v) {
    require(sizes_[v] >= 0, "sizes", "must not be negative");
    offsets_[v + 1] = offsets_[v] + sizes_[v];
  }
  dim_ = offsets_[n];

  // Row variables of each column variable: itself and every coupled variable before it.
  std::vector<std::vector<int>> rows_of(n);
  for (int v = 0; v < n; ++v)
    if (sizes_[v] > 0) rows_of[v].push_back(v);
  for (const auto& [a, b] : couplings) {
    require(a >= 0 && a < n && b >= 0 && b < n, "couplings", "must name existing variables");
    if (a == b || sizes_[a] == 0 || sizes_[b] == 0) continue;
    rows_of[std::max(a, b)].push_back(std::min(a, b));
  }

  std::vector<int> outer(dim_ + 1, 0);
  std::vector<int> inner;
  blocks_in_column_.assign(n, {});
  diagonal_index_.assign(dim_, 0);
  for (int j = 0; j < n; ++j) {
    auto& rows = rows_of[j];
    std::sort(rows.begin(), rows.end());
    rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
    const int first_block = static_cast<int>(blocks_.size());
    for (int i : rows) {
      blocks_in_column_[j].emplace_back(i, static_cast<int>(blocks_.size()));
      blocks_.push_back({i, j, static_cast<int>(column_starts_.size())});
      column_starts_.resize(column_starts_.size() + sizes_[j]);
    }
    for (int c = 0; c < sizes_[j]; ++c) {
      const int column = offsets_[j] + c;
      for (int b = first_block; b < static_cast<int>(blocks_.size()); ++b) {
        const int i = blocks_[b].row_var;
        column_starts_[blocks_[b].first_column_start + c] = static_cast<int>(inner.size());
        const int row_count = i == j ? c + 1 : sizes_[i];
        for (int r = 0; r < row_count; ++r) inner.push_back(offsets_[i] + r);
      }
      diagonal_index_[column] = static_cast<int>(inner.size()) - 1;
      outer[column + 1] = static_cast<int>(inner.size());
    }
  }
  upper_.resize(dim_, dim_);
  upper_.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), upper_.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), upper_.innerIndexPtr());
  set_zero();
}

BlockHandle BlockSystem::block(int i, int j) const {
  require(i >= 0 && i < num_variables() && j >= 0 && j < num_variables(), "block",
          "must name existing variables");
  if (sizes_[i] == 0 || sizes_[j] == 0) return {};
  const bool transposed = i > j;
  if (transposed) std::swap(i, j);
  for (const auto& [row_var, id] : blocks_in_column_[j])
    if (row_var == i) return {id, transposed};
  throw_invalid_argument("block", "was not declared as a coupling");
}

void BlockSystem::set_zero() {
  std::fill(upper_.valuePtr(), upper_.valuePtr() + upper_.nonZeros(), 0.0);
  rhs_.setZero(dim_);
}

void BlockSystem::add(BlockHandle handle, const Eigen::Ref<const Eigen::MatrixXd>& m) {
  if (handle.id < 0) return;
  const Block& b = blocks_[handle.id];
  double* values = upper_.valuePtr();
  const int cols = sizes_[b.col_var];
  for (int c = 0; c < cols; ++c) {
    double* column = values + column_starts_[b.first_column_start + c];
    const int row_count = b.row_var == b.col_var ? c + 1 : sizes_[b.row_var];
    if (handle.transposed)
      for (int r = 0; r < row_count; ++r) column[r] += m(c, r);
    else
      for (int r = 0; r < row_count; ++r) column[r] += m(r, c);
  }
}

void BlockSystem::add_rhs(int var, const Eigen::Ref<const Eigen::VectorXd>& v) {
  if (sizes_[var] == 0) return;
  rhs_.segment(offsets_[var], sizes_[var]) += v;
}

Eigen::VectorXd BlockSystem::diagonal() const {
  Eigen::VectorXd d(dim_);
  for (int k = 0; k < dim_; ++k) d[k] = upper_.valuePtr()[diagonal_index_[k]];
  return d;
}

void BlockSystem::add_to_diagonal(const Eigen::VectorXd& values) {
  for (int k = 0; k < dim_; ++k) upper_.valuePtr()[diagonal_index_[k]] += values[k];
}

}  // namespace probslam
