#include "probslam/localization/monte_carlo_localization.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <system_error>
#include <unordered_map>
#include <utility>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/worker_pool.hpp"

namespace probslam {
namespace {

// The filter's own random stream (resampling offsets, injected particles): a stream number no
// particle takes (particles count up from 0).
constexpr std::uint64_t kFilterStream = ~std::uint64_t{0};
// A particle standing in an occupied cell or off the map is not a pose the robot can have; its
// weight is cut by this factor (not zeroed: a whole cloud could stand there after a bad motion).
constexpr double kBlockedLogPenalty = -50.0;
// Beam model: a beam whose density underflows counts as this (the mixture's z_rand keeps real
// readings far above it; it only guards -inf from a reading beyond max_range of a zero z_max).
constexpr double kMinBeamLogProbability = -50.0;
// Particles per worker below which splitting over threads costs more than it saves.
constexpr int kMinParticlesPerWorker = 256;
// The same in elementary steps (look-ups of the default 60 likelihood-field beams): a worker
// gets at least this much work, so that particles of an expensive scan (beam model: a ray
// walk a beam) still spread over the threads.
constexpr double kMinWorkPerWorker = kMinParticlesPerWorker * 60.0;
// Elementary steps (a table look-up, a ray cell) between two interrupt checks: a few
// milliseconds of work, so that Ctrl-C stops a long update at once.
constexpr double kWorkPerCheck = 1 << 20;
// Histogram bin indices are clamped to +-2^53: every such index is a double exactly, and a
// neighbour (index +- 1) or a heading bin count stays far inside int64 (a bin of 5e-324 m put a
// pose's index, and its neighbour's, beyond int64: undefined behaviour).
constexpr double kMaxBinIndex = 9007199254740992.0;  // 2^53

std::int64_t bin_index(double scaled) {
  return static_cast<std::int64_t>(std::clamp(std::floor(scaled), -kMaxBinIndex, kMaxBinIndex));
}

}  // namespace

void MonteCarloLocalizationOptions::validate() const {
  odometry.validate();
  require(std::isfinite(occupied_threshold) && occupied_threshold > 0.0 && occupied_threshold < 1.0,
          "occupied_threshold", "must lie in (0, 1)");
  require(std::isfinite(free_threshold) && free_threshold > 0.0 && free_threshold <= occupied_threshold,
          "free_threshold", "must lie in (0, occupied_threshold]");
  require(sigma_hit >= LikelihoodFieldOptions::kMinSigma && sigma_hit <= LikelihoodFieldOptions::kMaxSigma, "sigma_hit",
          "must lie in [1e-300, 1e300] (LikelihoodFieldOptions::kMinSigma, kMaxSigma)");
  require_probability(p_rand, "p_rand");
  require_positive(max_range, "max_range");
  require(std::isfinite(min_range) && min_range >= 0.0 && min_range < max_range, "min_range",
          "must lie in [0, max_range)");
  require(max_beams >= 1, "max_beams", "must be >= 1");
  require(std::isfinite(weight_scale) && weight_scale > 0.0 && weight_scale <= 1.0, "weight_scale",
          "must lie in (0, 1]");
  require(min_particles >= 1 && min_particles <= kMaxParticles, "min_particles", "must lie in [1, 2^20]");
  require(max_particles >= min_particles && max_particles <= kMaxParticles, "max_particles",
          "must lie in [min_particles, 2^20]");
  require(std::isfinite(kld_epsilon) && kld_epsilon > 0.0, "kld_epsilon", "must be finite and > 0");
  require(std::isfinite(kld_z) && kld_z >= 0.0, "kld_z", "must be finite and >= 0");
  require_positive(bin_xy, "bin_xy");
  require(std::isfinite(bin_theta) && bin_theta > 0.0 && bin_theta <= kTwoPi, "bin_theta", "must lie in (0, 2 pi]");
  require(std::isfinite(alpha_slow) && alpha_slow >= 0.0 && alpha_slow <= 1.0, "alpha_slow", "must lie in [0, 1]");
  require(std::isfinite(alpha_fast) && alpha_fast >= alpha_slow && alpha_fast <= 1.0, "alpha_fast",
          "must lie in [alpha_slow, 1]");
  require(std::isfinite(recovery_ratio) && recovery_ratio > 0.0 && recovery_ratio <= 1.0, "recovery_ratio",
          "must lie in (0, 1]");
  require(recovery_updates >= 1 && recovery_updates <= 1000000, "recovery_updates", "must lie in [1, 10^6]");
  require(recovery_candidates >= 0 && recovery_candidates <= kMaxParticles, "recovery_candidates",
          "must lie in [0, 2^20]");
  require(std::isfinite(resample_threshold) && resample_threshold >= 0.0 && resample_threshold <= 1.0,
          "resample_threshold", "must lie in [0, 1]");
  require(std::isfinite(update_min_d) && update_min_d >= 0.0, "update_min_d", "must be finite and >= 0");
  require(std::isfinite(update_min_a) && update_min_a >= 0.0, "update_min_a", "must be finite and >= 0");
  require(threads >= 1 && threads <= 1024, "threads", "must lie in [1, 1024]");
  // The beam mixture is checked whichever model is used (a NaN given for it is refused, not kept
  // unseen), its errors naming the options as the bindings do (beam_sigma_hit, not sigma_hit,
  // which is the likelihood field's).
  BeamMixture b = beam;
  b.max_range = max_range;
  try {
    b.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("beam_") + e.what());
  }
}

