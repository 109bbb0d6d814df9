#pragma once
// Joint compatibility branch and bound (JCBB; Neira & Tardos 2001): the data association of a
// whole scan at once. Measurements of one scan share the robot's pose error, so pairings that
// are each plausible can be jointly implausible (two neighbouring landmarks swapped, or both
// measurements shifted the same way); the joint Mahalanobis distance, with the cross
// covariances between the pairings, sees this where one-at-a-time gating cannot.
#include <Eigen/Core>
#include <vector>

namespace probslam {

/// A candidate pairing: measurement `measurement` explained by target `target`. Its predicted
/// measurement is linear in the state columns `columns` with Jacobian `jacobian` (m x columns);
/// `noise` (m x m) is added to its own block of the innovation covariance: the sensor's Q, plus
/// the covariance of a target kept outside the state (it is then uncorrelated with the rest).
struct Pairing {
  int measurement = 0;
  int target = 0;
  Eigen::VectorXd innovation;
  Eigen::MatrixXd jacobian;
  std::vector<int> columns;
  Eigen::MatrixXd noise;
};

/// A joint association: per measurement the target it is paired with, -1 when unpaired.
struct JointAssociation {
  std::vector<int> target;
  int pairings = 0;
  double nis = 0.0;  // joint normalised innovation squared of the pairings (0 with none)
  bool complete = true;  // false when the search stopped at kJcbbMaxNodes (best found so far)
};

/// Hypotheses the branch and bound may grow (one Cholesky factorisation each). The search is
/// exponential in the worst case (a dense cluster of landmarks, many measurements: 16 of them
/// took minutes); beyond this budget it returns the best jointly compatible hypothesis found so
/// far, which the depth-first, most-plausible-first order makes a greedy-quality one. About
/// 20 us per hypothesis for 20 measurements: a second at most.
inline constexpr long kJcbbMaxNodes = 50000;

/// JCBB over `num_measurements` measurements. A hypothesis pairs each measurement with one of its
/// `pairings` (the individually compatible ones) or with nothing, each target at most once; it
/// is jointly compatible when, taking the measurements in order, the joint NIS of the pairings
/// made so far never exceeds gates[number of those pairings]. Returns the jointly compatible
/// hypothesis with the most pairings, ties broken by the smallest joint NIS (see kJcbbMaxNodes). `covariance` is
/// the state covariance the Jacobians refer to; `gates` needs num_measurements + 1 entries
/// (gates[0] unused), typically chi-square quantiles with n times one measurement's dof.
/// Throws std::invalid_argument naming the argument for inconsistent input.
JointAssociation joint_compatibility(int num_measurements, const std::vector<Pairing>& pairings,
                                     const Eigen::Ref<const Eigen::MatrixXd>& covariance,
                                     const std::vector<double>& gates);

}  // namespace probslam
