#pragma once
// The rotation group SO(3) as the 3-D pose graph needs it: exponential and logarithm between
// unit quaternions and rotation vectors (radians), and the right Jacobian's inverse that
// linearises Log around a rotation.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace probslam {

/// |norm - 1| allowed of a quaternion handed in (a file, an array), which is then normalised:
/// files print quaternions with 5-9 significant digits, and half a unit in the 5th decimal on each
/// of four components moves the norm by at most 5e-6 * sum|q_i| <= 1e-5. Anything further is not
/// a rotation (a raw rotation vector, a scale of 2 or 0.5, a zero quaternion). One value for the
/// readers, PoseGraph3D and the bindings.
constexpr double kQuaternionNormTolerance = 1e-5;

/// The rotation by angle |w| about w / |w|.
Eigen::Quaterniond so3_exp(const Eigen::Vector3d& w);
/// The rotation vector of q, angle in [0, pi] (q and -q give the same).
Eigen::Vector3d so3_log(const Eigen::Quaterniond& q);
/// Jr^-1(w): Log(Exp(w) Exp(dw)) = w + Jr^-1(w) dw + O(dw^2), for |w| < pi.
Eigen::Matrix3d so3_right_jacobian_inverse(const Eigen::Vector3d& w);
/// [w]x, the matrix of w x (.).
Eigen::Matrix3d skew(const Eigen::Vector3d& w);
/// The rotation nearest to m in the Frobenius norm (its SVD with the singular values set to 1,
/// the last one's sign chosen so that the determinant is +1).
Eigen::Matrix3d project_to_rotation(const Eigen::Matrix3d& m);

}  // namespace probslam