double MonteCarloLocalization::kld_bound(int k, double epsilon, double z) {
  if (k <= 1) return 0.0;
  const double km1 = static_cast<double>(k - 1);
  const double a = 2.0 / (9.0 * km1);
  const double c = 1.0 - a + std::sqrt(a) * z;
  const double bound = km1 / (2.0 * epsilon) * c * c * c;
  require(std::isfinite(bound), "epsilon", "is too small (or z too large): the particle bound overflows a double");
  return bound;
}

MonteCarloLocalization::MonteCarloLocalization(const OccupancyGrid2D& map, const MonteCarloLocalizationOptions& options)
    : options_(options), map_(map), filter_rng_(options.seed, kFilterStream) {
  options_.validate();
  const RowMatrixXd p = map_.probability();
  const std::size_t cells = static_cast<std::size_t>(p.size());
  cell_free_.assign(cells, 0);
  cell_occupied_.assign(cells, 0);
  for (std::size_t i = 0; i < cells; ++i) {
    const double v = p.data()[i];
    cell_free_[i] = v < options_.free_threshold;
    cell_occupied_[i] = v > options_.occupied_threshold;
    if (cell_free_[i]) free_cells_.push_back(static_cast<int>(i));
  }
  require(!free_cells_.empty(), "map", "has no free cell (occupancy probability below free_threshold)");
  if (options_.sensor_model == MclSensorModel::kLikelihoodField) {
    LikelihoodFieldOptions lf;
    lf.sigma = options_.sigma_hit;
    lf.p_rand = options_.p_rand;
    lf.occupied_probability = options_.occupied_threshold;
    field_ = std::make_shared<const LikelihoodField>(LikelihoodField::from_grid(map_, lf));
  } else {
    binary_map_ = std::make_shared<const BinaryMap2D>(map_, cell_occupied_);
    BeamMixture b = options_.beam;
    b.max_range = options_.max_range;
    beam_model_ = std::make_shared<const BeamSensorModel>(b, BeamShape::kLaser);
  }
  initialize_global();
}

MonteCarloLocalization::MonteCarloLocalization(const MonteCarloLocalization& o)
    : options_(o.options_), map_(o.map_), cell_free_(o.cell_free_), cell_occupied_(o.cell_occupied_),
      free_cells_(o.free_cells_), field_(o.field_), binary_map_(o.binary_map_), beam_model_(o.beam_model_),
      poses_(o.poses_), log_weights_(o.log_weights_), rngs_(o.rngs_), filter_rng_(o.filter_rng_),
      next_stream_(o.next_stream_), pending_(o.pending_), travel_d_(o.travel_d_), travel_a_(o.travel_a_),
      w_slow_(o.w_slow_), w_fast_(o.w_fast_), slow_raw_(o.slow_raw_), fast_raw_(o.fast_raw_),
      slow_mass_(o.slow_mass_), fast_mass_(o.fast_mass_), random_fraction_(o.random_fraction_), low_updates_(o.low_updates_),
      num_updates_(o.num_updates_),
      estimate_(o.estimate_), covariance_(o.covariance_), cluster_weight_(o.cluster_weight_) {}

MonteCarloLocalization::~MonteCarloLocalization() = default;

bool MonteCarloLocalization::is_free(const Eigen::Vector3d& pose) const {
  const Eigen::Vector2i rc = map_.cell_of(pose.x(), pose.y());
  return map_.contains(rc[0], rc[1]) &&
         cell_free_[static_cast<std::size_t>(rc[0]) * static_cast<std::size_t>(map_.width()) + rc[1]];
}

