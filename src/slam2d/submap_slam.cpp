#include "probslam/slam2d/submap_slam.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <list>
#include <functional>
#include <map>
#include <unordered_map>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/chi_square.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/pose2_covariance.hpp"
#include "probslam/slam2d/cpu_clock.hpp"
#include "probslam/slam2d/scan_batch.hpp"
#include "probslam/slam2d/start_map.hpp"

namespace probslam {

namespace {

/// A window half-width wider than 2^kSearchLevels cells starts with several top-level nodes;
/// 8 levels (12.8 m at 5 cm) cover the largest default window with one.
constexpr int kSearchLevels = 8;
/// A best pose this close to the window's edge (in cells or angular steps) may be the edge of
/// a peak that lies outside: such a match is not trusted as a closure.
constexpr double kEdgeCells = 1.0;
/// Added to the variances of a consecutive constraint: keeps its information finite should a
/// submap's chain ever have zero covariance (odometry floors make that impossible today).
constexpr double kMinConstraintVariance = 1e-9;
/// The quality test is made at the refined pose and the minimum score on the lattice: a lattice
/// pose a fraction of a cell off scores lower, so the bound is loosened by this factor.
constexpr double kClosureScoreSlack = 1.25;
/// Scans with fewer hits than this are not used for closures: too few to tell places apart.
constexpr int kMinClosurePoints = 30;

Pose2 pose_of(const Eigen::Vector3d& v) { return Pose2::from_vector(v); }

double largest_eigenvalue(const Eigen::Matrix2d& m) {
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(0.5 * (m + m.transpose())).eigenvalues()(1);
}

/// A relative pose (x, y, theta) with its covariance, to first order.
struct Leg {
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
};

Leg then(const Leg& a, const Leg& b) {
  return {pose_of(a.pose).compose(pose_of(b.pose)).vector(), compose_covariance(a.pose, a.cov, b.pose, b.cov)};
}

Leg inverted(const Leg& a) {
  const Eigen::Matrix3d J = inverse_jacobian(a.pose);
  return {pose_of(a.pose).inverse().vector(), J * a.cov * J.transpose()};
}

/// chi2 of a cycle's composition against the identity; 0 when its covariance is singular (no
/// evidence against it).
double cycle_chi2(const Leg& c) {
  Eigen::Vector3d e = c.pose;
  e.z() = wrap_angle(e.z());
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(0.5 * (c.cov + c.cov.transpose()));
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0.0).all()) return 0.0;
  return e.dot(ldlt.solve(e));
}

/// The consecutive constraints composed between any two submaps: what the odometry and the
/// frontend alone say of their relative pose, independent of every closure. The legs from a
/// start are built once, when first asked for.
class ChainLegs {
 public:
  explicit ChainLegs(const std::vector<SubmapConstraint>& constraints) {
    for (const SubmapConstraint& c : constraints) {
      if (c.loop) continue;
      if (static_cast<int>(steps_.size()) <= c.from) steps_.resize(static_cast<std::size_t>(c.from) + 1);
      steps_[static_cast<std::size_t>(c.from)] = {c.measurement, c.covariance};
    }
  }
  /// Submap b's origin seen from submap a's along the chain.
  Leg operator()(int a, int b) {
    if (a > b) return inverted((*this)(b, a));
    std::vector<Leg>& legs = from_[a];
    if (legs.empty()) {
      legs.emplace_back();
      for (std::size_t k = static_cast<std::size_t>(a); k < steps_.size(); ++k) legs.push_back(then(legs.back(), steps_[k]));
    }
    return legs[static_cast<std::size_t>(b - a)];
  }

 private:
  std::vector<Leg> steps_;  // k -> k + 1
  std::unordered_map<int, std::vector<Leg>> from_;
};

Leg leg_of(const SubmapConstraint& c) { return {c.measurement, c.covariance}; }

/// chi2 of the cycle two closures close with the chain: from a's submap to its scan's along a,
/// on along the chain to b's scan's submap, back along b, and along the chain to the start
/// (pairwise consistency, Mangelson et al. 2018's PCM; RRR's inter-cluster test). Where the two
/// chain legs share submaps (travelled both ways) their errors cancel, but the legs are composed
/// as independent: the spread is overstated there, so the test errs towards consistency.
double pair_chi2(const SubmapConstraint& a, const SubmapConstraint& b, ChainLegs& chain) {
  return cycle_chi2(then(then(then(leg_of(a), chain(a.to, b.to)), inverted(leg_of(b))), chain(b.from, a.from)));
}

/// chi2 of a closure against the chain between its submaps alone.
double chain_chi2(const SubmapConstraint& c, ChainLegs& chain) { return cycle_chi2(then(leg_of(c), chain(c.to, c.from))); }

}  // namespace

/// The likelihood fields (with their pyramids) of finished submaps, built on first use and
/// evicted least recently used beyond a byte budget: a long log has hundreds of submaps.
class SubmapSlam2D::FieldCache {
 public:
  explicit FieldCache(double budget) : budget_(budget) {}

