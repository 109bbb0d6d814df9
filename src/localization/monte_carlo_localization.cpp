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
  validate_group(odometry, "odometry");
  require(std::isfinite(occupied_threshold) && occupied_threshold > 0.0 && occupied_threshold < 1.0,
          "occupied_threshold", "must lie in (0, 1)");
  require(std::isfinite(free_threshold) && free_threshold > 0.0 && free_threshold <= occupied_threshold,
          "free_threshold", "must lie in (0, occupied_threshold]");
  require(sigma >= LikelihoodFieldOptions::kMinSigma && sigma <= LikelihoodFieldOptions::kMaxSigma, "sigma",
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
  require(resample_interval >= 1 && resample_interval <= 1000000, "resample_interval", "must lie in [1, 10^6]");
  validate_group(update, "update");
  require(threads >= 1 && threads <= 1024, "threads", "must lie in [1, 1024]");
  // The beam mixture is checked whichever model is used (a NaN given for it is refused, not kept
  // unseen), with the sensor's max_range in place of its own, as the beam model is built.
  BeamMixture b = beam;
  b.max_range = max_range;
  validate_group(b, "beam");
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
    : options_(options), map_(map) {
  options_.validate();
  f_.filter_rng = ParticleRng(options.seed, kFilterStream);
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
    lf.sigma = options_.sigma;
    lf.p_rand = options_.p_rand;
    lf.occupied_threshold = options_.occupied_threshold;
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
      f_(o.f_) {}

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
  f_.poses.assign(static_cast<std::size_t>(n), Eigen::Vector3d::Zero());
  f_.log_weights.assign(static_cast<std::size_t>(n), -std::log(static_cast<double>(n)));
  f_.rngs.clear();
  f_.rngs.reserve(static_cast<std::size_t>(n));
  for (int j = 0; j < n; ++j) f_.rngs.emplace_back(options_.seed, f_.next_stream + static_cast<std::uint64_t>(j));
  f_.next_stream += static_cast<std::uint64_t>(n);
  f_.pending.setZero();
  f_.travel_d = f_.travel_a = 0.0;
  f_.w_slow = f_.w_fast = f_.slow_raw = f_.fast_raw = f_.slow_mass = f_.fast_mass = 0.0;
  f_.random_fraction = 0.0;
  f_.low_updates = 0;
  f_.num_updates = 0;
}

void MonteCarloLocalization::initialize_global() {
  reset_particles(options_.max_particles);
  for (std::size_t j = 0; j < f_.poses.size(); ++j) f_.poses[j] = random_free_pose(f_.rngs[j]);
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
  for (std::size_t j = 0; j < f_.poses.size(); ++j) {
    const Eigen::Vector3d n(f_.rngs[j].normal(), f_.rngs[j].normal(), f_.rngs[j].normal());
    Eigen::Vector3d x = pose + root * n;
    x.z() = wrap_angle(x.z());
    f_.poses[j] = x;
  }
  compute_estimate();
}

void MonteCarloLocalization::predict_odometry(const Eigen::Vector3d& delta) {
  require_all_finite(delta, "delta");
  const double step = std::hypot(delta.x(), delta.y());
  require(step <= kMaxOdometryTravel, "delta", "moves more than 1e6 m (kMaxOdometryTravel) in one step");
  const double c = std::cos(f_.pending.z()), s = std::sin(f_.pending.z());
  const Eigen::Vector3d next(f_.pending.x() + c * delta.x() - s * delta.y(), f_.pending.y() + s * delta.x() + c * delta.y(),
                             wrap_angle(f_.pending.z() + delta.z()));
  require(std::hypot(next.x(), next.y()) <= kMaxOdometryTravel, "delta",
          "would bring the motion pending since the last update beyond 1e6 m (kMaxOdometryTravel)");
  f_.pending = next;
  f_.travel_d += step;
  f_.travel_a += std::abs(wrap_angle(delta.z()));
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

MclUpdate MonteCarloLocalization::update(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                         const Eigen::Ref<const Eigen::VectorXd>& angles, bool force,
                                         const std::function<void()>& interrupt) {
  check_scan(ranges, angles);
  MclUpdate out;
  out.num_particles = num_particles();
  const bool due = force || f_.num_updates == 0 || options_.update.reached(f_.travel_d, f_.travel_a);
  if (!due) return out;
  if (options_.threads > 1 && !pool_ &&
      std::max(num_particles(), options_.recovery_candidates) >= 2 * kMinParticlesPerWorker)
    start_pool();  // may throw: nothing changed yet
  FilterState before = f_;
  try {
    return apply_update(ranges, angles, interrupt);
  } catch (...) {
    f_ = std::move(before);
    throw;
  }
}

MclUpdate MonteCarloLocalization::apply_update(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                               const Eigen::Ref<const Eigen::VectorXd>& angles,
                                               const std::function<void()>& interrupt) {
  MclUpdate out;
  const std::vector<int> beams = used_beams(ranges);
  const double cost = scan_cost(beams.size());
  const OdometryMotion u = OdometryMotion::of_delta(f_.pending);
  const bool moved = f_.pending.cwiseAbs().maxCoeff() > 0.0;
  std::vector<double> ll(f_.poses.size());
  for_range_checked(num_particles(), cost, interrupt, [&](int j) {
    const std::size_t k = static_cast<std::size_t>(j);
    if (moved) f_.poses[k] = sample_odometry_motion(f_.poses[k], u, options_.odometry, f_.rngs[k]);
    double l = options_.weight_scale * scan_log_likelihood(f_.poses[k], ranges, angles, beams);
    if (is_occupied_or_outside(f_.poses[k])) l += kBlockedLogPenalty;
    ll[k] = l;
    f_.log_weights[k] += l;
  });
  f_.pending.setZero();
  f_.travel_d = f_.travel_a = 0.0;
  ++f_.num_updates;
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
    f_.slow_raw += options_.alpha_slow * (w_avg - f_.slow_raw);
    f_.fast_raw += options_.alpha_fast * (w_avg - f_.fast_raw);
    f_.slow_mass += options_.alpha_slow * (1.0 - f_.slow_mass);
    f_.fast_mass += options_.alpha_fast * (1.0 - f_.fast_mass);
    f_.w_slow = f_.slow_mass > 0.0 ? f_.slow_raw / f_.slow_mass : 0.0;
    f_.w_fast = f_.fast_mass > 0.0 ? f_.fast_raw / f_.fast_mass : 0.0;
  }
  const bool augmented = options_.alpha_slow > 0.0 && f_.w_slow > 0.0;
  const double p_random = augmented ? std::max(0.0, 1.0 - f_.w_fast / (options_.recovery_ratio * f_.w_slow)) : 0.0;
  if (!beams.empty()) f_.low_updates = p_random > 0.0 ? f_.low_updates + 1 : 0;
  const double n_eff = normalise_log_weights(f_.log_weights);
  out.effective_sample_size = n_eff;
  const bool interval_due = f_.num_updates % options_.resample_interval == 0;
  if (interval_due && n_eff < options_.resample_threshold * static_cast<double>(num_particles())) {
    auto scan = [&](const Eigen::Vector3d& x) {
      return options_.weight_scale * scan_log_likelihood(x, ranges, angles, beams);
    };
    resample(f_.low_updates >= options_.recovery_updates ? p_random : 0.0, scan, cost, interrupt);
    out.resampled = true;
  }
  compute_estimate();
  out.num_particles = num_particles();
  out.random_fraction = f_.random_fraction;
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
    if (c == 0) return random_free_pose(f_.filter_rng);
    if (candidates.empty()) {
      candidates.resize(static_cast<std::size_t>(c));
      for (auto& x : candidates) x = random_free_pose(f_.filter_rng);
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
    const double u = f_.filter_rng.uniform() * candidate_cdf.back();
    const auto it = std::upper_bound(candidate_cdf.begin(), candidate_cdf.end(), u);
    return candidates[std::min(candidates.size() - 1, static_cast<std::size_t>(it - candidate_cdf.begin()))];
  };
  Eigen::VectorXd w(m);
  for (int j = 0; j < m; ++j) w[j] = std::exp(f_.log_weights[static_cast<std::size_t>(j)]);
  // Draws come from a low-variance pass over M ancestors, visited in a random order (so that
  // any prefix is a sample of the posterior, as KLD sampling's sequential draws need); another
  // pass starts when KLD asks for more than M.
  std::vector<int> ancestors;
  std::size_t next = 0;
  auto draw_ancestor = [&]() {
    if (next == ancestors.size()) {
      ancestors = low_variance_resample(w, f_.filter_rng.uniform());
      for (std::size_t i = ancestors.size(); i > 1; --i) {
        const std::size_t k = std::min(i - 1, static_cast<std::size_t>(f_.filter_rng.uniform() * static_cast<double>(i)));
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
    if (random_probability > 0.0 && f_.filter_rng.uniform() < random_probability) {
      x = recovery_pose();
      ++injected;
    } else {
      x = f_.poses[static_cast<std::size_t>(draw_ancestor())];
    }
    bins.emplace(bin_key(x), 0);
    next_poses.push_back(x);
  }
  const int count = static_cast<int>(next_poses.size());
  // New particles, uniform weights and fresh streams; the odometry pending and the averages
  // of augmented MCL go on (Table 8.3 keeps them: the filter injects for as long as the short-term
  // average stays below the long-term one).
  f_.poses.swap(next_poses);
  f_.log_weights.assign(static_cast<std::size_t>(count), -std::log(static_cast<double>(count)));
  f_.rngs.clear();
  f_.rngs.reserve(static_cast<std::size_t>(count));
  for (int j = 0; j < count; ++j) f_.rngs.emplace_back(options_.seed, f_.next_stream + static_cast<std::uint64_t>(j));
  f_.next_stream += static_cast<std::uint64_t>(count);
  f_.random_fraction = static_cast<double>(injected) / static_cast<double>(count);
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
    const Eigen::Vector3d& x = f_.poses[static_cast<std::size_t>(j)];
    const Key k{bin_index(x.x() / options_.bin_xy), bin_index(x.y() / options_.bin_xy),
                std::min(n_theta - 1, bin_index((x.z() + kPi) / bin_theta))};
    auto it = bin_of_key.emplace(k, static_cast<int>(keys.size()));
    if (it.second) {
      keys.push_back(k);
      bin_weight.push_back(0.0);
    }
    particle_bin[static_cast<std::size_t>(j)] = it.first->second;
    bin_weight[static_cast<std::size_t>(it.first->second)] += std::exp(f_.log_weights[static_cast<std::size_t>(j)]);
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
    const double w = std::exp(f_.log_weights[static_cast<std::size_t>(j)]);
    const Eigen::Vector3d& x = f_.poses[static_cast<std::size_t>(j)];
    sw += w;
    sx += w * x.x();
    sy += w * x.y();
    sc += w * std::cos(x.z());
    ss += w * std::sin(x.z());
  }
  f_.estimate = Eigen::Vector3d(sx / sw, sy / sw, std::atan2(ss, sc));
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int j = 0; j < m; ++j) {
    if (cluster[static_cast<std::size_t>(particle_bin[static_cast<std::size_t>(j)])] != best) continue;
    const double w = std::exp(f_.log_weights[static_cast<std::size_t>(j)]);
    const Eigen::Vector3d& x = f_.poses[static_cast<std::size_t>(j)];
    const Eigen::Vector3d d(x.x() - f_.estimate.x(), x.y() - f_.estimate.y(), wrap_angle(x.z() - f_.estimate.z()));
    cov += w * d * d.transpose();
  }
  f_.covariance = cov / sw;
  double total = 0.0;
  for (double w : cluster_weight) total += w;
  f_.cluster_weight = total > 0.0 ? sw / total : 0.0;
}

Eigen::Vector3d MonteCarloLocalization::pose() const {
  const double c = std::cos(f_.estimate.z()), s = std::sin(f_.estimate.z());
  return {f_.estimate.x() + c * f_.pending.x() - s * f_.pending.y(), f_.estimate.y() + s * f_.pending.x() + c * f_.pending.y(),
          wrap_angle(f_.estimate.z() + f_.pending.z())};
}

Poses2 MonteCarloLocalization::poses() const {
  Poses2 out(num_particles(), 3);
  for (int j = 0; j < num_particles(); ++j) out.row(j) = f_.poses[static_cast<std::size_t>(j)].transpose();
  return out;
}

Eigen::VectorXd MonteCarloLocalization::weights() const {
  std::vector<double> lw = f_.log_weights;
  normalise_log_weights(lw);
  Eigen::VectorXd w(num_particles());
  for (int j = 0; j < num_particles(); ++j) w[j] = std::exp(lw[static_cast<std::size_t>(j)]);
  return w;
}

}  // namespace probslam
