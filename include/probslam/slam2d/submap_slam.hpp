#pragma once
// GraphSLAM over local submaps (Thrun et al. ch. 11.7, "Empirical implementation"): scan
// matching builds local submaps, each submap's origin is a pose node, consecutive nodes are
// linked by the scan-matched motion and its covariance, and a correlation between a scan and an
// older overlapping submap becomes a Gaussian constraint. The search adds and dissolves
// constraints until the graph is stable (Fig. 11.4); a robust kernel guards the optimiser.
#include <Eigen/Core>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "probslam/core/object_mutex.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/pose_graph_2d.hpp"
#include "probslam/slam2d/incremental_scan_matcher.hpp"
#include "probslam/slam2d/likelihood_field.hpp"

namespace probslam {

struct LoopClosureOptions {
  bool enabled = true;
  /// Scans of each finished submap matched against the older submaps (spread over the submap).
  int scans_per_submap = 3;
  /// A closure needs at least this match quality (mean hit likelihood, 0..1): stricter than the
  /// frontend's, since a wrong closure bends the whole map. ACES: 0.5 to 0.65 give the same
  /// 0.043 m, 0.45 lets wrong closures through (0.195 m); 0.6 keeps a margin from that edge.
  double min_match_quality = 0.6;
  /// The search window is this many standard deviations of the predicted relative pose ...
  double window_sigmas = 3.0;
  /// ... within these bounds (m, rad): the lower keeps a sharp prediction searchable, the
  /// upper bounds the search time.
  double min_linear_window = 0.3, max_linear_window = 4.0;
  double min_angular_window = 0.1, max_angular_window = 0.7;
  /// Submaps whose origins are predicted farther apart than this are not searched (m).
  double max_distance = 20.0;
  /// A closure whose error in the optimised graph exceeds this chi2 (3 dof) is dissolved
  /// (ch. 11.6 item 3); 16.27 is the 99.9% quantile.
  double dissolve_chi2 = 16.27;
  /// Fields of finished submaps kept for the search beyond the one in use (bytes); the least
  /// recently used are rebuilt. A field takes 8 bytes a cell, and its search pyramid 4 a cell
  /// per level, only as many levels as the windows searched in it need. The search of each
  /// finished submap sweeps the older ones in order (submap by submap, so that it builds each
  /// field once), and the next search sweeps them again: a least-recently-used cache smaller
  /// than a whole sweep evicts each field before the next sweep asks for it and never hits, and
  /// a sweep grows with the log. So by default none is kept (0): each search builds each field
  /// it needs once. A budget that holds a whole sweep saves the rebuilds (512 MiB on ACES); the
  /// run's results do not depend on it, only its time and memory do (docs/performance.md).
  double field_cache_bytes = 0.0;

  void validate() const;
  template <class V>
  static void describe(V& v) {
    using O = LoopClosureOptions;
    v("enabled", &O::enabled, "", "search for loop closures at all");
    v("scans_per_submap", &O::scans_per_submap, "", "scans of each finished submap matched against the older submaps");
    v("min_match_quality", &O::min_match_quality, "", "a closure needs this mean hit likelihood (0 .. 1)");
    v("window_sigmas", &O::window_sigmas, "", "the search window is this many std of the predicted relative pose ...");
    v("min_linear_window", &O::min_linear_window, "m", "... at least this ...");
    v("max_linear_window", &O::max_linear_window, "m", "... and at most this");
    v("min_angular_window", &O::min_angular_window, "rad", "the angular window at least this ...");
    v("max_angular_window", &O::max_angular_window, "rad", "... and at most this (<= pi)");
    v("max_distance", &O::max_distance, "m", "submaps predicted farther apart are not searched");
    v("dissolve_chi2", &O::dissolve_chi2, "", "a closure whose error in the optimised graph exceeds this chi2 (3 dof) is dissolved");
    v("field_cache_bytes", &O::field_cache_bytes, "bytes", "submap likelihood fields kept for the search beyond the one in use, >= 0 (least recently used rebuilt; results do not depend on it)");
  }
};

struct SubmapSlamOptions {
  IncrementalScanMatcherOptions frontend = default_frontend();
  LoopClosureOptions closures;
  /// Gauss-Newton with a Huber kernel: a closure that slipped through the tests pulls
  /// linearly, not quadratically.
  OptimizerOptions optimizer = default_optimizer();
  /// Rounds of search, optimisation and dissolution after the last scan (Fig. 11.4).
  int max_rounds = 10;