  /// The field of `submap` with pyramid levels up to `levels` at least: built by `build(levels)`
  /// unless cached, a cached one deepened when it has fewer.
  CorrelativeScanMatcher& get(int submap, int levels, int width, int height,
                              const std::function<CorrelativeScanMatcher(int)>& build) {
    const auto it = entries_.find(submap);
    if (it != entries_.end()) {
      order_.splice(order_.begin(), order_, it->second.position);
      Entry& e = it->second;
      if (e.matcher->max_level() < levels) {
        const double bytes = CorrelativeScanMatcher::bytes_for(width, height, levels);
        make_room(bytes - e.bytes, submap);
        e.matcher->extend_levels(levels);
        used_ += bytes - e.bytes;
        e.bytes = bytes;
      }
      return *e.matcher;
    }
    // Room is made before the build, so that the cache never holds more than its budget and
    // the field being built (the field's size is known from the cells it is built from).
    const double bytes = CorrelativeScanMatcher::bytes_for(width, height, levels);
    make_room(bytes, -1);
    auto matcher = std::make_shared<CorrelativeScanMatcher>(build(levels));
    order_.push_front(submap);
    entries_[submap] = Entry{matcher, bytes, order_.begin()};
    used_ += bytes;
    return *matcher;
  }

  double used() const { return used_; }

  /// Evicts the least recently used fields (never `keep`) until `bytes` more fit the budget.
  void make_room(double bytes, int keep) {
    for (auto it = order_.end(); used_ + bytes > budget_ && it != order_.begin();) {
      --it;
      if (*it == keep) continue;
      used_ -= entries_[*it].bytes;
      entries_.erase(*it);
      it = order_.erase(it);
    }
  }

  /// Forgets the fields of submaps `first` and later (a batch undone: they may change again).
  void forget_from(int first) {
    for (auto it = order_.begin(); it != order_.end();) {
      if (*it < first) {
        ++it;
        continue;
      }
      used_ -= entries_[*it].bytes;
      entries_.erase(*it);
      it = order_.erase(it);
    }
  }

 private:
  struct Entry {
    std::shared_ptr<CorrelativeScanMatcher> matcher;
    double bytes;
    std::list<int>::iterator position;
  };
  double budget_, used_ = 0.0;
  std::list<int> order_;  // most recent first
  std::unordered_map<int, Entry> entries_;
};

void LoopClosureOptions::validate() const {
  require(scans_per_submap >= 1, "scans_per_submap", "must be >= 1");
  require(std::isfinite(min_match_quality) && min_match_quality >= 0.0 && min_match_quality <= 1.0,
          "min_match_quality", "must be in [0, 1]");
  require_positive(window_sigmas, "window_sigmas");
  require(std::isfinite(min_linear_window) && min_linear_window >= 0.0, "min_linear_window", "must be finite and >= 0");
  require(std::isfinite(max_linear_window) && max_linear_window >= min_linear_window, "max_linear_window",
          "must be finite and >= min_linear_window");
  require(std::isfinite(min_angular_window) && min_angular_window >= 0.0, "min_angular_window",
          "must be finite and >= 0");
  require(max_angular_window >= min_angular_window && max_angular_window <= kPi, "max_angular_window",
          "must lie in [min_angular_window, pi]");
  require_positive(max_distance, "max_distance");
  require_positive(dissolve_chi2, "dissolve_chi2");
  require_positive(field_cache_bytes, "field_cache_bytes");
}

OptimizerOptions SubmapSlamOptions::default_optimizer() {
  OptimizerOptions o;
  o.algorithm = OptimizerAlgorithm::kLevenbergMarquardt;
  o.kernel = RobustKernel::kHuber;
  o.kernel_width = std::sqrt(7.81);  // the 95% quantile of chi2 with 3 dof
  o.max_iterations = 50;
  o.relative_tolerance = 1e-9;
  return o;
}

IncrementalScanMatcherOptions SubmapSlamOptions::default_frontend() {
  IncrementalScanMatcherOptions o;
  o.submap_distance = 10.0;
  return o;
}

void SubmapSlamOptions::validate() const {
  validate_group(frontend, "frontend");
  validate_group(closures, "closures");
  validate_group(optimizer, "optimizer");
  require(max_rounds >= 1, "max_rounds", "must be >= 1");
}

SubmapSlam2D::SubmapSlam2D(const SubmapSlamOptions& options)
    : options_((options.validate(), options)),
      frontend_(options.frontend),
      fields_(std::make_unique<FieldCache>(options.closures.field_cache_bytes)) {}

SubmapSlam2D::SubmapSlam2D(const SubmapSlam2D& other)
    : options_(other.options_),
      frontend_(other.frontend_),
      points_(other.points_),
      offset_cov_(other.offset_cov_),
      nodes_(other.nodes_),
      constraints_(other.constraints_),
      ranges_(other.ranges_),
      angles_(other.angles_),
      closure_cells_(other.closure_cells_),
      timings_(other.timings_),
      map_seconds_(other.map_seconds_),
      chain_pose_(other.chain_pose_),
      chain_cov_(other.chain_cov_),
      chain_submap_(other.chain_submap_),
      attempts_(other.attempts_),
      fields_(std::make_unique<FieldCache>(other.options_.closures.field_cache_bytes)),
      counts_(other.counts_),
      start_map_(other.start_map_),
      start_map_bounds_(other.start_map_bounds_) {}

