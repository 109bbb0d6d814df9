#pragma once
// Incremental scan matching (the lecture's "scan matching": x_t = argmax p(z_t | x_t, m_t-1)
// p(x_t | u_t-1, x_t-1)): each scan is matched against the map built from the scans before it
// and then inserted at the matched pose. With submap_distance > 0 the map is cut into local
// submaps (ch. 11.7's "local submaps from scan matching"), each starting at a scan's pose.
#include <Eigen/Core>
#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "probslam/core/object_mutex.hpp"
#include "probslam/core/options_description.hpp"
#include "probslam/core/update_trigger.hpp"
#include "probslam/core/types.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"
#include "probslam/slam2d/correlative_scan_matcher.hpp"
#include "probslam/slam2d/range_scan.hpp"

namespace probslam {

class StateWriter;
class StateReader;

/// The odometry motion model's noise (Thrun et al. Table 5.6 in spirit): the standard
/// deviations of the odometry-predicted relative motion grow with the distance travelled (d)
/// and the angle turned (a): sd_xy = trans_per_metre d + trans_per_radian a + trans_floor,
/// sd_theta = rot_per_radian a + rot_per_metre d + rot_floor.
struct OdometryNoise {
  double trans_per_metre = 0.1, trans_per_radian = 0.02, trans_floor = 0.01;
  double rot_per_radian = 0.1, rot_per_metre = 0.05, rot_floor = 0.005;
  void validate() const;
  template <class V>
  static void describe(V& v) {
    using O = OdometryNoise;
    v("trans_per_metre", &O::trans_per_metre, "m/m", "translation std per metre travelled");
    v("trans_per_radian", &O::trans_per_radian, "m/rad", "translation std per radian turned");
    v("trans_floor", &O::trans_floor, "m", "translation std of any motion, > 0");
    v("rot_per_radian", &O::rot_per_radian, "rad/rad", "rotation std per radian turned");
    v("rot_per_metre", &O::rot_per_metre, "rad/m", "rotation std per metre travelled");
    v("rot_floor", &O::rot_floor, "rad", "rotation std of any motion, > 0");
  }
  /// Covariance (3x3, in the frame of the earlier pose) of a relative motion `delta`.
  Eigen::Matrix3d covariance(const Eigen::Vector3d& delta) const;
};

/// How the frontend matches a scan against its submap (issue 54).
enum class FrontendSearch {
  /// A local optimiser (Gauss-Newton on the interpolated field from the prediction, the odometry
  /// prior as a residual); the correlative search only when that match is poor.
  kFallback,
  kAlways,  ///< the correlative search (branch and bound over the window) for every scan
};
template <>
struct OptionEnum<FrontendSearch> {
  static constexpr std::array<const char*, 2> names{"fallback", "always"};
};

struct IncrementalScanMatcherOptions {
  double resolution = 0.05;  ///< of the local maps, m
  ScanFilter filter;
  LikelihoodFieldOptions field;
  MatchOptions match;  ///< window and refinement; the prior covariance comes from `odometry`
  OdometryNoise odometry;
  bool use_odometry_prior = true;  ///< the odometry motion model enters the score
  /// Predict each scan's motion as the last matched one (scaled by the time since the scan
  /// before), not the odometry's: a log without odometry (whose poses never move) otherwise
  /// predicts "no motion", and where the scans do not fix the motion (a corridor seen by a
  /// short-range laser) the match stays near that prediction: the path shrinks (issue 51).
  bool constant_velocity = false;
  /// Hits beyond this fraction of the usable range are inserted into the map but not matched
  /// against it (0 < f <= 1). The map ends where the last scans' farthest hits end, and a wall
  /// seen at a grazing angle is filled in only as the robot passes it: a hit beyond that edge
  /// is scored against the edge's last cells, which pulls the scan back towards the previous
  /// pose (-17 mm of every 50 mm step in a simulated corridor with a 5 m laser, 1.6 % too short
  /// in an office). Matching only the hits whose surroundings earlier scans mapped removes the
  /// pull: 0.8 left a quarter of it, 0.6 left 3 % (probslam.sim_laser, Stage-like robot; ACES
  /// relations 0.042 m against 0.043 m with every hit). The default matches every hit: 0.6
  /// moved the long-range corridor loop of test_submap_slam 0.012 -> 0.12 m off at its end (its
  /// far hits are what hold the frontend), and cost LDS and RPLidar cells of the simulated matrix
  /// (docs/laser_slam.md); a fraction derived from the sensor and the map's extent is open (issue 51).
  double match_fraction = 1.0;
  /// A scan is matched only after the odometry has moved update.distance or turned
  /// update.angle since the last matched scan; scans in between take the odometry's relative motion.
  UpdateTrigger update{0.05, 0.05};
  /// A new submap starts after this much travel (m) or this many matched scans; 0 = never
  /// (one map: incremental scan matching alone, the inconsistent map of Fig. 11.2).
  double submap_distance = 5.0;
  int submap_scans = 0;
  /// Matches below this quality (mean hit likelihood, 0..1) fall back to the odometry prior.
  double min_match_quality = 0.1;
  /// Scans inserted into a new local map before matching starts against it.
  int warmup_scans = 1;
  /// The likelihood field of the local map is rebuilt once the robot has moved this far (m) or
  /// turned this much (rad) since it was built, or a scan lands outside it: matching against
  /// the map of a few decimetres ago costs nothing in accuracy and saves most distance transforms
  /// (ACES, first 2500 scans: 0.037 m relation error either way, 3x faster). 0: every scan.
  double field_refresh_distance = 0.3, field_refresh_angle = 0.3;
  /// kFallback: each scan is matched by a local optimiser from the prediction, and by the
  /// correlative search over `match.window` only when the local match is poor: it did not
  /// converge inside the window, its Hessian does not hold the pose within the window, its
  /// quality is below min_match_quality or significantly below the last matched scan's, or it
  /// lies beyond the prior's 99.9 % chi2 gate (see docs/performance.md). Without odometry
  /// (constant_velocity: the prediction is a guess) or without a prior in the score
  /// (use_odometry_prior off, a start on a map) every scan is searched. kAlways: every scan is
  /// searched.
  FrontendSearch search = FrontendSearch::kFallback;