bool MonteCarloLocalization::is_occupied_or_outside(const Eigen::Vector3d& pose) const {
  const Eigen::Vector2i rc = map_.cell_of(pose.x(), pose.y());
  return !map_.contains(rc[0], rc[1]) ||
         cell_occupied_[static_cast<std::size_t>(rc[0]) * static_cast<std::size_t>(map_.width()) + rc[1]];
}

Eigen::Vector3d MonteCarloLocalization::random_free_pose(ParticleRng& rng) const {
  const std::size_t n = free_cells_.size();
  const std::size_t k = std::min(n - 1, static_cast<std::size_t>(rng.uniform() * static_cast<double>(n)));
  const int cell = free_cells_[k];
  const int row = cell / map_.width(), col = cell % map_.width();
  const double res = map_.resolution();
  const Eigen::Vector2d o = map_.origin();
  const double x = o.x() + (col + rng.uniform()) * res;
  const double y = o.y() + (row + rng.uniform()) * res;
  return {x, y, wrap_angle(kTwoPi * rng.uniform() - kPi)};
}

void MonteCarloLocalization::reset_particles(int n) {
  poses_.assign(static_cast<std::size_t>(n), Eigen::Vector3d::Zero());
  log_weights_.assign(static_cast<std::size_t>(n), -std::log(static_cast<double>(n)));
  rngs_.clear();
  rngs_.reserve(static_cast<std::size_t>(n));
  for (int j = 0; j < n; ++j) rngs_.emplace_back(options_.seed, next_stream_ + static_cast<std::uint64_t>(j));
  next_stream_ += static_cast<std::uint64_t>(n);
  pending_.setZero();
  travel_d_ = travel_a_ = 0.0;
  w_slow_ = w_fast_ = slow_raw_ = fast_raw_ = slow_mass_ = fast_mass_ = 0.0;
  random_fraction_ = 0.0;
  low_updates_ = 0;
  num_updates_ = 0;
}

void MonteCarloLocalization::initialize_global() {
  reset_particles(options_.max_particles);
  for (std::size_t j = 0; j < poses_.size(); ++j) poses_[j] = random_free_pose(rngs_[j]);
  compute_estimate();
}

void MonteCarloLocalization::check_pose_free(const Eigen::Vector3d& pose, const char* name) const {
  require_all_finite(pose, name);
  const Eigen::Vector2i rc = map_.cell_of(pose.x(), pose.y());
  require(map_.contains(rc[0], rc[1]), name, "lies outside the map");
  require(!is_occupied_or_outside(pose), name, "lies in an occupied cell");
}

void MonteCarloLocalization::initialize_pose(const Eigen::Vector3d& pose, const Eigen::Matrix3d& covariance) {
  check_pose_free(pose, "pose");
  require_all_finite(covariance, "covariance");
  const double scale = std::max(covariance.cwiseAbs().maxCoeff(), std::numeric_limits<double>::min());
  // Symmetry up to rounding of a matrix typed in or computed in double.
  constexpr double kSymmetryTolerance = 1e-9;
  require((covariance - covariance.transpose()).cwiseAbs().maxCoeff() <= kSymmetryTolerance * scale, "covariance",
          "must be symmetric");
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(covariance);
  require(eig.eigenvalues().minCoeff() >= -kSymmetryTolerance * scale, "covariance", "must be positive semi-definite");
  const Eigen::Matrix3d root =
      eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
  reset_particles(options_.max_particles);
  for (std::size_t j = 0; j < poses_.size(); ++j) {
    const Eigen::Vector3d n(rngs_[j].normal(), rngs_[j].normal(), rngs_[j].normal());
    Eigen::Vector3d x = pose + root * n;
    x.z() = wrap_angle(x.z());
    poses_[j] = x;
  }
  compute_estimate();
}

void MonteCarloLocalization::predict_odometry(const Eigen::Vector3d& delta) {
  require_all_finite(delta, "delta");
  const double step = std::hypot(delta.x(), delta.y());
  require(step <= kMaxOdometryTravel, "delta", "moves more than 1e6 m (kMaxOdometryTravel) in one step");
  const double c = std::cos(pending_.z()), s = std::sin(pending_.z());
  const Eigen::Vector3d next(pending_.x() + c * delta.x() - s * delta.y(), pending_.y() + s * delta.x() + c * delta.y(),
                             wrap_angle(pending_.z() + delta.z()));
  require(std::hypot(next.x(), next.y()) <= kMaxOdometryTravel, "delta",
          "would bring the motion pending since the last update beyond 1e6 m (kMaxOdometryTravel)");
  pending_ = next;
  travel_d_ += step;
  travel_a_ += std::abs(wrap_angle(delta.z()));
}

