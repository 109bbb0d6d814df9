#pragma once
// FastSLAM 1.0 and 2.0 (Montemerlo et al. 2002, 2003; Probabilistic Robotics ch. 13): a
// Rao-Blackwellised particle filter whose particles each carry a path sample and one 2x2 EKF
// per landmark, with known or unknown (per-particle maximum-likelihood) correspondences and
// maps shared between particles in persistent trees (landmark_tree.hpp).
#include <Eigen/Core>

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "probslam/core/filter_limits.hpp"
#include "probslam/core/object_mutex.hpp"
#include "probslam/core/options_description.hpp"
#include "probslam/core/types.hpp"
#include "probslam/fastslam/landmark_tree.hpp"
#include "probslam/fastslam/particles.hpp"

namespace probslam {

class WorkerPool;

// Reliability limits beside the shared ones of core/filter_limits.hpp, refused by name beyond them.
/// Particles per filter: 2^20 particles of ~250 bytes each before any landmark.
inline constexpr int kFastSlamMaxParticles = kMaxParticles;
/// Worker threads of one filter.
inline constexpr int kFastSlamMaxThreads = 256;
/// Landmarks in one particle's map (each measurement adds at most one).
inline constexpr long kFastSlamMaxLandmarks = 1L << 26;
/// Sightings and scan counts of the provisional landmarks (FastSlamOptions::min_sightings).
inline constexpr int kFastSlamMaxCount = 1000000;

/// The tunables of FastSlam (the model, its motion and measurement noise and the start pose, is
/// the constructor's). validate() checks each; the constructor runs it.
struct FastSlamOptions {
  static constexpr int kDefaultParticles = 100;
  static constexpr double kDefaultResampleThreshold = 0.5;
  /// Density (per unit of the measurement space: 1 / (m rad), times 1 / signature unit with
  /// signatures) that a measurement comes from a landmark not in the map; see p_new below.
  static constexpr double kDefaultPNew = 1e-2;
  static constexpr double kDefaultAssociationRadius = 2.0;  // m
  static constexpr double kDefaultCellSize = 2.0;           // m

