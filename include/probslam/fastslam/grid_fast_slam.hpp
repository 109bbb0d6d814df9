#pragma once
// Grid-based FastSLAM (the lecture's "Grid-based FastSLAM"): a Rao-Blackwellised particle filter
// whose particles each carry a pose, a log weight and an occupancy grid map built with known
// poses (Table 9.1 with insert_rays' rules), the maps shared between particles in copy-on-write
// tiles. Three proposals:
//  - kMotion: the lecture's algorithm box; sample the odometry motion model, weight by
//    p(z | x, m) (EndpointLikelihood), insert the scan;
//  - kScanMatching: Grisetti et al. 2007 (GMapping); scan-match against the particle's own map,
//    sample from a Gaussian fitted to p(z | x, m) p(x | x_t-1, u) around the mode, weight by its
//    normaliser; falls back to kMotion (counted) when the match fails;
//  - kImprovedOdometry: Haehnel et al. 2003; the odometry is first corrected by incremental scan
//    matching over short submaps, then kMotion with the corrected motion and its covariance.
#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "probslam/core/object_mutex.hpp"
#include "probslam/core/options_description.hpp"
#include "probslam/core/update_trigger.hpp"
#include "probslam/core/types.hpp"
#include "probslam/fastslam/endpoint_likelihood.hpp"
#include "probslam/fastslam/particles.hpp"
#include "probslam/fastslam/scan_proposal.hpp"
#include "probslam/fastslam/tiled_grid_2d.hpp"
#include "probslam/slam2d/incremental_scan_matcher.hpp"
#include "probslam/slam2d/range_scan.hpp"

namespace probslam {

class WorkerPool;

enum class GridProposal : std::uint8_t { kMotion = 0, kScanMatching = 1, kImprovedOdometry = 2 };
template <>
struct OptionEnum<GridProposal> {
  static constexpr std::array<const char*, 3> names{"motion", "scan-matching", "improved-odometry"};
};

/// Particles at most: each holds a grid map's tile table; far beyond any published use (GMapping
/// runs 30 to 100).
inline constexpr int kGridFastSlamMaxParticles = 100000;
/// max_map_bytes' default: 8 GiB, a third of a 24 GiB machine, leaving the rest to the log, the
/// dense maps drawn from the particles and the rest of the process.
inline constexpr double kGridFastSlamDefaultMapBytes = 8.0 * 1024 * 1024 * 1024;

struct GridFastSlamOptions {
  int num_particles = 30;
  GridProposal proposal = GridProposal::kScanMatching;
  double resolution = 0.05;  ///< of the particles' maps, m
  ScanFilter filter;         ///< which readings hit, and the usable range
  OdometryNoise odometry;    ///< the odometry motion model's noise
  EndpointLikelihoodOptions likelihood;
  ScanProposalOptions matching;
  /// Each update's log weight increment is multiplied by this, in (0, 1]: the beams of a scan
  /// are not independent, so the product of their likelihoods is far more peaked than the
  /// evidence (Thrun et al. ch. 6.4). Unscaled weights (1, the textbook's) resample at 3 of 4
  /// updates and deplete the particles: ACES with 30 particles gave 0.058, 0.090 and 0.078 m
  /// relations error for seeds 0, 1, 2 (wrong loops); 0.03 gave 0.047 m for seeds 0 and 1, with
  /// 70 resamplings in 1278 updates. GMapping divides by a gain times the particle count for the
  /// same reason.
  double weight_scale = 0.03;
  /// Resample when N_eff = 1 / sum w^2 < resample_threshold * num_particles, in [0, 1].
  double resample_threshold = 0.5;
  /// The filter updates once the odometry has moved this far (m) or turned this much (rad)
  /// since the last update; scans in between take the odometry's motion from it. GMapping's
  /// 0.5 m / 0.5 rad would halve the updates (ACES, 30 particles: 688 instead of 1278, 0.0468 m
  /// relations error against 0.0458), but the scans between updates then follow the odometry
  /// over twice the distance: on the bundled excerpt with 4 particles the best path's median
  /// distance from GraphSLAM's grows from under 0.1 m to 0.2 m.
  UpdateTrigger update{0.25, 0.25};
  /// The filter also updates once this much log time (s) has passed since the last update,
  /// moved or not (GMapping's temporalUpdate): a robot standing still has its particles weighed
  /// by new scans. 0: on travel alone.
  double update_interval = 0.0;
  /// kImprovedOdometry's incremental scan matcher (its submaps cut every few metres). It sees
  /// the scans as the filter does: its resolution, filter and odometry are the filter's (the
  /// constructor sets them, so options() shows what runs).
  IncrementalScanMatcherOptions corrector = default_corrector();
  /// kScanMatching: the hill climb starts from the odometry corrected by incremental scan
  /// matching (`corrector`) instead of the raw odometry; the proposal's target, p(z | x, m) times
  /// the raw odometry's motion model, is unchanged. Where the odometry pose of a scan is stale
  /// (FR079 logs it up to 0.1 rad behind the laser while turning), the climb from it can stop in
  /// the wrong optimum; the correlative matcher's window finds the right one.
  bool corrected_start = true;
  std::uint64_t seed = 0;
  int threads = 1;
  /// Bound on the particles' maps (bytes): the tiles alive and every particle's tile table, plus
  /// the worst case one update can add (each particle copies its table and clones every tile in
  /// the usable-range disc around its pose). An update over it is refused before it changes
  /// anything, and so is a num_particles whose first update could exceed it.
  double max_map_bytes = kGridFastSlamDefaultMapBytes;

