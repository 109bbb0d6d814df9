#pragma once
// EKF SLAM (ch. 10) with point landmarks: Table 10.1 (known correspondences) and Table 10.2
// (maximum-likelihood correspondences), with the map management of ch. 10.3.3.
#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <tuple>
#include <unordered_map>
#include <vector>

#include "probslam/core/filter_limits.hpp"
#include "probslam/core/object_mutex.hpp"
#include "probslam/core/options_description.hpp"
#include "probslam/core/types.hpp"

namespace probslam {

class StateWriter;
class StateReader;

// Reliability limits beside the shared ones of core/filter_limits.hpp (kMaxCoordinate,
// kMaxVariance, kMaxLandmarkId), refused by name beyond them.
/// State dimension (3 + 2 x landmarks): a dense covariance of 2 GiB, whose O(n^2)
/// update takes about a second. Larger maps need a sparse method (graph SLAM).
inline constexpr int kEkfMaxStateDimension = 16384;
/// Existence log-odds increments and threshold: far beyond any probability a double can hold.
inline constexpr double kEkfMaxLogOdds = 1e6;
/// Sighting and age counts of the provisional list.
inline constexpr int kEkfMaxCount = 1000000;

/// Mean and covariance storage with spare capacity. Views into it stay valid (if stale) after
/// the state grows beyond the capacity, because growing moves to a new storage object.
struct EkfSlamStorage {
  Eigen::VectorXd mean;  // capacity
  Eigen::MatrixXd cov;   // capacity x capacity, column-major; the top-left dim x dim is in use
};

/// Ch. 10.3.3 map management for update_unknown; every part is off by default.
struct MapManagement {
  bool provisional = false;          // new landmarks first wait on a provisional list
  int min_observations = 3;          // sightings before a provisional landmark joins the map
  double provisional_max_std = 0.5;  // m: ... and its largest position std-dev is below this
  int provisional_max_age = 20;      // scans without a sighting before it is forgotten
  bool existence = false;            // landmark existence log-odds o_j
  double existence_hit = 1.0;        // added to o_j when landmark j is observed
  double existence_miss = 0.5;       // subtracted when j is in the perceptual field, unobserved
  double existence_threshold = -1.0; // landmarks with o_j below this are removed
  double sensor_range = std::numeric_limits<double>::infinity();  // m, perceptual field
  double sensor_fov = 6.283185307179586;                           // rad, full opening angle

  /// std::invalid_argument naming the first field out of its range.
  void validate() const;

  /// The fields in the order the state files hold them (core/options_description.hpp).
  template <class V>
  static void describe(V& v) {
    using O = MapManagement;
    v("provisional", &O::provisional, "", "new landmarks first wait on a provisional list");
    v("min_observations", &O::min_observations, "", "sightings before a provisional landmark joins the map, in [1, 1e6]");
    v("provisional_max_std", &O::provisional_max_std, "m", "... and its largest position standard deviation must be below this");
    v("provisional_max_age", &O::provisional_max_age, "", "scans without a sighting before a provisional landmark is forgotten, in [0, 1e6]");
    v("existence", &O::existence, "", "keep a per-landmark existence log-odds o_j");
    v("existence_hit", &O::existence_hit, "", "added to o_j when landmark j is seen");
    v("existence_miss", &O::existence_miss, "", "subtracted from o_j when j is in the sensor's field but not seen");
    v("existence_threshold", &O::existence_threshold, "", "landmarks with o_j below this are removed");
    v("sensor_range", &O::sensor_range, "m", "range of the sensor's field");
    v("sensor_fov", &O::sensor_fov, "rad", "full opening angle of the sensor's field");
  }
};

/// What update() did with each measurement.
struct UpdateReport {
  Eigen::VectorXd nis;             // normalised innovation squared; NaN for first sightings
  std::vector<std::uint8_t> used;  // 0 where the gate rejected the measurement
};

/// How update_unknown() pairs a scan's measurements with landmarks.
enum class Association : std::uint8_t {
  kMaximumLikelihood,   // Table 10.2: the best pairs first, one measurement at a time
  kJointCompatibility,  // JCBB over the scan (joint_compatibility.hpp)
};

/// What update_unknown() did with each measurement.
struct AssociationReport {
  enum Outcome : std::uint8_t { kAssociated = 0, kNewLandmark = 1, kProvisional = 2, kDiscarded = 3 };
  std::vector<long> ids;               // landmark id used or created; -1 if none
  Eigen::VectorXd mahalanobis;         // smallest pi_k over the candidates (inf if none)
  std::vector<std::uint8_t> outcome;   // Outcome per measurement
  std::vector<long> removed;           // landmarks dropped by the existence test
};

/// Every method validates all its input before changing anything (std::invalid_argument whose
/// message starts with the argument's name) and leaves the filter unchanged when it throws; a
/// call whose result would not be finite throws too. The filter does not lock itself: see mutex().
///
/// The dense state holds the pose and the landmarks' positions (3 + 2 per landmark). A landmark's
/// signature is kept apart, as its own mean and variance (a scalar Kalman filter): it is measured
/// directly (H's signature row has no other entry), starts uncorrelated with everything (the
/// measurement noise's signature is uncorrelated with range and bearing, which the constructor
/// requires), and so stays uncorrelated: in the full state its cross covariances would be zero to
/// the bit. Apart, the O(n^2) covariance update passes over (2/3)^2 of the full state's matrix.
class EkfSlam {
 public:
  /// Lock it around every call when several threads share this object (core/object_mutex.hpp).
  std::mutex& mutex() const noexcept { return mutex_.get(); }

