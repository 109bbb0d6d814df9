// Reliability round 3 (issue 33) for the laser SLAM classes: a failed add_scan or add_scans
// leaves IncrementalScanMatcher, SubmapSlam2D and GridFastSlam exactly as they were (field by
// field), and the next valid scan gives what a twin that never saw the bad call gives; a
// particle count whose maps could not fit max_map_bytes is refused before anything is allocated.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "probslam/core/angle.hpp"
#include "probslam/fastslam/grid_fast_slam.hpp"
#include "probslam/slam2d/incremental_scan_matcher.hpp"
#include "probslam/slam2d/submap_slam.hpp"
#include "test_support.hpp"

using namespace probslam;
using probslam::test_support::expect_invalid;

namespace {

const double kInf = std::numeric_limits<double>::infinity();

Eigen::VectorXd fan() { return Eigen::VectorXd::LinSpaced(91, -kPi / 2, kPi / 2); }

Eigen::VectorXd cast(const Eigen::Vector3d& pose) { return test_support::cast(pose, fan(), test_support::room_walls()); }

/// Scan k of a drive along the room: pose (-3 + 0.3 k, -0.5, 0.05 k).
Eigen::Vector3d pose_at(int k) { return {-3.0 + 0.3 * k, -0.5, 0.05 * k}; }

/// Rows first..first+n-1 of the drive as add_scans' arrays; the last row's odometry and timestamp
/// may be replaced.
struct Batch {
  RowMatrixXd ranges, angles, odometry;
  Eigen::VectorXd timestamps;
};
Batch batch(int first, int n) {
  Batch b{RowMatrixXd(n, fan().size()), RowMatrixXd(1, fan().size()), RowMatrixXd(n, 3), Eigen::VectorXd(n)};
  b.angles.row(0) = fan().transpose();
  for (int k = 0; k < n; ++k) {
    b.ranges.row(k) = cast(pose_at(first + k)).transpose();
    b.odometry.row(k) = pose_at(first + k).transpose();
    b.timestamps[k] = first + k;
  }
  return b;
}

template <typename Mapper>
void feed(Mapper& m, int first, int n) {
  const Batch b = batch(first, n);
  m.add_scans(b.ranges, b.angles, b.odometry, b.timestamps);
}

/// Everything observable of each class, compared field by field.
struct View {
  std::vector<Eigen::MatrixXd> matrices;
  std::vector<double> numbers;
  bool operator==(const View& o) const {
    if (matrices.size() != o.matrices.size() || numbers != o.numbers) return false;
    for (std::size_t k = 0; k < matrices.size(); ++k)
      if (matrices[k].rows() != o.matrices[k].rows() || matrices[k].cols() != o.matrices[k].cols() ||
          matrices[k] != o.matrices[k])
        return false;
    return true;
  }
};

Eigen::MatrixXd cells(const OccupancyGrid2D& g) {
  Eigen::MatrixXd m = g.log_odds();
  m.conservativeResize(m.rows(), m.cols() + 1);  // the origin and size count too
  m.col(m.cols() - 1).setConstant(g.origin().x() + 1e3 * g.origin().y());
  return m;
}

Eigen::MatrixXd rows(const std::vector<Eigen::Vector3d>& v) {
  Eigen::MatrixXd m(static_cast<Eigen::Index>(v.size()), 3);
  for (std::size_t k = 0; k < v.size(); ++k) m.row(static_cast<Eigen::Index>(k)) = v[k].transpose();
  return m;
}

Eigen::MatrixXd vec(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

View view(const IncrementalScanMatcher& m) {
  View v;
  std::vector<Eigen::Vector3d> poses;
  for (const ScanEstimate& e : m.estimates()) {
    poses.push_back(e.pose);
    v.numbers.insert(v.numbers.end(), {double(e.matched), double(e.fallback), double(e.submap), e.match_quality});
  }
  v.matrices.push_back(rows(poses));
  v.matrices.push_back(vec(m.timestamps()));
  for (const Submap& s : m.submaps()) {
    v.matrices.push_back(cells(s.grid));
    v.numbers.insert(v.numbers.end(), {s.travel, double(s.matched), double(s.scans.size())});
  }
  return v;
}

View view(const SubmapSlam2D& m) {
  View v = view(m.frontend());
  v.matrices.push_back(rows(m.scan_poses()));
  v.matrices.push_back(rows(m.submap_poses()));
  const SubmapSlamSummary s = m.summary();
  v.numbers.insert(v.numbers.end(), {double(s.scans), double(s.submaps), double(s.closures_searched),
                                     double(s.closures_accepted), double(s.optimizations), s.final_chi2,
                                     double(m.constraints().size())});
  if (m.num_scans() > 0) v.matrices.push_back(cells(m.map()));
  return v;
}

View view(const GridFastSlam& m) {
  View v;
  v.matrices.push_back(m.poses());
  v.matrices.push_back(m.log_weights());
  v.matrices.push_back(vec(m.timestamps()));
  for (int k = 0; k < m.num_particles(); ++k) {
    v.matrices.push_back(m.scan_poses(k));
    if (m.num_scans() > 0) v.matrices.push_back(cells(m.map(k)));
  }
  const GridFastSlamSummary s = m.summary();
  v.numbers.insert(v.numbers.end(), {double(m.num_scans()), double(s.scans), double(s.updates), double(s.resamples),
                                     double(s.matched), double(s.fallbacks), s.effective_sample_size});
  return v;
}

GridFastSlamOptions rbpf(GridProposal proposal) {
  GridFastSlamOptions o;
  o.num_particles = 4;
  o.proposal = proposal;
  o.filter.max_usable_range = 8.0;
  o.update.distance = 0.2;
  o.seed = 7;
  return o;
}

IncrementalScanMatcherOptions frontend() {
  IncrementalScanMatcherOptions o;
  o.filter.max_usable_range = 8.0;
  o.submap_distance = 1.0;  // several submaps in the drive
  return o;
}

SubmapSlamOptions submap_slam() {
  SubmapSlamOptions o;
  o.frontend = frontend();
  return o;
}

/// The bad calls and the names their errors must start with.
template <typename Mapper>
void bad_calls_change_nothing(const std::function<std::unique_ptr<Mapper>()>& make) {
  auto obj = make(), twin = make();
  feed(*obj, 0, 4);
  feed(*twin, 0, 4);
  const View before = view(*obj);
  ASSERT_TRUE(before == view(*twin));
  struct Bad {
    double x, t;
    const char* name;
  };
  for (const Bad& bad : {Bad{pose_at(6).x(), kInf, "timestamps[2]"}, Bad{2e9, 6.0, "odometry[2]"},
                         Bad{1e8, 6.0, "odometry"}}) {
    Batch b = batch(4, 3);
    b.odometry(2, 0) = bad.x;
    b.timestamps[2] = bad.t;
    expect_invalid([&] { obj->add_scans(b.ranges, b.angles, b.odometry, b.timestamps); }, bad.name);
    EXPECT_TRUE(before == view(*obj)) << bad.name;
  }
  // One scan, 1e8 m away: refused on the state (the maps' limit), nothing kept.
  const Batch b = batch(4, 1);
  expect_invalid([&] { obj->add_scan(b.ranges.row(0).transpose(), fan(), Eigen::Vector3d(1e8, 0, 0), 4.0); },
                 "odometry");
  EXPECT_TRUE(before == view(*obj));
  expect_invalid([&] { obj->add_scan(b.ranges.row(0).transpose(), fan(), pose_at(4), kInf); }, "timestamp");
  EXPECT_TRUE(before == view(*obj));
  // The next valid scans give what the twin gives.
  feed(*obj, 4, 3);
  feed(*twin, 4, 3);
  EXPECT_TRUE(view(*obj) == view(*twin));
}

}  // namespace

TEST(ReliabilitySlam2D, IncrementalScanMatcherBadCallsChangeNothing) {
  bad_calls_change_nothing<IncrementalScanMatcher>([] { return std::make_unique<IncrementalScanMatcher>(frontend()); });
}

TEST(ReliabilitySlam2D, SubmapSlamBadCallsChangeNothing) {
  bad_calls_change_nothing<SubmapSlam2D>([] { return std::make_unique<SubmapSlam2D>(submap_slam()); });
}

TEST(ReliabilitySlam2D, SubmapSlamStartedOnAMapBadCallsChangeNothing) {
  // A batch refused midway rebuilds the open submap's grid from its scans (the snapshot holds no
  // copy of it): on a run started from a saved map, submap 0 starts as that map.
  bad_calls_change_nothing<SubmapSlam2D>([] {
    OccupancyGrid2D room = OccupancyGrid2D::covering(-6.0, -5.0, 6.0, 5.0, frontend().resolution);
    for (int k = 0; k < 10; ++k) {
      const Eigen::Vector3d at(-4.0 + 0.8 * k, 0.5, 0.3 * k);
      room.insert_rays(at, cast(at), fan(), 8.0);
    }
    SubmapSlamOptions o = submap_slam();
    o.frontend.submap_distance = 2.0;  // the failing batch lies in submap 0, the map
    auto m = std::make_unique<SubmapSlam2D>(o);
    m->start_from_map(room, pose_at(0));
    return m;
  });
}

TEST(ReliabilitySlam2D, GridFastSlamMotionProposalBadCallsChangeNothing) {
  bad_calls_change_nothing<GridFastSlam>([] { return std::make_unique<GridFastSlam>(rbpf(GridProposal::kMotion)); });
}

TEST(ReliabilitySlam2D, GridFastSlamScanMatchingBadCallsChangeNothing) {
  bad_calls_change_nothing<GridFastSlam>(
      [] { return std::make_unique<GridFastSlam>(rbpf(GridProposal::kScanMatching)); });
}

TEST(ReliabilitySlam2D, GridFastSlamImprovedOdometryBadCallsChangeNothing) {
  bad_calls_change_nothing<GridFastSlam>(
      [] { return std::make_unique<GridFastSlam>(rbpf(GridProposal::kImprovedOdometry)); });
}

TEST(ReliabilitySlam2D, SubmapSlamMapRefusesBadResolution) {
  SubmapSlam2D m(submap_slam());
  feed(m, 0, 3);
  expect_invalid([&] { m.map(std::nan("")); }, "resolution");
  expect_invalid([&] { m.map(-1.0); }, "resolution");
  expect_invalid([&] { m.map(kInf); }, "resolution");
  EXPECT_DOUBLE_EQ(m.map(0.0).resolution(), m.options().frontend.resolution);
  EXPECT_DOUBLE_EQ(m.map(0.1).resolution(), 0.1);
}

TEST(ReliabilitySlam2D, GridFastSlamRefusesParticlesBeyondTheMapBudget) {
  GridFastSlamOptions o;
  o.num_particles = kGridFastSlamMaxParticles;
  expect_invalid([&] { GridFastSlam m(o); }, "num_particles");
  o.num_particles = 30;
  o.max_map_bytes = 1e6;
  expect_invalid([&] { GridFastSlam m(o); }, "num_particles");
  o.max_map_bytes = 0.0;
  expect_invalid([&] { GridFastSlam m(o); }, "max_map_bytes");
  o.max_map_bytes = std::nan("");
  expect_invalid([&] { GridFastSlam m(o); }, "max_map_bytes");
}

/// The least max_map_bytes GridFastSlam(o) accepts, within 1% (construction refuses before it
/// allocates, so the search is quick).
double smallest_budget(GridFastSlamOptions o) {
  double lo = 1e5, hi = 1e11;
  while (hi / lo > 1.01) {
    o.max_map_bytes = std::sqrt(lo * hi);
    try {
      GridFastSlam m(o);
      hi = o.max_map_bytes;
    } catch (const std::invalid_argument&) {
      lo = o.max_map_bytes;
    }
  }
  return hi;
}

TEST(ReliabilitySlam2D, GridFastSlamUpdateOverTheMapBudgetChangesNothing) {
  // A bound the first update fits (one shared map, little live) but the second does not (every
  // particle then holds its own tiles): a batch of both is undone whole, and the filter goes on
  // as its twin that never saw the batch.
  GridFastSlamOptions o = rbpf(GridProposal::kMotion);
  o.num_particles = 20;
  const double smallest = smallest_budget(o);
  o.max_map_bytes = smallest;
  GridFastSlam probe(o);
  feed(probe, 0, 1);
  const double first_scan = static_cast<double>(probe.tiled_map(0).live_tiles()) * sizeof(TiledGrid2D::Tile);
  o.max_map_bytes = smallest + 2.0 * first_scan + 2e6;
  GridFastSlam m(o), twin(o);
  feed(m, 0, 1);
  feed(twin, 0, 1);
  const View before = view(m);
  expect_invalid([&] { feed(m, 1, 6); }, "num_particles");
  EXPECT_TRUE(before == view(m));
  EXPECT_EQ(m.num_scans(), 1);
  // The first update alone fits; the twin agrees.
  feed(m, 1, 1);
  feed(twin, 1, 1);
  EXPECT_EQ(m.summary().updates, 1);
  EXPECT_TRUE(view(m) == view(twin));
}