  /// std::invalid_argument naming the first bad option by its path ("closures.min_match_quality").
  void validate() const;
  template <class V>
  static void describe(V& v) {
    using O = SubmapSlamOptions;
    v("frontend", &O::frontend, "", "the incremental scan matcher that builds the submaps (submap_distance 10 m here)");
    v("closures", &O::closures, "", "the loop-closure search");
    v("optimizer", &O::optimizer, "", "the pose-graph optimiser (Levenberg-Marquardt with a Huber kernel here)");
    v("max_rounds", &O::max_rounds, "", "rounds of search, optimisation and dissolution in finish()");
  }
  static OptimizerOptions default_optimizer();
  /// The frontend's defaults, with submaps cut every 10 m of travel: on ACES 5 m submaps (ch.
  /// 11.7's figure) gave 0.233 +- 0.891 m relation error, 10 m gave 0.043 +- 0.038 m; a short
  /// submap holds too little of a corridor to pin the next scans along it.
  static IncrementalScanMatcherOptions default_frontend();
};

/// A constraint between two submap nodes: `to`'s origin seen from `from`'s (x, y, theta).
struct SubmapConstraint {
  int from = 0, to = 0;
  Eigen::Vector3d measurement = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  bool loop = false;        ///< a loop closure (else consecutive submaps)
  int scan = -1;            ///< loop closures: the scan that was matched against `from`
  double match_quality = 0.0;
  bool active = true;       ///< false once dissolved
};

struct SubmapSlamSummary {
  int scans = 0, submaps = 0, matched_scans = 0;
  int closures_searched = 0;   ///< scan-submap pairs searched
  int closures_accepted = 0;   ///< added to the graph (and still active)
  int closures_rejected = 0;   ///< failed the quality or consistency test
  int closures_dissolved = 0;  ///< added, then undone by the optimised graph
  int rounds = 0, optimizations = 0;
  double final_chi2 = 0.0;
};

/// Processor seconds (cpu_clock.hpp) per stage since construction or loading (not saved; a
/// copy carries them; a batch undone by restore keeps its time counted).
struct SubmapSlamTimings {
  double filter = 0.0, match = 0.0, insert = 0.0;  ///< the frontend's (ScanMatcherTimings)
  double closure_search = 0.0;  ///< the loop-closure search, its fields and marginals included
  double closure_fields = 0.0;  ///< of which building likelihood fields and their pyramids
  double optimize = 0.0;        ///< pose-graph optimisation and dissolution
  double final_map = 0.0;       ///< map()
  long frontend_fields = 0, closure_fields_built = 0, closure_matches = 0;
  long frontend_local = 0, frontend_searches = 0;  ///< the frontend's (ScanMatcherTimings)

  template <class V>
  static void describe(V& v) {
    using T = SubmapSlamTimings;
    v("filter", &T::filter, "s", "the frontend's scan filtering");
    v("match", &T::match, "s", "the frontend's scan matching");
    v("insert", &T::insert, "s", "the frontend's map insertion");
    v("closure_search", &T::closure_search, "s", "the loop-closure search, its fields and marginals included");
    v("closure_fields", &T::closure_fields, "s", "of which building likelihood fields and their pyramids");
    v("optimize", &T::optimize, "s", "pose-graph optimisation and dissolution");
    v("final_map", &T::final_map, "s", "map()");
    v("frontend_fields", &T::frontend_fields, "", "likelihood fields the frontend built");
    v("closure_fields_built", &T::closure_fields_built, "", "fields the closure search built");
    v("closure_matches", &T::closure_matches, "", "closure matches tried");
    v("frontend_local", &T::frontend_local, "", "scans the frontend matched by its local optimiser alone");
    v("frontend_searches", &T::frontend_searches, "", "scans the frontend matched by the correlative search");
  }
};

/// What the object holds (bytes, approximate: the large buffers, not the bookkeeping).
struct SubmapSlamMemory {
  double scans = 0.0;           ///< every scan's ranges and beam angles (for the map and the search)
  double submap_grids = 0.0;    ///< the frontend's grids (the open submap's; finished ones are released)
  double closure_cells = 0.0;   ///< the obstacle cells kept of each finished submap
  double closure_fields = 0.0;  ///< the loop-closure search's cache of fields and pyramids
  double start_map = 0.0;
  double total() const { return scans + submap_grids + closure_cells + closure_fields + start_map; }

