#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <functional>
#include <limits>
#include <random>
#include <stdexcept>

#include "probslam/core/angle.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/pose2_covariance.hpp"
#include "probslam/core/range_bearing_model.hpp"
#include "probslam/core/spatial_hash_2d.hpp"
#include "probslam/core/velocity_motion_model.hpp"
#include "probslam/core/ackermann_motion_model.hpp"

using namespace probslam;

namespace {

// Central differences with this step are accurate to ~1e-10 for these smooth models.
constexpr double kFdStep = 1e-6;
constexpr double kFdTolerance = 1e-7;

Eigen::MatrixXd numeric_jacobian(const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f,
                                 const Eigen::VectorXd& x, bool wrap_last_output_angle_rows = false) {
  const Eigen::VectorXd f0 = f(x);
  Eigen::MatrixXd j(f0.size(), x.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    Eigen::VectorXd a = x, b = x;
    a[i] += kFdStep;
    b[i] -= kFdStep;
    Eigen::VectorXd d = f(a) - f(b);
    if (wrap_last_output_angle_rows)
      for (Eigen::Index r = 0; r < d.size(); ++r) d[r] = wrap_angle(d[r]);
    j.col(i) = d / (2 * kFdStep);
  }
  return j;
}

}  // namespace

TEST(WrapAngle, RangeAndIdentity) {
  EXPECT_DOUBLE_EQ(wrap_angle(kPi), kPi);
  EXPECT_DOUBLE_EQ(wrap_angle(-kPi), kPi);
  EXPECT_DOUBLE_EQ(wrap_angle(3 * kPi), kPi);
  EXPECT_NEAR(wrap_angle(2 * kPi + 0.5), 0.5, 1e-12);
  EXPECT_NEAR(wrap_angle(-7.0), -7.0 + 2 * kPi, 1e-12);
  for (double a = -50.0; a < 50.0; a += 0.37) {
    const double w = wrap_angle(a);
    EXPECT_GT(w, -kPi);
    EXPECT_LE(w, kPi);
    EXPECT_NEAR(std::remainder(w - a, 2 * kPi), 0.0, 1e-9);
  }
}

TEST(Pose2, ComposeInverseBetween) {
  const Pose2 a(1.0, 2.0, 0.5), b(-0.3, 0.7, 2.9);
  const Pose2 ab = a.compose(b);
  const Pose2 back = a.between(ab);
  EXPECT_NEAR(back.x, b.x, 1e-12);
  EXPECT_NEAR(back.y, b.y, 1e-12);
  EXPECT_NEAR(back.theta, b.theta, 1e-12);
  const Pose2 identity = a.compose(a.inverse());
  EXPECT_NEAR(identity.vector().norm(), 0.0, 1e-12);
  EXPECT_NEAR(ab.theta, wrap_angle(0.5 + 2.9), 1e-12);
  const Eigen::Vector2d p(0.4, -1.1);
  EXPECT_NEAR((a.transform_to(a.transform_from(p)) - p).norm(), 0.0, 1e-12);
  EXPECT_THROW(Pose2::from_vector({NAN, 0, 0}), std::invalid_argument);
}

TEST(VelocityMotion, MatchesEquation1011AndStraightLine) {
  const Eigen::Vector3d x(1.0, -2.0, 0.3);
  const double v = 1.3, w = 0.7, dt = 0.5;
  // Eq. 10.11 written with v / w, valid away from w = 0.
  const Eigen::Vector3d expected(x[0] - v / w * std::sin(x[2]) + v / w * std::sin(x[2] + w * dt),
                                 x[1] + v / w * std::cos(x[2]) - v / w * std::cos(x[2] + w * dt), x[2] + w * dt);
  EXPECT_LT((velocity_motion(x, v, w, dt) - expected).norm(), 1e-12);
  const Eigen::Vector3d straight = velocity_motion(x, v, 0.0, dt);
  EXPECT_LT((straight - Eigen::Vector3d(x[0] + v * dt * std::cos(x[2]), x[1] + v * dt * std::sin(x[2]), x[2])).norm(), 1e-15);
  // Continuous across w = 0: the tiny-w arc converges to the straight line.
  EXPECT_LT((velocity_motion(x, v, 1e-9, dt) - straight).norm(), 1e-9);
  EXPECT_LT((velocity_motion(x, v, -1e-9, dt) - straight).norm(), 1e-9);
  EXPECT_GT(velocity_motion(x, 0.0, 10.0, 1.0)[2], -kPi);  // heading wrapped
}