SubmapSlam2D::~SubmapSlam2D() = default;

void SubmapSlam2D::start_from_map(const OccupancyGrid2D& map, const Eigen::Vector3d& initial_pose) {
  frontend_.start_from_map(map, initial_pose);  // checks everything first; nothing changed if it throws
  set_start_map(map);
}

void SubmapSlam2D::set_start_map(const OccupancyGrid2D& map) {
  start_map_ = map;
  start_map_bounds_ = occupied_bounds(map);  // where a scan can close a loop onto the map
}

void SubmapSlam2D::add_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                            const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const Eigen::Vector3d& odometry,
                            double timestamp) {
  check_scan(ranges, beam_angles, odometry, timestamp);
  IncrementalScanMatcher::PendingScan scan = frontend_.prepare(ranges, beam_angles, odometry, timestamp);
  // Within add_scans the batch's snapshot restores this scan too: a second copy of the open
  // submap's grid would only raise the peak memory.
  if (!scan.open_next || in_batch_) {
    add_prepared(std::move(scan), ranges, beam_angles);
    return;
  }
  // This scan finishes a submap: the search and optimisation that follow may fail on the
  // graph's state; undone from a snapshot taken once per submap, not per scan.
  Snapshot before = snapshot();
  try {
    add_prepared(std::move(scan), ranges, beam_angles);
  } catch (...) {
    restore(std::move(before));
    throw;
  }
}

void SubmapSlam2D::add_prepared(IncrementalScanMatcher::PendingScan&& scan, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                const Eigen::Ref<const Eigen::VectorXd>& beam_angles) {
  const std::size_t submaps_before = frontend_.submaps().size();
  Points2 hits = std::move(scan.hits);  // the frontend's filtering, not repeated
  const ScanEstimate est = frontend_.commit(std::move(scan));
  points_.push_back(std::move(hits));
  ranges_.emplace_back(ranges);
  keep_angles(beam_angles);
  // The scan's offset from its submap's origin, and its covariance along the chain of matches.
  const int index = frontend_.num_scans() - 1;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  if (est.submap >= 0 && index > 0 && est.submap == chain_submap_) {
    const Eigen::Vector3d origin = frontend_.submaps()[est.submap].origin;
    const Eigen::Vector3d prev = pose_of(origin).between(pose_of(chain_pose_)).vector();
    const Eigen::Vector3d step = pose_of(chain_pose_).between(pose_of(est.pose)).vector();
    cov = compose_covariance(prev, chain_cov_, step, est.relative_covariance);
  } else if (index == 0 && start_map_) {
    cov = est.relative_covariance;  // matched against the map, whose origin is submap 0's
  }
  offset_cov_.push_back(cov);
  if (est.submap >= 0) {
    chain_pose_ = est.pose;
    chain_cov_ = cov;
    chain_submap_ = est.submap;
  }
  if (nodes_.empty()) nodes_.push_back(frontend_.submaps()[0].origin);
  if (frontend_.submaps().size() > submaps_before && submaps_before > 0) {
    // This scan completed submap `submaps_before - 1` and opened the next one at its pose.
    link_finished_submap(static_cast<int>(submaps_before) - 1);
    chain_pose_ = est.pose;
    chain_cov_.setZero();
    chain_submap_ = static_cast<int>(submaps_before);
  }
}

void SubmapSlam2D::keep_angles(const Eigen::Ref<const Eigen::VectorXd>& beam_angles) {
  if (!angles_.empty() && *angles_.back() == beam_angles) {
    angles_.push_back(angles_.back());
  } else {
    angles_.push_back(std::make_shared<const Eigen::VectorXd>(beam_angles));
  }
}

void SubmapSlam2D::add_scans(const Eigen::Ref<const RowMatrixXd>& ranges, const Eigen::Ref<const RowMatrixXd>& beam_angles,
                             const Eigen::Ref<const RowMatrixXd>& odometry,
                             const Eigen::Ref<const Eigen::VectorXd>& timestamps) {
  struct Batch {  // reset however the batch ends
    bool& flag;
    ~Batch() { flag = false; }
  } batch{in_batch_};
  in_batch_ = ranges.rows() > 1;  // one row: add_scan alone, no batch snapshot (add_scan_rows)
  add_scan_rows(*this, ranges, beam_angles, odometry, timestamps);
}

SubmapSlam2D::Snapshot SubmapSlam2D::snapshot() const {
  return Snapshot{frontend_.snapshot(), points_.size(), nodes_, constraints_, chain_pose_, chain_cov_, chain_submap_,
                  attempts_, counts_};
}

void SubmapSlam2D::restore(Snapshot&& s) {
  const int open = static_cast<int>(s.frontend.submaps) - 1;
  frontend_.restore(std::move(s.frontend));
  closure_cells_.resize(static_cast<std::size_t>(std::max(0, open)));  // the open one's grid is back
  points_.resize(s.scans);
  offset_cov_.resize(s.scans);
  ranges_.resize(s.scans);
  angles_.resize(s.scans);
  nodes_ = std::move(s.nodes);
  constraints_ = std::move(s.constraints);
  chain_pose_ = s.chain_pose;
  chain_cov_ = s.chain_cov;
  chain_submap_ = s.chain_submap;
  attempts_ = std::move(s.attempts);
  counts_ = s.counts;
  fields_->forget_from(std::max(0, open));  // the open submap and later ones may be rebuilt differently
}

