#include "probslam/ekf/multi_hypothesis_ekf_slam.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <queue>
#include <utility>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/chi_square.hpp"
#include "probslam/core/gaussian.hpp"
#include "probslam/core/range_bearing_model.hpp"

namespace probslam {
namespace {

constexpr long kClutter = -1;
constexpr long kNewLandmark = -2;

struct Option {
  double cost;
  long target;  // landmark id, kClutter or kNewLandmark
  bool operator<(const Option& o) const { return cost < o.cost; }
};

struct Assignment {
  double cost;
  std::vector<long> targets;
  bool operator<(const Assignment& o) const { return cost < o.cost; }  // max-heap on cost
};

// The `keep` cheapest assignments by summed individual costs, one landmark per measurement and
// vice versa: depth-first over the options sorted by cost, bounded by the cheapest completion.
class AssignmentSearch {
 public:
  AssignmentSearch(const std::vector<std::vector<Option>>& options, int keep) : options_(options), keep_(keep) {
    floor_.assign(options.size() + 1, 0.0);
    for (std::size_t i = options.size(); i-- > 0;) floor_[i] = floor_[i + 1] + options[i].front().cost;
    current_.reserve(options.size());
  }
  std::vector<Assignment> run() {
    visit(0, 0.0);
    std::vector<Assignment> out;
    while (!heap_.empty()) {
      out.push_back(heap_.top());
      heap_.pop();
    }
    std::reverse(out.begin(), out.end());
    return out;
  }