  int num_particles = kDefaultParticles;
  /// 1: FastSLAM 1.0 (poses sampled from the motion model); 2: FastSLAM 2.0 (from the proposal
  /// that includes the scan's measurements). Version 2's proposal covers every motion since the
  /// last update (their means composed from that update's pose, the covariance propagated
  /// through each), and its path between updates is that chain of means bridged to the pose the
  /// update draws: with many odometry rows per scan (MRCLAM: ~25) a proposal over the last
  /// motion alone leaves the noise of the others to the weights.
  int version = 1;
  /// Measurements and landmarks carry a signature (measurement_noise is then 3x3).
  bool use_signatures = false;
  /// Particle k starts with random stream k of this seed (see FastSlam's comment).
  std::uint64_t seed = 0;
  /// Particles are updated by this many threads; results do not depend on it.
  int threads = 1;
  /// Resample when N_eff = 1 / sum w^2 < resample_threshold * num_particles; in [0, 1].
  double resample_threshold = kDefaultResampleThreshold;
  /// The likelihood of a new landmark. Unknown correspondences: a measurement becomes a new
  /// landmark when no landmark's likelihood N(z - z_hat; 0, S) exceeds p_new. Both versions and
  /// both kinds of correspondence: a particle's weight is multiplied by p_new for each new
  /// landmark (Table 13.1 / 13.3's default importance weight p_0).
  double p_new = kDefaultPNew;
  /// Known correspondences: density (same units as p_new: 1 / (m rad), times 1 / signature unit
  /// with signatures) of a measurement that its labelled landmark did not produce (a wrong
  /// label, a false detection). Each measurement's weight factor is then the mixture
  /// N(z - z_hat; 0, Q_j) + outlier_density (the scale (1 - eps) of the Gaussian is the same for
  /// every particle and cancels), and the landmark is updated only where the Gaussian term is
  /// the larger one, i.e. where the measurement more likely came from the landmark than from
  /// the outlier density. Without it one gross outlier multiplies the particles' weights by
  /// exp(-NIS / 2) with NIS in the hundreds and leaves one particle, and it drags the landmark.
  /// 0 (the default): no outlier model, every measurement updates its landmark.
  double outlier_density = 0.0;
  /// Association candidates of a measurement: the landmarks whose mean is within
  /// association_radius plus three standard deviations of where the measurement places it.
  double association_radius = kDefaultAssociationRadius;
  /// update_unknown's association of a scan: true, the joint maximum-likelihood assignment of
  /// the scan's measurements to distinct landmarks or new ones (per particle; version 2 scores
  /// it with the pose's uncertainty shared by the scan, as JCBB does); false, each measurement
  /// its most likely landmark, best pairs first, one measurement per landmark.
  bool joint_association = true;
  /// Side (m) of the square cells of the spatial key; about association_radius.
  double cell_size = kDefaultCellSize;
  /// Negative information in update_unknown: a landmark inside sensor_range and sensor_fov of
  /// the particle's pose but not seen loses existence_miss from its existence counter, and is
  /// removed when the counter falls below zero. Seen landmarks gain existence_hit; a new one
  /// starts with existence_hit.
  bool negative_information = false;
  double existence_hit = 1.0;
  double existence_miss = 1.0;
  double sensor_range = std::numeric_limits<double>::infinity();  // m; finite for negative_information
  double sensor_fov = 6.283185307179586;                           // rad, full opening angle
  /// Provisional landmarks in update_unknown (the landmark candidates of RFS-SLAM's FastSLAM,
  /// Probabilistic Robotics' provisional list, ch. 10.3.3): a new landmark is provisional until
  /// a particle has seen it in min_sightings scans (its first sighting counts); a provisional
  /// landmark that goes more than provisional_max_age update_unknown calls without a sighting is
  /// removed. It is in the particle's map meanwhile (associated and updated as any other).
  /// 1 (the default): every new landmark is permanent at once. In [1, 1e6] and [0, 1e6].
  int min_sightings = 1;
  int provisional_max_age = 20;
  /// Keep every particle's path (a persistent list: shared after resampling, O(1) to copy).
  bool record_path = true;
  /// A bearing offset b shared by the measurements of one scan (a camera's timing or mounting
  /// error; measured bearing = true bearing + b + noise), carried by each particle as a state:
  /// stationary standard deviation (rad; 0, the default: no offset), and its correlation from
  /// one update to the next (b' = rho b + sqrt(1 - rho^2) sigma n; 0: independent per scan).
  /// Each update samples b' from that transition and explains the scan with the bearings
  /// corrected by it, so the weights pick the offsets that fit. measurement_noise is then the
  /// part of the bearing noise that is not shared.
  double bearing_offset_sigma = 0.0;
  double bearing_offset_correlation = 0.0;

  /// std::invalid_argument naming the first field out of its range.
  void validate() const;

