#pragma once
// Monte Carlo localization in a known occupancy grid (Probabilistic Robotics ch. 8.3): Table 8.2
// with the odometry motion model (Table 5.6) and the likelihood-field (Table 6.3) or beam
// (Table 6.1) measurement model; augmented MCL (Table 8.3: random particles in free space when
// the short-term average weight drops below the long-term one); KLD sampling (Fox 2003) for the
// particle count; resampling when N_eff is low; an update only after a minimum travel, as
// ROS AMCL's update_min_d / update_min_a (UpdateTrigger).
#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "probslam/core/object_mutex.hpp"
#include "probslam/core/options_description.hpp"
#include "probslam/core/odometry_motion_model.hpp"
#include "probslam/core/types.hpp"
#include "probslam/core/update_trigger.hpp"
#include "probslam/fastslam/particles.hpp"
#include "probslam/grid/beam_mixture.hpp"
#include "probslam/grid/beam_sensor_model.hpp"
#include "probslam/grid/binary_map_2d.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"
#include "probslam/slam2d/likelihood_field.hpp"

namespace probslam {

class WorkerPool;

enum class MclSensorModel { kLikelihoodField, kBeam };
template <>
struct OptionEnum<MclSensorModel> {
  static constexpr std::array<const char*, 2> names{"likelihood-field", "beam"};
};

struct MonteCarloLocalizationOptions {
  MclSensorModel sensor_model = MclSensorModel::kLikelihoodField;
  OdometryMotionNoise odometry;  ///< alpha1..alpha4 of Table 5.6
  // ---- the map ----
  double occupied_threshold = 0.65;  ///< cells above this probability are obstacles
  double free_threshold = 0.25;      ///< cells below this probability are free (where a robot can be)
  // ---- the measurement ----
  double sigma = 0.1;       ///< likelihood field: std of a hit around the nearest obstacle, m (LikelihoodFieldOptions' sigma)
  double p_rand = 0.05;     ///< likelihood field: weight of the uniform part (z_rand / z_max)
  BeamMixture beam;         ///< beam model: the mixture of Table 6.1 (its max_range too)
  double max_range = 30.0;  ///< readings >= this are max readings, skipped (Table 6.3 line 3), m
  double min_range = 0.0;   ///< readings <= this are skipped, m
  int max_beams = 60;       ///< beams used per scan, evenly spaced (beams of one scan are not independent)
  /// Each scan's log-likelihood is multiplied by this, in (0, 1]: a tempered weight. The beams'
  /// errors are correlated (the map's cells, the scan's own distortion), so their product
  /// overstates the evidence: at 1 a global start on the Intel excerpt collapses onto a wrong
  /// place at the first scan and an ACES corridor's small bumps drag the track metres along it;
  /// 0.1 localizes both (docs/localization.md).
  double weight_scale = 0.1;
  // ---- particles: KLD sampling (Fox 2003) ----
  int min_particles = 500;  ///< a tracked cloud fills few bins: below ~500 it loses the track in corridors
  int max_particles = 20000;
  double kld_epsilon = 0.05;  ///< bound on the K-L divergence between the sample and the posterior
  double kld_z = 2.326;       ///< z_{1-delta}: the upper 1 - delta quantile of N(0, 1) (delta = 0.01)
  double bin_xy = 0.5;        ///< histogram bin side, m
  double bin_theta = 0.1745329251994330;  ///< histogram bin width, rad (10 degrees)
  // ---- augmented MCL (Table 8.3); alpha_slow = 0 turns it off ----
  double alpha_slow = 0.001;
  double alpha_fast = 0.1;
  /// Particles are injected with probability max(0, 1 - w_fast / (recovery_ratio w_slow)), in
  /// (0, 1]: 1 is Table 8.3, where every dip of the short-term average (a person in front of
  /// the laser, a part of the map drawn poorly) injects a few; a tracked robot then jumped to a
  /// similar-looking place on ACES and FR079. At 0.5 only a halving of the likelihood injects.
  double recovery_ratio = 0.5;
  /// Injection starts once w_fast < recovery_ratio w_slow has held at this many consecutive
  /// updates (>= 1; 1 is Table 8.3): a person in front of the laser dims a scan or two, a
  /// kidnapping every scan after it.
  int recovery_updates = 1;
  /// Injected particles are drawn from this many candidate poses uniform over the free cells,
  /// each in proportion to the current scan's tempered likelihood there (sensor resetting,
  /// Lenser & Veloso 2000; Mixture MCL's dual proposal, Thrun et al. 2001): a uniform pose rarely
  /// lands near the right one in a large map. 0 draws them uniformly (Table 8.3).
  int recovery_candidates = 0;
  // ---- when to update and resample ----
  double resample_threshold = 0.5;  ///< resample when N_eff < this * M, in [0, 1]
  int resample_interval = 1;        ///< resample at every this-th update at most (AMCL's resample_interval)
  UpdateTrigger update{0.2, 0.5235987755982988};  ///< travel (m) or turn (rad, 30 degrees) before an update
  std::uint64_t seed = 0;
  int threads = 1;
  /// std::invalid_argument naming the first bad option by its path ("beam.z_hit").
  void validate() const;