void SubmapSlam2D::link_finished_submap(int j) {
  const auto& submaps = frontend_.submaps();
  const Eigen::Vector3d z = pose_of(submaps[j].origin).between(pose_of(submaps[j + 1].origin)).vector();
  SubmapConstraint c;
  c.from = j;
  c.to = j + 1;
  c.measurement = z;
  // The boundary scan's covariance from submap j's origin; a floor keeps it invertible when
  // every scan in between fell back to a zero-motion prior (it never does: odometry has floors).
  c.covariance = chain_cov_ + kMinConstraintVariance * Eigen::Matrix3d::Identity();
  constraints_.push_back(c);
  nodes_.push_back(pose_of(nodes_[j]).compose(pose_of(z)).vector());
  keep_closure_cells(j);
  const int dissolved = counts_.closures_dissolved;  // an active closure outvoted: the graph changed too
  if (options_.closures.enabled && (search_closures(j) > 0 || counts_.closures_dissolved != dissolved))
    optimize_and_dissolve();
}

void SubmapSlam2D::keep_closure_cells(int j) {
  // A finished submap's grid (12 bytes a cell, sized for the sensor's reach around every scan)
  // is only read again to build its loop-closure field, which needs one bit of each cell in its
  // region: keeping that (a byte a cell) and freeing the grid takes a long log from gigabytes
  // to megabytes (docs/performance.md). The field built from it is from_grid's, value for value.
  closure_cells_.resize(static_cast<std::size_t>(j));  // one link per submap, in order: a no-op
  closure_cells_.push_back(LikelihoodField::obstacles_of(frontend_.submaps()[j].grid, closure_region(j),
                                                         options_.frontend.field.occupied_threshold));
  frontend_.release_grid(j);
}

int SubmapSlam2D::search_closures(int j) {
  if (j < 2) return 0;
  const ScopedCpuTimer timer(timings_.closure_search);
  const std::vector<ScanEstimate>& est = frontend_.estimates();
  std::vector<int> candidates;
  for (int s : frontend_.submaps()[j].scans)
    if (est[s].submap == j && points_[s].rows() >= kMinClosurePoints) candidates.push_back(s);
  if (candidates.empty()) return 0;
  const PoseGraph2D g = graph();
  std::vector<int> ids(static_cast<std::size_t>(j) + 1);
  for (int k = 0; k <= j; ++k) ids[k] = k;
  std::vector<Eigen::Matrix3d> marginals;
  for (const Eigen::MatrixXd& m : marginal_covariances(g, ids, options_.optimizer.linear_solver))
    marginals.push_back(m);
  const int n = std::min<int>(options_.closures.scans_per_submap, static_cast<int>(candidates.size()));
  // Submap by submap, so that each field is wanted once per search, not once per scan (a cache
  // smaller than the submaps searched would rebuild every field n times); the closures found
  // are added scan by scan, the order of old, which the optimiser's sums depend on.
  std::vector<std::vector<SubmapConstraint>> found(static_cast<std::size_t>(n));
  for (int i = 0; i + 2 <= j; ++i)
    for (int q = 0; q < n; ++q) {
      const int s = candidates[static_cast<std::size_t>((q + 0.5) * candidates.size() / n)];
      if (auto c = try_closure(s, i, marginals)) found[static_cast<std::size_t>(q)].push_back(*c);
    }
  std::vector<SubmapConstraint> all;
  for (const std::vector<SubmapConstraint>& f : found) all.insert(all.end(), f.begin(), f.end());
  return add_consistent(all);
}

