// EkfSlam's and MultiHypothesisEkfSlam's state (docs/file_format.md).
#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "probslam/core/state_file.hpp"
#include "probslam/ekf/ekf_slam.hpp"
#include "probslam/ekf/multi_hypothesis_ekf_slam.hpp"

namespace probslam {
namespace {
// A saved signature variance's bound: the filter's own bound on a covariance entry
// (ekf_slam.cpp's kMaxCovarianceEntry), so that the next update's products stay finite.
constexpr double kMaxSignatureVariance = 1e150;
}  // namespace

void EkfSlam::write_state(StateWriter& w) const {
  w.boolean(control_noise_);
  w.matrix(r_pose_);
  w.matrix(m_control_);
  w.matrix(Q_);
  w.i32(md_);
  w.i32(n_);
  w.matrix(s_->mean.head(n_));
  w.matrix(s_->cov.topLeftCorner(n_, n_));
  w.longs(ids_);
  for (long id : ids_) w.i32(index_.at(id));
  w.doubles(existence_);
  w.doubles(signature_);
  w.doubles(signature_var_);
  w.count(provisional_.size());
  for (const Provisional& p : provisional_) {
    w.matrix(p.mean);
    w.matrix(p.cov);
    w.i32(p.seen);
    w.i32(p.age);
  }
  w.i64(next_id_);
  w.f64(gate_distance_);
  write_options(w, mm_);
}

EkfSlam EkfSlam::read_state(StateReader& r) {
  const bool control = r.boolean();
  const Eigen::Matrix3d r_pose = r.matrix<Eigen::Matrix3d>();
  const Eigen::Matrix2d m_control = r.matrix<Eigen::Matrix2d>();
  const Eigen::MatrixXd q = r.matrix<Eigen::MatrixXd>();
  const int md = r.int_in(2, 3, "the measurement dimension");
  const int n = r.int_in(3, kEkfMaxStateDimension, "the state dimension");
  constexpr int ld = EkfSlam::ld_;
  if (q.rows() != md || (n - 3) % ld != 0) r.fail("the filter's dimensions do not agree");
  const Eigen::VectorXd mean = r.matrix<Eigen::VectorXd>();
  if (mean.size() != n) r.fail("the mean is not as long as the state");
  r.require_bytes(8.0 * n * n, "the covariance");
  const Eigen::MatrixXd cov = r.matrix<Eigen::MatrixXd>();
  if (cov.rows() != n || cov.cols() != n) r.fail("the covariance is not state x state");
  if (!mean.allFinite() || !cov.allFinite()) r.fail("the mean or covariance is not finite");
  // The constructor checks the noise and the pose; everything else is then the saved state.
  EkfSlam f = validated(r, "filter", [&] {
    const Eigen::MatrixXd motion = control ? Eigen::MatrixXd(m_control) : Eigen::MatrixXd(r_pose);
    return EkfSlam(motion, q, md == 3, mean.head<3>(), Eigen::Matrix3d::Zero());
  });
  f.r_pose_ = r_pose;
  f.m_control_ = m_control;
  f.s_ = std::make_shared<EkfSlamStorage>();
  f.s_->mean = mean;
  f.s_->cov = cov;
  f.n_ = n;
  f.ids_ = r.longs();
  if (static_cast<long>(f.ids_.size()) * ld + 3 != n) r.fail("the landmark ids do not match the state dimension");
  std::unordered_set<int> slots;
  for (long id : f.ids_) {
    const int index = r.i32();
    if (index < 3 || index > n - ld || (index - 3) % ld != 0 || !slots.insert(index).second)
      r.fail("landmark " + std::to_string(id) + "'s state index is out of range or repeated");
    if (!f.index_.emplace(id, index).second) r.fail("landmark id " + std::to_string(id) + " is repeated");
  }
  f.existence_ = r.doubles();
  if (f.existence_.size() != f.ids_.size()) r.fail("the existence log-odds are not one per landmark");
  f.signature_ = r.doubles();
  f.signature_var_ = r.doubles();
  const std::size_t signatures = md == 3 ? f.ids_.size() : 0;
  if (f.signature_.size() != signatures || f.signature_var_.size() != signatures)
    r.fail("the signatures are not one per landmark (with signatures) or absent (without)");
  for (std::size_t j = 0; j < signatures; ++j)
    if (!std::isfinite(f.signature_[j]) || !(f.signature_var_[j] >= 0.0 && f.signature_var_[j] <= kMaxSignatureVariance))
      r.fail("a signature is not finite or its variance not in [0, 1e150]");
  const std::size_t np = r.count(2 * 16 + 8);
  for (std::size_t k = 0; k < np; ++k) {
    Provisional p;
    p.mean = r.matrix<Eigen::VectorXd>();
    p.cov = r.matrix<Eigen::MatrixXd>();
    p.seen = r.i32();
    p.age = r.i32();
    if (p.mean.size() != md || p.cov.rows() != md || p.cov.cols() != md || !p.mean.allFinite() || !p.cov.allFinite())
      r.fail("a provisional landmark is not a finite landmark-sized Gaussian");
    f.provisional_.push_back(std::move(p));
  }
  f.next_id_ = static_cast<long>(r.i64());
  const double gate = r.f64();
  MapManagement mm;
  read_options(r, mm);
  validated(r, "map management", [&] {
    f.set_gate_distance(gate);
    f.set_map_management(mm);
  });
  return f;
}

void EkfSlam::save(const std::string& path) const { save_state(*this, path); }
EkfSlam EkfSlam::load(const std::string& path) { return load_state<EkfSlam>(path); }

// ---- the beam of filters ----

void MultiHypothesisEkfSlam::write_state(StateWriter& w) const {
  write_options(w, options_);
  w.f64(log_det_q_);
  w.f64(offset_);
  // History nodes, each once, parents before children: node k's parent is -1 or an index < k.
  std::unordered_map<const HistoryNode*, long> index;
  std::vector<const HistoryNode*> order;
  for (const Hypothesis& h : beam_) {
    std::vector<const HistoryNode*> chain;
    for (const HistoryNode* n = h.history.get(); n && !index.count(n); n = n->parent.get()) chain.push_back(n);
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
      index.emplace(*it, static_cast<long>(order.size()));
      order.push_back(*it);
    }
  }
  w.count(order.size());
  for (const HistoryNode* n : order) {
    w.i64(n->parent ? index.at(n->parent.get()) : -1);
    w.longs(n->ids);
  }
  w.count(beam_.size());
  for (const Hypothesis& h : beam_) {
    h.filter.write_state(w);
    w.f64(h.cost);
    w.i64(h.next_id);
    w.i64(h.history ? index.at(h.history.get()) : -1);
    w.f64(h.offset.mean);
    w.f64(h.offset.var);
    w.matrix(h.offset.cov);
  }
}

