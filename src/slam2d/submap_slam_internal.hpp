// SubmapSlam2D's private parts, shared by its source files (src/slam2d/submap_slam*.cpp): the
// constant both kinds of constraint are floored by, the vector-to-pose shorthand and the cache
// of the closure search's likelihood fields. Not installed.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <list>
#include <memory>
#include <unordered_map>

#include "probslam/core/pose2.hpp"
#include "probslam/slam2d/correlative_scan_matcher.hpp"
#include "probslam/slam2d/submap_slam.hpp"

namespace probslam {
namespace submap_slam_detail {

/// Added to the variances of a consecutive constraint: keeps its information finite should a
/// submap's chain ever have zero covariance (odometry floors make that impossible today).
constexpr double kMinConstraintVariance = 1e-9;

inline Pose2 pose_of(const Eigen::Vector3d& v) { return Pose2::from_vector(v); }

}  // namespace submap_slam_detail

/// The likelihood fields (with their pyramids) of finished submaps, built on first use and
/// evicted least recently used beyond a byte budget: a long log has hundreds of submaps.
class SubmapSlam2D::FieldCache {
 public:
  explicit FieldCache(double budget) : budget_(budget) {}

  /// The field of `submap` with pyramid levels up to `levels` at least: built by `build(levels)`
  /// unless cached, a cached one deepened when it has fewer.
  CorrelativeScanMatcher& get(int submap, int levels, int width, int height,
                              const std::function<CorrelativeScanMatcher(int)>& build);
  double used() const { return used_; }
  /// Evicts the least recently used fields (never `keep`) until `bytes` more fit the budget.
  void make_room(double bytes, int keep);
  /// Forgets the fields of submaps `first` and later (a batch undone: they may change again).
  void forget_from(int first);

 private:
  struct Entry {
    std::shared_ptr<CorrelativeScanMatcher> matcher;
    double bytes;
    std::list<int>::iterator position;
  };
  /// Deepens a cached field's pyramid to `levels`, within the budget.
  void deepen(Entry& e, int submap, int levels, int width, int height);

  double budget_, used_ = 0.0;
  std::list<int> order_;  // most recent first
  std::unordered_map<int, Entry> entries_;
};

}  // namespace probslam