  /// std::invalid_argument naming the first bad option by its path ("filter.max_range").
  void validate() const;
  template <class V>
  static void describe(V& v) {
    using O = IncrementalScanMatcherOptions;
    v("resolution", &O::resolution, "m", "cell side of the local maps");
    v("filter", &O::filter, "", "which readings hit, and the usable range");
    v("field", &O::field, "", "the likelihood field scans are matched against");
    v("match", &O::match, "", "the search window and refinement (the prior comes from odometry)");
    v("odometry", &O::odometry, "", "the odometry motion model's noise (the match's prior)");
    v("use_odometry_prior", &O::use_odometry_prior, "", "the odometry motion model enters the score");
    v("constant_velocity", &O::constant_velocity, "", "predict each scan's motion as the last matched one (a log without odometry)");
    v("match_fraction", &O::match_fraction, "", "hits beyond this share of the usable range are inserted, not matched, in (0, 1]");
    v("update", &O::update, "", "a scan is matched once the odometry moved or turned this much since the last matched one");
    v("submap_distance", &O::submap_distance, "m", "a new submap starts after this much travel (0: one map)");
    v("submap_scans", &O::submap_scans, "", "... or after this many matched scans (0: no limit)");
    v("min_match_quality", &O::min_match_quality, "", "matches below this mean hit likelihood (0 .. 1) fall back to odometry");
    v("warmup_scans", &O::warmup_scans, "", "scans inserted into a new local map before matching starts against it");
    v("field_refresh_distance", &O::field_refresh_distance, "m", "the likelihood field is rebuilt once the robot moved this far (0: every scan)");
    v("field_refresh_angle", &O::field_refresh_angle, "rad", "... or turned this much");
    v("search", &O::search, "",
      "'fallback': a local optimiser from the prediction, the correlative search only where its match is poor; "
      "'always': the search for every scan");
  }
};

/// One submap: a local occupancy grid in the frontend's world frame, the pose of its first scan
/// (its node in the pose graph) and the scans inserted into it.
struct Submap {
  OccupancyGrid2D grid;
  Eigen::Vector3d origin;  ///< pose of the first scan, world frame of the frontend
  std::vector<int> scans;  ///< indices of the scans inserted
  double travel = 0.0;     ///< distance covered by the scans' estimated poses, m
  int matched = 0;
};

/// Per scan: the pose estimate, whether it was matched, the match quality and the covariance of
/// the pose relative to the previous matched scan's (the constraint ch. 11.7 links nodes with).
struct ScanEstimate {
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();
  Eigen::Matrix3d relative_covariance = Eigen::Matrix3d::Zero();
  double match_quality = 0.0;
  bool matched = false;   ///< scan-matched (else the odometry's motion)
  bool fallback = false;  ///< matching ran but failed the quality test
  int submap = -1;        ///< submap it was inserted into (-1: not inserted)
  int points = 0;
};

/// Processor seconds (cpu_clock.hpp) the frontend spent per stage since construction (or
/// loading): a batch undone by restore keeps its time counted. Not saved.
struct ScanMatcherTimings {
  double filter = 0.0;  ///< the scan's hits and insertion ranges (ScanFilter)
  double match = 0.0;   ///< correlative matching, the likelihood fields built for it included
  double insert = 0.0;  ///< rays into the submap grids, their growth and new submaps included
  long fields_built = 0;  ///< likelihood fields built for matching
  long local_matches = 0;  ///< scans matched by the local optimiser alone (options.search)
  long searches = 0;       ///< scans matched by the correlative search
};

/// Every call is all or nothing: add_scan checks its input (check_scan), then works out the scan's
/// estimate and any grown or new grid into a PendingScan, and changes the object only in commit,
/// which cannot fail. add_scans checks every row first; a row refused on the object's state (a
/// submap grid beyond OccupancyGrid2D::kMaxCells) restores the state of before the batch from a
/// snapshot (the open submap's grid copied once per batch, not per scan).
class IncrementalScanMatcher {
  struct FieldCache;  // the last likelihood field built, reused while the robot stays near

