#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "probslam/core/angle.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"

using namespace probslam;

namespace {

Eigen::VectorXd beam_fan(int n, double first, double last) { return Eigen::VectorXd::LinSpaced(n, first, last); }

// Table 9.2 as printed (line 8 corrected), with the loop over all beams of line 5.
double brute_force_ism(double cx, double cy, const Eigen::Vector3d& x, const Eigen::VectorXd& z,
                       const Eigen::VectorXd& th, const ConeModel& m) {
  const double r = std::sqrt((cx - x[0]) * (cx - x[0]) + (cy - x[1]) * (cy - x[1]));
  const double phi = std::atan2(cy - x[1], cx - x[0]) - x[2];
  int k = -1;
  double best = std::numeric_limits<double>::infinity();
  for (int j = 0; j < z.size(); ++j) {
    if (!(std::isfinite(z[j]) && z[j] >= 0)) continue;
    const double d = std::fabs(wrap_angle(phi - th[j]));
    if (d < best) best = d, k = j;
  }
  if (k < 0) return m.l0;
  if (r > std::min(m.z_max, z[k] + m.alpha / 2) || std::fabs(wrap_angle(phi - th[k])) > m.beta / 2) return m.l0;
  if (z[k] < m.z_max && std::fabs(r - z[k]) < m.alpha / 2) return m.l_occ;
  if (r <= z[k]) return m.l_free;
  return m.l0;
}

}  // namespace

TEST(OccupancyGrid2D, GeometryAndPrior) {
  OccupancyGrid2D g(0.5, 4, 3, {-1.0, 2.0}, 0.3, LogOddsClamp::none());
  EXPECT_EQ(g.cell_of(-1.0, 2.0), Eigen::Vector2i(0, 0));
  EXPECT_EQ(g.cell_of(0.99, 3.49), Eigen::Vector2i(2, 3));
  EXPECT_EQ(g.cell_of(1.0, 2.0), Eigen::Vector2i(0, 4));  // right edge belongs to the next cell
  EXPECT_EQ(g.cell_center(1, 2), Eigen::Vector2d(0.25, 2.75));
  EXPECT_NEAR(g.probability()(2, 3), 0.3, 1e-12);
  EXPECT_THROW(OccupancyGrid2D(0.0, 4, 3), std::invalid_argument);
  EXPECT_THROW(OccupancyGrid2D(NAN, 4, 3), std::invalid_argument);
  EXPECT_THROW(OccupancyGrid2D(0.1, 0, 3), std::invalid_argument);
  EXPECT_THROW(OccupancyGrid2D(0.1, 4, -1), std::invalid_argument);
  EXPECT_THROW(OccupancyGrid2D(0.1, 4, 3, {NAN, 0.0}), std::invalid_argument);
  EXPECT_THROW(OccupancyGrid2D(0.1, 4, 3, {0, 0}, 1.0), std::invalid_argument);
}

TEST(OccupancyGrid2D, ConeScanEqualsAllCellsLoop) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  OccupancyGrid2D g(0.1, 90, 70, {-4.0, -3.0}, 0.4, LogOddsClamp::none());
  Eigen::MatrixXd expected = g.log_odds();
  for (int scan = 0; scan < 5; ++scan) {
    const Eigen::Vector3d x(-4 + 9 * u(rng), -3 + 7 * u(rng), 6 * u(rng) - 3);
    const int n = 10 + scan * 7;
    Eigen::VectorXd th = beam_fan(n, -1.2, 1.9), z(n);
    for (int j = 0; j < n; ++j) z[j] = 0.3 + 4.5 * u(rng);
    z[1] = NAN;  // left out as if that beam did not exist
    z[2] = 5.0;  // a max-range reading
    const ConeModel m{5.0, 0.2, 0.15, g.prior_log_odds(), 0.9, -0.7};
    g.insert_cone_scan(x, z, th, m.z_max, m.alpha, m.beta, m.l_occ, m.l_free);
    for (int r = 0; r < g.height(); ++r)
      for (int c = 0; c < g.width(); ++c) {
        const Eigen::Vector2d cc = g.cell_center(r, c);
        expected(r, c) += brute_force_ism(cc.x(), cc.y(), x, z, th, m) - m.l0;
      }
    ASSERT_EQ((expected - Eigen::MatrixXd(g.log_odds())).cwiseAbs().maxCoeff(), 0.0) << "scan " << scan;
  }
}

