#include "probslam/ekf/joint_compatibility.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "probslam/core/check.hpp"

namespace probslam {
namespace {

class Search {
 public:
  Search(int k, const std::vector<Pairing>& pairings, const Eigen::Ref<const Eigen::MatrixXd>& p,
         const std::vector<double>& gates)
      : k_(k), pairings_(pairings), p_(p), gates_(gates), by_measurement_(k) {
    // Candidates of each measurement, most plausible first: good hypotheses found early bound
    // the search sooner.
    std::vector<double> own(pairings.size());
    for (std::size_t q = 0; q < pairings.size(); ++q) {
      const Eigen::MatrixXd s = block(q, q);
      own[q] = pairings[q].innovation.dot(s.llt().solve(pairings[q].innovation));
      by_measurement_[pairings[q].measurement].push_back(static_cast<int>(q));
    }
    for (auto& list : by_measurement_)
      std::sort(list.begin(), list.end(), [&](int a, int b) { return own[a] < own[b]; });
    best_.target.assign(k, -1);
    current_.assign(k, -1);
  }

  JointAssociation run() {
    descend(0, Eigen::MatrixXd(0, 0), Eigen::VectorXd(0), 0.0);
    best_.complete = nodes_ <= kJcbbMaxNodes;
    return best_;
  }

 private:
  // Innovation covariance block between pairings a and b: H_a P H_b^T (+ noise when a == b).
  Eigen::MatrixXd block(std::size_t a, std::size_t b) const {
    const Pairing& pa = pairings_[a];
    const Pairing& pb = pairings_[b];
    Eigen::MatrixXd sub(pa.columns.size(), pb.columns.size());
    for (std::size_t r = 0; r < pa.columns.size(); ++r)
      for (std::size_t c = 0; c < pb.columns.size(); ++c) sub(r, c) = p_(pa.columns[r], pb.columns[c]);
    Eigen::MatrixXd s = pa.jacobian * sub * pb.jacobian.transpose();
    if (a == b) s += pa.noise;
    return s;
  }

  bool taken(int target) const { return std::find(chosen_targets_.begin(), chosen_targets_.end(), target) != chosen_targets_.end(); }

  // s, nu: joint innovation covariance and innovation of the pairings chosen so far.
  void descend(int i, const Eigen::MatrixXd& s, const Eigen::VectorXd& nu, double nis) {
    const int paired = static_cast<int>(chosen_.size());
    if (i == k_) {
      if (paired > best_.pairings || (paired == best_.pairings && nis < best_.nis)) {
        best_.target = current_;
        best_.pairings = paired;
        best_.nis = nis;
      }
      return;
    }
    const int remaining = k_ - i - 1;
    for (int q : by_measurement_[i]) {
      const Pairing& pq = pairings_[q];
      if (taken(pq.target)) continue;
      // The most this branch can still reach: prune when it cannot beat the best, knowing that
      // the joint NIS never decreases as pairings are added.
      if (paired + 1 + remaining < best_.pairings) break;
      if (nodes_++ >= kJcbbMaxNodes) return;  // budget spent: keep the best found so far
      const Eigen::Index m = pq.innovation.size(), n = s.rows();
      Eigen::MatrixXd grown(n + m, n + m);
      grown.topLeftCorner(n, n) = s;
      for (int c = 0; c < paired; ++c) {
        const Eigen::MatrixXd cross = block(q, chosen_[c]);
        const Eigen::Index at = offsets_[c];
        grown.block(n, at, m, cross.cols()) = cross;
        grown.block(at, n, cross.cols(), m) = cross.transpose();
      }
      grown.bottomRightCorner(m, m) = block(q, q);
      Eigen::VectorXd nu_grown(n + m);
      nu_grown << nu, pq.innovation;
      const Eigen::LLT<Eigen::MatrixXd> llt(grown);
      if (llt.info() != Eigen::Success) continue;
      const double nis_grown = llt.matrixL().solve(nu_grown).squaredNorm();
      if (!(nis_grown <= gates_[paired + 1])) continue;
      if (paired + 1 + remaining == best_.pairings && nis_grown >= best_.nis) continue;
      chosen_.push_back(q);
      chosen_targets_.push_back(pq.target);
      offsets_.push_back(n);
      current_[i] = pq.target;
      descend(i + 1, grown, nu_grown, nis_grown);
      current_[i] = -1;
      chosen_.pop_back();
      chosen_targets_.pop_back();
      offsets_.pop_back();
    }
    // Measurement i unpaired (a new landmark, clutter, or ambiguous).
    if (nodes_ >= kJcbbMaxNodes) return;
    if (paired + remaining > best_.pairings || (paired + remaining == best_.pairings && nis < best_.nis))
      descend(i + 1, s, nu, nis);
  }

  int k_;
  const std::vector<Pairing>& pairings_;
  const Eigen::Ref<const Eigen::MatrixXd>& p_;
  const std::vector<double>& gates_;
  std::vector<std::vector<int>> by_measurement_;
  std::vector<int> chosen_, chosen_targets_, current_;
  std::vector<Eigen::Index> offsets_;
  JointAssociation best_;
  long nodes_ = 0;
};

}  // namespace

JointAssociation joint_compatibility(int num_measurements, const std::vector<Pairing>& pairings,
                                     const Eigen::Ref<const Eigen::MatrixXd>& covariance,
                                     const std::vector<double>& gates) {
  require(num_measurements >= 0, "num_measurements", "must be >= 0");
  require(covariance.rows() == covariance.cols(), "covariance", "must be square");
  require(static_cast<int>(gates.size()) >= num_measurements + 1, "gates", "needs num_measurements + 1 entries");
  for (const double g : gates) require(!std::isnan(g), "gates", "must not be NaN");
  for (const Pairing& p : pairings) {
    require(p.measurement >= 0 && p.measurement < num_measurements, "pairings", "measurement index out of range");
    const Eigen::Index m = p.innovation.size();
    require(m > 0 && p.innovation.allFinite(), "pairings", "innovation must be non-empty and finite");
    require(p.jacobian.rows() == m && p.jacobian.cols() == static_cast<Eigen::Index>(p.columns.size()), "pairings",
            "jacobian must be (innovation size) x (number of columns)");
    require(p.noise.rows() == m && p.noise.cols() == m, "pairings", "noise must be square of the innovation size");
    for (const int c : p.columns)
      require(c >= 0 && c < covariance.rows(), "pairings", "column outside the covariance");
  }
  return Search(num_measurements, pairings, covariance, gates).run();
}

}  // namespace probslam