  /// motion_noise: 3x3 pose-space R_t, or 2x2 control-space M (R_t = V M V^T) for (v, w).
  /// measurement_noise: Q_t, variances of (range, bearing[, signature]): 3x3 with signatures,
  /// the signature uncorrelated with range and bearing (Q(0, 2) = Q(1, 2) = 0).
  /// All must be symmetric positive definite (initial_pose_cov positive semi-definite).
  EkfSlam(const Eigen::MatrixXd& motion_noise, const Eigen::MatrixXd& measurement_noise, bool use_signatures,
          const Eigen::Vector3d& initial_pose, const Eigen::Matrix3d& initial_pose_cov);

  /// Dimension of the dense state: 3 + 2 per landmark (signatures are kept apart).
  int state_dim() const { return n_; }
  /// Values per landmark: 2 (x, y), or 3 with the signature.
  int landmark_dim() const { return md_; }
  int num_landmarks() const { return static_cast<int>(ids_.size()); }
  bool use_signatures() const { return md_ == 3; }
  /// Each landmark's signature mean and variance, in state order (empty without signatures).
  const std::vector<double>& signatures() const { return signature_; }
  const std::vector<double>& signature_variances() const { return signature_var_; }
  Eigen::VectorBlock<Eigen::VectorXd> mean() { return s_->mean.head(n_); }
  Eigen::Block<Eigen::MatrixXd> covariance() { return s_->cov.topLeftCorner(n_, n_); }
  Eigen::Vector3d pose() const { return s_->mean.head<3>(); }
  const std::vector<long>& landmark_ids() const { return ids_; }
  bool has_landmark(long id) const { return index_.count(id) != 0; }
  /// (x, y[, signature]) of landmark `id`.
  Eigen::VectorXd landmark(long id) const;
  /// Its landmark_dim() x landmark_dim() covariance (a signature's cross terms are zero).
  Eigen::MatrixXd landmark_covariance(long id) const;
  double existence(long id) const;
  std::shared_ptr<EkfSlamStorage> storage() const { return s_; }
  /// Copies are deep: a copy has its own storage (the views handed out before keep the
  /// original's), so two filters never alias one mean and covariance.
  EkfSlam(const EkfSlam& other);
  EkfSlam& operator=(const EkfSlam& other);
  EkfSlam(EkfSlam&&) noexcept = default;
  EkfSlam& operator=(EkfSlam&&) noexcept = default;
  Eigen::Index capacity() const { return s_->mean.size(); }
  const Eigen::MatrixXd& measurement_noise() const { return Q_; }

