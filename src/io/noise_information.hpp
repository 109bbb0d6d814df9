#pragma once
// Private to src/io: the information matrix an edge's noise entries stand for (NoiseFormat),
// shared by the 2-D and 3-D pose-graph readers.
#include <Eigen/Cholesky>
#include <Eigen/Core>

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

}  // namespace probslam::io_detail