  /// The fields in the order the state files hold them (core/options_description.hpp).
  template <class V>
  static void describe(V& v) {
    using O = FastSlamOptions;
    v("num_particles", &O::num_particles, "", "M, in [1, 2^20]");
    v("version", &O::version, "", "1: FastSLAM 1.0 (poses from the motion model); 2: FastSLAM 2.0 (from the proposal that includes the scan)");
    v("use_signatures", &O::use_signatures, "", "measurements and landmarks carry a signature (measurement_noise 3x3)");
    v("seed", &O::seed, "", "random seed, in [0, 2^64): particle k starts with random stream k of it");
    v("threads", &O::threads, "", "worker threads, in [1, 256] (results identical for any count)");
    v("resample_threshold", &O::resample_threshold, "", "resample when N_eff < this * M, in [0, 1]");
    v("p_new", &O::p_new, "m^-1 rad^-1", "density of a new landmark's measurement (times 1 / signature unit with signatures)");
    v("outlier_density", &O::outlier_density, "m^-1 rad^-1", "known correspondences: density of a measurement its labelled landmark did not produce (0: no outlier model)");
    v("association_radius", &O::association_radius, "m", "association candidates lie within it plus three standard deviations of where the measurement places its landmark");
    v("joint_association", &O::joint_association, "", "update_unknown assigns a scan's measurements jointly (maximum likelihood over distinct landmarks or new ones); False: each its most likely landmark, best pairs first");
    v("cell_size", &O::cell_size, "m", "side of the landmarks' spatial key cells (about association_radius)");
    v("negative_information", &O::negative_information, "", "update_unknown's existence counter: an unseen landmark inside sensor_range and sensor_fov loses existence_miss, a seen one gains existence_hit; below zero it is removed");
    v("existence_hit", &O::existence_hit, "", "the counter's step up, in [0, 1e9]");
    v("existence_miss", &O::existence_miss, "", "the counter's step down, in [0, 1e9]");
    v("sensor_range", &O::sensor_range, "m", "range of the sensor's field (finite with negative_information)");
    v("sensor_fov", &O::sensor_fov, "rad", "full opening angle of the sensor's field, in (0, 2 pi]");
    v("min_sightings", &O::min_sightings, "", "update_unknown: a new landmark is provisional until seen in this many scans (its first counts), in [1, 1e6] (1: off)");
    v("provisional_max_age", &O::provisional_max_age, "", "update_unknown calls a provisional landmark may go unseen before it is removed, in [0, 1e6]");
    v("record_path", &O::record_path, "", "keep each particle's path (path())");
    v("bearing_offset_sigma", &O::bearing_offset_sigma, "rad", "std of a bearing offset shared by one scan's measurements, carried per particle, in [0, pi] (0: off)");
    v("bearing_offset_correlation", &O::bearing_offset_correlation, "", "its correlation from one update to the next, in [0, 1)");
  }
};

/// One particle: a pose sample, its log weight and its map; in version 2 also the motion prior
/// N(prior_mean, prior_cov) of the last predict, which the next update's proposal starts from.
struct FastSlamParticle {
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();
  double log_weight = 0.0;
  double last_log_likelihood = 0.0;  // of the last update: the log of the weight's factor
  LandmarkMap map;
  PosePath path;
  ParticleRng rng;
  long next_id = 0;  // unknown correspondences: the next new landmark's id
  bool has_prior = false;
  int moves_since_update = 0;  // version 2: motions since the last update (path poses the proposal moves)
  Eigen::Vector3d prior_mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d prior_cov = Eigen::Matrix3d::Zero();
  double bearing_offset = 0.0;  // rad; see FastSlamOptions::bearing_offset_sigma
  long scans = 0;                 // update_unknown calls this particle took (the provisional clock)
  std::vector<long> provisional;  // ids of its provisional landmarks (FastSlamOptions::min_sightings)

