// FastSLAM with unknown correspondences: candidate pairs from the particle's map, the joint
// (or pair-by-pair) maximum-likelihood association, the scan's updates and negative
// information, and the filter's update_unknown.
#include "fast_slam_internal.hpp"

#include <unordered_set>
#include <utility>

#include "probslam/core/check.hpp"

namespace probslam {
using namespace fastslam_detail;

JointAssignment FastSlam::Context::joint_association(const Scan& s, std::vector<Pair>& pairs,
                                                     const Eigen::Vector3d& mu0, const Eigen::Matrix3d& p0,
                                                     bool proposal, double log_p_new_call) const {
  const Eigen::Index k = s.z.rows();
  // Measurement i's candidates, best first: pairs[first[i] .. first[i + 1]) after the sort.
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
    if (a.i != b.i) return a.i < b.i;
    return a.ll != b.ll ? a.ll > b.ll : a.id < b.id;
  });
  std::vector<std::size_t> first(static_cast<std::size_t>(k) + 1, 0);
  for (const Pair& pr : pairs) ++first[static_cast<std::size_t>(pr.i) + 1];
  for (std::size_t i = 0; i < static_cast<std::size_t>(k); ++i) first[i + 1] += first[i];
  struct Candidates {
    const Pair* b;
    const Pair* e;
    const Pair* begin() const { return b; }
    const Pair* end() const { return e; }
    bool empty() const { return b == e; }
    const Pair* front() const { return b; }
  };
  std::vector<Candidates> cands(static_cast<std::size_t>(k));
  for (std::size_t i = 0; i < cands.size(); ++i) cands[i] = {pairs.data() + first[i], pairs.data() + first[i + 1]};
  JointAssignment best;
  if (!proposal) {
    // The pose known, the terms are independent: when no two measurements' best candidates
    // coincide, each taking its best is the optimum (the common case, at no search).
    best.ids.assign(static_cast<std::size_t>(k), -1);
    std::unordered_set<long> firsts;
    bool distinct = true;
    for (Eigen::Index i = 0; i < k && distinct; ++i) {
      const auto& c = cands[static_cast<std::size_t>(i)];
      if (c.empty()) continue;
      distinct = firsts.insert(c.front()->id).second;
      best.ids[static_cast<std::size_t>(i)] = c.front()->id;
    }
    if (distinct) return best;
  }
  std::vector<Eigen::Index> order(static_cast<std::size_t>(k));
  for (Eigen::Index i = 0; i < k; ++i) order[static_cast<std::size_t>(i)] = i;
  const auto best_ll = [&](Eigen::Index i) {
    const auto& c = cands[static_cast<std::size_t>(i)];
    return c.empty() ? log_p_new_call : c.front()->ll;
  };
  std::stable_sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) { return best_ll(a) > best_ll(b); });
  const double sig_peak = s.signatures ? -0.5 * std::log(kTwoPi * q_sig) : 0.0;
  const double peak = std::max(log_p_new_call, -0.5 * std::log(kTwoPi * kTwoPi * q.determinant()) + sig_peak);
  // bound[d]: the most the measurements order[d..] can add.
  std::vector<double> bound(static_cast<std::size_t>(k) + 1, 0.0);
  for (Eigen::Index d = k - 1; d >= 0; --d) {
    const bool matchable = !cands[static_cast<std::size_t>(order[static_cast<std::size_t>(d)])].empty();
    bound[static_cast<std::size_t>(d)] = bound[static_cast<std::size_t>(d) + 1] + (matchable ? peak : log_p_new_call);
  }
  double best_score = -std::numeric_limits<double>::infinity();
  std::vector<long> current(static_cast<std::size_t>(k), -1);
  long nodes = 0;
  // score: the total so far; match: its matched part.
  const auto search = [&](const auto& self, std::size_t d, const Eigen::Vector3d& mu, const Eigen::Matrix3d& p,
                          double score, double match, bool any) -> void {
    if (++nodes > kJointAssociationMaxNodes && best_score > -std::numeric_limits<double>::infinity()) return;
    if (!(score + bound[d] > best_score)) return;
    if (d == static_cast<std::size_t>(k)) {
      best_score = score;
      best.ids = current;
      best.match_log_likelihood = match;
      best.any = any;
      best.mu = mu;
      best.p = p;
      return;
    }
    const Eigen::Index i = order[d];
    for (const Pair& cand : cands[static_cast<std::size_t>(i)]) {
      const Pair* c = &cand;
      if (std::find(current.begin(), current.end(), c->id) != current.end()) continue;
      Eigen::Vector3d mu_next = mu;
      Eigen::Matrix3d p_next = p;
      double step = c->ll;
      if (proposal) {
        if (!proposal_step(mu_next, p_next, *c->lm, s.rb(i), q, step)) continue;
        step += sig_log_likelihood(s, i, *c->lm);
        if (!std::isfinite(step)) continue;
      }
      current[static_cast<std::size_t>(i)] = c->id;
      self(self, d + 1, mu_next, p_next, score + step, match + step, true);
      current[static_cast<std::size_t>(i)] = -1;
    }
    self(self, d + 1, mu, p, score + log_p_new_call, match, any);
  };
  search(search, 0, mu0, p0, 0.0, 0.0, false);
  return best;
}