TEST(VelocityMotion, JacobiansMatchFiniteDifferences) {
  for (double w : {0.7, -1.9, 1e-5, 0.0}) {
    const Eigen::Vector3d x(0.5, 0.2, 2.0);
    const double v = 0.9, dt = 0.4;
    const auto f_pose = [&](const Eigen::VectorXd& p) -> Eigen::VectorXd { return velocity_motion(p, v, w, dt); };
    const auto f_ctrl = [&](const Eigen::VectorXd& u) -> Eigen::VectorXd { return velocity_motion(x, u[0], u[1], dt); };
    EXPECT_LT((velocity_motion_jacobian(x, v, w, dt) - numeric_jacobian(f_pose, x, true)).norm(), kFdTolerance) << w;
    EXPECT_LT((Eigen::MatrixXd(velocity_motion_control_jacobian(x, v, w, dt)) -
               numeric_jacobian(f_ctrl, Eigen::Vector2d(v, w), true)).norm(),
              kFdTolerance)
        << w;
  }
}

TEST(VelocityMotion, RejectsBadInput) {
  const Eigen::Vector3d x(0, 0, 0);
  EXPECT_THROW(velocity_motion(x, 1.0, 0.0, 0.0), std::invalid_argument);
  EXPECT_THROW(velocity_motion(x, 1.0, 0.0, -1.0), std::invalid_argument);
  EXPECT_THROW(velocity_motion(x, NAN, 0.0, 1.0), std::invalid_argument);
  EXPECT_THROW(velocity_motion(Eigen::Vector3d(0, INFINITY, 0), 1.0, 0.0, 1.0), std::invalid_argument);
  try {
    velocity_motion(x, 1.0, 0.0, 0.0);
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("dt", 0), 0u);
  }
}

// The README's equations of the Victoria Park data, written out in the world frame: the
// independent reference the model's sensor-frame increment is checked against.
Eigen::Vector3d guivant_nebot_step(const Eigen::Vector3d& x, double ve, double alpha, double dt,
                                   const AckermannGeometry& g) {
  const double vc = ve / (1.0 - std::tan(alpha) * g.encoder_offset / g.wheelbase);
  const double w = vc / g.wheelbase * std::tan(alpha), a = g.sensor_ahead, b = g.sensor_left;
  const double c = std::cos(x[2]), s = std::sin(x[2]);
  return {x[0] + dt * (vc * c - w * (a * s + b * c)), x[1] + dt * (vc * s + w * (a * c - b * s)),
          wrap_angle(x[2] + dt * w)};
}

TEST(AckermannMotion, MatchesTheWorldFrameEquations) {
  const AckermannGeometry g;
  for (double alpha : {0.0, 0.3, -0.45, 1e-7}) {
    for (double ve : {0.0, 3.2, -1.5}) {
      const Eigen::Vector3d x(12.0, -4.0, 2.9);
      EXPECT_LT((ackermann_motion(x, ve, alpha, 0.025, g) - guivant_nebot_step(x, ve, alpha, 0.025, g)).norm(), 1e-13)
          << ve << " " << alpha;
    }
  }
  // Straight ahead the sensor moves along the heading, whatever its mounting.
  const Eigen::Vector3d straight = ackermann_motion(Eigen::Vector3d(1, 2, 0.5), 4.0, 0.0, 0.5, g);
  EXPECT_LT((straight - Eigen::Vector3d(1 + 2 * std::cos(0.5), 2 + 2 * std::sin(0.5), 0.5)).norm(), 1e-14);
}