int SubmapSlam2D::add_consistent(const std::vector<SubmapConstraint>& found) {
  if (found.empty()) return 0;
  // Each closure passed the graph's gate alone; two look-alike places can each pass it and
  // still contradict each other by metres (two closures of one submap pair that cannot both
  // hold). Every pair of closures, the new against the active and each other, must close its
  // cycle over the consecutive chain within dissolve_chi2 (the same 99.9% quantile of chi2(3)
  // the optimised graph dissolves at); where pairs conflict, the closure in most conflicts goes
  // first (a greedy largest consistent set, as PCM's heuristic clique), on a tie the one the
  // chain between its own submaps agrees with least.
  const double gate = options_.closures.dissolve_chi2;
  const std::size_t first_new = constraints_.size();
  constraints_.insert(constraints_.end(), found.begin(), found.end());
  std::vector<std::size_t> members;  // the active closures, then the new ones
  for (std::size_t k = 0; k < constraints_.size(); ++k)
    if (constraints_[k].loop && constraints_[k].active) members.push_back(k);
  ChainLegs chain(constraints_);
  std::vector<std::vector<std::size_t>> conflicts(members.size());
  for (std::size_t a = 0; a < members.size(); ++a) {
    if (members[a] < first_new) continue;  // the active ones agree with each other already
    for (std::size_t b = 0; b < a; ++b)
      if (pair_chi2(constraints_[members[a]], constraints_[members[b]], chain) > gate) {
        conflicts[a].push_back(b);
        conflicts[b].push_back(a);
      }
  }
  std::vector<int> live(members.size());
  std::vector<double> own(members.size(), -1.0);
  for (std::size_t a = 0; a < members.size(); ++a) live[a] = static_cast<int>(conflicts[a].size());
  std::vector<bool> dropped(members.size(), false);
  for (std::size_t a = 0; a < members.size(); ++a) {
    if (members[a] < first_new) continue;
    own[a] = chain_chi2(constraints_[members[a]], chain);
    if (own[a] <= gate) continue;
    dropped[a] = true;
    for (std::size_t b : conflicts[a]) --live[b];
    constraints_[members[a]].active = false;
    ++counts_.closures_rejected;
  }
  for (;;) {
    std::size_t worst = members.size();
    for (std::size_t a = 0; a < members.size(); ++a) {
      if (dropped[a] || live[a] == 0) continue;
      if (own[a] < 0.0) own[a] = chain_chi2(constraints_[members[a]], chain);
      if (worst == members.size() || live[a] > live[worst] || (live[a] == live[worst] && own[a] > own[worst]))
        worst = a;
    }
    if (worst == members.size()) break;
    dropped[worst] = true;
    for (std::size_t b : conflicts[worst])
      if (!dropped[b]) --live[b];
    constraints_[members[worst]].active = false;
    if (members[worst] < first_new) {
      ++counts_.closures_dissolved;
    } else {
      ++counts_.closures_rejected;
    }
  }
  // The new closures refused are not kept; an active one outvoted stays, dissolved.
  int kept = 0;
  std::vector<SubmapConstraint> rest(constraints_.begin(), constraints_.begin() + static_cast<std::ptrdiff_t>(first_new));
  for (std::size_t k = first_new; k < constraints_.size(); ++k)
    if (constraints_[k].active) rest.push_back(constraints_[k]), ++kept;
  constraints_ = std::move(rest);
  return kept;
}