void FastSlam::Context::update_unknown(FastSlamParticle& part, const Scan& given, double log_p_new_call, long* ids_out,
                                       std::uint8_t* new_out, std::vector<long>& removed) const {
  RowMatrixXd storage;
  const Eigen::Ref<const RowMatrixXd> z = offset_corrected(part, given, storage);
  const Scan s{z, given.signatures};
  const Eigen::Index k = s.z.rows();
  const bool proposal = o.version == 2 && part.has_prior;
  Eigen::Vector3d mu = proposal ? part.prior_mean : part.pose;
  Eigen::Matrix3d p = proposal ? part.prior_cov : Eigen::Matrix3d::Zero();
  // Candidate pairs whose likelihood exceeds p_new, from the landmarks near where each
  // measurement places its landmark (version 2: the marginal likelihood at the prior mean),
  // found in one walk of the map for the whole scan (their order does not matter: the
  // association sorts them).
  std::vector<LandmarkMap::Disc> discs(static_cast<std::size_t>(k));
  for (Eigen::Index i = 0; i < k; ++i) {
    MeasurementJacobians<2> j;
    LandmarkMap::Disc& d = discs[static_cast<std::size_t>(i)];
    landmark_from_range_bearing_unchecked(mu, s.rb(i), d.center, j);
    const Eigen::Matrix2d spread =
        j.landmark * q * j.landmark.transpose() + j.pose * p * j.pose.transpose();
    d.radius = o.association_radius + kPlacementSigmas * std::sqrt(std::max(0.0, lambda_max(spread)));
  }
  std::vector<Pair> pairs;
  part.map.for_each_within_any(discs, [&](const Landmark& lm, std::size_t at) {
    const auto i = static_cast<Eigen::Index>(at);
    Predicted pr;
    if (!predict_measurement(mu, lm.mean, pr)) return;
    const Eigen::Matrix2d sm = symmetric<2>(pr.hm * lm.cov * pr.hm.transpose()) + q +
                               symmetric<2>(pr.hx * p * pr.hx.transpose());
    const double ll = log_gauss2(innovation(s.rb(i), pr.z_hat), sm) + sig_log_likelihood(s, i, lm);
    if (ll > log_p_new_call) pairs.push_back({ll, i, lm.id, &lm});
  });
  std::vector<long> assigned(static_cast<std::size_t>(k), -1);
  double ll = 0.0;
  std::vector<std::uint8_t> in_proposal(static_cast<std::size_t>(k), 0);
  if (o.joint_association) {
    const JointAssignment best = joint_association(s, pairs, mu, p, proposal, log_p_new_call);
    assigned = best.ids;
    if (proposal && best.any) {
      for (Eigen::Index i = 0; i < k; ++i) in_proposal[static_cast<std::size_t>(i)] = assigned[static_cast<std::size_t>(i)] >= 0;
      ll += best.match_log_likelihood;
      take_proposal_sample(part, best.mu, best.p);
    }
  } else {
    // Maximum likelihood, best pairs first, one measurement per landmark and scan.
    std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
      if (a.ll != b.ll) return a.ll > b.ll;
      if (a.i != b.i) return a.i < b.i;
      return a.id < b.id;
    });
    std::unordered_set<long> taken;
    for (const Pair& pr : pairs) {
      long& a = assigned[static_cast<std::size_t>(pr.i)];
      if (a < 0 && taken.insert(pr.id).second) a = pr.id;
    }
    if (proposal) {
      bool any = false;
      for (Eigen::Index i = 0; i < k; ++i) {
        if (assigned[static_cast<std::size_t>(i)] < 0) continue;
        const Landmark& lm = *part.map.find(assigned[static_cast<std::size_t>(i)]);
        double step = 0.0;
        if (!proposal_step(mu, p, lm, s.rb(i), q, step)) continue;
        ll += step + sig_log_likelihood(s, i, lm);
        in_proposal[static_cast<std::size_t>(i)] = 1;
        any = true;
      }
      if (any) take_proposal_sample(part, mu, p);
    }
  }
  std::unordered_set<long> seen;  // for negative information only
  const long scan = ++part.scans;
  for (Eigen::Index i = 0; i < k; ++i) {
    const long id = assigned[static_cast<std::size_t>(i)];
    bool created = id < 0;
    if (!created) {
      Landmark lm = *part.map.find(id);
      const double step = update_landmark(lm, part.pose, s, i);
      if (std::isnan(step)) {
        created = true;  // on the robot now: cannot be this landmark
      } else {
        if (!in_proposal[static_cast<std::size_t>(i)]) ll += step;
        lm.sightings = std::min(lm.sightings + 1, kFastSlamMaxCount);
        lm.last_seen = scan;
        part.map.put(lm);
        ids_out[i] = id;
        new_out[i] = 0;
        if (o.negative_information) seen.insert(id);
      }
    }
    if (created) {
      const long nid = part.next_id++;
      Landmark lm = new_landmark(nid, part.pose, s, i);
      lm.last_seen = scan;
      part.map.put(lm);
      if (o.min_sightings > 1) part.provisional.push_back(nid);
      ll += log_p_new_call;
      ids_out[i] = nid;
      new_out[i] = 1;
      if (o.negative_information) seen.insert(nid);
    }
  }
  if (o.negative_information) {
    // Landmarks in the perceptual field that this scan did not see lose existence.
    std::vector<Landmark> missed;
    const Eigen::Vector3d x = part.pose;
    part.map.for_each_within(x.head<2>(), o.sensor_range, [&](const Landmark& lm) {
      if (!seen.count(lm.id) && in_sensor_field(x, lm.mean, o.sensor_range, o.sensor_fov)) missed.push_back(lm);
    });
    for (Landmark& lm : missed) {
      lm.existence -= o.existence_miss;
      if (lm.existence < 0.0) {
        part.map.erase(lm.id);
        removed.push_back(lm.id);
      } else {
        part.map.put(lm);
      }
    }
  }
  expire_provisional(part, scan, removed);
  if (k > 0) end_motion(part);
  add_log_likelihood(part, ll);
}