  /// Table 10.1 lines 2-5: velocity motion model for dt seconds. O(N).
  void predict(double v, double w, double dt);
  /// The same with this call's noise: 3x3 pose-space R_t or 2x2 control-space M.
  void predict(double v, double w, double dt, const Eigen::MatrixXd& noise);
  /// Odometry given as a relative pose: x <- x (+) delta, delta ~ N(., noise) in the robot frame.
  void predict_odometry(const Eigen::Vector3d& delta, const Eigen::Matrix3d& noise);
  /// predict_odometry(deltas.row(k), noises.row(k) as a row-major 3x3) for k = 0 .. K - 1 in one
  /// call: deltas (K, 3), noises (K, 9); returns the pose after each step (K, 3). The robot's
  /// rows of the covariance are carried through every step, the landmarks' cross terms once
  /// through the steps' composed Jacobian: O(K + N) against K calls' O(K N), equal to them up to
  /// rounding. Every step is checked first (std::invalid_argument naming "deltas" / "noises" and
  /// the row); a failed call changes nothing.
  Poses2 predict_odometry_batch(const Eigen::Ref<const RowMatrixXd>& deltas, const Eigen::Ref<const RowMatrixXd>& noises);

  /// Table 10.1 lines 6-20 for measurements z (k x 2, or k x 3 with signatures) of landmarks
  /// `ids`, applied one after another (the exact EKF). A landmark seen for the first time is
  /// added by state augmentation. Measurements whose NIS exceeds `gate` are skipped.
  UpdateReport update(const Eigen::Ref<const RowMatrixXd>& z, const std::vector<long>& ids,
                      double gate = std::numeric_limits<double>::infinity());

  /// std::invalid_argument naming "z" unless z is k x landmark_dim() of finite values with
  /// ranges in [0, kMaxCoordinate] and |bearing|, |signature| <= kMaxCoordinate.
  void check_measurements(const Eigen::Ref<const RowMatrixXd>& z) const;
  /// Table 10.1 lines 12-16 for one measurement z against landmark `id`, without updating:
  /// the normalised innovation squared and log det(2 pi S), whose sum is -2 log N(nu; 0, S).
  /// NaN for a landmark on the robot (no bearing); otherwise finite, or std::invalid_argument.
  struct PairingLikelihood {
    double nis;
    double log_det;
  };
  PairingLikelihood pairing_likelihood(const Eigen::VectorXd& z, long id) const;
  /// Landmarks that may explain measurement z: within gate_distance() plus three standard
  /// deviations of where z places its landmark (the candidates update_unknown looks at).
  std::vector<long> nearby_landmarks(const Eigen::VectorXd& z) const;

  /// Table 10.2: unknown correspondences. Candidates are the landmarks with Mahalanobis distance
  /// pi <= alpha; each landmark takes at most one measurement of the scan. kMaximumLikelihood
  /// pairs the smallest pi first; kJointCompatibility takes the jointly compatible pairing of the
  /// whole scan with the most pairs (JCBB), the joint gates being the chi-square quantiles at
  /// alpha's probability. An unpaired measurement creates a landmark when its pi exceeds
  /// alpha_new for every landmark not paired with another measurement of this scan (a landmark
  /// explains one measurement per scan); otherwise it is discarded as ambiguous.
  AssociationReport update_unknown(const Eigen::Ref<const RowMatrixXd>& z, double alpha, double alpha_new,
                                   Association association = Association::kMaximumLikelihood);

  void set_map_management(const MapManagement& m);
  const MapManagement& map_management() const { return mm_; }
  /// Candidates for association: landmarks within this distance (m) of where the measurement
  /// places its landmark.
  void set_gate_distance(double metres);
  double gate_distance() const { return gate_distance_; }
  int num_provisional() const { return static_cast<int>(provisional_.size()); }
  /// Marginalises landmark `id` out of the state.
  void remove_landmark(long id);

  /// Saves the filter (noise, mean, covariance, landmark ids and slots, existence, provisional
  /// list, map management, counters) bit for bit (docs/file_format.md). A loaded filter's
  /// storage has no spare capacity, as a copy's.
  static constexpr const char* kStateTag = "EkfSlam";
  void save(const std::string& path) const;
  static EkfSlam load(const std::string& path);
  void write_state(StateWriter& w) const;
  static EkfSlam read_state(StateReader& r);

 private:
  struct Provisional {
    Eigen::VectorXd mean;  // landmark_dim(): (x, y[, signature])
    Eigen::MatrixXd cov;   // landmark_dim() x landmark_dim()
    int seen = 1;
    int age = 0;
  };
  struct Candidate {
    Eigen::VectorXd z_hat;
    Eigen::MatrixXd psi_inv;
    Eigen::MatrixXd hx, hm;  // measurement Jacobians (robot, landmark)
  };

  struct Staged;  // a call's corrections and new landmarks, not yet applied (ekf_slam.cpp)
  struct Saved;   // a copy of the whole state, to restore when a long call fails part way