std::vector<int> MonteCarloLocalization::used_beams(const Eigen::Ref<const Eigen::VectorXd>& ranges) const {
  const bool keep_max = options_.sensor_model == MclSensorModel::kBeam;  // the beam model scores max readings
  std::vector<int> usable;
  for (Eigen::Index b = 0; b < ranges.size(); ++b) {
    const double r = ranges[b];
    if (r <= options_.min_range) continue;
    if (r >= options_.max_range && !keep_max) continue;
    usable.push_back(static_cast<int>(b));
  }
  const std::size_t n = usable.size(), m = static_cast<std::size_t>(options_.max_beams);
  if (n <= m) return usable;
  std::vector<int> out(m);
  for (std::size_t i = 0; i < m; ++i) out[i] = usable[i * n / m];
  return out;
}

double MonteCarloLocalization::scan_log_likelihood(const Eigen::Vector3d& pose,
                                                   const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                                   const Eigen::Ref<const Eigen::VectorXd>& angles,
                                                   const std::vector<int>& beams) const {
  if (beams.empty()) return 0.0;
  if (field_) {
    const double c = std::cos(pose.z()), s = std::sin(pose.z());
    double sum = 0.0;
    for (int b : beams) {
      const double lx = ranges[b] * std::cos(angles[b]), ly = ranges[b] * std::sin(angles[b]);
      const double x = pose.x() + c * lx - s * ly, y = pose.y() + s * lx + c * ly;
      sum += field_->cell_value(field_->row_of(y), field_->col_of(x));
    }
    return sum;
  }
  Eigen::VectorXd r(static_cast<Eigen::Index>(beams.size())), a(static_cast<Eigen::Index>(beams.size()));
  for (std::size_t i = 0; i < beams.size(); ++i) {
    r[static_cast<Eigen::Index>(i)] = std::min(ranges[beams[i]], options_.max_range);
    a[static_cast<Eigen::Index>(i)] = angles[beams[i]];
  }
  const Eigen::VectorXd lp = beam_model_->log_likelihoods(r, pose, a, *binary_map_);
  return lp.cwiseMax(kMinBeamLogProbability).sum();
}

namespace {
void check_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Ref<const Eigen::VectorXd>& angles) {
  require(ranges.size() > 0, "ranges", "must not be empty");
  require(ranges.allFinite(), "ranges", "must be finite (no NaN or inf)");
  require((ranges.array() >= 0.0).all(), "ranges", "must be >= 0");
  require(angles.size() == ranges.size(), "angles", "must have one entry per range");
  require_all_finite(angles, "angles");
}
}  // namespace

double MonteCarloLocalization::measurement_log_likelihood(const Eigen::Vector3d& pose,
                                                          const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                                          const Eigen::Ref<const Eigen::VectorXd>& angles) const {
  require_all_finite(pose, "pose");
  check_scan(ranges, angles);
  return scan_log_likelihood(pose, ranges, angles, used_beams(ranges));
}

void MonteCarloLocalization::start_pool() {
  try {
    pool_ = std::make_unique<WorkerPool>(static_cast<std::size_t>(options_.threads));
  } catch (const std::system_error& e) {
    throw std::invalid_argument("threads: the system refused to start " + std::to_string(options_.threads) +
                                " worker threads (" + e.what() + "); use fewer");
  }
}

template <class F>
void MonteCarloLocalization::for_range(int m, F&& f, int min_per_worker) {
  const int workers = std::min(options_.threads, std::max(1, m / min_per_worker));
  if (workers <= 1) {
    for (int j = 0; j < m; ++j) f(j);
    return;
  }
  if (!pool_ || static_cast<int>(pool_->size()) < options_.threads) start_pool();
  const int n = static_cast<int>(pool_->size());
  pool_->run([&](std::size_t w) {
    const int begin = static_cast<int>(static_cast<long long>(m) * static_cast<long long>(w) / n);
    const int end = static_cast<int>(static_cast<long long>(m) * static_cast<long long>(w + 1) / n);
    for (int j = begin; j < end; ++j) f(j);
  });
}