TEST(AckermannMotion, JacobiansMatchFiniteDifferences) {
  AckermannGeometry g;
  g.sensor_left = -0.3;  // a mounting on the other side exercises b's sign
  for (double alpha : {0.35, -0.5, 0.0}) {
    const Eigen::Vector3d x(0.5, 0.2, 3.0);
    const double ve = 2.5, dt = 0.2;
    const auto f_pose = [&](const Eigen::VectorXd& p) -> Eigen::VectorXd { return ackermann_motion(p, ve, alpha, dt, g); };
    const auto f_ctrl = [&](const Eigen::VectorXd& u) -> Eigen::VectorXd {
      return ackermann_motion(x, u[0], u[1], dt, g);
    };
    const auto f_inc = [&](const Eigen::VectorXd& u) -> Eigen::VectorXd {
      return ackermann_increment(u[0], u[1], dt, g);
    };
    const Eigen::Vector2d u(ve, alpha);
    EXPECT_LT((ackermann_motion_jacobian(x, ve, alpha, dt, g) - numeric_jacobian(f_pose, x, true)).norm(), kFdTolerance)
        << alpha;
    EXPECT_LT((Eigen::MatrixXd(ackermann_motion_control_jacobian(x, ve, alpha, dt, g)) -
               numeric_jacobian(f_ctrl, u, true)).norm(),
              kFdTolerance)
        << alpha;
    EXPECT_LT((Eigen::MatrixXd(ackermann_increment_jacobian(ve, alpha, dt, g)) - numeric_jacobian(f_inc, u)).norm(),
              kFdTolerance)
        << alpha;
  }
}

TEST(AckermannMotion, RejectsBadInput) {
  const Eigen::Vector3d x(0, 0, 0);
  const AckermannGeometry g;
  const auto starts_with = [](const std::function<void()>& f, const std::string& name) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what()).rfind(name, 0) == 0;
    }
    return false;
  };
  EXPECT_TRUE(starts_with([&] { ackermann_motion(x, 1.0, 0.1, 0.0, g); }, "dt"));
  EXPECT_TRUE(starts_with([&] { ackermann_motion(x, NAN, 0.1, 0.1, g); }, "speed"));
  EXPECT_TRUE(starts_with([&] { ackermann_motion(x, 1.0, 1.6, 0.1, g); }, "steering"));
  // tan(1.4) H / L = 1.55: the encoder wheel would turn about itself.
  EXPECT_TRUE(starts_with([&] { ackermann_increment(1.0, 1.4, 0.1, g); }, "steering"));
  EXPECT_TRUE(starts_with([&] { ackermann_motion(Eigen::Vector3d(0, NAN, 0), 1.0, 0.1, 0.1, g); }, "pose"));
  EXPECT_TRUE(starts_with([&] { ackermann_motion(x, 1e300, 0.1, 1e300, g); }, "speed"));
  AckermannGeometry bad;
  bad.wheelbase = 0.0;
  EXPECT_TRUE(starts_with([&] { ackermann_motion(x, 1.0, 0.1, 0.1, bad); }, "wheelbase"));
  bad = g;
  bad.sensor_left = INFINITY;
  EXPECT_TRUE(starts_with([&] { ackermann_increment_jacobian(1.0, 0.1, 0.1, bad); }, "sensor_left"));
}

TEST(RangeBearing, ValuesJacobiansAndInverse) {
  const Eigen::Vector3d x(1.0, 1.0, 2.5);
  const Eigen::Vector2d m(-2.0, 3.0);
  const Eigen::Vector2d z = range_bearing(x, m);
  EXPECT_NEAR(z[0], std::hypot(-3.0, 2.0), 1e-12);
  EXPECT_NEAR(z[1], wrap_angle(std::atan2(2.0, -3.0) - 2.5), 1e-12);
  const auto j = range_bearing_jacobians(x, m);
  const auto f_pose = [&](const Eigen::VectorXd& p) -> Eigen::VectorXd { return range_bearing(p, m); };
  const auto f_lm = [&](const Eigen::VectorXd& l) -> Eigen::VectorXd { return range_bearing(x, Eigen::Vector2d(l)); };
  EXPECT_LT((Eigen::MatrixXd(j.pose) - numeric_jacobian(f_pose, x, true)).norm(), kFdTolerance);
  EXPECT_LT((Eigen::MatrixXd(j.landmark) - numeric_jacobian(f_lm, m, true)).norm(), kFdTolerance);
  // Inverse model: places the landmark back, and its Jacobians match finite differences.
  EXPECT_LT((landmark_from_range_bearing(x, z) - m).norm(), 1e-12);
  const auto ji = landmark_from_range_bearing_jacobians(x, z);
  const auto g_pose = [&](const Eigen::VectorXd& p) -> Eigen::VectorXd { return landmark_from_range_bearing(p, z); };
  const auto g_z = [&](const Eigen::VectorXd& zz) -> Eigen::VectorXd { return landmark_from_range_bearing(x, Eigen::Vector2d(zz)); };
  EXPECT_LT((Eigen::MatrixXd(ji.pose) - numeric_jacobian(g_pose, x)).norm(), kFdTolerance);
  EXPECT_LT((Eigen::MatrixXd(ji.landmark) - numeric_jacobian(g_z, z)).norm(), kFdTolerance);
  // With signature: the signature passes through with unit Jacobian.
  const auto j3 = range_bearing_jacobians(x, Eigen::Vector3d(m[0], m[1], 4.0));
  EXPECT_EQ(j3.landmark(2, 2), 1.0);
  EXPECT_EQ(range_bearing(x, Eigen::Vector3d(m[0], m[1], 4.0))[2], 4.0);
  EXPECT_THROW(range_bearing_jacobians(x, Eigen::Vector2d(1.0, 1.0)), std::invalid_argument);
  EXPECT_THROW(range_bearing(x, Eigen::Vector2d(NAN, 1.0)), std::invalid_argument);
  EXPECT_THROW(landmark_from_range_bearing(x, Eigen::Vector2d(-1.0, 0.0)), std::invalid_argument);
}