  /// Lets go of the map and path this particle shares, keeping the rest (cheaper than
  /// constructing a particle, whose random stream is seeded).
  void drop_shared() {
    map = LandmarkMap(map.cell_size());
    path = PosePath();
  }
};

/// What update_unknown() did, per particle and measurement (row-major num_particles x k). Rows
/// follow the particles after the call: when it resampled, row j is particle j's ancestor's.
struct FastSlamAssociation {
  int num_particles = 0, num_measurements = 0;
  std::vector<long> ids;                    // landmark used or created
  std::vector<std::uint8_t> is_new;         // 1 where the measurement created the landmark
  std::vector<std::vector<long>> removed;   // per particle, landmarks removed (negative information,
                                            // provisional ones not seen often enough)
};

/// Nodes shared between the particles' maps.
struct MapSharing {
  std::size_t distinct_nodes = 0;  // tree nodes reachable from some particle (allocated for the maps)
  std::size_t total_nodes = 0;     // sum over particles of their trees' nodes (what deep copies hold)
  std::size_t landmarks = 0;       // sum over particles of their landmark counts
  std::size_t path_nodes = 0;      // distinct path chunks (PosePath::kChunkPoses poses each)
};

/// FastSLAM 2.0's proposal for one measurement of a landmark N(landmark_mean, landmark_cov) from
/// the pose prior N(pose_mean, pose_cov) (pose_cov may be singular): with G_x, H the Jacobians
/// of h at (pose_mean, landmark_mean), Q_j = H landmark_cov H^T + Q and S = G_x pose_cov G_x^T + Q_j,
///   Sigma_x = (G_x^T Q_j^-1 G_x + pose_cov^-1)^-1 = pose_cov - K S K^T,  K = pose_cov G_x^T S^-1,
///   mu_x = pose_mean + Sigma_x G_x^T Q_j^-1 (z - z_hat) = pose_mean + K (z - z_hat),
/// (the Kalman form on the right needs no inverse of pose_cov) and the weight factor
/// N(z - z_hat; 0, S). The bearing innovation is wrapped, mu_x's heading too.
struct PoseProposal {
  Eigen::Vector3d mean;
  Eigen::Matrix3d cov;
  double log_likelihood;
};
PoseProposal fastslam2_proposal(const Eigen::Vector3d& pose_mean, const Eigen::Matrix3d& pose_cov,
                                const Eigen::Vector2d& landmark_mean, const Eigen::Matrix2d& landmark_cov,
                                const Eigen::Vector2d& z, const Eigen::Matrix2d& measurement_noise);

/// The filter. Random numbers: particle k draws from its own stream, starting as stream k of
/// the seed; resampling gives the j-th new particle the stream (next stream number + j), and the
/// filter's own stream (for the resampling offset) is used by the calling thread only. So a
/// seed gives the same result for any number of threads, bit for bit.
///
/// Version 2 (FastSLAM 2.0). predict() samples the pose from the motion model as version 1 does
/// and keeps the prior N(x_hat, R_t): x_hat = g(x, u) noise-free, R_t the motion noise of that
/// prediction in pose space (R, or V M V^T for control noise at the particle's previous pose, or
/// J noise J^T for odometry). The next update() / update_unknown() with measurements of landmarks
/// already in the particle's map builds the proposal from that prior one measurement at a time:
/// measurement j's Gaussian (fastslam2_proposal, linearised at the previous step's mean) is the
/// prior of measurement j + 1, so after the scan the proposal is the linearised posterior of the
/// pose given every such measurement, and the weight factor is the product of the steps'
/// N(z_j - z_hat_j; 0, G_x Sigma_{j-1} G_x^T + Q_j) (the chain rule: the scan's marginal
/// likelihood; one measurement gives exactly the book's N(z - z_hat; 0, G_x R G_x^T + Q_j)).
/// The pose is then sampled once from that proposal (replacing the motion sample, also in the
/// path) and every landmark is updated at the sampled pose: sampling once per measurement would
/// update landmarks at poses other than the particle's final one and add the proposal's spread
/// once per measurement. New landmarks are initialised at the sampled pose (weight factor p_new).
/// Without a prior (an update before any predict, or a second update after one predict) the
/// prior covariance is zero and version 2 updates as version 1 does.
///
/// Every call validates all its input first (std::invalid_argument whose message starts with
/// the argument's name) and works on copies of the particles (O(1) each: maps and paths are
/// persistent), committing only when every particle succeeded: when it throws, the filter is
/// unchanged. It does not lock itself: see mutex().
class FastSlam {
 public:
  /// motion_noise: 3x3 pose-space covariance R of (x, y, theta), or 2x2 control-space covariance
  /// M of (v, w); symmetric positive semi-definite (zero is allowed: a noise-free motion).
  /// measurement_noise: Q, covariance of (range [m], bearing [rad]), or 3x3 with the signature's
  /// variance (options.use_signatures; the signature uncorrelated with range and bearing);
  /// symmetric positive definite. initial_pose: every particle's start (x, y, theta).
  FastSlam(const Eigen::MatrixXd& motion_noise, const Eigen::MatrixXd& measurement_noise,
           const FastSlamOptions& options = FastSlamOptions(),
           const Eigen::Vector3d& initial_pose = Eigen::Vector3d::Zero());
  FastSlam(const FastSlam& other);
  FastSlam& operator=(const FastSlam& other);
  FastSlam(FastSlam&&) noexcept;
  FastSlam& operator=(FastSlam&&) noexcept;
  ~FastSlam();

