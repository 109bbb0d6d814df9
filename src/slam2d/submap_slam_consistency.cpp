// Whether the closures found agree with each other and with the active ones: each pair must
// close its cycle over the chain of consecutive constraints (pairwise consistency, Mangelson et
// al. 2018's PCM), and where pairs conflict a greedy largest consistent set is kept.
#include <Eigen/Cholesky>
#include <cstddef>
#include <unordered_map>
#include <utility>
#include <vector>

#include "probslam/core/angle.hpp"
#include "probslam/core/pose2_covariance.hpp"
#include "submap_slam_internal.hpp"

namespace probslam {

using submap_slam_detail::pose_of;

namespace {

/// A relative pose (x, y, theta) with its covariance, to first order.
struct Leg {
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
};

Leg then(const Leg& a, const Leg& b) {
  return {pose_of(a.pose).compose(pose_of(b.pose)).vector(), compose_covariance(a.pose, a.cov, b.pose, b.cov)};
}

Leg inverted(const Leg& a) {
  const Eigen::Matrix3d J = inverse_jacobian(a.pose);
  return {pose_of(a.pose).inverse().vector(), J * a.cov * J.transpose()};
}

/// chi2 of a cycle's composition against the identity; 0 when its covariance is singular (no
/// evidence against it).
double cycle_chi2(const Leg& c) {
  Eigen::Vector3d e = c.pose;
  e.z() = wrap_angle(e.z());
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(0.5 * (c.cov + c.cov.transpose()));
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0.0).all()) return 0.0;
  return e.dot(ldlt.solve(e));
}

/// The consecutive constraints composed between any two submaps: what the odometry and the
/// frontend alone say of their relative pose, independent of every closure. The legs from a
/// start are built once, when first asked for.
class ChainLegs {
 public:
  explicit ChainLegs(const std::vector<SubmapConstraint>& constraints) {
    for (const SubmapConstraint& c : constraints) {
      if (c.loop) continue;
      if (static_cast<int>(steps_.size()) <= c.from) steps_.resize(static_cast<std::size_t>(c.from) + 1);
      steps_[static_cast<std::size_t>(c.from)] = {c.measurement, c.covariance};
    }
  }
  /// Submap b's origin seen from submap a's along the chain.
  Leg operator()(int a, int b) {
    if (a > b) return inverted((*this)(b, a));
    std::vector<Leg>& legs = from_[a];
    if (legs.empty()) {
      legs.emplace_back();
      for (std::size_t k = static_cast<std::size_t>(a); k < steps_.size(); ++k) legs.push_back(then(legs.back(), steps_[k]));
    }
    return legs[static_cast<std::size_t>(b - a)];
  }

 private:
  std::vector<Leg> steps_;  // k -> k + 1
  std::unordered_map<int, std::vector<Leg>> from_;
};

Leg leg_of(const SubmapConstraint& c) { return {c.measurement, c.covariance}; }

/// chi2 of the cycle two closures close with the chain: from a's submap to its scan's along a,
/// on along the chain to b's scan's submap, back along b, and along the chain to the start
/// (pairwise consistency, Mangelson et al. 2018's PCM; RRR's inter-cluster test). Where the two
/// chain legs share submaps (travelled both ways) their errors cancel, but the legs are composed
/// as independent: the spread is overstated there, so the test errs towards consistency.
double pair_chi2(const SubmapConstraint& a, const SubmapConstraint& b, ChainLegs& chain) {
  return cycle_chi2(then(then(then(leg_of(a), chain(a.to, b.to)), inverted(leg_of(b))), chain(b.from, a.from)));
}

/// chi2 of a closure against the chain between its submaps alone.
double chain_chi2(const SubmapConstraint& c, ChainLegs& chain) { return cycle_chi2(then(leg_of(c), chain(c.to, c.from))); }

/// The vote among closures `members` (indices into `constraints`: the active ones, then the new
/// ones from `first_new` on). The active ones agree with each other already, so only pairs with a
/// new one are tested. A new closure the chain between its own submaps refutes goes first; then,
/// while pairs conflict, the closure in most conflicts (a greedy largest consistent set, as PCM's
/// heuristic clique), on a tie the one its own chain agrees with least.
class ConsistencyVote {
 public:
  ConsistencyVote(const std::vector<SubmapConstraint>& constraints, std::vector<std::size_t> members,
                  std::size_t first_new, double gate)
      : constraints_(constraints),
        members_(std::move(members)),
        first_new_(first_new),
        gate_(gate),
        chain_(constraints),
        conflicts_(members_.size()),
        live_(members_.size()),
        own_(members_.size(), -1.0),
        dropped_(members_.size(), false) {}

