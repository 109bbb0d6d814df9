#pragma once
// Private to src/io: the information matrix an edge's noise entries stand for (NoiseFormat),
// shared by the 2-D and 3-D pose-graph readers.
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include <cmath>
#include <optional>

#include "probslam/io/pose_graph_file.hpp"
#include "text_fields.hpp"

namespace probslam::io_detail {

// NoiseFormat::kDefault made the format's own convention: square-root information for iSAM,
// information for g2o and TORO.
inline NoiseFormat own_noise(NoiseFormat noise, PoseGraphFormat format) {
  if (noise != NoiseFormat::kDefault) return noise;
  return format == PoseGraphFormat::kIsam ? NoiseFormat::kSquareRootInformation : NoiseFormat::kInformation;
}

// The information `entries` stand for under `noise`. `entries` is symmetric, built from the
// upper triangle the file gives; a square root uses that triangle only. kDefault must have been
// resolved to the format's own convention by the caller.
template <int N>
Eigen::Matrix<double, N, N> information_from(const Eigen::Matrix<double, N, N>& entries, NoiseFormat noise,
                                             const LineError& err) {
  using Matrix = Eigen::Matrix<double, N, N>;
  if (!entries.allFinite()) err.fail("noise entries must be finite");
  if (noise == NoiseFormat::kInformation) return entries;
  if (noise == NoiseFormat::kSquareRootInformation) {
    const Matrix r = entries.template triangularView<Eigen::Upper>();
    return r.transpose() * r;  // exactly symmetric: (i, j) and (j, i) sum the same products
  }
  const Eigen::LLT<Matrix> llt(entries);
  if (llt.info() != Eigen::Success) err.fail("covariance is not positive definite");
  const Matrix information = llt.solve(Matrix::Identity());
  return 0.5 * (information + information.transpose());
}

// The information-repair policy (docs/pose_graphs.md): an information matrix that is finite and
// symmetric but not positive definite (SE-Sync's cubicle.g2o: 5,021 of 16,869 edges with a
// negative eigenvalue) gets its eigenvalues raised to at least kInformationEigenvalueFloor times
// the largest, the eigenvectors kept: the edge keeps its well-determined directions and gives
// the doubtful ones almost no weight, instead of the whole file being refused. One with no
// positive eigenvalue has nothing to keep and stays an error. Returns the repaired matrix and
// its smallest eigenvalue before, or nothing when `information` is positive definite.

template <int N>
struct RepairedInformation {
  Eigen::Matrix<double, N, N> information;
  double smallest_eigenvalue;  // of the matrix the file gave
};

template <int N>
std::optional<RepairedInformation<N>> repaired_information(const Eigen::Matrix<double, N, N>& information) {
  using Matrix = Eigen::Matrix<double, N, N>;
  if (!information.allFinite() || Eigen::LLT<Matrix>(information).info() == Eigen::Success) return std::nullopt;
  const Eigen::SelfAdjointEigenSolver<Matrix> eigen(information);
  if (eigen.info() != Eigen::Success) return std::nullopt;
  const double largest = eigen.eigenvalues().maxCoeff();
  if (!(largest > 0.0) || !std::isfinite(largest)) return std::nullopt;
  const Eigen::Matrix<double, N, 1> raised = eigen.eigenvalues().cwiseMax(kInformationEigenvalueFloor * largest);
  Matrix out = eigen.eigenvectors() * raised.asDiagonal() * eigen.eigenvectors().transpose();
  out = 0.5 * (out + out.transpose());
  if (Eigen::LLT<Matrix>(out).info() != Eigen::Success) return std::nullopt;
  return RepairedInformation<N>{out, eigen.eigenvalues().minCoeff()};
}

}  // namespace probslam::io_detail