  std::mutex& mutex() const noexcept { return mutex_.get(); }
  const FastSlamOptions& options() const { return o_; }
  /// The motion and measurement noise as given (symmetrised), and the start pose (heading wrapped).
  const Eigen::MatrixXd& motion_noise() const { return motion_noise_; }
  const Eigen::MatrixXd& measurement_noise() const { return measurement_noise_; }
  const Eigen::Vector3d& initial_pose() const { return initial_pose_; }
  int num_particles() const { return static_cast<int>(particles_.size()); }
  int version() const { return o_.version; }
  int landmark_dim() const { return o_.use_signatures ? 3 : 2; }

  /// Samples every particle's pose from the velocity motion model for dt seconds (pose-space
  /// noise added to g(x, u); control-space noise added to (v, w)). Version 2 also keeps the
  /// linearised prior for the next update: N(g(x, u), R_t) (R_t = V M V^T for control noise)
  /// after an update, composed with the previous prior (G P G^T + R_t) when no update came since.
  void predict(double v, double w, double dt);
  /// Odometry as a relative pose: x <- x (+) (delta + e), e ~ N(0, noise) in the robot frame.
  void predict_odometry(const Eigen::Vector3d& delta, const Eigen::Matrix3d& noise);
  /// predict_odometry(deltas.row(k), noises.row(k) as a row-major 3x3) for k = 0 .. K - 1, in
  /// one call and bit for bit the same: deltas (K, 3), noises (K, 9). Every step is checked
  /// before any particle moves (std::invalid_argument naming "deltas" / "noises" and the row).
  void predict_odometry_batch(const Eigen::Ref<const RowMatrixXd>& deltas, const Eigen::Ref<const RowMatrixXd>& noises);

  /// Known correspondences: measurements z (k x 2, or k x 3 with signatures) of landmarks `ids`.
  /// Returns true when it resampled.
  bool update(const Eigen::Ref<const RowMatrixXd>& z, const std::vector<long>& ids);
  /// Unknown correspondences, with options().p_new or the given p_new.
  FastSlamAssociation update_unknown(const Eigen::Ref<const RowMatrixXd>& z);
  FastSlamAssociation update_unknown(const Eigen::Ref<const RowMatrixXd>& z, double p_new);
  /// Low-variance resampling now, whatever N_eff.
  void resample();

  const FastSlamParticle& particle(int k) const;
  Poses2 poses() const;
  /// (M,) each particle's bearing offset (rad) of its last update; zeros without the model.
  Eigen::VectorXd bearing_offsets() const;
  /// Normalised log weights (log-sum-exp 0).
  Eigen::VectorXd log_weights() const;
  Eigen::VectorXd last_log_likelihoods() const;
  double effective_sample_size() const;
  /// The particle of highest weight (the first of equals).
  int best_index() const;
  /// Particle k's path, oldest first ((steps + 1) x 3); empty without record_path.
  Poses2 path(int k) const;
  /// Weighted mean pose (heading: circular mean) and the weighted covariance about it.
  Eigen::Vector3d mean_pose() const;
  Eigen::Matrix3d pose_covariance() const;
  /// Particle k's landmarks sorted by id.
  std::vector<Landmark> landmarks(int k) const;
  MapSharing map_sharing() const;
  long num_resamples() const { return resamples_; }
  bool resampled() const { return last_resampled_; }
  /// When the last call (predict, update or resample()) resampled: particle j's ancestor index
  /// before it, for every j; empty otherwise. Lets a caller carry per-particle histories along.
  const std::vector<int>& last_ancestors() const { return last_ancestors_; }