  static IncrementalScanMatcherOptions default_corrector();
  /// std::invalid_argument naming the first bad option by its path ("likelihood.sigma").
  void validate() const;
  /// These options with the corrector's resolution, filter and odometry set to the filter's:
  /// what the filter runs with.
  GridFastSlamOptions coupled() const;
  template <class V>
  static void describe(V& v) {
    using O = GridFastSlamOptions;
    v("num_particles", &O::num_particles, "", "M, in [1, 100000]");
    v("proposal", &O::proposal, "", "\"scan-matching\" (Grisetti et al. 2007), \"motion\" (the odometry motion model) or \"improved-odometry\" (Haehnel et al. 2003)");
    v("resolution", &O::resolution, "m", "cell side of the particles' maps");
    v("filter", &O::filter, "", "which readings hit, and the usable range");
    v("odometry", &O::odometry, "", "the odometry motion model's noise");
    v("likelihood", &O::likelihood, "", "the end-point likelihood p(z | x, m)");
    v("matching", &O::matching, "", "the scan-matching proposal's hill climb and Gaussian fit");
    v("weight_scale", &O::weight_scale, "", "in (0, 1]: each update's log weight increment is multiplied by this (a scan's beams are not independent)");
    v("resample_threshold", &O::resample_threshold, "", "resample when N_eff < this * M, in [0, 1]");
    v("update", &O::update, "", "the filter updates once the odometry moved or turned this much since the last update");
    v("update_interval", &O::update_interval, "s", "... or once this much log time passed since the last update (0: travel alone)");
    v("corrector", &O::corrector, "", "the incremental scan matcher that corrects the odometry (its resolution, filter and odometry are the filter's)");
    v("corrected_start", &O::corrected_start, "", "scan-matching: the climb starts from the corrected odometry");
    v("seed", &O::seed, "", "random seed, in [0, 2^64)");
    v("threads", &O::threads, "", "worker threads (results identical for any count)");
    v("max_map_bytes", &O::max_map_bytes, "bytes", "bound on the particles' maps with the worst case of the next update");
  }
  /// kImprovedOdometry, or kScanMatching with corrected_start: the corrector runs.
  bool uses_corrector() const {
    return proposal == GridProposal::kImprovedOdometry || (proposal == GridProposal::kScanMatching && corrected_start);
  }
};

struct GridFastSlamSummary {
  long scans = 0, updates = 0, resamples = 0;
  long matched = 0;    ///< particle updates drawn from the scan-matching proposal
  long fallbacks = 0;  ///< particle updates whose match failed (motion model instead)
  double effective_sample_size = 0.0;  ///< after the last update, before any resampling
};

/// Processor seconds (slam2d/cpu_clock.hpp: every thread of the process) per stage since
/// construction or loading; not saved, a copy carries them, a batch undone by restore keeps its time.
struct GridFastSlamTimings {
  double filter = 0.0;     ///< the scan's hits and insertion ranges
  double corrector = 0.0;  ///< the odometry corrector's scan matching and insertion
  double proposal = 0.0;   ///< sampling every particle: its scan match, Gaussian fit and weight
  double resample = 0.0;   ///< normalising the weights and resampling
  double map_update = 0.0; ///< the scan's rays into every particle's map, tile clones included
  double table_copies = 0.0;  ///< of which copying shared maps' tile tables (before the rays)
  double final_map = 0.0;  ///< map(): a particle's tiles drawn into a dense grid
  long proposals = 0;        ///< scan-matching proposals computed (one per distinct parent)
  long proposal_local = 0;   ///< of which found their mode by Gauss-Newton alone (matching.search)
  long proposal_evaluations = 0;  ///< evaluations of p(z | x, m) the proposals made
  long corrector_local = 0, corrector_searches = 0;  ///< the corrector's (ScanMatcherTimings)