  template <class V>
  static void describe(V& v) {
    using O = MonteCarloLocalizationOptions;
    v("sensor_model", &O::sensor_model, "", "\"likelihood-field\" (Table 6.3) or \"beam\" (Table 6.1)");
    v("odometry", &O::odometry, "", "the odometry motion model's alpha1..alpha4 (Table 5.6)");
    v("occupied_threshold", &O::occupied_threshold, "", "cells above this probability are obstacles");
    v("free_threshold", &O::free_threshold, "", "cells below this probability are free (where a robot can be)");
    v("sigma", &O::sigma, "m", "likelihood field: std of a hit around the nearest obstacle");
    v("p_rand", &O::p_rand, "", "likelihood field: weight of the uniform part");
    v("beam", &O::beam, "", "beam model: the mixture of Table 6.1 (its max_range is not used: max_range below is the sensor's for both models)");
    v("max_range", &O::max_range, "m", "readings >= this are max readings (skipped by the likelihood field)");
    v("min_range", &O::min_range, "m", "readings <= this are skipped");
    v("max_beams", &O::max_beams, "", "beams used per scan, evenly spaced");
    v("weight_scale", &O::weight_scale, "", "in (0, 1]: each scan's log-likelihood is multiplied by this (the beams' errors are correlated)");
    v("min_particles", &O::min_particles, "", "KLD sampling's lower bound on the particle count");
    v("max_particles", &O::max_particles, "", "KLD sampling's upper bound, and the global start's count");
    v("kld_epsilon", &O::kld_epsilon, "", "bound on the K-L divergence between the sample and the posterior");
    v("kld_z", &O::kld_z, "", "z_{1-delta}, the upper 1 - delta quantile of N(0, 1)");
    v("bin_xy", &O::bin_xy, "m", "KLD histogram bin side");
    v("bin_theta", &O::bin_theta, "rad", "KLD histogram bin width");
    v("alpha_slow", &O::alpha_slow, "", "augmented MCL's long-term average rate (0 turns it off)");
    v("alpha_fast", &O::alpha_fast, "", "its short-term average rate");
    v("recovery_ratio", &O::recovery_ratio, "", "in (0, 1]: inject with probability max(0, 1 - w_fast / (recovery_ratio w_slow))");
    v("recovery_updates", &O::recovery_updates, "", "consecutive low updates before injection starts");
    v("recovery_candidates", &O::recovery_candidates, "", "injected particles drawn from this many free poses by the scan's likelihood (0: uniform)");
    v("resample_threshold", &O::resample_threshold, "", "resample when N_eff < this * M, in [0, 1]");
    v("resample_interval", &O::resample_interval, "", "resample at every this-th update at most (AMCL's resample_interval)");
    v("update", &O::update, "", "the filter updates once the odometry moved or turned this much since the last update");
    v("seed", &O::seed, "", "random seed, in [0, 2^64)");
    v("threads", &O::threads, "", "worker threads (results identical for any count)");
  }
};

/// One entry of update(): whether the filter updated, and its state after.
struct MclUpdate {
  bool updated = false;
  bool resampled = false;
  int num_particles = 0;
  double effective_sample_size = 0.0;
  double random_fraction = 0.0;  ///< augmented MCL's share of random particles at the last resampling
};

class MonteCarloLocalization {
 public:
  /// `map` is copied. Starts with a global initialisation (max_particles uniform over free cells).
  /// Throws std::invalid_argument for bad options or a map with no free cell.
  MonteCarloLocalization(const OccupancyGrid2D& map, const MonteCarloLocalizationOptions& options = {});
  /// A deep copy (particles, random streams, averages); it starts its own worker threads.
  MonteCarloLocalization(const MonteCarloLocalization& other);
  ~MonteCarloLocalization();
  MonteCarloLocalization& operator=(const MonteCarloLocalization&) = delete;