TEST(OccupancyGrid2D, InsertRaysHitsMissesAndBounds) {
  OccupancyGrid2D g(0.1, 100, 100, {-5.0, -5.0});
  const double l0 = g.prior_log_odds(), hit = logit(0.7), miss = logit(0.4);
  Eigen::VectorXd z(4), th(4);
  z << 2.0, 2.0, 3.0, 9.0;  // a duplicated beam, another hit, a max-range reading
  th << 0.0, 0.0, kPi / 2, kPi;
  const Eigen::Vector3d x(0.05, 0.05, 0.0);
  g.insert_rays(x, z, th, 8.0);
  const auto at = [&](double px, double py) {
    const Eigen::Vector2i c = g.cell_of(px, py);
    return g.log_odds()(c[0], c[1]);
  };
  EXPECT_DOUBLE_EQ(at(2.05, 0.05), hit);
  EXPECT_DOUBLE_EQ(at(1.0, 0.05), miss);          // traversed once despite two beams
  EXPECT_DOUBLE_EQ(at(0.05, 0.05), miss);         // the sensor's own cell
  EXPECT_DOUBLE_EQ(at(0.05, 3.05), hit);
  EXPECT_DOUBLE_EQ(at(-4.9, 0.05), miss);         // cleared to the map's edge, no hit
  EXPECT_DOUBLE_EQ(at(3.0, 3.0), l0);             // untouched
  // NaN, inf and negative readings are skipped; an empty or mismatched scan is refused.
  const Eigen::MatrixXd before = g.log_odds();
  Eigen::VectorXd bad(3), bad_th = beam_fan(3, -1, 1);
  bad << NAN, INFINITY, -1.0;
  EXPECT_EQ(g.insert_rays(x, bad, bad_th, 8.0), 0u);
  EXPECT_EQ((before - Eigen::MatrixXd(g.log_odds())).norm(), 0.0);
  EXPECT_THROW(g.insert_rays(Eigen::Vector3d(NAN, 0, 0), z, th, 8.0), std::invalid_argument);
  EXPECT_THROW(g.insert_rays(x, Eigen::VectorXd(0), Eigen::VectorXd(0), 8.0), std::invalid_argument);
  EXPECT_THROW(g.insert_rays(x, z, beam_fan(3, 0, 1), 8.0), std::invalid_argument);
  EXPECT_THROW(g.insert_rays(x, z, th, -1.0), std::invalid_argument);
  // A sensor outside the map whose rays cross it: clipped, never out of bounds.
  OccupancyGrid2D small(0.1, 20, 20, {0.0, 0.0});
  Eigen::VectorXd one(1), zero(1);
  one << 10.0;
  zero << 0.0;
  EXPECT_EQ(small.insert_rays(Eigen::Vector3d(-3.0, 1.03, 0.0), one, zero, 20.0), 20u);
  EXPECT_EQ(small.insert_rays(Eigen::Vector3d(-30.0, 1.03, 0.0), one, zero, 20.0), 0u);
}

TEST(OccupancyGrid2D, FootprintFuseAndGrow) {
  OccupancyGrid2D a(0.1, 30, 30, {0.0, 0.0}, 0.5, LogOddsClamp::none());
  EXPECT_EQ(a.clear_footprint(Eigen::Vector3d(1.55, 1.55, 0.0), 0.25, -2.0), 21u);  // 21 centres within 0.25 m of a cell centre
  OccupancyGrid2D b = a;
  b.log_odds()(0, 0) = 3.0;
  a.log_odds()(1, 1) = 1.0;
  const OccupancyGrid2D f = fuse_max({&a, &b});
  EXPECT_EQ(f.log_odds()(0, 0), 3.0);
  EXPECT_EQ(f.log_odds()(1, 1), 1.0);
  EXPECT_EQ(f.log_odds()(15, 15), -2.0);
  OccupancyGrid2D other(0.2, 30, 30);
  EXPECT_THROW(fuse_max({&a, &other}), std::invalid_argument);
  EXPECT_THROW(fuse_max({}), std::invalid_argument);
  const OccupancyGrid2D grown = a.grown_to_include(-1.0, -0.05, 3.5, 2.0);
  EXPECT_EQ(grown.width(), 30 + 10 + 5);
  EXPECT_EQ(grown.height(), 30 + 1);
  EXPECT_NEAR(grown.origin().x(), -1.0, 1e-12);
  EXPECT_EQ(grown.log_odds()(2, 11), a.log_odds()(1, 1));
  EXPECT_EQ(grown.log_odds()(0, 0), a.prior_log_odds());
}

TEST(OccupancyGrid2D, ClampingBoundsEveryUpdate) {
  OccupancyGrid2D g(0.1, 50, 10, {0.0, 0.0});
  Eigen::VectorXd z(1), th(1);
  z << 2.0;
  th << 0.0;
  for (int i = 0; i < 50; ++i) g.insert_rays(Eigen::Vector3d(0.05, 0.55, 0.0), z, th, 4.0);
  EXPECT_NEAR(g.log_odds()(5, 20), logit(0.971), 1e-12);
  EXPECT_NEAR(g.log_odds()(5, 5), logit(0.1192), 1e-12);
}