std::optional<SubmapConstraint> SubmapSlam2D::try_closure(int s, int i, const std::vector<Eigen::Matrix3d>& marginals) {
  const LoopClosureOptions& lc = options_.closures;
  const std::vector<Submap>& submaps = frontend_.submaps();
  const std::vector<ScanEstimate>& est = frontend_.estimates();
  const int j = est[s].submap;
  const Pose2 origin_i = pose_of(submaps[i].origin), origin_j = pose_of(submaps[j].origin);
  const Eigen::Vector3d o = origin_j.between(pose_of(est[s].pose)).vector();
  const Eigen::Vector3d W = pose_of(nodes_[j]).compose(pose_of(o)).vector();
  const Eigen::Matrix3d SW = compose_covariance(nodes_[j], marginals[j], o, offset_cov_[s]);
  const Eigen::Matrix3d& Si = marginals[i];
  // Submap i's frontend frame in the world: its scans' positions, where W must come near.
  const Pose2 Ti = pose_of(nodes_[i]).compose(origin_i.inverse());
  double nearest = std::numeric_limits<double>::infinity();
  for (int k : submaps[i].scans)
    nearest = std::min(nearest, (Ti.transform_from(est[k].pose.head<2>()) - W.head<2>()).norm());
  if (i == 0 && start_map_) {  // the saved map reaches beyond the scans of its stretch
    const Eigen::Vector2d w = Ti.inverse().transform_from(W.head<2>());
    const Eigen::Vector2d out = (start_map_bounds_.head<2>() - w).cwiseMax(w - start_map_bounds_.tail<2>()).cwiseMax(0.0);
    nearest = std::min(nearest, out.norm());
  }
  const double lever = (W.head<2>() - nodes_[i].head<2>()).squaredNorm();
  const double lin_sd = std::sqrt(std::max(0.0, largest_eigenvalue(SW.topLeftCorner<2, 2>()) +
                                                    largest_eigenvalue(Si.topLeftCorner<2, 2>()) + Si(2, 2) * lever));
  const double ang_sd = std::sqrt(std::max(0.0, SW(2, 2) + Si(2, 2)));
  MatchOptions m = options_.frontend.match;
  m.use_prior = false;
  m.refine = true;
  m.window.linear = std::clamp(lc.window_sigmas * lin_sd, lc.min_linear_window, lc.max_linear_window);
  m.window.angular = std::clamp(lc.window_sigmas * ang_sd, lc.min_angular_window, lc.max_angular_window);
  if (nearest > lc.max_distance + m.window.linear) return std::nullopt;

  // Where the graph puts the scan in submap i's grid; skip a pair already searched there.
  const Eigen::Vector3d predicted = Ti.inverse().compose(pose_of(W)).vector();
  const auto key = std::make_pair(s, i);
  const auto seen = attempts_.find(key);
  if (seen != attempts_.end()) {
    const Eigen::Vector3d d = seen->second - predicted;
    if (d.head<2>().norm() < 0.5 * lc.min_linear_window && std::abs(wrap_angle(d.z())) < 0.5 * lc.min_angular_window)
      return std::nullopt;
  }
  attempts_[key] = predicted;
  // A pair that holds an active closure is not searched again: once the graph moved, the same
  // match would be added a second time and count twice (a look-alike's as much as a true one's).
  for (const SubmapConstraint& c : constraints_)
    if (c.loop && c.active && c.scan == s && c.from == i) return std::nullopt;

  const ObstacleCells& cells = closure_cells_[static_cast<std::size_t>(i)];
  // The pyramid only as deep as this window needs (a search of a deeper one is the same
  // search): most windows are a few decimetres, and the deep levels, padded by their span,
  // are most of a field's bytes and build time.
  const int levels =
      std::min(kSearchLevels, CorrelativeScanMatcher::levels_for_window(m.window.linear, cells.resolution));
  const double fields_before = timings_.closure_fields, t_field = cpu_seconds();
  const CorrelativeScanMatcher& matcher =
      fields_->get(i, levels, cells.width, cells.height, [&](int depth) { return build_matcher(i, depth); });
  timings_.closure_fields = fields_before + (cpu_seconds() - t_field);  // a build's or a deepening's
  // log p >= (1 - h) log p_rand for a hit share h (log p is concave in h): a pose whose mean h
  // reaches min_match_quality scores at least this, and the search prunes everything below.
  m.min_score = kClosureScoreSlack * static_cast<double>(points_[s].rows()) * (1.0 - lc.min_match_quality) *
                std::log(options_.frontend.field.p_rand);
  const MatchResult r = matcher.match(points_[s], predicted, m);
  ++counts_.closures_searched;
  ++timings_.closure_matches;
  if (!r.found) {
    ++counts_.closures_rejected;
    return std::nullopt;
  }
  const double res = matcher.field().resolution();
  const Eigen::Vector3d off = r.search_pose - predicted;
  const bool at_edge =
      (m.window.linear < lc.max_linear_window &&
       std::max(std::abs(off.x()), std::abs(off.y())) > m.window.linear - kEdgeCells * res) ||
      (m.window.angular < lc.max_angular_window &&
       std::abs(wrap_angle(off.z())) > m.window.angular - kEdgeCells * r.angular_step);
  const Eigen::Matrix3d gate = graph_gate(r, Ti, W, SW, i, Si);
  if (r.match_quality < lc.min_match_quality || at_edge || gate_chi2(gate, r.pose, predicted) > lc.dissolve_chi2 ||
      !unique_match(matcher, points_[s], predicted, m, r, gate)) {
    ++counts_.closures_rejected;
    return std::nullopt;
  }
  // The scan in submap i's frame (a), and submap j's origin seen from the scan (b = o^-1).
  const Eigen::Vector3d a = origin_i.between(pose_of(r.pose)).vector();
  const Eigen::Matrix3d Ri = frame_rotation(origin_i.theta);
  const Eigen::Matrix3d Sa = Ri.transpose() * r.covariance * Ri;
  const Eigen::Vector3d b = pose_of(o).inverse().vector();
  const Eigen::Matrix3d Jinv = inverse_jacobian(o);
  SubmapConstraint c;
  c.from = i;
  c.to = j;
  c.loop = true;
  c.scan = s;
  c.match_quality = r.match_quality;
  c.measurement = pose_of(a).compose(pose_of(b)).vector();
  c.covariance = compose_covariance(a, Sa, b, Jinv * offset_cov_[s] * Jinv.transpose()) +
                 kMinConstraintVariance * Eigen::Matrix3d::Identity();
  return c;
}

Eigen::Matrix3d SubmapSlam2D::graph_gate(const MatchResult& r, const Pose2& Ti, const Eigen::Vector3d& W,
                                         const Eigen::Matrix3d& SW, int i, const Eigen::Matrix3d& Si) const {
  // The match against where the graph predicts the scan, in the world frame: the window spans
  // the prediction's largest spread on both axes and the largest turn, so a look-alike place
  // can score well inside it where the prediction's own spread makes it improbable (a corridor
  // known across, not along; the map's heading known to a degree). A closure the optimised
  // graph would dissolve at once (dissolve_chi2) is not added: the same test, before, with the
  // two submaps' marginals taken as independent (their correlation only shrinks the spread of
  // the difference, so this errs towards accepting) and submap i's heading spread carried to
  // the scan by its lever arm.
  const Eigen::Matrix3d R = frame_rotation(Ti.theta);  // submap i's frontend frame -> the world's
  Eigen::Matrix3d J = Eigen::Matrix3d::Identity();
  J(0, 2) = -(W.y() - nodes_[i].y());
  J(1, 2) = W.x() - nodes_[i].x();
  const Eigen::Matrix3d C = SW + J * Si * J.transpose() + R * r.covariance * R.transpose();
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(0.5 * (C + C.transpose()));
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0.0).all()) return Eigen::Matrix3d::Zero();
  const Eigen::Matrix3d info = R.transpose() * ldlt.solve(R);
  return 0.5 * (info + info.transpose());
}

double SubmapSlam2D::gate_chi2(const Eigen::Matrix3d& gate, const Eigen::Vector3d& pose, const Eigen::Vector3d& predicted) {
  Eigen::Vector3d d = pose - predicted;
  d.z() = wrap_angle(d.z());
  return d.dot(gate * d);
}

