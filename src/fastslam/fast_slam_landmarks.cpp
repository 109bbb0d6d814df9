// FastSLAM's landmark side: the landmark EKF update, new landmarks (Table 13.1), the bearing
// offset's correction of a scan, the update with known correspondences and provisional
// landmarks' expiry.
#include "fast_slam_internal.hpp"

#include <unordered_set>

#include "probslam/core/check.hpp"

namespace probslam {
using namespace fastslam_detail;

double FastSlam::Context::update_landmark(Landmark& lm, const Eigen::Vector3d& x, const Scan& s,
                                          Eigen::Index i) const {
  Predicted pr;
  if (!predict_measurement(x, lm.mean, pr)) return std::numeric_limits<double>::quiet_NaN();
  const Eigen::Vector2d nu = innovation(s.rb(i), pr.z_hat);
  const Eigen::Matrix2d qj = symmetric<2>(pr.hm * lm.cov * pr.hm.transpose()) + q;
  const Eigen::Matrix2d k = lm.cov * pr.hm.transpose() * qj.inverse();
  double ll = log_gauss2(nu, qj) + sig_log_likelihood(s, i, lm);
  lm.mean += k * nu;
  lm.cov = symmetric<2>(lm.cov - k * qj * k.transpose());
  if (s.signatures) {
    const double gain = lm.signature_var / (lm.signature_var + q_sig);
    lm.signature += gain * (s.sig(i) - lm.signature);
    lm.signature_var = (1.0 - gain) * lm.signature_var;
  }
  lm.existence += o.existence_hit;
  require(lm.mean.allFinite() && lm.cov.allFinite() && std::isfinite(ll) &&
              lm.mean.cwiseAbs().maxCoeff() <= 4.0 * kMaxCoordinate,
          "z", "cannot be applied: the landmark update would not be finite");
  return ll;
}

Landmark FastSlam::Context::new_landmark(long id, const Eigen::Vector3d& x, const Scan& s, Eigen::Index i) const {
  Landmark lm;
  lm.id = id;
  MeasurementJacobians<2> j;
  landmark_from_range_bearing_unchecked(x, s.rb(i), lm.mean, j);
  const Eigen::Matrix2d& gz = j.landmark;  // = H^-1
  lm.cov = symmetric<2>(gz * q * gz.transpose());
  lm.existence = o.existence_hit;
  if (s.signatures) {
    lm.signature = s.sig(i);
    lm.signature_var = q_sig;
  }
  require(lm.cov.allFinite(), "z", "places a landmark whose covariance is not finite");
  return lm;
}

Eigen::Ref<const RowMatrixXd> FastSlam::Context::offset_corrected(FastSlamParticle& part, const Scan& s,
                                                                  RowMatrixXd& storage) const {
  if (o.bearing_offset_sigma == 0.0 || s.z.rows() == 0) return s.z;
  const double rho = o.bearing_offset_correlation;
  part.bearing_offset = rho * part.bearing_offset + std::sqrt(1.0 - rho * rho) * o.bearing_offset_sigma * part.rng.normal();
  storage = s.z;
  for (Eigen::Index i = 0; i < storage.rows(); ++i) storage(i, 1) = wrap_angle(storage(i, 1) - part.bearing_offset);
  return storage;
}

void FastSlam::Context::update_known(FastSlamParticle& part, const Scan& given,
                                     const std::vector<long>& ids) const {
  RowMatrixXd storage;
  const Eigen::Ref<const RowMatrixXd> z = offset_corrected(part, given, storage);
  const Scan s{z, given.signatures};
  const Eigen::Index k = s.z.rows();
  if (k == 0) {
    part.last_log_likelihood = 0.0;
    return;
  }
  double ll = 0.0;
  // Per measurement: 1 when it entered the proposal (weighted there), 2 when the outlier
  // density claimed it (weighted, its landmark left as it was).
  std::vector<std::uint8_t> handled(static_cast<std::size_t>(k), 0);
  constexpr std::uint8_t kInProposal = 1, kOutlier = 2;
  if (o.version == 2 && part.has_prior) {
    // The proposal, measurement by measurement: each step's posterior is the next one's prior.
    Eigen::Vector3d mu = part.prior_mean;
    Eigen::Matrix3d p = part.prior_cov;
    std::unordered_set<long> used;
    bool any = false;
    for (Eigen::Index i = 0; i < k; ++i) {
      const Landmark* lm = part.map.find(ids[static_cast<std::size_t>(i)]);
      if (!lm || !used.insert(lm->id).second) continue;
      Eigen::Vector3d mu_next = mu;
      Eigen::Matrix3d p_next = p;
      double step = 0.0;
      if (!proposal_step(mu_next, p_next, *lm, s.rb(i), q, step)) continue;
      step += sig_log_likelihood(s, i, *lm);
      ll += with_outliers(step);
      // An outlier under the marginal likelihood must not pull the proposal either.
      if (is_outlier(step)) {
        handled[static_cast<std::size_t>(i)] = kOutlier;
        continue;
      }
      mu = mu_next;
      p = p_next;
      handled[static_cast<std::size_t>(i)] = kInProposal;
      any = true;
    }
    if (any) take_proposal_sample(part, mu, p);
  }
  for (Eigen::Index i = 0; i < k; ++i) {
    const long id = ids[static_cast<std::size_t>(i)];
    const std::uint8_t how = handled[static_cast<std::size_t>(i)];
    if (how == kOutlier) continue;
    if (const Landmark* found = part.map.find(id)) {
      Landmark lm = *found;
      const double step = update_landmark(lm, part.pose, s, i);
      if (std::isnan(step)) continue;  // on the robot: no bearing, skipped
      if (how != kInProposal) {
        ll += with_outliers(step);
        if (is_outlier(step)) continue;  // lm is a copy: the map keeps the landmark as it was
      }
      part.map.put(lm);
    } else {
      part.map.put(new_landmark(id, part.pose, s, i));
      ll += log_p_new;
    }
  }
  end_motion(part);
  add_log_likelihood(part, ll);
}

void FastSlam::Context::expire_provisional(FastSlamParticle& part, long scan, std::vector<long>& removed) const {
  std::size_t kept = 0;
  for (const long id : part.provisional) {
    const Landmark* lm = part.map.find(id);
    if (lm == nullptr || lm->sightings >= o.min_sightings) continue;  // gone, or confirmed
    if (scan - lm->last_seen > o.provisional_max_age) {
      part.map.erase(id);
      removed.push_back(id);
      continue;
    }
    part.provisional[kept++] = id;
  }
  part.provisional.resize(kept);
}

void FastSlam::check_measurements(const Eigen::Ref<const RowMatrixXd>& z) const {
  require_measurement_rows(z, landmark_dim());
}

void FastSlam::check_room(const FastSlamParticle& p, Eigen::Index added) {
  require(static_cast<long>(p.map.size()) + added <= kFastSlamMaxLandmarks, "z",
          "would grow a map beyond 2^26 landmarks (kFastSlamMaxLandmarks)");
  require(p.next_id <= kMaxLandmarkId - added, "z", "would need landmark ids beyond 2^62");
}

bool FastSlam::update(const Eigen::Ref<const RowMatrixXd>& z, const std::vector<long>& ids) {
  check_measurements(z);
  require(static_cast<Eigen::Index>(ids.size()) == z.rows(), "ids", "must have one id per measurement");
  for (long id : ids) require(id >= 0 && id <= kMaxLandmarkId, "ids", "must be in [0, 2^62]");
  const Context c{o_, q2_, q_signature_, std::log(o_.p_new), std::log(o_.outlier_density)};
  const Scan s{z, o_.use_signatures};
  staged([&](int, FastSlamParticle& p) {
    check_room(p, z.rows());  // in the workers: the caller reads no particle
    c.update_known(p, s, ids);
  });
  commit();
  return last_resampled_;
}

}  // namespace probslam