  /// Saves the filter (options, every particle's pose, weight, map, path, random stream and
  /// version 2's pending motion prior, the filter's stream and counters) bit for bit
  /// (docs/file_format.md): a loaded filter continues exactly as this one would. Maps and paths
  /// are saved per particle and loaded unshared (as deep copies: more memory, same results).
  static constexpr const char* kStateTag = "FastSlam";
  void save(const std::string& path) const;
  static FastSlam load(const std::string& path);
  void write_state(StateWriter& w) const;
  static FastSlam read_state(StateReader& r);

 private:
  struct Context;
  template <class F>
  void for_particles(F&& f);
  /// Replaces the particles by copies with work(k, copy) applied, made by the workers (see
  /// for_particles); when work throws, the particles are unchanged.
  template <class F>
  void staged(F&& work);
  void drop_spare_if_serial();
  /// A particle's sampled motion: its new pose, and for version 2 the prior of the proposal.
  struct Motion {
    Eigen::Vector3d pose = Eigen::Vector3d::Zero();
    Eigen::Vector3d prior_mean = Eigen::Vector3d::Zero();
    Eigen::Matrix3d prior_cov = Eigen::Matrix3d::Zero();
  };
  /// A particle's state before move_particles() moved it (in call number `stamp`).
  struct Move {
    Motion before;
    ParticleRng rng;
    bool has_prior = false;
    int moves_since_update = 0;
    std::uint64_t stamp = 0;
    int pushed = 0;  // path poses the move appended
  };
  /// Moves every particle `steps` times by sample(step, pose, rng, motion, since), which fills
  /// `motion` drawing from rng (a copy of the particle's stream); in place, and not at all when a
  /// sample throws.
  template <class Sample>
  void move_particles(int steps, Sample&& sample);
  /// The odometry steps (validated; covariances symmetric, with their factors) as one move.
  void odometry_steps(const std::vector<Eigen::Vector3d>& deltas, const std::vector<Eigen::Matrix3d>& covs,
                      const std::vector<Eigen::Matrix3d>& factors, const char* name);
  /// (M,) the field of every particle.
  Eigen::VectorXd per_particle(double FastSlamParticle::*field) const;
  void check_measurements(const Eigen::Ref<const RowMatrixXd>& z) const;
  static void check_room(const FastSlamParticle& p, Eigen::Index added);
  /// Normalises the weights staged() left, resamples if N_eff is low: the ancestors, or empty.
  std::vector<int> commit();
  /// Writes the normalised weights_ into the particles, or, given ancestors, replaces the
  /// particles by copies of them (weights 1 / M); on the workers.
  void settle(const std::vector<int>& ancestors);

  FastSlamOptions o_;
  Eigen::MatrixXd motion_noise_;
  Eigen::MatrixXd measurement_noise_;
  Eigen::Vector3d initial_pose_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d motion_factor_ = Eigen::Matrix3d::Zero();  // L with L L^T = R (pose space)
  Eigen::Matrix2d control_factor_ = Eigen::Matrix2d::Zero();  // L with L L^T = M (control space)
  bool control_noise_ = false;
  Eigen::Matrix2d q2_ = Eigen::Matrix2d::Zero();
  double q_signature_ = 0.0;
  std::vector<FastSlamParticle> particles_;
  std::vector<FastSlamParticle> spare_;  // see staged(): particles no longer used, or empty ones
  std::vector<double> weights_;          // see staged(): log weights the workers left
  std::vector<Move> moves_;              // see move_particles()
  std::uint64_t move_calls_ = 0;
  ParticleRng rng_;                    // the filter's own stream (resampling offsets)
  std::uint64_t next_stream_ = 0;      // the stream number of the next new particle
  long resamples_ = 0;
  bool last_resampled_ = false;
  std::vector<int> last_ancestors_;
  std::unique_ptr<WorkerPool> pool_;   // started on first use; never copied
  ObjectMutex mutex_;
};

}  // namespace probslam