  template <class V>
  static void describe(V& v) {
    using T = SubmapSlamMemory;
    v("scans", &T::scans, "bytes", "every scan's ranges and beam angles (for the map and the search)");
    v("submap_grids", &T::submap_grids, "bytes", "the frontend's grids (the open submap's; finished ones are released)");
    v("closure_cells", &T::closure_cells, "bytes", "the obstacle cells kept of each finished submap");
    v("closure_fields", &T::closure_fields, "bytes", "the loop-closure search's cache of fields and pyramids");
    v("start_map", &T::start_map, "bytes", "the saved map a run started from");
  }
};

/// Every call is all or nothing. add_scan checks its input first (check_scan) and the frontend
/// adds the scan whole or not at all. add_scans checks every row first; a row refused on the
/// object's state (a submap grid beyond OccupancyGrid2D::kMaxCells, an optimisation that fails)
/// restores the state of before the batch from a snapshot taken once per batch (the graph's
/// nodes, constraints and search history; the open submap's grid not copied but built again
/// from its scans, which the object keeps: IncrementalScanMatcher::snapshot).
class SubmapSlam2D {
 public:
  std::mutex& mutex() const noexcept { return mutex_.get(); }

  explicit SubmapSlam2D(const SubmapSlamOptions& options = {});
  /// A deep copy (scans, submaps, graph, search history). It starts with an empty cache of
  /// likelihood fields: the closure search rebuilds the same fields from the same submaps, so
  /// the copy's results are the original's.
  SubmapSlam2D(const SubmapSlam2D& other);
  SubmapSlam2D& operator=(const SubmapSlam2D&) = delete;
  ~SubmapSlam2D();