bool SubmapSlam2D::unique_match(const CorrelativeScanMatcher& matcher, const Points2& points,
                                const Eigen::Vector3d& predicted, const MatchOptions& m, const MatchResult& r,
                                const Eigen::Matrix3d& gate) const {
  // A look-alike place (the next door along a corridor, the neighbouring box) can score as well
  // as the match and lie within the graph's gate as well: the match alone cannot tell them
  // apart, and the one it picked may be the wrong one (Olson 2009's uniqueness test). The
  // runner-up is the best pose that is another place (beyond the match's own spread at
  // dissolve_chi2 and beyond the field's reach of its points) which the graph's gate admits as
  // well; the match is kept only when it explains the scan better than the runner-up beyond
  // chance: Vuong's statistic above the normal quantile of dissolve_chi2's confidence (one
  // sided: 3.09 at 0.999).
  const double chi2 = options_.closures.dissolve_chi2;
  const MatchResult ru = matcher.runner_up(points, predicted, m, r, chi2, gate / chi2);
  const double z = ru.found ? matcher.closeness(points, r.pose, ru.pose) : std::numeric_limits<double>::infinity();
  const double confidence = chi_square_cdf(chi2, 3);
  const double z_min = std::sqrt(chi_square_quantile(2.0 * confidence - 1.0, 1));
  return z > z_min;
}