  template <class V>
  static void describe(V& v) {
    using T = GridFastSlamTimings;
    v("filter", &T::filter, "s", "the scan's hits and insertion ranges");
    v("corrector", &T::corrector, "s", "the odometry corrector's scan matching and insertion");
    v("proposal", &T::proposal, "s", "sampling every particle: its scan match, Gaussian fit and weight");
    v("resample", &T::resample, "s", "normalising the weights and resampling");
    v("map_update", &T::map_update, "s", "the scan's rays into every particle's map, tile clones included");
    v("table_copies", &T::table_copies, "s", "of which copying shared maps' tile tables (before the rays)");
    v("final_map", &T::final_map, "s", "map(): a particle's tiles drawn into a dense grid");
    v("proposals", &T::proposals, "", "scan-matching proposals computed (one per distinct parent)");
    v("proposal_local", &T::proposal_local, "", "of which found their mode by Gauss-Newton alone");
    v("proposal_evaluations", &T::proposal_evaluations, "", "evaluations of p(z | x, m) the proposals made");
    v("corrector_local", &T::corrector_local, "", "scans the corrector matched by its local optimiser alone");
    v("corrector_searches", &T::corrector_searches, "", "scans the corrector matched by the correlative search");
  }
};

/// Every call is all or nothing (std::invalid_argument naming the argument, the object unchanged).
/// add_scan works in two phases: it checks its input (check_scan), has the corrector prepare its
/// estimate without committing it, samples every particle's pose, weight and random stream into
/// temporaries, checks that every particle's map can grow to hold its pose (a size computation,
/// OccupancyGrid2D::kMaxCells) and that the maps stay within max_map_bytes; only then does it
/// commit (corrector, rays, paths, counters). No map is copied for this: the tiles stay shared.
/// Batches (add_scans): every row is checked first; a row refused on the filter's state (map
/// limit, memory bound) restores the state of before the batch from a snapshot taken once per
/// batch (the particles' map pointers, paths and streams, the corrector's open submap): a batch is
/// applied whole or not at all. Lock mutex() around calls when several threads share the object.
class GridFastSlam {
 public:
  std::mutex& mutex() const noexcept { return mutex_.get(); }

  explicit GridFastSlam(const GridFastSlamOptions& options);
  ~GridFastSlam();
  /// A deep copy: the particles' maps are cloned into a family of their own (TiledGrid2D::
  /// deep_copy: the tiles the particles share stay shared among the copy's particles, none with
  /// the original, so each filter's max_map_bytes counts its own tiles); paths, random streams
  /// and the corrector are copied. The copy starts its own worker threads when it needs them.
  /// The same scans then give both filters the same results.
  GridFastSlam(const GridFastSlam& other);
  GridFastSlam& operator=(const GridFastSlam&) = delete;

  /// One scan: ranges (B,) m, beam_angles (B,) rad relative to the sensor, the sensor's odometry
  /// pose (x, y, theta) and a timestamp (s). Returns true when the filter updated on it.
  bool add_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                const Eigen::Vector3d& odometry, double timestamp);