  /// Adds one scan (see IncrementalScanMatcher::add_scan); a submap that this scan completes is
  /// linked to the graph and searched for loop closures at once.
  void add_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                const Eigen::Vector3d& odometry, double timestamp);
  /// Every input check add_scan makes; row >= 0 names add_scans' row.
  void check_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                  const Eigen::Vector3d& odometry, double timestamp, long row = -1) const {
    frontend_.check_scan(ranges, beam_angles, odometry, timestamp, row);
  }
  /// S scans (see IncrementalScanMatcher::add_scans): all rows or none.
  void add_scans(const Eigen::Ref<const RowMatrixXd>& ranges, const Eigen::Ref<const RowMatrixXd>& beam_angles,
                 const Eigen::Ref<const RowMatrixXd>& odometry, const Eigen::Ref<const Eigen::VectorXd>& timestamps);
  struct Snapshot;
  Snapshot snapshot() const;
  void restore(Snapshot&& s);
  /// Starts the run on a saved map (before the first scan; see
  /// IncrementalScanMatcher::start_from_map for what is refused): the map is submap 0, its node
  /// fixed at the map's origin, so the run's frame is the map's; the first scan is matched
  /// against it around initial_pose, the scans of the first stretch (submap_distance) are matched
  /// against and inserted into (a copy of) it, and later submaps' loop-closure search includes
  /// it over its whole extent. map() draws every scan into the saved map, on its lattice.
  void start_from_map(const OccupancyGrid2D& map, const Eigen::Vector3d& initial_pose);
  /// The saved map the run started from, or nullptr.
  const OccupancyGrid2D* start_map() const { return start_map_ ? &*start_map_ : nullptr; }
  /// Closes the last submap and repeats search, optimisation and dissolution until no
  /// constraint changes (or max_rounds). Adding scans afterwards starts a new finish.
  void finish();

  const SubmapSlamOptions& options() const { return options_; }
  const IncrementalScanMatcher& frontend() const { return frontend_; }
  int num_scans() const { return frontend_.num_scans(); }
  int num_submaps() const { return static_cast<int>(nodes_.size()); }
  /// Optimised submap origins (N, 3), world frame = the first scan's odometry frame.
  const std::vector<Eigen::Vector3d>& submap_poses() const { return nodes_; }
  const std::vector<SubmapConstraint>& constraints() const { return constraints_; }
  /// Every scan's pose (x, y, theta): its submap's optimised origin composed with the scan's
  /// scan-matched offset from that origin.
  std::vector<Eigen::Vector3d> scan_poses() const;
  /// The graph as optimised: one pose per submap (id = submap index), the consecutive edges
  /// and the active closures.
  PoseGraph2D graph() const;
  /// An occupancy grid of every scan at scan_poses(): resolution in metres, 0 for the
  /// frontend's; std::invalid_argument naming `resolution` when negative or not finite. A run
  /// started from a map draws into that map (grown as needed), so only 0 or its resolution.
  OccupancyGrid2D map(double resolution = 0.0) const;
  SubmapSlamSummary summary() const;
  SubmapSlamTimings timings() const;
  SubmapSlamMemory memory() const;

  /// Saves everything the next scans depend on (options, the frontend with its open submap and
  /// likelihood field, every scan, the graph, constraints and search history) bit for bit
  /// (docs/file_format.md): a loaded object continues exactly as this one would. The closure
  /// search's field cache is not saved (rebuilt from the same submaps, as in a copy).
  static constexpr const char* kStateTag = "SubmapSlam2D";
  void save(const std::string& path) const;
  static SubmapSlam2D load(const std::string& path);
  void write_state(StateWriter& w) const;
  static SubmapSlam2D read_state(StateReader& r);

 private:
  class FieldCache;
  /// add_scan after the frontend prepared the scan.
  void add_prepared(IncrementalScanMatcher::PendingScan&& scan, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                    const Eigen::Ref<const Eigen::VectorXd>& beam_angles);
  /// The covariance of scan `index`'s offset from its submap's origin (estimate est), along
  /// the chain of matches since that origin.
  Eigen::Matrix3d offset_covariance(const ScanEstimate& est, int index) const;
  void link_finished_submap(int j);
  /// Searches finished submap j's scans against the older submaps; returns the closures added.
  int search_closures(int j);
  /// The scans of submap j matched in it with hits enough to be searched.
  std::vector<int> closure_candidates(int j) const;
  /// The marginal covariances of submap nodes 0 .. j in the graph as it stands.
  std::vector<Eigen::Matrix3d> submap_marginals(int j) const;
  /// The closure a scan of submap j (its hits, sensor frame) makes with submap i, if it passes
  /// every test (counted).
  std::optional<SubmapConstraint> try_closure(int scan, const Points2& hits, int i,
                                              const std::vector<Eigen::Matrix3d>& marginals);
  /// Scan s's hits (sensor frame): the frontend's filtering of its ranges, computed again
  /// rather than kept (they follow from the ranges, and held for every scan would double the
  /// scans' bytes).
  Points2 hits_of(int s) const;
  /// Scan s's pose seen from its submap's origin (frontend frame).
  Eigen::Vector3d scan_offset(int s) const;
  /// How far world position W lies from submap i's scans (Ti its frontend frame in the world;
  /// from the saved map's occupied extent, for submap 0 of a run started from one).
  double distance_to_submap(int i, const Pose2& Ti, const Eigen::Vector3d& W) const;
  /// Whether scan s need not be searched in submap i (predicted there in its frame): searched
  /// at about that place before, or the pair holds an active closure. Records the attempt.
  bool searched_before(int s, int i, const Eigen::Vector3d& predicted);
  /// The loop constraint from submap i to scan s's submap of match r of s in submap i.
  SubmapConstraint closure_constraint(int s, int i, const MatchResult& r) const;
  /// The information of where the graph predicts a scan (in submap i's frontend frame Ti,
  /// against match r there; W, SW the scan's world pose and covariance, Si submap i's marginal):
  /// a match agrees with the graph when gate_chi2 is within dissolve_chi2. Zero when singular.
  Eigen::Matrix3d graph_gate(const MatchResult& r, const Pose2& Ti, const Eigen::Vector3d& W,
                             const Eigen::Matrix3d& SW, int i, const Eigen::Matrix3d& Si) const;
  static double gate_chi2(const Eigen::Matrix3d& gate, const Eigen::Vector3d& pose, const Eigen::Vector3d& predicted);
  /// Whether match r of `points` (searched around `predicted` with options m) explains the scan
  /// better than any other place the gate admits (see the definition).
  bool unique_match(const CorrelativeScanMatcher& matcher, const Points2& points, const Eigen::Vector3d& predicted,
                    const MatchOptions& m, const MatchResult& r, const Eigen::Matrix3d& gate) const;
  void optimize_and_dissolve();
  /// The active closure the graph contradicts most beyond dissolve_chi2, or nullptr.
  SubmapConstraint* most_contradicted();
  /// Adds the closures found (consecutive order) where they agree with each other and with the
  /// active closures (pairwise over the consecutive chain, resolve_conflicts); returns how many
  /// of them stay. An active closure outvoted by the new ones is dissolved.
  int add_consistent(const std::vector<SubmapConstraint>& found);
  CorrelativeScanMatcher build_matcher(int submap, int levels);
  /// Submap i's closure field (from the cache) with the pyramid a window of this half-width needs.
  const CorrelativeScanMatcher& closure_matcher(int i, double linear_window);
  /// Where the loop-closure field of a finished submap lies: its hits, widened by the field's
  /// reach (and the saved map's occupied extent for a run started from one).
  Eigen::Vector4d closure_region(int submap) const;
  /// Keeps the obstacle cells of finished submap j in closure_region(j) and releases its grid.
  void keep_closure_cells(int j);
  double constraint_chi2(const SubmapConstraint& c) const;

  SubmapSlamOptions options_;
  IncrementalScanMatcher frontend_;
  std::vector<int> hit_counts_;             // hits of each scan (hits_of(s).rows())
  std::vector<Eigen::Matrix3d> offset_cov_; // of each inserted scan's pose from its submap's origin
  std::vector<Eigen::Vector3d> nodes_;      // optimised submap origins
  std::vector<SubmapConstraint> constraints_;
  std::vector<Eigen::VectorXd> ranges_;  // every scan, for the final map
  // Every scan's beam angles, shared with the scan before when equal (a log's scans all have
  // the same: one copy, not one a scan). Immutable once stored.
  std::vector<std::shared_ptr<const Eigen::VectorXd>> angles_;
  void keep_angles(const Eigen::Ref<const Eigen::VectorXd>& beam_angles);
  // Of each finished submap: what its loop-closure field is built from (its grid is released).
  std::vector<ObstacleCells> closure_cells_;
  SubmapSlamTimings timings_;
  mutable double map_seconds_ = 0.0;
  // The chain of matched scans in the open submap: last pose (frontend frame), its covariance
  // from the submap's origin.
  Eigen::Vector3d chain_pose_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d chain_cov_ = Eigen::Matrix3d::Zero();
  int chain_submap_ = 0;
  // Scan-submap pairs searched, with where the graph predicted the scan then.
  std::map<std::pair<int, int>, Eigen::Vector3d> attempts_;
  std::unique_ptr<FieldCache> fields_;
  SubmapSlamSummary counts_;
  std::optional<OccupancyGrid2D> start_map_;  // the saved map the run started from, unchanged
  Eigen::Vector4d start_map_bounds_ = Eigen::Vector4d::Zero();  // its occupied cells' (xmin, ymin, xmax, ymax)
  void set_start_map(const OccupancyGrid2D& map);
  bool in_batch_ = false;  // add_scans' snapshot covers every scan it adds
  ObjectMutex mutex_;
};

struct SubmapSlam2D::Snapshot {
  IncrementalScanMatcher::Snapshot frontend;
  std::size_t scans = 0;
  std::vector<Eigen::Vector3d> nodes;
  std::vector<SubmapConstraint> constraints;
  Eigen::Vector3d chain_pose = Eigen::Vector3d::Zero();
  Eigen::Matrix3d chain_cov = Eigen::Matrix3d::Zero();
  int chain_submap = 0;
  std::map<std::pair<int, int>, Eigen::Vector3d> attempts;
  SubmapSlamSummary counts;
};

}  // namespace probslam
