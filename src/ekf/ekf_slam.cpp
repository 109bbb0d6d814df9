#include "probslam/ekf/ekf_slam.hpp"

#include "ekf_slam_internal.hpp"

#include <algorithm>
#include <string>

#include "probslam/core/angle.hpp"

namespace probslam {
using namespace ekf_detail;

namespace {

constexpr Eigen::Index kInitialLandmarkCapacity = 16;

}  // namespace

EkfSlam::EkfSlam(const Eigen::MatrixXd& motion_noise, const Eigen::MatrixXd& measurement_noise, bool use_signatures,
                 const Eigen::Vector3d& initial_pose, const Eigen::Matrix3d& initial_pose_cov) {
  md_ = use_signatures ? 3 : 2;
  require_motion_noise(motion_noise, "motion_noise", false);
  control_noise_ = motion_noise.rows() == 2;
  if (control_noise_) m_control_ = motion_noise;
  else r_pose_ = motion_noise;
  require(measurement_noise.rows() == md_ && measurement_noise.cols() == md_, "measurement_noise",
          use_signatures ? "must be 3x3 (range, bearing, signature)" : "must be 2x2 (range, bearing)");
  require_covariance(measurement_noise, "measurement_noise", false);
  require(!use_signatures || (measurement_noise(0, 2) == 0.0 && measurement_noise(1, 2) == 0.0), "measurement_noise",
          "must leave the signature uncorrelated with range and bearing (zero (0, 2) and (1, 2) entries): the "
          "filter keeps signatures apart from the dense state");
  Q_ = measurement_noise;
  require_on_map(initial_pose, "initial_pose", "must be finite with |x|, |y| <= 1e9 m (kMaxCoordinate)");
  require_covariance(initial_pose_cov, "initial_pose_cov", true);
  s_ = std::make_shared<EkfSlamStorage>();
  const Eigen::Index cap = 3 + kInitialLandmarkCapacity * ld_;
  s_->mean = Eigen::VectorXd::Zero(cap);
  s_->cov = Eigen::MatrixXd::Zero(cap, cap);
  s_->mean.head<3>() = initial_pose;
  s_->mean[2] = wrap_angle(initial_pose[2]);
  s_->cov.topLeftCorner<3, 3>() = 0.5 * (initial_pose_cov + initial_pose_cov.transpose());
}

int EkfSlam::index_of(long id) const {
  const auto it = index_.find(id);
  require(it != index_.end(), "id", ("is not a landmark of the map: " + std::to_string(id)).c_str());
  return it->second;
}

Eigen::VectorXd EkfSlam::landmark_at(Eigen::Index index) const {
  Eigen::VectorXd lm(md_);
  lm.head<2>() = s_->mean.segment<2>(index);
  if (md_ == 3) lm[2] = signature_[static_cast<std::size_t>((index - 3) / ld_)];
  return lm;
}

Eigen::VectorXd EkfSlam::landmark(long id) const { return landmark_at(index_of(id)); }

Eigen::MatrixXd EkfSlam::landmark_covariance(long id) const {
  const int at = index_of(id);
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(md_, md_);
  c.topLeftCorner<2, 2>() = s_->cov.block<2, 2>(at, at);
  if (md_ == 3) c(2, 2) = signature_var_[static_cast<std::size_t>((at - 3) / ld_)];
  return c;
}

double EkfSlam::existence(long id) const {
  return existence_[(index_of(id) - 3) / ld_];
}

namespace {
// The used part of a filter's storage, copied: no spare capacity (it grows again on demand).
std::shared_ptr<EkfSlamStorage> trimmed_copy(const EkfSlamStorage& s, Eigen::Index n) {
  auto c = std::make_shared<EkfSlamStorage>();
  c->mean = s.mean.head(n);
  c->cov = s.cov.topLeftCorner(n, n);
  return c;
}
}  // namespace

// Every member as the default copy would, but the storage: a new one (EkfSlamTest.CopiesAreDeep
// compares every observable field, so a member added later and forgotten here shows).
EkfSlam::EkfSlam(const EkfSlam& o)
    : r_pose_(o.r_pose_), m_control_(o.m_control_), control_noise_(o.control_noise_), Q_(o.Q_), md_(o.md_),
      s_(trimmed_copy(*o.s_, o.n_)), n_(o.n_), ids_(o.ids_), index_(o.index_), signature_(o.signature_),
      signature_var_(o.signature_var_), existence_(o.existence_),
      provisional_(o.provisional_), next_id_(o.next_id_), gate_distance_(o.gate_distance_), mm_(o.mm_) {}

EkfSlam& EkfSlam::operator=(const EkfSlam& o) {
  if (this != &o) *this = EkfSlam(o);
  return *this;
}

void EkfSlam::require_state_room(Eigen::Index added_landmarks) const {
  require(added_landmarks <= (kEkfMaxStateDimension - n_) / ld_, "z",
          "would grow the state beyond 16384 dimensions (kEkfMaxStateDimension)");
}

void EkfSlam::reserve(Eigen::Index dim) {
  if (dim <= s_->mean.size()) return;
  auto grown = std::make_shared<EkfSlamStorage>();
  const Eigen::Index cap = std::min<Eigen::Index>(std::max(dim, 2 * s_->mean.size()), kEkfMaxStateDimension);
  grown->mean = Eigen::VectorXd::Zero(cap);
  grown->cov = Eigen::MatrixXd::Zero(cap, cap);
  grown->mean.head(n_) = s_->mean.head(n_);
  grown->cov.topLeftCorner(n_, n_) = s_->cov.topLeftCorner(n_, n_);
  s_ = std::move(grown);  // old views keep the old storage alive
}

}  // namespace probslam