FastSlamAssociation FastSlam::update_unknown(const Eigen::Ref<const RowMatrixXd>& z) {
  return update_unknown(z, o_.p_new);
}

FastSlamAssociation FastSlam::update_unknown(const Eigen::Ref<const RowMatrixXd>& z, double p_new) {
  check_measurements(z);
  require(std::isfinite(p_new) && p_new > 0.0 && std::isfinite(std::log(p_new)), "p_new", "must be finite and > 0");
  const Context c{o_, q2_, q_signature_, std::log(o_.p_new), std::log(o_.outlier_density)};
  const Scan s{z, o_.use_signatures};
  const int m = num_particles();
  const auto k = static_cast<std::size_t>(z.rows());
  FastSlamAssociation out;
  out.num_particles = m;
  out.num_measurements = static_cast<int>(k);
  out.ids.assign(static_cast<std::size_t>(m) * k, -1);
  out.is_new.assign(static_cast<std::size_t>(m) * k, 0);
  std::vector<std::vector<long>> removed(static_cast<std::size_t>(m));
  out.removed.resize(static_cast<std::size_t>(m));
  const double log_p_new = std::log(p_new);
  staged([&](int j, FastSlamParticle& p) {
    check_room(p, z.rows());
    const auto at = static_cast<std::size_t>(j) * k;
    c.update_unknown(p, s, log_p_new, out.ids.data() + at, out.is_new.data() + at, removed[static_cast<std::size_t>(j)]);
  });
  const std::vector<int> ancestors = commit();
  if (!ancestors.empty()) {  // rows follow the particles after resampling
    FastSlamAssociation moved = out;
    for (int j = 0; j < m; ++j) {
      const auto from = static_cast<std::size_t>(ancestors[static_cast<std::size_t>(j)]);
      std::copy_n(out.ids.begin() + static_cast<std::ptrdiff_t>(from * k), k,
                  moved.ids.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(j) * k));
      std::copy_n(out.is_new.begin() + static_cast<std::ptrdiff_t>(from * k), k,
                  moved.is_new.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(j) * k));
      moved.removed[static_cast<std::size_t>(j)] = removed[from];
    }
    return moved;
  }
  out.removed = std::move(removed);
  return out;
}

}  // namespace probslam