template <class F>
void MonteCarloLocalization::for_range_checked(int m, double cost, const std::function<void()>& interrupt, F&& f) {
  const double steps = std::max(cost, 1.0);
  const int per_worker =
      static_cast<int>(std::clamp(kMinWorkPerWorker / steps, 1.0, static_cast<double>(kMinParticlesPerWorker)));
  const int chunk = std::max(per_worker * options_.threads,
                             static_cast<int>(std::clamp(kWorkPerCheck / steps, 1.0, static_cast<double>(kMaxParticles))));
  for (int begin = 0; begin < m; begin += chunk) {
    if (interrupt) interrupt();
    const int count = std::min(chunk, m - begin);
    for_range(count, [&](int i) { f(begin + i); }, per_worker);
  }
}

double MonteCarloLocalization::scan_cost(std::size_t beams) const {
  const double n = static_cast<double>(std::max<std::size_t>(beams, 1));
  if (field_) return n;
  // A beam's ray walks at most max_range or the map's width plus height in cells.
  const double reach = std::min(options_.max_range / map_.resolution(), static_cast<double>(map_.width() + map_.height()));
  return n * std::max(reach, 1.0);
}

struct MonteCarloLocalization::FilterState {
  std::vector<Eigen::Vector3d> poses;
  std::vector<double> log_weights;
  std::vector<ParticleRng> rngs;
  ParticleRng filter_rng;
  std::uint64_t next_stream;
  Eigen::Vector3d pending;
  double travel_d, travel_a, w_slow, w_fast, slow_raw, fast_raw, slow_mass, fast_mass, random_fraction;
  int low_updates, num_updates;
  Eigen::Vector3d estimate;
  Eigen::Matrix3d covariance;
  double cluster_weight;
};

MonteCarloLocalization::FilterState MonteCarloLocalization::save_filter_state() const {
  return {poses_,     log_weights_, rngs_,     filter_rng_, next_stream_,     pending_,   travel_d_,
          travel_a_,  w_slow_,      w_fast_,   slow_raw_,   fast_raw_,        slow_mass_, fast_mass_,
          random_fraction_, low_updates_, num_updates_, estimate_, covariance_, cluster_weight_};
}

void MonteCarloLocalization::restore_filter_state(FilterState&& s) {
  poses_ = std::move(s.poses);
  log_weights_ = std::move(s.log_weights);
  rngs_ = std::move(s.rngs);
  filter_rng_ = s.filter_rng;
  next_stream_ = s.next_stream;
  pending_ = s.pending;
  travel_d_ = s.travel_d;
  travel_a_ = s.travel_a;
  w_slow_ = s.w_slow;
  w_fast_ = s.w_fast;
  slow_raw_ = s.slow_raw;
  fast_raw_ = s.fast_raw;
  slow_mass_ = s.slow_mass;
  fast_mass_ = s.fast_mass;
  random_fraction_ = s.random_fraction;
  low_updates_ = s.low_updates;
  num_updates_ = s.num_updates;
  estimate_ = s.estimate;
  covariance_ = s.covariance;
  cluster_weight_ = s.cluster_weight;
}

MclUpdate MonteCarloLocalization::update(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                         const Eigen::Ref<const Eigen::VectorXd>& angles, bool force,
                                         const std::function<void()>& interrupt) {
  check_scan(ranges, angles);
  MclUpdate out;
  out.num_particles = num_particles();
  const bool due = force || num_updates_ == 0 || travel_d_ >= options_.update_min_d ||
                   travel_a_ >= options_.update_min_a;
  if (!due) return out;
  if (options_.threads > 1 && !pool_ &&
      std::max(num_particles(), options_.recovery_candidates) >= 2 * kMinParticlesPerWorker)
    start_pool();  // may throw: nothing changed yet
  FilterState before = save_filter_state();
  try {
    return apply_update(ranges, angles, interrupt);
  } catch (...) {
    restore_filter_state(std::move(before));
    throw;
  }
}