  const MonteCarloLocalizationOptions& options() const { return options_; }
  const OccupancyGrid2D& map() const { return map_; }

  /// max_particles poses uniform over the free cells, headings uniform.
  void initialize_global();
  /// max_particles poses from N(pose, covariance) (3x3, symmetric positive semi-definite).
  /// Throws when pose lies outside the map or in a cell that is not free.
  void initialize_pose(const Eigen::Vector3d& pose, const Eigen::Matrix3d& covariance);

  /// Accumulates an odometry motion: delta = (dx, dy, dtheta) in the frame of the previous
  /// odometry pose. The particles move at the next update (the whole motion since the last one
  /// is one Table 5.6 step, as AMCL does). Refuses (nothing changed) a translation, or a pending
  /// motion, beyond kMaxOdometryTravel.
  void predict_odometry(const Eigen::Vector3d& delta);
  /// The longest odometry motion accepted between two updates, m: 10^6 m (1000 km) is far more
  /// than any robot travels between two scans, and the sampled poses stay finite and exact to
  /// ~1e-10 m (1e300 m sampled through Table 5.6's variance alpha trans^2 gives inf - inf = NaN).
  static constexpr double kMaxOdometryTravel = 1e6;
  /// A scan: ranges (B,) m, beam angles (B,) rad relative to the sensor's heading (the poses are
  /// the sensor's). Updates when the travel since the last update reaches update.distance or
  /// update.angle, or on the first scan, or when `force`. Ranges must be finite or +inf (a max
  /// reading) and >= 0; at least one must be usable. `interrupt`, when given, is called every
  /// few milliseconds of work from the calling thread (the bindings make it throw on Ctrl-C).
  /// Changes nothing when it throws (bad input, an interrupt, threads that cannot start:
  /// std::invalid_argument naming threads).
  MclUpdate update(const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Ref<const Eigen::VectorXd>& angles,
                   bool force = false, const std::function<void()>& interrupt = {});

  /// log p(z | pose, m) of the configured model with the scan subsampled as update() does
  /// (before weight_scale): the weight of one particle.
  double measurement_log_likelihood(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                    const Eigen::Ref<const Eigen::VectorXd>& angles) const;

  int num_particles() const { return static_cast<int>(f_.poses.size()); }
  Poses2 poses() const;
  Eigen::VectorXd weights() const;  ///< normalised
  /// The weighted mean of the largest cluster (connected occupied bins of the KLD histogram,
  /// by weight), moved by the odometry not yet applied; and that cluster's covariance.
  Eigen::Vector3d pose() const;
  Eigen::Matrix3d covariance() const { return f_.covariance; }
  /// The share of the (normalised) weight in that cluster: near 1 when the filter has settled
  /// on one place, small while other places are as likely (a tight cluster is then no answer).
  double cluster_weight() const { return f_.cluster_weight; }
  int num_updates() const { return f_.num_updates; }
  /// Augmented MCL's long- and short-term averages of the per-beam likelihood (Table 8.3).
  double w_slow() const { return f_.w_slow; }
  double w_fast() const { return f_.w_fast; }
  const LikelihoodField* likelihood_field() const { return field_.get(); }