  /// The constraints (indices) outvoted, in the order they go.
  std::vector<std::size_t> losers() {
    find_conflicts();
    drop_refuted_by_chain();
    for (std::size_t worst = most_conflicting(); worst < members_.size(); worst = most_conflicting()) drop(worst);
    return losers_;
  }

 private:
  bool is_new(std::size_t a) const { return members_[a] >= first_new_; }
  const SubmapConstraint& closure(std::size_t a) const { return constraints_[members_[a]]; }
  /// The closure's chi2 against its own chain, computed once.
  double own(std::size_t a) {
    if (own_[a] < 0.0) own_[a] = chain_chi2(closure(a), chain_);
    return own_[a];
  }

  void find_conflicts() {
    for (std::size_t a = 0; a < members_.size(); ++a) {
      if (!is_new(a)) continue;
      for (std::size_t b = 0; b < a; ++b)
        if (pair_chi2(closure(a), closure(b), chain_) > gate_) {
          conflicts_[a].push_back(b);
          conflicts_[b].push_back(a);
        }
    }
    for (std::size_t a = 0; a < members_.size(); ++a) live_[a] = static_cast<int>(conflicts_[a].size());
  }

  void drop_refuted_by_chain() {
    for (std::size_t a = 0; a < members_.size(); ++a)
      if (is_new(a) && own(a) > gate_) drop(a);
  }

  /// The member in most live conflicts (members_.size() when none is in any).
  std::size_t most_conflicting() {
    std::size_t worst = members_.size();
    for (std::size_t a = 0; a < members_.size(); ++a) {
      if (dropped_[a] || live_[a] == 0) continue;
      const double own_a = own(a);
      if (worst == members_.size() || live_[a] > live_[worst] || (live_[a] == live_[worst] && own_a > own_[worst]))
        worst = a;
    }
    return worst;
  }

  void drop(std::size_t a) {
    dropped_[a] = true;
    for (std::size_t b : conflicts_[a])
      if (!dropped_[b]) --live_[b];
    losers_.push_back(members_[a]);
  }

  const std::vector<SubmapConstraint>& constraints_;
  const std::vector<std::size_t> members_;
  const std::size_t first_new_;
  const double gate_;
  ChainLegs chain_;
  std::vector<std::vector<std::size_t>> conflicts_;
  std::vector<int> live_;     // conflicts with members not dropped
  std::vector<double> own_;   // chain_chi2, -1 until computed
  std::vector<bool> dropped_;
  std::vector<std::size_t> losers_;
};

}  // namespace

int SubmapSlam2D::add_consistent(const std::vector<SubmapConstraint>& found) {
  if (found.empty()) return 0;
  // Each closure passed the graph's gate alone; two look-alike places can each pass it and
  // still contradict each other by metres (two closures of one submap pair that cannot both
  // hold). Every pair of closures, the new against the active and each other, must close its
  // cycle over the consecutive chain within dissolve_chi2 (the same 99.9% quantile of chi2(3)
  // the optimised graph dissolves at).
  const std::size_t first_new = constraints_.size();
  constraints_.insert(constraints_.end(), found.begin(), found.end());
  std::vector<std::size_t> members;  // the active closures, then the new ones
  for (std::size_t k = 0; k < constraints_.size(); ++k)
    if (constraints_[k].loop && constraints_[k].active) members.push_back(k);
  for (std::size_t k : ConsistencyVote(constraints_, members, first_new, options_.closures.dissolve_chi2).losers()) {
    constraints_[k].active = false;
    if (k < first_new) {
      ++counts_.closures_dissolved;
    } else {
      ++counts_.closures_rejected;
    }
  }
  // The new closures refused are not kept; an active one outvoted stays, dissolved.
  int kept = 0;
  std::vector<SubmapConstraint> rest(constraints_.begin(), constraints_.begin() + static_cast<std::ptrdiff_t>(first_new));
  for (std::size_t k = first_new; k < constraints_.size(); ++k)
    if (constraints_[k].active) rest.push_back(constraints_[k]), ++kept;
  constraints_ = std::move(rest);
  return kept;
}

}  // namespace probslam