MclUpdate MonteCarloLocalization::apply_update(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                               const Eigen::Ref<const Eigen::VectorXd>& angles,
                                               const std::function<void()>& interrupt) {
  MclUpdate out;
  const std::vector<int> beams = used_beams(ranges);
  const double cost = scan_cost(beams.size());
  const OdometryMotion u = OdometryMotion::of_delta(pending_);
  const bool moved = pending_.cwiseAbs().maxCoeff() > 0.0;
  std::vector<double> ll(poses_.size());
  for_range_checked(num_particles(), cost, interrupt, [&](int j) {
    const std::size_t k = static_cast<std::size_t>(j);
    if (moved) poses_[k] = sample_odometry_motion(poses_[k], u, options_.odometry, rngs_[k]);
    double l = options_.weight_scale * scan_log_likelihood(poses_[k], ranges, angles, beams);
    if (is_occupied_or_outside(poses_[k])) l += kBlockedLogPenalty;
    ll[k] = l;
    log_weights_[k] += l;
  });
  pending_.setZero();
  travel_d_ = travel_a_ = 0.0;
  ++num_updates_;
  out.updated = true;
  if (!beams.empty()) {
    // Table 8.3's w_avg on the per-beam geometric mean of each particle's likelihood: the
    // scan's product underflows, and the ratio w_fast / w_slow only needs a consistent scale.
    const double inv_beams = 1.0 / (options_.weight_scale * static_cast<double>(beams.size()));
    double w_avg = 0.0;
    for (double l : ll) w_avg += std::exp(l * inv_beams);
    w_avg /= static_cast<double>(ll.size());
    // Table 8.3 lines 8-9, each average divided by the weight its updates have had so far
    // (1 - (1 - alpha)^n): started from 0, w_slow would stay near 0 for ~1 / alpha_slow updates
    // (no recovery in that time); started from the first w_avg, it would keep the low
    // likelihood of the initial spread cloud as long.
    slow_raw_ += options_.alpha_slow * (w_avg - slow_raw_);
    fast_raw_ += options_.alpha_fast * (w_avg - fast_raw_);
    slow_mass_ += options_.alpha_slow * (1.0 - slow_mass_);
    fast_mass_ += options_.alpha_fast * (1.0 - fast_mass_);
    w_slow_ = slow_mass_ > 0.0 ? slow_raw_ / slow_mass_ : 0.0;
    w_fast_ = fast_mass_ > 0.0 ? fast_raw_ / fast_mass_ : 0.0;
  }
  const bool augmented = options_.alpha_slow > 0.0 && w_slow_ > 0.0;
  const double p_random = augmented ? std::max(0.0, 1.0 - w_fast_ / (options_.recovery_ratio * w_slow_)) : 0.0;
  if (!beams.empty()) low_updates_ = p_random > 0.0 ? low_updates_ + 1 : 0;
  const double n_eff = normalise_log_weights(log_weights_);
  out.effective_sample_size = n_eff;
  if (n_eff < options_.resample_threshold * static_cast<double>(num_particles())) {
    auto scan = [&](const Eigen::Vector3d& x) {
      return options_.weight_scale * scan_log_likelihood(x, ranges, angles, beams);
    };
    resample(low_updates_ >= options_.recovery_updates ? p_random : 0.0, scan, cost, interrupt);
    out.resampled = true;
  }
  compute_estimate();
  out.num_particles = num_particles();
  out.random_fraction = random_fraction_;
  return out;
}