MultiHypothesisEkfSlam MultiHypothesisEkfSlam::read_state(StateReader& r) {
  MultiHypothesisOptions options;
  read_options(r, options);
  const double log_det_q = r.f64(), offset = r.f64();
  if (!std::isfinite(log_det_q) || !std::isfinite(offset)) r.fail("a cost is not finite");
  const std::size_t nn = r.count(16);
  std::vector<std::shared_ptr<const HistoryNode>> nodes;
  nodes.reserve(nn);
  for (std::size_t k = 0; k < nn; ++k) {
    const std::int64_t parent = r.i64();
    if (parent < -1 || parent >= static_cast<std::int64_t>(k)) r.fail("a history node's parent is out of order");
    auto node = std::make_shared<HistoryNode>();
    if (parent >= 0) node->parent = nodes[static_cast<std::size_t>(parent)];
    node->ids = r.longs();
    nodes.push_back(std::move(node));
  }
  const std::size_t nh = r.count(64);
  if (nh == 0) r.fail("the beam is empty");
  std::vector<Hypothesis> beam;
  for (std::size_t k = 0; k < nh; ++k) {
    EkfSlam filter = EkfSlam::read_state(r);
    const double cost = r.f64();
    const long next_id = static_cast<long>(r.i64());
    const std::int64_t history = r.i64();
    if (history < -1 || history >= static_cast<std::int64_t>(nn)) r.fail("a filter's history is out of range");
    ScanOffset b;
    b.mean = r.f64();
    b.var = r.f64();
    b.cov = r.matrix<Eigen::VectorXd>();
    if (!std::isfinite(cost) || !std::isfinite(b.mean) || !std::isfinite(b.var) || !b.cov.allFinite())
      r.fail("a filter's cost or bearing offset is not finite");
    if (!beam.empty() && filter.landmark_dim() != beam.front().filter.landmark_dim())
      r.fail("the beam's filters differ in their landmark dimension");
    beam.push_back({std::move(filter), cost, next_id,
                    history >= 0 ? nodes[static_cast<std::size_t>(history)] : nullptr, std::move(b)});
  }
  // The constructor checks the options; the saved beam replaces its single filter.
  MultiHypothesisEkfSlam mht = validated(r, "options", [&] { return MultiHypothesisEkfSlam(beam.front().filter, options); });
  if (mht.has_offset())
    for (const Hypothesis& h : beam)
      if (h.offset.cov.size() != h.filter.state_dim()) r.fail("a bearing offset's covariance does not match its filter");
  mht.beam_ = std::move(beam);
  mht.log_det_q_ = log_det_q;
  mht.offset_ = offset;
  return mht;
}

void MultiHypothesisEkfSlam::save(const std::string& path) const { save_state(*this, path); }
MultiHypothesisEkfSlam MultiHypothesisEkfSlam::load(const std::string& path) {
  return load_state<MultiHypothesisEkfSlam>(path);
}

}  // namespace probslam