  /// First state index of landmark `id`; std::invalid_argument if it is not in the map.
  int index_of(long id) const;
  /// The landmark at state index `index` as a measurement sees it: (x, y[, signature]).
  Eigen::VectorXd landmark_at(Eigen::Index index) const;
  friend class MultiHypothesisEkfSlam;  // plans every filter's motion before applying any
  struct Motion {  // Table 10.1 lines 3-5's result: the robot's mean, covariance and cross rows
    Eigen::Vector3d pose;
    Eigen::Matrix3d prr;
    Eigen::MatrixXd prm;
    Eigen::Matrix3d g;  // the motion's Jacobian (Table 10.1 line 4)
  };
  /// The motion's result, checked finite; std::invalid_argument otherwise. Changes nothing.
  Motion plan_motion(const Eigen::Vector3d& new_pose, const Eigen::Matrix3d& g, const Eigen::Matrix3d& r) const;
  Motion plan_predict(double v, double w, double dt, const Eigen::MatrixXd& noise) const;
  void apply(const Motion& motion);
  void measurement_jacobian(const Eigen::Vector3d& x, const Eigen::VectorXd& landmark, Eigen::VectorXd& z_hat,
                            Eigen::MatrixXd& hx, Eigen::MatrixXd& hm) const;
  void innovation(const Eigen::VectorXd& z, const Eigen::VectorXd& z_hat, Eigen::VectorXd& nu) const;
  /// Innovation nu, its covariance S and P H^T of z against the landmark at state index `index`;
  /// false for a landmark on the robot.
  bool innovation_at(const Eigen::VectorXd& z, int index, Eigen::VectorXd& nu, Eigen::MatrixXd& s,
                     Eigen::MatrixXd& pht) const;
  double placement_radius(const Eigen::Vector3d& x, const Eigen::VectorXd& z) const;
  void inverse_measurement(const Eigen::Vector3d& x, const Eigen::VectorXd& z, Eigen::VectorXd& m,
                           Eigen::MatrixXd& gx, Eigen::MatrixXd& gz) const;
  void reserve(Eigen::Index dim);
  /// Table 10.1 lines 12-20 for one measurement, staged; returns the NIS (NaN: no bearing).
  double stage_correct(Staged& st, const Eigen::VectorXd& z, Eigen::Index index, double gate, bool& used) const;
  /// Table 10.1 line 10 (state augmentation), staged.
  void stage_augment(Staged& st, const Eigen::VectorXd& z, long id) const;
  /// Writes a staged call into the state; throws nothing once the staged values are checked.
  void commit(Staged& st);
  Saved save() const;
  void restore(Saved& saved);
  void require_state_room(Eigen::Index added_landmarks) const;
  Candidate candidate(const Eigen::VectorXd& landmark, const Eigen::MatrixXd* own_cov, int index) const;
  bool update_provisional(Provisional& p, const Eigen::Vector3d& x, const Eigen::Matrix3d& pose_cov,
                          const Eigen::VectorXd& z) const;
  std::vector<int> joint_target(const Eigen::Ref<const RowMatrixXd>& z,
                                const std::vector<std::tuple<double, int, int>>& pairs,
                                const std::unordered_map<int, Candidate>& cache, int n_map, double alpha) const;
  void update_existence(const std::vector<std::uint8_t>& observed, const Eigen::Vector3d& pose,
                        AssociationReport& report);

  Eigen::Matrix3d r_pose_ = Eigen::Matrix3d::Zero();
  Eigen::Matrix2d m_control_ = Eigen::Matrix2d::Zero();
  bool control_noise_ = false;
  Eigen::MatrixXd Q_;
  // md_: measured values per landmark (2, or 3 with the signature); ld_: its dense state rows.
  int md_ = 2;
  static constexpr int ld_ = 2;
  std::shared_ptr<EkfSlamStorage> s_;
  int n_ = 3;
  std::vector<long> ids_;
  std::unordered_map<long, int> index_;  // id -> first state index
  std::vector<double> signature_, signature_var_;  // per landmark, in state order (with signatures)
  std::vector<double> existence_;
  std::vector<Provisional> provisional_;
  long next_id_ = 0;
  double gate_distance_ = 5.0;
  MapManagement mm_;
  ObjectMutex mutex_;
};

}  // namespace probslam