template <class Scan>
void MonteCarloLocalization::resample(double random_probability, const Scan& scan, double scan_cost,
                                      const std::function<void()>& interrupt) {
  const int m = num_particles();
  // Recovery candidates, made on the first injection: poses uniform over the free cells and
  // the cumulative sum of their scan likelihoods, from which injected particles are drawn.
  std::vector<Eigen::Vector3d> candidates;
  std::vector<double> candidate_cdf;
  auto recovery_pose = [&]() -> Eigen::Vector3d {
    const int c = options_.recovery_candidates;
    if (c == 0) return random_free_pose(filter_rng_);
    if (candidates.empty()) {
      candidates.resize(static_cast<std::size_t>(c));
      for (auto& x : candidates) x = random_free_pose(filter_rng_);
      std::vector<double> ll(static_cast<std::size_t>(c));
      for_range_checked(c, scan_cost, interrupt, [&](int i) {
        const auto k = static_cast<std::size_t>(i);
        ll[k] = scan(candidates[k]);
      });
      const double top = *std::max_element(ll.begin(), ll.end());
      candidate_cdf.resize(ll.size());
      double sum = 0.0;
      for (std::size_t i = 0; i < ll.size(); ++i) candidate_cdf[i] = sum += std::exp(ll[i] - top);
    }
    const double u = filter_rng_.uniform() * candidate_cdf.back();
    const auto it = std::upper_bound(candidate_cdf.begin(), candidate_cdf.end(), u);
    return candidates[std::min(candidates.size() - 1, static_cast<std::size_t>(it - candidate_cdf.begin()))];
  };
  Eigen::VectorXd w(m);
  for (int j = 0; j < m; ++j) w[j] = std::exp(log_weights_[static_cast<std::size_t>(j)]);
  // Draws come from a low-variance pass over M ancestors, visited in a random order (so that
  // any prefix is a sample of the posterior, as KLD sampling's sequential draws need); another
  // pass starts when KLD asks for more than M.
  std::vector<int> ancestors;
  std::size_t next = 0;
  auto draw_ancestor = [&]() {
    if (next == ancestors.size()) {
      ancestors = low_variance_resample(w, filter_rng_.uniform());
      for (std::size_t i = ancestors.size(); i > 1; --i) {
        const std::size_t k = std::min(i - 1, static_cast<std::size_t>(filter_rng_.uniform() * static_cast<double>(i)));
        std::swap(ancestors[i - 1], ancestors[k]);
      }
      next = 0;
    }
    return ancestors[next++];
  };
  const double bin_theta = options_.bin_theta;
  auto bin_key = [&](const Eigen::Vector3d& x) {
    return std::make_tuple(bin_index(x.x() / options_.bin_xy), bin_index(x.y() / options_.bin_xy),
                           bin_index((x.z() + kPi) / bin_theta));
  };
  struct KeyHash {
    std::size_t operator()(const std::tuple<std::int64_t, std::int64_t, std::int64_t>& k) const {
      return static_cast<std::size_t>(mix64(static_cast<std::uint64_t>(std::get<0>(k)) * 0x9e3779b97f4a7c15ULL ^
                                            static_cast<std::uint64_t>(std::get<1>(k)) * 0xc2b2ae3d27d4eb4fULL ^
                                            static_cast<std::uint64_t>(std::get<2>(k))));
    }
  };
  std::unordered_map<std::tuple<std::int64_t, std::int64_t, std::int64_t>, int, KeyHash> bins;
  std::vector<Eigen::Vector3d> next_poses;
  int injected = 0;
  const int lo = options_.min_particles, hi = options_.max_particles;
  while (static_cast<int>(next_poses.size()) < hi) {
    const int n = static_cast<int>(next_poses.size());
    if (n >= lo && static_cast<double>(n) >= kld_bound(static_cast<int>(bins.size()), options_.kld_epsilon, options_.kld_z))
      break;
    Eigen::Vector3d x;
    if (random_probability > 0.0 && filter_rng_.uniform() < random_probability) {
      x = recovery_pose();
      ++injected;
    } else {
      x = poses_[static_cast<std::size_t>(draw_ancestor())];
    }
    bins.emplace(bin_key(x), 0);
    next_poses.push_back(x);
  }
  const int count = static_cast<int>(next_poses.size());
  // New particles, uniform weights and fresh streams; the odometry pending and the averages
  // of augmented MCL go on (Table 8.3 keeps them: the filter injects for as long as the short-term
  // average stays below the long-term one).
  poses_.swap(next_poses);
  log_weights_.assign(static_cast<std::size_t>(count), -std::log(static_cast<double>(count)));
  rngs_.clear();
  rngs_.reserve(static_cast<std::size_t>(count));
  for (int j = 0; j < count; ++j) rngs_.emplace_back(options_.seed, next_stream_ + static_cast<std::uint64_t>(j));
  next_stream_ += static_cast<std::uint64_t>(count);
  random_fraction_ = static_cast<double>(injected) / static_cast<double>(count);
}