 private:
  void visit(std::size_t i, double cost) {
    if (static_cast<int>(heap_.size()) == keep_ && cost + floor_[i] >= heap_.top().cost) return;
    if (i == options_.size()) {
      heap_.push({cost, current_});
      if (static_cast<int>(heap_.size()) > keep_) heap_.pop();
      return;
    }
    for (const Option& o : options_[i]) {
      if (o.target >= 0 && std::find(current_.begin(), current_.end(), o.target) != current_.end()) continue;
      current_.push_back(o.target);
      visit(i + 1, cost + o.cost);
      current_.pop_back();
    }
  }
  const std::vector<std::vector<Option>>& options_;
  int keep_;
  std::vector<double> floor_;
  std::vector<long> current_;
  std::priority_queue<Assignment> heap_;
};

}  // namespace

void MultiHypothesisOptions::validate() const {
  const MultiHypothesisOptions& o = *this;
  require(o.max_hypotheses >= 1 && o.max_hypotheses <= kMhtMaxHypotheses, "max_hypotheses", "must be in [1, 1000]");
  require(o.max_children >= 1 && o.max_children <= kMhtMaxChildren, "max_children", "must be in [1, 100]");
  const auto cost = [](double v, const char* name, bool zero) {
    require(std::isfinite(v) && (v > 0.0 || (zero && v == 0.0)) && v <= kMhtMaxCost, name,
            zero ? "must be in (0, 1e6] (kMhtMaxCost), or 0 for the default" : "must be in (0, 1e6] (kMhtMaxCost)");
  };
  cost(o.gate, "gate", true);
  cost(o.new_landmark_cost, "new_landmark_cost", true);
  cost(o.clutter_cost, "clutter_cost", true);
  cost(o.prune_margin, "prune_margin", false);
  require(std::isfinite(o.detection_probability) && o.detection_probability >= 0.0 && o.detection_probability < 1.0,
          "detection_probability", "must be in [0, 1)");
  if (o.detection_probability > 0.0) {
    require(std::isfinite(o.sensor_range) && o.sensor_range > 0.0, "sensor_range", "must be finite and > 0");
    require(std::isfinite(o.sensor_fov) && o.sensor_fov > 0.0 && o.sensor_fov <= 2.0 * kPi, "sensor_fov",
            "must be in (0, 2 pi] rad");
  }
  require(std::isfinite(o.bearing_offset_sigma) && o.bearing_offset_sigma >= 0.0 && o.bearing_offset_sigma <= kPi,
          "bearing_offset_sigma", "must be in [0, pi] rad");
  require(std::isfinite(o.bearing_offset_correlation) && o.bearing_offset_correlation >= 0.0 &&
              o.bearing_offset_correlation < 1.0,
          "bearing_offset_correlation", "must be in [0, 1)");
}

MultiHypothesisOptions MultiHypothesisOptions::resolved(int dof) const {
  MultiHypothesisOptions o = *this;
  if (o.gate == 0.0) o.gate = chi_square_quantile(kDefaultGateProbability, dof);
  if (o.new_landmark_cost == 0.0) o.new_landmark_cost = chi_square_quantile(kDefaultNewLandmarkProbability, dof);
  if (o.clutter_cost == 0.0) o.clutter_cost = chi_square_quantile(kDefaultClutterProbability, dof);
  return o;
}

MultiHypothesisEkfSlam::MultiHypothesisEkfSlam(const EkfSlam& initial, const MultiHypothesisOptions& options)
    : options_((options.validate(), options.resolved(initial.landmark_dim()))) {
  // Costs are relative to one measurement's whole noise, the offset's share included, so that
  // moving noise from Q into the offset leaves the new-landmark and clutter costs' meaning.
  Eigen::MatrixXd q = initial.measurement_noise();
  q(1, 1) += options.bearing_offset_sigma * options.bearing_offset_sigma;
  log_det_q_ = log_det_2pi(Eigen::LLT<Eigen::MatrixXd>(q));
  long next_id = 0;
  for (const long id : initial.landmark_ids()) next_id = std::max(next_id, id + 1);
  beam_.push_back({initial, 0.0, next_id, nullptr, {}});
  if (has_offset()) {  // b's stationary distribution, independent of the start
    ScanOffset& b = beam_.front().offset;
    b.var = options.bearing_offset_sigma * options.bearing_offset_sigma;
    b.cov = Eigen::VectorXd::Zero(initial.state_dim());
  }
}

// Every filter's motion is planned (and checked) before any is applied.
void MultiHypothesisEkfSlam::predict(double v, double w, double dt) {
  const EkfSlam& f = best();
  predict(v, w, dt, f.control_noise_ ? Eigen::MatrixXd(f.m_control_) : Eigen::MatrixXd(f.r_pose_));
}

void MultiHypothesisEkfSlam::predict(double v, double w, double dt, const Eigen::MatrixXd& noise) {
  std::vector<EkfSlam::Motion> planned;
  planned.reserve(beam_.size());
  for (const Hypothesis& h : beam_) planned.push_back(h.filter.plan_predict(v, w, dt, noise));
  for (std::size_t i = 0; i < beam_.size(); ++i) {
    beam_[i].filter.apply(planned[i]);
    // Cov(pose, b) moves with the pose, as the landmarks' cross rows do (G P_rm).
    if (has_offset()) beam_[i].offset.cov.head<3>() = planned[i].g * beam_[i].offset.cov.head<3>();
  }
}

// The joint Gaussian of the filter's state u (heading theta + b) and the offset b is updated as
// one: b is not measured, so a measurement with Jacobian H, innovation nu and covariance S moves
// it by Cov(b, u) H^T S^-1 nu, and Cov(u, b) by -P H^T S^-1 H Cov(u, b) (the Kalman update of
// the augmented state, its b rows written out).
void MultiHypothesisEkfSlam::condition_offset(const EkfSlam& f, const Eigen::VectorXd& z, long id, ScanOffset& b) {
  const int index = f.index_of(id);
  Eigen::VectorXd nu, z_hat;
  Eigen::MatrixXd s, pht, hx, hm;
  if (!f.innovation_at(z, index, nu, s, pht)) return;  // a landmark on the robot: no update
  f.measurement_jacobian(f.pose(), f.landmark_at(index), z_hat, hx, hm);
  const Eigen::VectorXd hd = hx * b.cov.head<3>() + hm.leftCols(f.ld_) * b.cov.segment(index, f.ld_);
  const Eigen::VectorXd s_inv_hd = Eigen::LLT<Eigen::MatrixXd>(s).solve(hd);
  b.mean += s_inv_hd.dot(nu);
  b.var -= hd.dot(s_inv_hd);
  b.cov -= pht * s_inv_hd;
}

// Table 10.1 line 10's new rows, m = f(pose, z): Cov(m, b) = G_x Cov(pose, b).
void MultiHypothesisEkfSlam::extend_offset(const EkfSlam& f, const Eigen::VectorXd& z, ScanOffset& b) {
  Eigen::VectorXd m;
  Eigen::MatrixXd gx, gz;
  f.inverse_measurement(f.pose(), z, m, gx, gz);
  const Eigen::VectorXd rows = gx * b.cov.head<3>();
  b.cov.conservativeResize(b.cov.size() + rows.size());
  b.cov.tail(rows.size()) = rows;
}

// u = s + sign e_theta b: Cov(u, .) = Cov(s, .) + sign e_theta Cov(b, .), Var(u_theta) adds
// 2 sign Cov(theta, b) + Var(b), and Cov(u, b) = Cov(s, b) + sign e_theta Var(b).
void MultiHypothesisEkfSlam::shift_heading(EkfSlam& f, ScanOffset& b, double sign) {
  f.s_->mean[2] = wrap_angle(f.s_->mean[2] + sign * b.mean);
  auto p = f.covariance();
  p.col(2) += sign * b.cov;
  p.row(2) += sign * b.cov.transpose();
  p(2, 2) += b.var;
  b.cov[2] += sign * b.var;
}

void MultiHypothesisEkfSlam::branch(const Hypothesis& parent, const Eigen::Ref<const RowMatrixXd>& z,
                                    std::vector<Hypothesis>& out) const {
  const Eigen::Index k = z.rows();
  // Bearings depend on theta + b only: with an offset, the scan is taken by a filter whose
  // heading stands for theta + b (after b's AR(1) step), b's covariance with it tracked alongside
  // by every child, and the heading is moved back to theta afterwards.
  ScanOffset scan_offset = parent.offset;
  std::optional<EkfSlam> shifted;
  if (has_offset()) {
    const double rho = options_.bearing_offset_correlation, sigma = options_.bearing_offset_sigma;
    scan_offset.mean *= rho;
    scan_offset.cov *= rho;
    scan_offset.var = rho * rho * scan_offset.var + (1.0 - rho * rho) * sigma * sigma;
    shifted.emplace(parent.filter);
    shift_heading(*shifted, scan_offset, 1.0);
  }
  const EkfSlam& scan_filter = shifted ? *shifted : parent.filter;
  std::vector<std::vector<Option>> options(k);
  for (Eigen::Index i = 0; i < k; ++i) {
    const Eigen::VectorXd zi = z.row(i).transpose();
    options[i] = {{options_.new_landmark_cost, kNewLandmark}, {options_.clutter_cost, kClutter}};
    for (const long id : scan_filter.nearby_landmarks(zi)) {
      const EkfSlam::PairingLikelihood p = scan_filter.pairing_likelihood(zi, id);
      if (p.nis <= options_.gate) options[i].push_back({p.nis + p.log_det - log_det_q_, id});
    }
    std::sort(options[i].begin(), options[i].end());
  }
  // Landmarks the sensor should have seen from the pose before the scan, and what seeing or
  // missing one costs (no landmark is in view when P_D is 0: the costs are then unused).
  const double p_d = options_.detection_probability;
  std::vector<long> in_view;
  if (p_d > 0.0)
    for (const long id : parent.filter.landmark_ids())
      if (in_sensor_field(parent.filter.pose(), parent.filter.landmark(id).head<2>(), options_.sensor_range,
                          options_.sensor_fov))
        in_view.push_back(id);
  const double detect_cost = p_d > 0.0 ? -2.0 * std::log(p_d) : 0.0;
  const double miss_cost = -2.0 * std::log1p(-p_d);
  for (const Assignment& a : AssignmentSearch(options, options_.max_children).run()) {
    Hypothesis child{scan_filter, parent.cost, parent.next_id, nullptr, scan_offset};
    ScanOffset& offset = child.offset;
    for (const long id : in_view)
      child.cost += std::find(a.targets.begin(), a.targets.end(), id) != a.targets.end() ? detect_cost : miss_cost;
    auto node = std::make_shared<HistoryNode>();
    node->parent = parent.history;
    node->ids.assign(k, kClutter);
    for (Eigen::Index i = 0; i < k; ++i) {
      const long target = a.targets[i];
      if (target == kClutter) {
        child.cost += options_.clutter_cost;
        continue;
      }
      long id = target;
      const Eigen::VectorXd zi = z.row(i).transpose();
      if (target == kNewLandmark) {
        id = child.next_id++;
        child.cost += options_.new_landmark_cost;
        if (shifted) extend_offset(child.filter, zi, offset);
      } else {  // exact: the filter has taken this scan's earlier measurements
        const EkfSlam::PairingLikelihood p = child.filter.pairing_likelihood(zi, id);
        child.cost += p.nis + p.log_det - log_det_q_;
        if (shifted) condition_offset(child.filter, zi, id, offset);
      }
      child.filter.update(z.row(i), {id});
      node->ids[i] = id;
    }
    if (shifted) shift_heading(child.filter, offset, -1.0);
    child.history = std::move(node);
    out.push_back(std::move(child));
  }
}

std::vector<long> MultiHypothesisEkfSlam::update(const Eigen::Ref<const RowMatrixXd>& z) {
  best().check_measurements(z);
  if (z.rows() == 0) return {};
  double bytes = 0.0;  // the children's covariances, at most
  for (const Hypothesis& h : beam_) {
    const double dim = h.filter.state_dim() + static_cast<double>(z.rows()) * h.filter.landmark_dim();
    bytes += options_.max_children * dim * dim * sizeof(double);
  }
  require(bytes <= kMhtMaxBranchBytes, "z", "would make the children of this scan hold more than 4 GiB "
          "(kMhtMaxBranchBytes): lower max_hypotheses or max_children");
  std::vector<Hypothesis> children;
  for (const Hypothesis& h : beam_) branch(h, z, children);
  // Children of better parents first among equal costs (the sort is stable and the parents are in
  // beam order). Costs are compared on a grid of kMhtCostResolution: alternatives that differ from
  // their parent by the same decisions (say, one measurement a new landmark rather than clutter)
  // cost the same but for the last bits, which the order of the sums decides; compared exactly,
  // an old alternative could win such a tie against the best parent's fresh one by 1e-15.
  const auto bucket = [](double cost) { return std::floor(cost / kMhtCostResolution); };
  std::stable_sort(children.begin(), children.end(),
                   [&](const Hypothesis& a, const Hypothesis& b) { return bucket(a.cost) < bucket(b.cost); });
  const double best_cost = children.front().cost;
  for (const Hypothesis& c : children)
    require(std::isfinite(c.cost) && std::isfinite(offset_ + best_cost), "z", "gives a hypothesis a non-finite cost");
  std::vector<Hypothesis> kept;
  for (Hypothesis& c : children) {
    if (static_cast<int>(kept.size()) == options_.max_hypotheses || c.cost > best_cost + options_.prune_margin) break;
    c.cost -= best_cost;  // only differences matter; this keeps the numbers small
    kept.push_back(std::move(c));
  }
  beam_ = std::move(kept);
  offset_ += best_cost;
  return beam_.front().history->ids;
}

std::vector<double> MultiHypothesisEkfSlam::costs() const {
  std::vector<double> out;
  for (const Hypothesis& h : beam_) out.push_back(h.cost);
  return out;
}

std::vector<std::vector<long>> MultiHypothesisEkfSlam::history() const {
  std::vector<std::vector<long>> out;
  for (const HistoryNode* n = beam_.front().history.get(); n != nullptr; n = n->parent.get()) out.push_back(n->ids);
  std::reverse(out.begin(), out.end());
  return out;
}

}  // namespace probslam
