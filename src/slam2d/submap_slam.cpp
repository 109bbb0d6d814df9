// SubmapSlam2D's frontend side: scans in, submaps finished and linked to the graph as they
// close (each then searched for loop closures), and the snapshot that makes a call all or
// nothing. The closure search, its fields, the consistency vote, the backend, the map and the
// accounting are in the submap_slam_*.cpp beside this file.
#include "probslam/slam2d/submap_slam.hpp"

#include <algorithm>
#include <utility>

#include "probslam/core/pose2_covariance.hpp"
#include "probslam/slam2d/scan_batch.hpp"
#include "probslam/slam2d/start_map.hpp"
#include "submap_slam_internal.hpp"

namespace probslam {

using submap_slam_detail::kMinConstraintVariance;
using submap_slam_detail::pose_of;

SubmapSlam2D::SubmapSlam2D(const SubmapSlamOptions& options)
    : options_((options.validate(), options)),
      frontend_(options.frontend),
      fields_(std::make_unique<FieldCache>(options.closures.field_cache_bytes)) {}

SubmapSlam2D::SubmapSlam2D(const SubmapSlam2D& other)
    : options_(other.options_),
      frontend_(other.frontend_),
      hit_counts_(other.hit_counts_),
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
  all_or_nothing(*this, [&] { add_prepared(std::move(scan), ranges, beam_angles); });
}

void SubmapSlam2D::add_prepared(IncrementalScanMatcher::PendingScan&& scan, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                const Eigen::Ref<const Eigen::VectorXd>& beam_angles) {
  const std::size_t submaps_before = frontend_.submaps().size();
  const int hits = static_cast<int>(scan.hits.rows());  // the frontend's filtering, not repeated
  const ScanEstimate est = frontend_.commit(std::move(scan));
  hit_counts_.push_back(hits);
  ranges_.emplace_back(ranges);
  keep_angles(beam_angles);
  const Eigen::Matrix3d cov = offset_covariance(est, frontend_.num_scans() - 1);
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

Eigen::Matrix3d SubmapSlam2D::offset_covariance(const ScanEstimate& est, int index) const {
  if (est.submap >= 0 && index > 0 && est.submap == chain_submap_) {
    const Eigen::Vector3d origin = frontend_.submaps()[est.submap].origin;
    const Eigen::Vector3d prev = pose_of(origin).between(pose_of(chain_pose_)).vector();
    const Eigen::Vector3d step = pose_of(chain_pose_).between(pose_of(est.pose)).vector();
    return compose_covariance(prev, chain_cov_, step, est.relative_covariance);
  }
  if (index == 0 && start_map_) return est.relative_covariance;  // matched against the map, whose origin is submap 0's
  return Eigen::Matrix3d::Zero();
}

Points2 SubmapSlam2D::hits_of(int s) const {
  const std::size_t k = static_cast<std::size_t>(s);
  return scan_hits(ranges_[k], *angles_[k], options_.frontend.filter);
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
  // Without a copy of the open submap's grid: every scan is kept, so restore inserts them again.
  return Snapshot{frontend_.snapshot(false), hit_counts_.size(), nodes_, constraints_, chain_pose_, chain_cov_, chain_submap_,
                  attempts_, counts_};
}

void SubmapSlam2D::restore(Snapshot&& s) {
  const int open = static_cast<int>(s.frontend.submaps) - 1;
  IncrementalScanMatcher::ScanReplay replay;
  replay.scan = [this](int k) {
    const std::size_t i = static_cast<std::size_t>(k);
    return std::make_pair(&ranges_[i], angles_[i].get());
  };
  replay.start_map = start_map_ ? &*start_map_ : nullptr;
  frontend_.restore(std::move(s.frontend), &replay);
  closure_cells_.resize(static_cast<std::size_t>(std::max(0, open)));  // the open one's grid is back
  hit_counts_.resize(s.scans);
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

}  // namespace probslam