Eigen::Vector4d SubmapSlam2D::closure_region(int i) const {
  // The field over the submap's hits only (a submap grid is sized for the sensor's full reach).
  const Submap& sub = frontend_.submaps()[i];
  const std::vector<ScanEstimate>& est = frontend_.estimates();
  Eigen::Vector2d lo = sub.origin.head<2>(), hi = lo;
  if (i == 0 && start_map_) {  // the saved map's occupied extent
    lo = lo.cwiseMin(start_map_bounds_.head<2>());
    hi = hi.cwiseMax(start_map_bounds_.tail<2>());
  }
  for (int k : sub.scans) {
    const Pose2 p = pose_of(est[k].pose);
    for (Eigen::Index n = 0; n < points_[k].rows(); ++n) {
      const Eigen::Vector2d q = p.transform_from(points_[k].row(n).transpose());
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
  }
  const double margin = options_.frontend.field.truncation() + 2.0 * options_.frontend.resolution;
  return Eigen::Vector4d(lo.x() - margin, lo.y() - margin, hi.x() + margin, hi.y() + margin);
}

CorrelativeScanMatcher SubmapSlam2D::build_matcher(int i, int levels) {
  const double t0 = cpu_seconds();
  CorrelativeScanMatcher matcher(LikelihoodField::from_obstacles(closure_cells_[static_cast<std::size_t>(i)],
                                                                 options_.frontend.field),
                                 levels);
  timings_.closure_fields += cpu_seconds() - t0;
  ++timings_.closure_fields_built;
  return matcher;
}

PoseGraph2D SubmapSlam2D::graph() const {
  PoseGraph2D g;
  for (std::size_t k = 0; k < nodes_.size(); ++k) g.add_pose(static_cast<int>(k), nodes_[k]);
  if (!nodes_.empty()) g.set_fixed(0);
  for (const SubmapConstraint& c : constraints_)
    if (c.active) g.add_pose_edge(c.from, c.to, c.measurement, c.covariance.inverse());
  return g;
}

double SubmapSlam2D::constraint_chi2(const SubmapConstraint& c) const {
  const Eigen::Vector3d e = linearize_pose_edge(nodes_[c.from], nodes_[c.to], c.measurement).error;
  return e.dot(c.covariance.ldlt().solve(e));
}

void SubmapSlam2D::optimize_and_dissolve() {
  if (nodes_.size() < 2) return;  // one submap: nothing to optimise
  const ScopedCpuTimer timer(timings_.optimize);
  for (;;) {
    PoseGraph2D g = graph();
    optimize(g, options_.optimizer);
    ++counts_.optimizations;
    nodes_ = g.values();
    // Undo the closure the optimised graph contradicts most (ch. 11.6 item 3), one at a time:
    // a single wrong closure can make right ones look wrong until it is gone.
    SubmapConstraint* worst = nullptr;
    double worst_chi2 = options_.closures.dissolve_chi2;
    for (SubmapConstraint& c : constraints_) {
      if (!c.loop || !c.active) continue;
      const double chi2 = constraint_chi2(c);
      if (chi2 > worst_chi2) worst = &c, worst_chi2 = chi2;
    }
    if (!worst) return;
    worst->active = false;
    ++counts_.closures_dissolved;
  }
}

void SubmapSlam2D::finish() {
  const int last = static_cast<int>(nodes_.size()) - 1;
  if (last < 0) return;
  if (options_.closures.enabled) {
    for (int round = 0; round < options_.max_rounds; ++round) {
      const int dissolved = counts_.closures_dissolved;
      int added = 0;
      for (int j = 2; j <= last; ++j) added += search_closures(j);
      optimize_and_dissolve();
      ++counts_.rounds;
      if (added == 0 && counts_.closures_dissolved == dissolved) break;
    }
  } else if (last > 0) {
    optimize_and_dissolve();
  }
}

std::vector<Eigen::Vector3d> SubmapSlam2D::scan_poses() const {
  const std::vector<ScanEstimate>& est = frontend_.estimates();
  const std::vector<Submap>& submaps = frontend_.submaps();
  std::vector<Eigen::Vector3d> poses;
  poses.reserve(est.size());
  int ref = 0;  // scans not inserted moved with the odometry from the last inserted one
  for (const ScanEstimate& e : est) {
    if (e.submap >= 0) ref = e.submap;
    const Eigen::Vector3d node = ref < static_cast<int>(nodes_.size()) ? nodes_[ref] : submaps[ref].origin;
    poses.push_back(pose_of(node).compose(pose_of(submaps[ref].origin).between(pose_of(e.pose))).vector());
  }
  return poses;
}

OccupancyGrid2D SubmapSlam2D::map(double resolution) const {
  // Rule: finite or raise; NaN or a negative value was read as "the default" before.
  require(std::isfinite(resolution) && resolution >= 0.0, "resolution",
          "must be finite and >= 0 (0: the submaps' resolution)");
  const double res = resolution > 0.0 ? resolution : options_.frontend.resolution;
  if (start_map_ && res != start_map_->resolution())
    throw_invalid_argument("resolution", "a run started from a map is drawn into that map: 0 or its resolution " +
                                             std::to_string(start_map_->resolution()) + " m");
  require(num_scans() > 0, "scans", "none added: nothing to map");
  const double t0 = cpu_seconds();
  const std::vector<Eigen::Vector3d> poses = scan_poses();
  // No-return beams (glass, open doors, the sky) and hits beyond the usable range say little
  // about the cells they cross: the final map leaves them out, as `probslam map` does.
  ScanFilter filter = options_.frontend.filter;
  filter.clear_no_return = false;
  const double reach = filter.usable_range();
  // The filtered ranges are computed again for the insertion rather than kept for every scan
  // (they are cheap; all of them would be as large as the scans themselves).
  Eigen::Vector2d lo = poses[0].head<2>(), hi = lo;
  for (std::size_t s = 0; s < poses.size(); ++s) {
    // The extent of what the scan saw (hits and cleared space), not of the sensor's reach.
    const Eigen::VectorXd r = ranges_for_insertion(ranges_[s], filter);
    const Eigen::VectorXd& angles = *angles_[s];
    const Pose2 p = pose_of(poses[s]);
    for (Eigen::Index b = 0; b < r.size(); ++b) {
      if (!std::isfinite(r[b])) continue;
      const double a = p.theta + angles[b];
      const Eigen::Vector2d q(p.x + r[b] * std::cos(a), p.y + r[b] * std::sin(a));
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    lo = lo.cwiseMin(p.translation());
    hi = hi.cwiseMax(p.translation());
  }
  OccupancyGrid2D grid = start_map_ ? start_map_->grown_to_include(lo.x() - res, lo.y() - res, hi.x() + res, hi.y() + res)
                                    : OccupancyGrid2D::covering(lo.x() - res, lo.y() - res, hi.x() + res, hi.y() + res, res);
  for (std::size_t s = 0; s < poses.size(); ++s)
    grid.insert_rays(poses[s], ranges_for_insertion(ranges_[s], filter), *angles_[s], reach);
  map_seconds_ += cpu_seconds() - t0;
  return grid;
}

SubmapSlamTimings SubmapSlam2D::timings() const {
  SubmapSlamTimings t = timings_;
  const ScanMatcherTimings& f = frontend_.timings();
  t.filter = f.filter;
  t.match = f.match;
  t.insert = f.insert;
  t.frontend_fields = f.fields_built;
  t.frontend_local = f.local_matches;
  t.frontend_searches = f.searches;
  t.final_map = map_seconds_;
  return t;
}

SubmapSlamMemory SubmapSlam2D::memory() const {
  SubmapSlamMemory m;
  for (std::size_t k = 0; k < ranges_.size(); ++k) {
    const bool shared = k > 0 && angles_[k] == angles_[k - 1];
    m.scans += 8.0 * static_cast<double>(ranges_[k].size() + (shared ? 0 : angles_[k]->size()) + points_[k].size());
  }
  m.scans += static_cast<double>(offset_cov_.size() * sizeof(Eigen::Matrix3d));
  m.submap_grids = frontend_.grid_bytes();
  for (const ObstacleCells& c : closure_cells_) m.closure_cells += static_cast<double>(c.bytes());
  m.closure_fields = fields_->used();
  if (start_map_) m.start_map = 12.0 * start_map_->width() * start_map_->height();
  return m;
}

SubmapSlamSummary SubmapSlam2D::summary() const {
  SubmapSlamSummary out = counts_;
  out.scans = num_scans();
  out.submaps = num_submaps();
  out.matched_scans = 0;
  for (const ScanEstimate& e : frontend_.estimates()) out.matched_scans += e.matched;
  out.closures_accepted = 0;
  for (const SubmapConstraint& c : constraints_) out.closures_accepted += c.loop && c.active;
  out.final_chi2 = nodes_.empty() ? 0.0 : graph().chi2();
  return out;
}

}  // namespace probslam