  /// Fox 2003 eq. (the Wilson-Hilferty approximation of the chi-square quantile): particles
  /// needed for `k` occupied bins, before the min/max bounds. Throws std::invalid_argument
  /// (naming epsilon) when the bound overflows a double.
  static double kld_bound(int k, double epsilon, double z);

  std::mutex& mutex() const noexcept { return mutex_.get(); }

  /// Saves the options, the map and the whole filter (particles, random streams, averages, the
  /// motion not yet applied, the estimate) bit for bit (docs/file_format.md): a loaded object
  /// continues exactly as this one would. The map's tables are rebuilt from the map.
  static constexpr const char* kStateTag = "MonteCarloLocalization";
  void save(const std::string& path) const;
  static MonteCarloLocalization load(const std::string& path);
  void write_state(StateWriter& w) const;
  static MonteCarloLocalization read_state(StateReader& r);

 private:
  void check_pose_free(const Eigen::Vector3d& pose, const char* name) const;
  bool is_free(const Eigen::Vector3d& pose) const;
  bool is_occupied_or_outside(const Eigen::Vector3d& pose) const;
  Eigen::Vector3d random_free_pose(ParticleRng& rng) const;
  void reset_particles(int n);
  /// `scan` gives the current scan's tempered log-likelihood of a pose (for recovery candidates).
  template <class Scan>
  void resample(double random_probability, const Scan& scan, double scan_cost, const std::function<void()>& interrupt);
  /// f(j) for j in [0, n) over the worker threads, at least min_per_worker items a worker.
  template <class F>
  void for_range(int n, F&& f, int min_per_worker);
  /// for_range in chunks of about kWorkPerCheck elementary steps (`cost` steps an item), with
  /// interrupt() called from this thread before each chunk.
  template <class F>
  void for_range_checked(int n, double cost, const std::function<void()>& interrupt, F&& f);
  /// Elementary steps (table look-ups or ray cells) of one scan's likelihood at one pose.
  double scan_cost(std::size_t beams) const;
  void start_pool();
  /// update() once it is due, changing the filter in place (update() puts it back if this throws).
  MclUpdate apply_update(const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Ref<const Eigen::VectorXd>& angles,
                         const std::function<void()>& interrupt);
  void compute_estimate();
  std::vector<int> used_beams(const Eigen::Ref<const Eigen::VectorXd>& ranges) const;
  double scan_log_likelihood(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                             const Eigen::Ref<const Eigen::VectorXd>& angles, const std::vector<int>& beams) const;

  MonteCarloLocalizationOptions options_;
  OccupancyGrid2D map_;
  std::vector<std::uint8_t> cell_free_, cell_occupied_;
  std::vector<int> free_cells_;
  std::shared_ptr<const LikelihoodField> field_;    // immutable: shared by copies
  std::shared_ptr<const BinaryMap2D> binary_map_;
  std::shared_ptr<const BeamSensorModel> beam_model_;

  /// Everything update() changes, in one place: kept before an update and put back when it
  /// throws, copied whole by the copy constructor, written whole by save().
  struct FilterState {
    std::vector<Eigen::Vector3d> poses;
    std::vector<double> log_weights;
    std::vector<ParticleRng> rngs;
    ParticleRng filter_rng;
    std::uint64_t next_stream = 0;
    Eigen::Vector3d pending = Eigen::Vector3d::Zero();  // odometry since the last update
    double travel_d = 0.0, travel_a = 0.0;
    double w_slow = 0.0, w_fast = 0.0;
    double slow_raw = 0.0, fast_raw = 0.0, slow_mass = 0.0, fast_mass = 0.0;  // before bias correction
    double random_fraction = 0.0;
    int low_updates = 0;  // consecutive updates with w_fast < recovery_ratio w_slow
    int num_updates = 0;
    Eigen::Vector3d estimate = Eigen::Vector3d::Zero();
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    double cluster_weight = 0.0;  // derived from the particles by compute_estimate()
  };
  FilterState f_;
  std::unique_ptr<WorkerPool> pool_;  // threads > 1: started on the first update
  ObjectMutex mutex_;
};

}  // namespace probslam
