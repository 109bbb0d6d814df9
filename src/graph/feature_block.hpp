#pragma once
// Private to src/graph: one feature's diagonal block of Omega, shared by Tables 11.3, 11.4
// (information_form.cpp) and 11.8 (eif_correspondence.cpp).
#include <Eigen/Core>

#include "probslam/graph/information_form.hpp"

namespace probslam::graph_detail {

/// Omega_jj^-1 (d x d). Throws std::invalid_argument when feature j shares information with
/// another feature (Omega_mm must be block diagonal) or its block is not positive definite.
Eigen::MatrixXd feature_information_inverse(const InformationForm& form, int j);

}  // namespace probslam::graph_detail