  /// Every input check add_scan makes (check_scan_input); row >= 0 names add_scans' row.
  void check_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                  const Eigen::Vector3d& odometry, double timestamp, long row = -1) const;
  /// S scans: ranges (S, B), beam_angles (1, B) or (S, B), odometry (S, 3), timestamps (S): all
  /// rows or none.
  void add_scans(const Eigen::Ref<const RowMatrixXd>& ranges, const Eigen::Ref<const RowMatrixXd>& beam_angles,
                 const Eigen::Ref<const RowMatrixXd>& odometry, const Eigen::Ref<const Eigen::VectorXd>& timestamps);
  struct Snapshot;
  Snapshot snapshot() const;
  void restore(Snapshot&& s);

  /// Starts the filter on a saved map, before the first scan (check_start_map says what is
  /// refused; also refused after a scan; nothing changed then): the run's frame is the map's.
  /// The first scan is placed by correlative matching against the map within the default search
  /// window (0.3 m, 0.35 rad) around initial_pose (the pose itself when the match fails), and
  /// every particle's map starts as the saved map with that scan drawn in, its tiles shared.
  void start_from_map(const OccupancyGrid2D& map, const Eigen::Vector3d& initial_pose);
  /// The saved map the filter started from, or nullptr.
  const OccupancyGrid2D* start_map() const { return start_map_ ? &*start_map_ : nullptr; }
  const GridFastSlamOptions& options() const { return options_; }
  int num_particles() const { return static_cast<int>(particles_.size()); }
  int num_scans() const { return static_cast<int>(scan_step_.size()); }
  /// Particle poses (M x 3) and normalised log weights (M,).
  Poses2 poses() const;
  Eigen::VectorXd log_weights() const;
  int best_index() const;
  /// Every scan's pose under the particle's path: its pose at the scan's update step composed
  /// with the (corrected) odometry's motion since (N x 3). std::invalid_argument naming
  /// `particle` outside [0, num_particles()).
  Poses2 scan_poses(int particle) const;
  /// The particle's map as a dense grid (std::invalid_argument before the first scan).
  OccupancyGrid2D map(int particle) const;
  const TiledGrid2D& tiled_map(int particle) const;
  TileSharing tile_sharing() const;
  GridFastSlamSummary summary() const;
  GridFastSlamTimings timings() const;
  const std::vector<double>& timestamps() const { return timestamps_; }

  /// Saves the filter (options, particles' poses, weights, paths and random streams, their maps
  /// with the tiles they share kept shared, the corrector, the odometry since the last update,
  /// every scan's step and counters) bit for bit (docs/file_format.md): a loaded filter continues
  /// exactly as this one would. Paths are loaded unshared (one copy per particle).
  static constexpr const char* kStateTag = "GridFastSlam";
  void save(const std::string& path) const;
  static GridFastSlam load(const std::string& path);
  void write_state(StateWriter& w) const;
  static GridFastSlam read_state(StateReader& r);

 private:
  struct Particle {
    Eigen::Vector3d pose = Eigen::Vector3d::Zero();
    double log_weight = 0.0;
    std::shared_ptr<TiledGrid2D> map;  // its tiles are shared; the table is the particle's own
    PosePath path;                     // the pose at every update step
    ParticleRng rng;
  };
  /// A particle's new pose, weight and stream, before they are committed.
  struct Sampled {
    Eigen::Vector3d pose = Eigen::Vector3d::Zero();
    double log_weight = 0.0;
    ParticleRng rng;
    bool matched = false, fallback = false;
  };
  std::shared_ptr<TiledGrid2D> first_map(const Eigen::Vector3d& odometry) const;
  /// The first scan's pose on the start map: matched around initial_pose_.
  Eigen::Vector3d pose_on_start_map(const Points2& points) const;
  void first_scan(std::shared_ptr<TiledGrid2D> map, const Eigen::VectorXd& insertion,
                  const Eigen::Ref<const Eigen::VectorXd>& angles, const Eigen::Vector3d& odometry);
  /// The motion since the last update, in the frame of the pose there: the motion model's mean
  /// and covariance, and (with corrected_start) the corrected odometry's motion, where the
  /// scan-matching proposal's second climb may start.
  struct Motion {
    Eigen::Vector3d delta;
    Eigen::Matrix3d cov;
    std::optional<Eigen::Vector3d> start;
  };
  /// Runs body(k) for every particle, split over the worker threads.
  template <typename Body>
  void for_each_particle(const Body& body);
  std::vector<Sampled> sample(const Points2& points, const Motion& motion);
  /// kScanMatching: the particle's proposal (its climb, Gaussian fit and normaliser).
  ScanProposal propose(const Particle& p, const Points2& points, const Motion& motion) const;
  /// The particle's new pose and weight: drawn from its proposal `q`, or from the motion model
  /// when q is null (kMotion, kImprovedOdometry, a scan without hits) or failed.
  Sampled sample_particle(const Particle& p, const ScanProposal* q, const Points2& points, const Motion& motion) const;
  /// Throws (nothing changed) when a particle's map could not grow to hold its sampled pose, or
  /// the maps could exceed max_map_bytes after the update.
  void check_update(const std::vector<Sampled>& sampled) const;
  void commit_update(std::vector<Sampled>&& sampled, const Eigen::VectorXd& insertion,
                     const Eigen::Ref<const Eigen::VectorXd>& angles);
  /// Does a map around `pose` need to grow, and to which bounds (xmin, ymin, xmax, ymax)?
  bool needs_growth(const TiledGrid2D& map, const Eigen::Vector3d& pose, Eigen::Vector4d& bounds) const;
  /// Returns the processor seconds spent copying a shared map's tile table.
  double insert(Particle& p, const Eigen::VectorXd& insertion, const Eigen::Ref<const Eigen::VectorXd>& angles) const;
  /// The log time of the last update's scan (the first scan's before any update).
  double last_update_time() const;
  /// Frees the corrector's finished submap grids: it only matches against its open submap.
  void release_corrector_grids();
  /// kImprovedOdometry: the covariance of the corrected motion since the last update, given the
  /// chain's covariance and last matched pose after this scan.
  Eigen::Matrix3d corrected_motion_covariance(const Eigen::Vector3d& source, const Eigen::Matrix3d& chain_cov,
                                              const Eigen::Vector3d& last_corrected) const;
  /// After the first scan or an update at `source` (raw odometry `raw`): a new stretch of travel starts there; the
  /// scan just added hangs from update `step`.
  void start_stretch(const Eigen::Vector3d& source, const Eigen::Vector3d& raw, int step);
  void normalise_and_resample();
  /// Refuses a num_particles whose first update could exceed max_map_bytes; sets footprint_bytes_.
  void check_particle_budget();

  GridFastSlamOptions options_;
  EndpointLikelihood likelihood_;
  std::unique_ptr<IncrementalScanMatcher> corrector_;
  std::vector<Particle> particles_;
  ParticleRng rng_;
  std::uint64_t next_stream_ = 0;
  // Odometry (or corrected odometry) at the last update, and the motion's covariance since then.
  Eigen::Vector3d last_update_odometry_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d last_update_raw_ = Eigen::Vector3d::Zero();  // the raw odometry there
  Eigen::Matrix3d corrected_cov_ = Eigen::Matrix3d::Zero();
  Eigen::Vector3d last_corrected_ = Eigen::Vector3d::Zero();
  std::vector<int> scan_step_;               // update step each scan hangs from
  std::vector<Eigen::Vector3d> scan_offset_; // its odometry motion since that step
  std::vector<double> timestamps_;
  GridFastSlamSummary summary_;
  GridFastSlamTimings timings_;
  mutable double map_seconds_ = 0.0;
  double footprint_bytes_ = 0.0;  // worst case one particle's update clones (its usable-range disc)
  std::unique_ptr<WorkerPool> pool_;  // threads > 1: started on the first update
  std::optional<OccupancyGrid2D> start_map_;  // start_from_map's map, unchanged
  Eigen::Vector3d initial_pose_ = Eigen::Vector3d::Zero();
  ObjectMutex mutex_;
};

struct GridFastSlam::Snapshot {
  std::optional<IncrementalScanMatcher::Snapshot> corrector;
  std::vector<Particle> particles;  // map pointers, paths and streams: no tile is copied
  ParticleRng rng;
  std::uint64_t next_stream = 0;
  Eigen::Vector3d last_update_odometry, last_update_raw, last_corrected;
  Eigen::Matrix3d corrected_cov;
  std::size_t scans = 0;
  GridFastSlamSummary summary;
};

}  // namespace probslam
