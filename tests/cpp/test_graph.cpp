// The shared sparse path: BlockSystem assembly and SparseCholesky against dense Eigen.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cstdlib>
#include <random>
#include <stdexcept>

#include "probslam/graph/block_system.hpp"
#include "probslam/graph/sparse_cholesky.hpp"

namespace probslam {
namespace {

// Agreement of a sparse and a dense factorisation of a well-conditioned system.
constexpr double kTolerance = 1e-10;

// A random block system over a chain with a few extra couplings; returns the dense H too.
BlockSystem random_system(std::mt19937& rng, Eigen::MatrixXd& dense, const std::vector<int>& sizes,
                          const std::vector<std::pair<int, int>>& couplings) {
  BlockSystem system(sizes, couplings);
  dense.setZero(system.dim(), system.dim());
  std::normal_distribution<double> normal;
  auto random = [&](int r, int c) {
    Eigen::MatrixXd m(r, c);
    for (int i = 0; i < r; ++i)
      for (int j = 0; j < c; ++j) m(i, j) = normal(rng);
    return m;
  };
  for (const auto& [i, j] : couplings) {
    if (sizes[i] == 0 || sizes[j] == 0) continue;
    // A factor touching (i, j): J^T J, added through the three blocks in both orientations.
    const Eigen::MatrixXd ji = random(4, sizes[i]), jj = random(4, sizes[j]);
    system.add(system.block(i, i), ji.transpose() * ji);
    system.add(system.block(j, j), jj.transpose() * jj);
    system.add(system.block(j, i), jj.transpose() * ji);  // stored transposed when j > i
    const int oi = system.offset(i), oj = system.offset(j);
    dense.block(oi, oi, sizes[i], sizes[i]) += ji.transpose() * ji;
    dense.block(oj, oj, sizes[j], sizes[j]) += jj.transpose() * jj;
    dense.block(oj, oi, sizes[j], sizes[i]) += jj.transpose() * ji;
    dense.block(oi, oj, sizes[i], sizes[j]) += ji.transpose() * jj;
  }
  const Eigen::VectorXd diag = Eigen::VectorXd::Constant(system.dim(), 0.5);
  system.add_to_diagonal(diag);
  dense.diagonal() += diag;
  return system;
}

BlockSystem random_system(std::mt19937& rng, Eigen::MatrixXd& dense) {
  const std::vector<int> sizes = {3, 2, 3, 3, 0, 2, 3};  // variable 4 is fixed
  return random_system(rng, dense, sizes, {{0, 1}, {1, 2}, {2, 3}, {3, 4}, {4, 5}, {5, 6}, {6, 0}, {2, 5}});
}

TEST(SparseCholesky, InverseBlocksOutsideThePatternComeInChunksOfColumns) {
  // A chain of 50 poses: most block pairs lie outside L's pattern, 150 columns to solve for,
  // more than one chunk of inverse_blocks' solves (64 columns).
  std::vector<int> sizes(50, 3);
  std::vector<std::pair<int, int>> couplings;
  for (int i = 0; i + 1 < 50; ++i) couplings.emplace_back(i, i + 1);
  for (FactorMethod method : {FactorMethod::kSimplicial, FactorMethod::kSupernodal}) {
    std::mt19937 rng(3);
    Eigen::MatrixXd dense;
    BlockSystem system = random_system(rng, dense, sizes, couplings);
    SparseCholesky cholesky({method, FillOrdering::kAmd});
    cholesky.factorize(system.upper());
    const Eigen::MatrixXd inverse = dense.inverse();
    std::vector<InverseBlock> requests;
    for (int i = 0; i < 50; ++i)
      for (int j = 0; j < 50; ++j) requests.push_back({system.offset(i), 3, system.offset(j), 3});
    const auto blocks = cholesky.inverse_blocks(requests);
    double worst = 0.0;
    for (size_t k = 0; k < requests.size(); ++k)
      worst = std::max(worst, (blocks[k] - inverse.block(requests[k].row, requests[k].col, 3, 3)).cwiseAbs().maxCoeff());
    EXPECT_LT(worst, kTolerance * std::max(1.0, inverse.cwiseAbs().maxCoeff()));
  }
}

TEST(BlockSystem, AssemblesTheUpperTriangleOfTheDenseSum) {
  std::mt19937 rng(1);
  Eigen::MatrixXd dense;
  BlockSystem system = random_system(rng, dense);
  const Eigen::MatrixXd full = Eigen::MatrixXd(SparseMatrixd(system.upper().selfadjointView<Eigen::Upper>()));
  EXPECT_LT((full - dense).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((system.diagonal() - dense.diagonal()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(system.block(3, 4).id, -1);  // the fixed variable takes nothing
  EXPECT_THROW(system.block(0, 3), std::invalid_argument);
}

TEST(SparseCholesky, SolvesAndInvertsLikeDenseLlt) {
  for (FactorMethod method : {FactorMethod::kSimplicial, FactorMethod::kSupernodal}) {
    for (FillOrdering ordering : {FillOrdering::kAmd, FillOrdering::kMetis}) {
      std::mt19937 rng(2);
      Eigen::MatrixXd dense;
      BlockSystem system = random_system(rng, dense);
      SparseCholesky cholesky({method, ordering});
      cholesky.factorize(system.upper());
      EXPECT_FALSE(cholesky.analysis_reused());
      const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(system.dim(), -1.0, 2.0);
      const Eigen::VectorXd x = cholesky.solve(b);
      EXPECT_LT((x - dense.llt().solve(b)).cwiseAbs().maxCoeff(), kTolerance);

      const Eigen::MatrixXd inverse = dense.inverse();
      // Every block pair: some lie in the factor's pattern, others need solves.
      std::vector<InverseBlock> requests;
      for (int i = 0; i < system.num_variables(); ++i)
        for (int j = 0; j < system.num_variables(); ++j)
          if (system.size(i) && system.size(j))
            requests.push_back({system.offset(i), system.size(i), system.offset(j), system.size(j)});
      const auto blocks = cholesky.inverse_blocks(requests);
      for (size_t k = 0; k < requests.size(); ++k) {
        const InverseBlock& r = requests[k];
        EXPECT_LT((blocks[k] - inverse.block(r.row, r.col, r.rows, r.cols)).cwiseAbs().maxCoeff(), kTolerance);
      }
      // Same pattern, new values: the analysis is reused and the result follows the values.
      system.add_to_diagonal(Eigen::VectorXd::Ones(system.dim()));
      cholesky.factorize(system.upper());
      EXPECT_TRUE(cholesky.analysis_reused());
      dense.diagonal().array() += 1.0;
      EXPECT_LT((cholesky.solve(b) - dense.llt().solve(b)).cwiseAbs().maxCoeff(), kTolerance);
    }
  }
}

TEST(SparseCholesky, RefusesSingularAndIndefiniteMatrices) {
  // Two decoupled 1-D chains, one unanchored: singular.
  SparseMatrixd a(4, 4);
  a.insert(0, 0) = 2.0;
  a.insert(0, 1) = -1.0;
  a.insert(1, 1) = 2.0;
  a.insert(2, 2) = 1.0;
  a.insert(2, 3) = -1.0;
  a.insert(3, 3) = 1.0;
  a.makeCompressed();
  SparseCholesky cholesky;
  EXPECT_THROW(cholesky.factorize(a), std::invalid_argument);
  EXPECT_FALSE(cholesky.factorized());
  EXPECT_THROW(cholesky.solve(Eigen::VectorXd(Eigen::VectorXd::Ones(4))), std::invalid_argument);
  a.coeffRef(3, 3) = -1.0;
  EXPECT_THROW(cholesky.factorize(a), std::invalid_argument);
  a.coeffRef(3, 3) = std::nan("");
  EXPECT_THROW(cholesky.factorize(a), std::invalid_argument);
  a.coeffRef(3, 3) = 2.0;  // now positive definite, and the same pattern
  EXPECT_NO_THROW(cholesky.factorize(a));
  EXPECT_TRUE(cholesky.analysis_reused());
}

// A 6x6-block system the size of a small 3-D pose graph (a loop with random chords), with enough
// fill for CHOLMOD to make many supernodes of several columns: the supernodal path (Eigen's
// kernels on CHOLMOD's analysis, supernodal_numeric.hpp) against CHOLMOD's simplicial one.
SparseMatrixd random_pose_graph_system(std::mt19937& rng, int n, Eigen::MatrixXd& dense) {
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::normal_distribution<double> normal;
  dense = Eigen::MatrixXd::Identity(6 * n, 6 * n);
  auto couple = [&](int i, int j) {
    Eigen::MatrixXd ji(6, 6), jj(6, 6);
    for (int k = 0; k < 36; ++k) ji.data()[k] = normal(rng), jj.data()[k] = normal(rng);
    dense.block(6 * i, 6 * i, 6, 6) += ji.transpose() * ji;
    dense.block(6 * j, 6 * j, 6, 6) += jj.transpose() * jj;
    dense.block(6 * i, 6 * j, 6, 6) += ji.transpose() * jj;
    dense.block(6 * j, 6 * i, 6, 6) += jj.transpose() * ji;
  };
  for (int i = 0; i < n; ++i) couple(i, (i + 1) % n);
  for (int k = 0; k < n; ++k) {
    const int i = pick(rng), j = pick(rng);
    if (i != j) couple(i, j);
  }
  const Eigen::MatrixXd upper = dense.triangularView<Eigen::Upper>();
  return upper.sparseView();
}

TEST(SparseCholesky, SupernodalKernelsMatchCholmodsSimplicialFactor) {
  constexpr int kPoses = 120;
  // Both copies of the dense kernels: this CPU's (AVX2 + FMA where it has them) and the baseline
  // (src/graph/supernodal_kernels.hpp), chosen when a supernodal analysis is made.
  for (const char* kernels : {"", "generic"})
  for (FillOrdering ordering : {FillOrdering::kAmd, FillOrdering::kMetis}) {
    setenv("PROBSLAM_SUPERNODAL_KERNELS", kernels, 1);
    std::mt19937 rng(7);
    Eigen::MatrixXd dense;
    SparseMatrixd upper = random_pose_graph_system(rng, kPoses, dense);
    upper.makeCompressed();
    SparseCholesky supernodal({FactorMethod::kSupernodal, ordering}), simplicial({FactorMethod::kSimplicial, ordering});
    supernodal.factorize(upper);
    simplicial.factorize(upper);
    const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(6 * kPoses, -1.0, 2.0);
    const Eigen::VectorXd x = dense.llt().solve(b);
    EXPECT_LT((supernodal.solve(b) - x).cwiseAbs().maxCoeff(), kTolerance);
    EXPECT_LT((simplicial.solve(b) - x).cwiseAbs().maxCoeff(), kTolerance);
    const std::vector<InverseBlock> blocks = {{0, 6, 0, 6}, {6 * 17, 6, 6 * 90, 6}};
    const auto a = supernodal.inverse_blocks(blocks), c = simplicial.inverse_blocks(blocks);
    for (size_t k = 0; k < blocks.size(); ++k) EXPECT_LT((a[k] - c[k]).cwiseAbs().maxCoeff(), kTolerance);
    // New values on the same pattern: the plan is reused and follows them.
    for (int k = 0; k < upper.outerSize(); ++k) upper.coeffRef(k, k) += 3.0;
    dense.diagonal().array() += 3.0;
    supernodal.factorize(upper);
    EXPECT_TRUE(supernodal.analysis_reused());
    EXPECT_LT((supernodal.solve(b) - dense.llt().solve(b)).cwiseAbs().maxCoeff(), kTolerance);
    // An indefinite matrix: refused at the same column as the simplicial path refuses it.
    upper.coeffRef(6 * 50 + 2, 6 * 50 + 2) = -1e3;
    EXPECT_THROW(supernodal.factorize(upper), std::invalid_argument);
    EXPECT_THROW(simplicial.factorize(upper), std::invalid_argument);
    EXPECT_EQ(supernodal.singular_column(), simplicial.singular_column());
    EXPECT_FALSE(supernodal.factorized());
    unsetenv("PROBSLAM_SUPERNODAL_KERNELS");
  }
}

}  // namespace
}  // namespace probslam