 public:
  std::mutex& mutex() const noexcept { return mutex_.get(); }

  explicit IncrementalScanMatcher(const IncrementalScanMatcherOptions& options = {});
  // Copies are deep: submaps and estimates are values, and the field cache they share is
  // immutable (a scan replaces it, never changes it).

  /// Adds one scan: ranges (B,) metres, beam_angles (B,) rad relative to the sensor, the
  /// sensor's odometry pose (x, y, theta) and a timestamp (s). Returns its estimate. Throws
  /// std::invalid_argument (nothing changed) for the inputs check_scan refuses, or a submap
  /// grid that would grow beyond OccupancyGrid2D::kMaxCells.
  ScanEstimate add_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                        const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const Eigen::Vector3d& odometry,
                        double timestamp);
  /// Every input check add_scan makes (check_scan_input); row >= 0 names add_scans' row.
  void check_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                  const Eigen::Vector3d& odometry, double timestamp, long row = -1) const;
  /// S scans: ranges (S, B), beam_angles (1, B) or (S, B), odometry (S, 3), timestamps (S):
  /// every row checked before the first is added; all rows or none.
  void add_scans(const Eigen::Ref<const RowMatrixXd>& ranges, const Eigen::Ref<const RowMatrixXd>& beam_angles,
                 const Eigen::Ref<const RowMatrixXd>& odometry, const Eigen::Ref<const Eigen::VectorXd>& timestamps);

  /// One scan's work, computed without changing the object (prepare), applied by commit.
  struct PendingScan {
    ScanEstimate est;
    Eigen::Vector3d odometry = Eigen::Vector3d::Zero();
    double timestamp = 0.0;
    Eigen::VectorXd insertion, angles;   // ranges_for_insertion and the beam angles
    Points2 hits;                        // scan_hits, sensor frame (for owners that keep them)
    bool moved = false, open_next = false;
    double travel = 0.0;                 // the open submap's travel after this scan
    std::optional<OccupancyGrid2D> grid; // the open submap's grid grown for this scan
    std::optional<OccupancyGrid2D> next; // a new submap's grid (first scan, or the one this scan opens)
    std::shared_ptr<const FieldCache> cache;  // the field cache after matching
    double filter_seconds = 0.0, match_seconds = 0.0;  // spent in prepare, added by commit
    bool field_built = false;
    bool searched = false, local = false;  // which matcher gave the estimate
  };
  /// The estimate of a scan that passed check_scan, and every grid it needs: throws (nothing
  /// changed) when a grid would exceed its limit.
  PendingScan prepare(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                      const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const Eigen::Vector3d& odometry,
                      double timestamp) const;
  /// Applies a prepared scan (cannot fail). The object must not have changed since prepare.
  ScanEstimate commit(PendingScan&& scan);

  /// The state a batch may change, and its restoration (add_scans, and the classes that own one).
  struct Snapshot {
    std::size_t scans = 0, submaps = 0;
    std::optional<Submap> open;  // the open submap as it was (the only one a scan changes in place)
    bool open_grid_kept = true;  // false: `open` holds a 1 x 1 grid; restore inserts its scans again
    Eigen::Vector3d matched_odometry = Eigen::Vector3d::Zero(), matched_pose = Eigen::Vector3d::Zero();
    std::shared_ptr<const FieldCache> cache;
  };
  /// What restore needs to rebuild the open submap's grid of a snapshot taken without it: scan
  /// k's ranges and beam angles as add_scan received them, and for a run started on a map the
  /// map as start_from_map received it (submap 0 starts as that map).
  struct ScanReplay {
    std::function<std::pair<const Eigen::VectorXd*, const Eigen::VectorXd*>(int)> scan;
    const OccupancyGrid2D* start_map = nullptr;
  };
  /// copy_open_grid = false leaves out the open submap's grid, the one large thing a batch
  /// changes (30 MB for a 30 m laser at 5 cm): for an owner that keeps every scan, restore then
  /// inserts the submap's scans again into a new grid, replaying its growth, which gives the same
  /// grid value for value (restore's `replay`).
  Snapshot snapshot(bool copy_open_grid = true) const;
  /// std::invalid_argument (nothing changed) for a snapshot without the open grid and no replay.
  void restore(Snapshot&& s, const ScanReplay* replay = nullptr);

  /// Starts the run on a saved map (before the first scan; std::invalid_argument naming `map`
  /// or `initial_pose` otherwise, nothing changed): the map becomes submap 0, in its own frame
  /// (origin (0, 0, 0)), and the run's frame is the map's. The first scan is matched against it
  /// around initial_pose (no motion prior: initial_pose is a guess within the match window) and,
  /// like every later scan of that stretch, inserted into it; its relative_covariance is the
  /// match's, in the map's frame. The map must have the frontend's resolution, at least one cell
  /// more likely occupied than free, and hold initial_pose's position.
  void start_from_map(const OccupancyGrid2D& map, const Eigen::Vector3d& initial_pose);
  /// Whether the next scan is the first of a run started from a map.
  bool awaits_first_scan_on_map() const { return estimates_.empty() && !submaps_.empty(); }
  const IncrementalScanMatcherOptions& options() const { return options_; }
  const std::vector<ScanEstimate>& estimates() const { return estimates_; }
  const std::vector<double>& timestamps() const { return timestamps_; }
  const std::vector<Submap>& submaps() const { return submaps_; }
  int num_scans() const { return static_cast<int>(estimates_.size()); }
  const ScanMatcherTimings& timings() const { return timings_; }
  /// Replaces finished submap k's grid (k < submaps().size() - 1: the frontend only matches
  /// against the open one) by a 1 x 1 grid on its lattice's origin, freeing it: SubmapSlam2D
  /// keeps what the loop-closure search needs of it (ObstacleCells), GridFastSlam's corrector
  /// needs none of it. std::invalid_argument naming `index` otherwise.
  void release_grid(int k);
  /// Puts a grid back into finished submap k (SubmapSlam2D's save, from what it kept).
  void replace_grid(int k, OccupancyGrid2D grid);
  /// Bytes the submap grids hold (log-odds and scan stamps).
  double grid_bytes() const;

  /// Options, estimates, submaps and the likelihood field the next scans are matched against
  /// (built from an earlier state of the map, so it is saved, not rebuilt): bit for bit, to one
  /// file (docs/file_format.md) as the other stateful classes; a loaded object continues exactly
  /// as this one would.
  static constexpr const char* kStateTag = "IncrementalScanMatcher";
  void save(const std::string& path) const;
  static IncrementalScanMatcher load(const std::string& path);
  void write_state(StateWriter& w) const;
  static IncrementalScanMatcher read_state(StateReader& r);

 private:
  struct FieldCache {
    std::shared_ptr<const CorrelativeScanMatcher> matcher;
    int submap = -1, grid_width = 0, grid_height = 0;
    Eigen::Vector3d built_at = Eigen::Vector3d::Zero();  // the prior it was built for
    Eigen::Vector4d region = Eigen::Vector4d::Zero();
    Eigen::Vector2d grid_origin = Eigen::Vector2d::Zero();
  };
  OccupancyGrid2D new_submap_grid(const Eigen::Vector3d& origin) const;
  /// The open submap's grid grown to hold a scan at `pose`, or nothing when it holds it already.
  std::optional<OccupancyGrid2D> grown_for(const OccupancyGrid2D& grid, const Eigen::Vector3d& pose) const;
  /// Submap k's grid built again from its scans as add_scan built it (start, growth, insertion).
  OccupancyGrid2D replayed_grid(std::size_t k, const ScanReplay& replay) const;
  /// The scan's match: the local optimiser's when options_.search allows and it holds (see
  /// local_match_holds against reference_quality), else the correlative search's (`searched`).
  MatchResult match(const Submap& submap, const Points2& points, const Eigen::Vector3d& prior,
                    const Eigen::Matrix3d& prior_cov, FieldCache& cache, bool use_prior, double reference_quality,
                    bool& searched) const;
  /// Whether a local match stands without the search (options_.search's tests).
  bool local_match_holds(const MatchResult& local, const Eigen::Vector3d& prior, const Eigen::Matrix3d& prior_cov,
                         double reference_quality) const;
  /// The match quality of the open submap's last scan-matched scan (NaN: none yet).
  double reference_quality() const;
  /// The hits a scan is matched on (options_.match_fraction).
  Points2 matched_hits(const Points2& hits) const;
  /// The constant-velocity prediction of the motion to a scan at `timestamp`; nothing before
  /// enough scans have moved to tell a velocity.
  std::optional<Eigen::Vector3d> last_motion(double timestamp) const;
  std::shared_ptr<const CorrelativeScanMatcher> matcher_for(const Submap& submap, const Eigen::Vector4d& region,
                                                            const Eigen::Vector3d& prior, FieldCache& cache) const;

  std::shared_ptr<const FieldCache> field_cache_ = std::make_shared<FieldCache>();

  IncrementalScanMatcherOptions options_;
  std::vector<ScanEstimate> estimates_;
  std::vector<double> timestamps_;
  std::vector<Submap> submaps_;
  Eigen::Vector3d matched_odometry_ = Eigen::Vector3d::Zero();  // of the last matched scan
  Eigen::Vector3d matched_pose_ = Eigen::Vector3d::Zero();
  bool started_on_map_ = false;  // submap 0 is a saved map (start_from_map)
  ScanMatcherTimings timings_;
  ObjectMutex mutex_;
};

}  // namespace probslam