void MonteCarloLocalization::compute_estimate() {
  const int m = num_particles();
  const double bin_theta = options_.bin_theta;
  const std::int64_t n_theta = bin_index(std::ceil(kTwoPi / bin_theta));
  using Key = std::tuple<std::int64_t, std::int64_t, std::int64_t>;
  struct KeyHash {
    std::size_t operator()(const Key& k) const {
      return static_cast<std::size_t>(mix64(static_cast<std::uint64_t>(std::get<0>(k)) * 0x9e3779b97f4a7c15ULL ^
                                            static_cast<std::uint64_t>(std::get<1>(k)) * 0xc2b2ae3d27d4eb4fULL ^
                                            static_cast<std::uint64_t>(std::get<2>(k))));
    }
  };
  std::unordered_map<Key, int, KeyHash> bin_of_key;
  std::vector<Key> keys;
  std::vector<int> particle_bin(static_cast<std::size_t>(m));
  std::vector<double> bin_weight;
  for (int j = 0; j < m; ++j) {
    const Eigen::Vector3d& x = poses_[static_cast<std::size_t>(j)];
    const Key k{bin_index(x.x() / options_.bin_xy), bin_index(x.y() / options_.bin_xy),
                std::min(n_theta - 1, bin_index((x.z() + kPi) / bin_theta))};
    auto it = bin_of_key.emplace(k, static_cast<int>(keys.size()));
    if (it.second) {
      keys.push_back(k);
      bin_weight.push_back(0.0);
    }
    particle_bin[static_cast<std::size_t>(j)] = it.first->second;
    bin_weight[static_cast<std::size_t>(it.first->second)] += std::exp(log_weights_[static_cast<std::size_t>(j)]);
  }
  // Connected components of occupied bins (26-neighbourhood, heading bins wrap around).
  const int nb = static_cast<int>(keys.size());
  std::vector<int> cluster(static_cast<std::size_t>(nb), -1);
  std::vector<double> cluster_weight;
  std::vector<int> stack;
  for (int b = 0; b < nb; ++b) {
    if (cluster[static_cast<std::size_t>(b)] >= 0) continue;
    const int c = static_cast<int>(cluster_weight.size());
    cluster_weight.push_back(0.0);
    cluster[static_cast<std::size_t>(b)] = c;
    stack.push_back(b);
    while (!stack.empty()) {
      const int cur = stack.back();
      stack.pop_back();
      cluster_weight[static_cast<std::size_t>(c)] += bin_weight[static_cast<std::size_t>(cur)];
      const Key& k = keys[static_cast<std::size_t>(cur)];
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dt = -1; dt <= 1; ++dt) {
            if (dx == 0 && dy == 0 && dt == 0) continue;
            const Key nk{std::get<0>(k) + dx, std::get<1>(k) + dy, ((std::get<2>(k) + dt) % n_theta + n_theta) % n_theta};
            const auto f = bin_of_key.find(nk);
            if (f == bin_of_key.end() || cluster[static_cast<std::size_t>(f->second)] >= 0) continue;
            cluster[static_cast<std::size_t>(f->second)] = c;
            stack.push_back(f->second);
          }
    }
  }
  const int best = static_cast<int>(std::max_element(cluster_weight.begin(), cluster_weight.end()) - cluster_weight.begin());
  double sw = 0.0, sx = 0.0, sy = 0.0, sc = 0.0, ss = 0.0;
  for (int j = 0; j < m; ++j) {
    if (cluster[static_cast<std::size_t>(particle_bin[static_cast<std::size_t>(j)])] != best) continue;
    const double w = std::exp(log_weights_[static_cast<std::size_t>(j)]);
    const Eigen::Vector3d& x = poses_[static_cast<std::size_t>(j)];
    sw += w;
    sx += w * x.x();
    sy += w * x.y();
    sc += w * std::cos(x.z());
    ss += w * std::sin(x.z());
  }
  estimate_ = Eigen::Vector3d(sx / sw, sy / sw, std::atan2(ss, sc));
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int j = 0; j < m; ++j) {
    if (cluster[static_cast<std::size_t>(particle_bin[static_cast<std::size_t>(j)])] != best) continue;
    const double w = std::exp(log_weights_[static_cast<std::size_t>(j)]);
    const Eigen::Vector3d& x = poses_[static_cast<std::size_t>(j)];
    const Eigen::Vector3d d(x.x() - estimate_.x(), x.y() - estimate_.y(), wrap_angle(x.z() - estimate_.z()));
    cov += w * d * d.transpose();
  }
  covariance_ = cov / sw;
  double total = 0.0;
  for (double w : cluster_weight) total += w;
  cluster_weight_ = total > 0.0 ? sw / total : 0.0;
}

Eigen::Vector3d MonteCarloLocalization::pose() const {
  const double c = std::cos(estimate_.z()), s = std::sin(estimate_.z());
  return {estimate_.x() + c * pending_.x() - s * pending_.y(), estimate_.y() + s * pending_.x() + c * pending_.y(),
          wrap_angle(estimate_.z() + pending_.z())};
}

Poses2 MonteCarloLocalization::particles() const {
  Poses2 out(num_particles(), 3);
  for (int j = 0; j < num_particles(); ++j) out.row(j) = poses_[static_cast<std::size_t>(j)].transpose();
  return out;
}

Eigen::VectorXd MonteCarloLocalization::weights() const {
  std::vector<double> lw = log_weights_;
  normalise_log_weights(lw);
  Eigen::VectorXd w(num_particles());
  for (int j = 0; j < num_particles(); ++j) w[j] = std::exp(lw[static_cast<std::size_t>(j)]);
  return w;
}

}  // namespace probslam
