#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <cmath>

#include "probslam/core/angle.hpp"

namespace probslam {

/// log det(2 pi Sigma) from the Cholesky factorisation of Sigma: with the squared Mahalanobis
/// distance it makes -2 log N(x; mu, Sigma).
inline double log_det_2pi(const Eigen::LLT<Eigen::MatrixXd>& llt) {
  return 2.0 * llt.matrixLLT().diagonal().array().log().sum() + static_cast<double>(llt.rows()) * std::log(kTwoPi);
}

}  // namespace probslam