// Negative and huge coordinates: the hash's cell keys must stay defined (the sanitizer
// build caught a left shift of a negative index) and queries must equal a brute-force scan.
TEST(SpatialHash2D, QueriesMatchBruteForceAtAnyCoordinate) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-50.0, 50.0);
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> pts(200, 2);
  for (int i = 0; i < 200; ++i) pts.row(i) << u(rng), u(rng);
  pts.row(0) << 1e300, -1e300;
  pts.row(1) << -1e-300, 3.0;
  pts.row(2) << -1e18, 1e18;
  probslam::SpatialHash2D hash(2.0);
  for (int i = 0; i < pts.rows(); ++i) hash.insert(i, pts(i, 0), pts(i, 1));
  const double queries[][3] = {{0, 0, 5}, {-30, -30, 7}, {1e300, -1e300, 1}, {-1e18, 1e18, 10}, {12, -40, 0.5}};
  for (const auto& q : queries) {
    std::vector<int> got;
    hash.query(q[0], q[1], q[2], pts, got);
    std::sort(got.begin(), got.end());
    std::vector<int> want;
    for (int i = 0; i < pts.rows(); ++i) {
      const double dx = pts(i, 0) - q[0], dy = pts(i, 1) - q[1];
      if (dx * dx + dy * dy <= q[2] * q[2]) want.push_back(i);
    }
    EXPECT_EQ(got, want) << "query at " << q[0] << ", " << q[1];
  }
}

TEST(Pose2Covariance, JacobiansMatchFiniteDifferences) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  auto vec = [](const Pose2& p) -> Eigen::VectorXd { return p.vector(); };
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d a(u(rng), u(rng), u(rng) * 0.9), b(u(rng), u(rng), u(rng) * 0.9);
    Eigen::Matrix3d Ja, Jb;
    compose_jacobians(a, b, Ja, Jb);
    auto f_a = [&](const Eigen::VectorXd& x) { return vec(Pose2::from_vector(x).compose(Pose2::from_vector(b))); };
    auto f_b = [&](const Eigen::VectorXd& x) { return vec(Pose2::from_vector(a).compose(Pose2::from_vector(x))); };
    auto f_inv = [&](const Eigen::VectorXd& x) { return vec(Pose2::from_vector(x).inverse()); };
    EXPECT_LT((Eigen::MatrixXd(Ja) - numeric_jacobian(f_a, a, true)).norm(), kFdTolerance);
    EXPECT_LT((Eigen::MatrixXd(Jb) - numeric_jacobian(f_b, b, true)).norm(), kFdTolerance);
    EXPECT_LT((Eigen::MatrixXd(inverse_jacobian(a)) - numeric_jacobian(f_inv, a, true)).norm(), kFdTolerance);
    // compose_covariance is J_a Sa J_a^T + J_b Sb J_b^T, symmetric.
    const Eigen::Matrix3d Sa = Eigen::Vector3d(0.1, 0.2, 0.03).asDiagonal(), Sb = Eigen::Vector3d(0.05, 0.01, 0.02).asDiagonal();
    const Eigen::Matrix3d S = compose_covariance(a, Sa, b, Sb);
    EXPECT_LT((S - (Ja * Sa * Ja.transpose() + Jb * Sb * Jb.transpose())).norm(), 1e-12);
    EXPECT_EQ(S, S.transpose());
  }
  EXPECT_LT((frame_rotation(0.7).topLeftCorner<2, 2>() - rotation_matrix(0.7)).norm(), 1e-15);
}
