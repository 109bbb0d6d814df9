// What a run yields: every scan's pose from its submap's optimised origin, and the final
// occupancy map of every scan drawn at those poses.
#include <cmath>
#include <string>
#include <vector>

#include "probslam/core/check.hpp"
#include "probslam/slam2d/cpu_clock.hpp"
#include "submap_slam_internal.hpp"

namespace probslam {

using submap_slam_detail::pose_of;

namespace {

/// The extent (xmin, ymin, xmax, ymax) of what the scans saw at `poses`: their hits and the
/// space cleared by `filter`'s ranges, and the poses themselves (not the sensor's reach).
Eigen::Vector4d seen_extent(const std::vector<Eigen::Vector3d>& poses, const std::vector<Eigen::VectorXd>& ranges,
                            const std::vector<std::shared_ptr<const Eigen::VectorXd>>& angles, const ScanFilter& filter) {
  Eigen::Vector2d lo = poses[0].head<2>(), hi = lo;
  for (std::size_t s = 0; s < poses.size(); ++s) {
    const Eigen::VectorXd r = ranges_for_insertion(ranges[s], filter);
    const Eigen::VectorXd& a = *angles[s];
    const Pose2 p = pose_of(poses[s]);
    for (Eigen::Index b = 0; b < r.size(); ++b) {
      if (!std::isfinite(r[b])) continue;
      const double heading = p.theta + a[b];
      const Eigen::Vector2d q(p.x + r[b] * std::cos(heading), p.y + r[b] * std::sin(heading));
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    lo = lo.cwiseMin(p.translation());
    hi = hi.cwiseMax(p.translation());
  }
  return Eigen::Vector4d(lo.x(), lo.y(), hi.x(), hi.y());
}

}  // namespace

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
  const Eigen::Vector4d e = seen_extent(poses, ranges_, angles_, filter);
  const double x0 = e[0] - res, y0 = e[1] - res, x1 = e[2] + res, y1 = e[3] + res;
  OccupancyGrid2D grid = start_map_ ? start_map_->grown_to_include(x0, y0, x1, y1)
                                    : OccupancyGrid2D::covering(x0, y0, x1, y1, res);
  for (std::size_t s = 0; s < poses.size(); ++s)
    grid.insert_rays(poses[s], ranges_for_insertion(ranges_[s], filter), *angles_[s], reach);
  map_seconds_ += cpu_seconds() - t0;
  return grid;
}

}  // namespace probslam
