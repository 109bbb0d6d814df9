#include "probslam/slam2d/correlative_scan_matcher.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/pose2.hpp"

namespace probslam {

namespace {

/// Relative slack on branch-and-bound bounds: a bound and the exact score of a leaf are sums of
/// the same floats in the same order, so a bound can fall short only by the rounding of the
/// prior term; this keeps such a node from being pruned.
constexpr double kBoundSlack = 1e-12;
/// Gauss-Newton refinement: at most this many iterations, each with at most kMaxHalvings step
/// halvings, stopping when the step is below kRefineStepTolerance (m and rad: far below any
/// map's resolution).
constexpr int kMaxRefineIterations = 30;
constexpr int kMaxHalvings = 12;
constexpr double kRefineStepTolerance = 1e-7;
/// The response surface is sampled at +-kSurfaceSteps steps per axis around the optimum, the
/// steps set from the Laplace approximation so that the samples reach 3 standard deviations.
constexpr int kSurfaceSteps = 3;

struct Cell {
  int col, row;
};

/// A node of the branch-and-bound search: rotation a, translation offsets [cx, cx + 2^level)
/// x [cy, cy + 2^level) in cells, and an upper bound of the score of every pose it covers.
struct Node {
  int a, cx, cy;
  double bound;
};

struct SearchSpace {
  double res = 0, step = 0;
  int linear_cells = 0, angular_steps = 0;
  Eigen::Vector3d prior;
  bool use_prior = false;
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();  // prior information (inverse covariance)
  double info_xy_min_eigen = 0;                    // smallest eigenvalue of its xy block
  Eigen::Vector2d xy_per_theta = Eigen::Vector2d::Zero();  // -Lxx^-1 l_xtheta
  double theta_schur = 0;                                  // l_thth - l_xth^T Lxx^-1 l_xth
  std::vector<std::vector<Cell>> scans;                    // discretised, per rotation

  double theta_offset(int a) const { return (a - angular_steps) * step; }
  double prior_term(int a, int cx, int cy) const {
    if (!use_prior) return 0.0;
    const Eigen::Vector3d d(cx * res, cy * res, theta_offset(a));
    return -0.5 * d.dot(info * d);
  }
  /// The largest prior term over the translations [cx, cx+size) x [cy, cy+size) at rotation a:
  /// the quadratic's unconstrained minimum over (x, y) plus the smallest eigenvalue times the
  /// squared distance from its minimiser to the box (a lower bound of the quadratic there).
  double prior_bound(int a, int cx, int cy, int size) const {
    if (!use_prior) return 0.0;
    const double dth = theta_offset(a);
    const Eigen::Vector2d best = xy_per_theta * dth;
    const double lo_x = cx * res, hi_x = (cx + size - 1) * res;
    const double lo_y = cy * res, hi_y = (cy + size - 1) * res;
    const double ex = std::max({lo_x - best.x(), 0.0, best.x() - hi_x});
    const double ey = std::max({lo_y - best.y(), 0.0, best.y() - hi_y});
    const double q = dth * dth * theta_schur + info_xy_min_eigen * (ex * ex + ey * ey);
    return -0.5 * std::max(q, 0.0);
  }
};

}  // namespace

void MatchOptions::validate() const {
  require(std::isfinite(window.linear) && window.linear >= 0.0, "linear_window", "must be finite and >= 0");
  require(std::isfinite(window.angular) && window.angular >= 0.0 && window.angular <= kPi, "angular_window",
          "must be finite and in [0, pi]");
  require(std::isfinite(window.angular_step), "angular_step", "must be finite (<= 0: automatic)");
  require(std::isfinite(min_translation_std) && std::isfinite(min_rotation_std), "min_translation_std",
          "and min_rotation_std must be finite");
  require(!std::isnan(min_score) && min_score < std::numeric_limits<double>::infinity(), "min_score",
          "must be a number below +inf (-inf: no minimum)");
  if (use_prior) require_symmetric_positive_definite(prior_covariance, "prior_covariance", 1e-9);
}

CorrelativeScanMatcher::CorrelativeScanMatcher(LikelihoodField field, int max_level) : field_(std::move(field)) {
  require(max_level >= 0 && max_level <= kMaxLevel, "max_level", "must be in [0, 10]");
  pyramid_.resize(static_cast<std::size_t>(max_level) + 1);
  Level& base = pyramid_[0];
  base.width = field_.width();
  base.height = field_.height();
  base.values.assign(field_.log_likelihood().data(), field_.log_likelihood().data() + field_.log_likelihood().size());
  for (int k = 1; k <= max_level; ++k) {
    // Level k at (r, c): the maximum over rows [r, r + 2^k) and cols [c, c + 2^k), stored for
    // every window that meets the table (r, c >= -(2^k - 1)), from four level k-1 windows.
    Level& L = pyramid_[static_cast<std::size_t>(k)];
    const int half = 1 << (k - 1);
    L.pad = (1 << k) - 1;
    L.width = base.width + L.pad;
    L.height = base.height + L.pad;
    L.values.resize(static_cast<std::size_t>(L.width) * L.height);
    for (int i = 0; i < L.height; ++i) {
      const int r = i - L.pad;
      for (int j = 0; j < L.width; ++j) {
        const int c = j - L.pad;
        L.values[static_cast<std::size_t>(i) * L.width + j] =
            std::max(std::max(level_value(k - 1, r, c), level_value(k - 1, r, c + half)),
                     std::max(level_value(k - 1, r + half, c), level_value(k - 1, r + half, c + half)));
      }
    }
  }
}

float CorrelativeScanMatcher::level_value(int k, int row, int col) const {
  const Level& L = pyramid_[static_cast<std::size_t>(k)];
  const int i = row + L.pad, j = col + L.pad;
  if (static_cast<unsigned>(i) >= static_cast<unsigned>(L.height) ||
      static_cast<unsigned>(j) >= static_cast<unsigned>(L.width))
    return field_.floor_value();
  return L.values[static_cast<std::size_t>(i) * L.width + j];
}

double CorrelativeScanMatcher::evaluate(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& pose,
                                        const Eigen::Vector3d& prior, const Eigen::Matrix3d* prior_info,
                                        Eigen::Matrix3d* hessian, Eigen::Vector3d* gradient,
                                        double* quality) const {
  const double sigma = field_.options().sigma, p_rand = field_.options().p_rand;
  const Eigen::Matrix2d R = rotation_matrix(pose.z());
  const Eigen::Vector2d t = pose.head<2>();
  if (hessian) hessian->setZero();
  if (gradient) gradient->setZero();
  double sum = 0.0, fit = 0.0;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const Eigen::Vector2d q = R * points.row(i).transpose() + t;
    Eigen::Vector2d grad;
    const double d = field_.interpolate_distance(q.x(), q.y(), hessian ? &grad : nullptr);
    double log_p, f;
    field_.tabulated(d, &log_p, &f);
    sum += log_p;
    fit += f;
    if (!hessian) continue;
    // -log p(d) has gradient (d / sigma^2) w J with w the hit part's share of the mixture:
    // iteratively reweighted least squares on the distance, robust to stray points.
    const double w = (1.0 - p_rand) * f / std::exp(log_p) / (sigma * sigma);
    const Eigen::Vector2d dq_dtheta(-(q.y() - t.y()), q.x() - t.x());
    const Eigen::Vector3d J(grad.x(), grad.y(), grad.dot(dq_dtheta));
    *gradient += (w * d) * J;
    *hessian += w * J * J.transpose();
  }
  if (prior_info) {
    Eigen::Vector3d d = pose - prior;
    d.z() = wrap_angle(d.z());
    sum -= 0.5 * d.dot(*prior_info * d);
    if (hessian) {
      *gradient += *prior_info * d;
      *hessian += *prior_info;
    }
  }
  if (quality) *quality = fit / static_cast<double>(points.rows());
  return sum;
}

double CorrelativeScanMatcher::smooth_score(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& pose,
                                            const Eigen::Vector3d& prior, const MatchOptions& options) const {
  options.validate();
  require_all_finite(points, "points");
  require_all_finite(pose, "pose");
  require_all_finite(prior, "prior");
  const Eigen::Matrix3d info = options.prior_covariance.inverse();
  return evaluate(points, pose, prior, options.use_prior ? &info : nullptr, nullptr, nullptr, nullptr);
}

void CorrelativeScanMatcher::refine_and_measure(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                                const Eigen::Matrix3d* prior_info, const MatchOptions& options,
                                                double angular_step, MatchResult& result) const {
  const double res = field_.resolution();
  Eigen::Matrix3d H;
  Eigen::Vector3d g;
  double quality = 0.0;
  double score = evaluate(points, result.pose, prior, prior_info, &H, &g, &quality);
  if (options.refine) {
    Eigen::Vector3d x = result.pose;
    Eigen::Matrix3d Hx = H;
    Eigen::Vector3d gx = g;
    double sx = score, qx = quality;
    for (int it = 0; it < kMaxRefineIterations; ++it) {
      const Eigen::LDLT<Eigen::Matrix3d> ldlt(Hx);
      if (ldlt.info() != Eigen::Success || !ldlt.isPositive() || ldlt.vectorD().minCoeff() <= 0.0) break;
      const Eigen::Vector3d step = -ldlt.solve(gx);
      if (!step.allFinite()) break;
      double scale = 1.0;
      bool accepted = false;
      for (int h = 0; h < kMaxHalvings && !accepted; ++h, scale *= 0.5) {
        Eigen::Vector3d cand = x + scale * step;
        cand.z() = wrap_angle(cand.z());
        Eigen::Matrix3d Hc;
        Eigen::Vector3d gc;
        double qc = 0.0;
        const double sc = evaluate(points, cand, prior, prior_info, &Hc, &gc, &qc);
        if (sc > sx) {
          x = cand, Hx = Hc, gx = gc, sx = sc, qx = qc;
          accepted = true;
        }
      }
      if (!accepted || (scale * step).cwiseAbs().maxCoeff() < kRefineStepTolerance) break;
    }
    // A refinement that wanders out of the window has left the basin the search found.
    const Eigen::Vector3d moved(x.x() - prior.x(), x.y() - prior.y(), wrap_angle(x.z() - prior.z()));
    if (std::abs(moved.x()) <= options.window.linear + res && std::abs(moved.y()) <= options.window.linear + res &&
        std::abs(moved.z()) <= options.window.angular + angular_step) {
      result.pose = x, H = Hx, score = sx, quality = qx;
    }
  }
  result.score = score;
  result.match_quality = quality;
  result.covariance = response_covariance(points, prior, prior_info, options, angular_step, result.pose, H);
}

Eigen::Matrix3d CorrelativeScanMatcher::response_covariance(const Eigen::Ref<const Points2>& points,
                                                            const Eigen::Vector3d& prior,
                                                            const Eigen::Matrix3d* prior_info,
                                                            const MatchOptions& options, double angular_step,
                                                            const Eigen::Vector3d& pose,
                                                            const Eigen::Matrix3d& hessian) const {
  const double res = field_.resolution();
  // Sample spacing per axis from the Laplace approximation (H^-1), within [1/8 cell, window/3]:
  // the samples then reach about 3 standard deviations of the surface.
  Eigen::Vector3d laplace_var(options.window.linear, options.window.linear, options.window.angular);
  laplace_var = laplace_var.cwiseAbs2();
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(hessian);
  if (ldlt.info() == Eigen::Success && ldlt.isPositive() && ldlt.vectorD().minCoeff() > 0.0)
    laplace_var = ldlt.solve(Eigen::Matrix3d::Identity()).diagonal();
  Eigen::Vector3d spacing;
  const double lin_max = std::max(options.window.linear, res) / kSurfaceSteps;
  const double ang_max = std::max(options.window.angular, angular_step) / kSurfaceSteps;
  for (int j = 0; j < 3; ++j) {
    const double lo = (j < 2 ? res : angular_step) / 8.0, hi = j < 2 ? lin_max : ang_max;
    const double sd = std::sqrt(std::max(laplace_var[j], 0.0));
    spacing[j] = std::clamp(std::isfinite(sd) ? sd : hi, lo, hi);
  }
  const int K = kSurfaceSteps, n = 2 * K + 1;
  std::vector<double> values;
  values.reserve(static_cast<std::size_t>(n * n * n));
  double vmax = -std::numeric_limits<double>::infinity();
  for (int i = -K; i <= K; ++i)
    for (int j = -K; j <= K; ++j)
      for (int k = -K; k <= K; ++k) {
        Eigen::Vector3d p = pose + Eigen::Vector3d(i, j, k).cwiseProduct(spacing);
        p.z() = wrap_angle(p.z());
        values.push_back(evaluate(points, p, prior, prior_info, nullptr, nullptr, nullptr));
        vmax = std::max(vmax, values.back());
      }
  double total = 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  std::size_t idx = 0;
  for (int i = -K; i <= K; ++i)
    for (int j = -K; j <= K; ++j)
      for (int k = -K; k <= K; ++k) {
        const double w = std::exp(values[idx++] - vmax);
        const Eigen::Vector3d o = Eigen::Vector3d(i, j, k).cwiseProduct(spacing);
        total += w;
        mean += w * o;
        second += w * o * o.transpose();
      }
  mean /= total;
  Eigen::Matrix3d cov = second / total - mean * mean.transpose();
  // The map is known to a cell and the search to a step: a uniform error over one of each.
  const double ft = options.min_translation_std > 0.0 ? options.min_translation_std : res / std::sqrt(12.0);
  const double fr = options.min_rotation_std > 0.0 ? options.min_rotation_std : angular_step / std::sqrt(12.0);
  cov += Eigen::Vector3d(ft * ft, ft * ft, fr * fr).asDiagonal();
  return 0.5 * (cov + cov.transpose());
}

MatchResult CorrelativeScanMatcher::match(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                          const MatchOptions& options) const {
  options.validate();
  require(points.rows() > 0, "points", "must not be empty (a scan with no valid reading cannot be matched)");
  require(points.rows() <= kMaxPoints, "points", "has more than 2^20 rows; decimate the scan first");
  require_all_finite(points, "points");
  require_all_finite(prior, "prior");
  const double res = field_.resolution();

  SearchSpace sp;
  sp.res = res;
  sp.prior = prior;
  sp.use_prior = options.use_prior;
  const double max_range = std::max(points.rowwise().norm().maxCoeff(), res);
  // The step at which the farthest point moves one cell (law of cosines).
  sp.step = options.window.angular_step > 0.0
                ? options.window.angular_step
                : std::acos(std::clamp(1.0 - res * res / (2.0 * max_range * max_range), -1.0, 1.0));
  const double linear_cells = std::ceil(options.window.linear / res);
  const double angular_steps = std::floor(options.window.angular / sp.step + 1e-9);
  const double candidates = (2 * angular_steps + 1) * (2 * linear_cells + 1) * (2 * linear_cells + 1);
  require(candidates <= kMaxCandidates, "window",
          "holds more than 2e9 poses at this resolution; narrow it or coarsen angular_step");
  // The rotated scans and the top-level nodes are stored: bound them as well (a fine step over a
  // wide angle with no translation passes the candidate limit yet fills memory).
  require((2 * angular_steps + 1) * static_cast<double>(points.rows()) <= kMaxStoredCells, "angular_step",
          "gives more rotated scan points than 2^27; coarsen it or narrow angular_window");
  sp.linear_cells = static_cast<int>(linear_cells);
  sp.angular_steps = static_cast<int>(angular_steps);
  if (sp.use_prior) {
    sp.info = options.prior_covariance.inverse();
    sp.info = 0.5 * (sp.info + sp.info.transpose());
    const Eigen::Matrix2d lxx = sp.info.topLeftCorner<2, 2>();
    const Eigen::Vector2d lxt = sp.info.block<2, 1>(0, 2);
    const Eigen::Matrix2d lxx_inv = lxx.inverse();
    sp.xy_per_theta = -lxx_inv * lxt;
    sp.theta_schur = sp.info(2, 2) - lxt.dot(lxx_inv * lxt);
    sp.info_xy_min_eigen = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(lxx).eigenvalues()(0);
  }

  // Rotate once per angle and discretise once (at the prior translation).
  const int num_angles = 2 * sp.angular_steps + 1;
  sp.scans.resize(static_cast<std::size_t>(num_angles));
  for (int a = 0; a < num_angles; ++a) {
    const Eigen::Matrix2d R = rotation_matrix(prior.z() + sp.theta_offset(a));
    auto& cells = sp.scans[static_cast<std::size_t>(a)];
    cells.resize(static_cast<std::size_t>(points.rows()));
    for (Eigen::Index i = 0; i < points.rows(); ++i) {
      const Eigen::Vector2d q = R * points.row(i).transpose() + prior.head<2>();
      cells[static_cast<std::size_t>(i)] = {field_.col_of(q.x()), field_.row_of(q.y())};
    }
  }

  long scored = 0;
  auto score_at = [&](int level, int a, int cx, int cy) {
    ++scored;
    double sum = 0.0;
    for (const Cell& p : sp.scans[static_cast<std::size_t>(a)]) sum += level_value(level, p.row + cy, p.col + cx);
    if (level == 0) return sum + sp.prior_term(a, cx, cy);
    const double bound = sum + sp.prior_bound(a, cx, cy, 1 << level);
    return bound + kBoundSlack * std::abs(bound);
  };

  const int W = sp.linear_cells;
  // Nothing below min_score is wanted: B&B prunes against it from the start (Hess et al.'s
  // minimum score), so a scan that fits nowhere ends after the coarse levels.
  Node best{-1, 0, 0, options.min_score};
  if (options.brute_force) {
    for (int a = 0; a < num_angles; ++a)
      for (int cx = -W; cx <= W; ++cx)
        for (int cy = -W; cy <= W; ++cy) {
          const double s = score_at(0, a, cx, cy);
          if (s > best.bound) best = {a, cx, cy, s};
        }
  } else {
    int top = 0;
    while (top < max_level() && (1 << top) < 2 * W + 1) ++top;
    const double per_axis = std::ceil((2.0 * W + 1) / (1 << top));
    require(num_angles * per_axis * per_axis <= kMaxStoredCells, "max_level",
            "is too low for this window: more than 2^27 top-level nodes");
    std::vector<Node> roots;
    for (int a = 0; a < num_angles; ++a)
      for (int cx = -W; cx <= W; cx += 1 << top)
        for (int cy = -W; cy <= W; cy += 1 << top) roots.push_back({a, cx, cy, score_at(top, a, cx, cy)});
    // Best-first depth-first branch and bound (Hess et al. 2016, Algorithm 3).
    auto by_bound = [](const Node& x, const Node& y) { return x.bound > y.bound; };
    std::sort(roots.begin(), roots.end(), by_bound);
    struct Frame {
      std::vector<Node> nodes;
      int level;
      std::size_t next;
    };
    std::vector<Frame> frames;
    frames.push_back({std::move(roots), top, 0});
    while (!frames.empty()) {
      Frame& f = frames.back();
      if (f.next >= f.nodes.size() || f.nodes[f.next].bound <= best.bound) {
        frames.pop_back();
        continue;
      }
      const Node n = f.nodes[f.next++];
      if (f.level == 0) {
        best = n;
        continue;
      }
      const int child_level = f.level - 1, half = 1 << child_level;
      std::vector<Node> children;
      children.reserve(4);
      for (int dx = 0; dx <= half; dx += half)
        for (int dy = 0; dy <= half; dy += half) {
          const int cx = n.cx + dx, cy = n.cy + dy;
          if (cx > W || cy > W) continue;
          children.push_back({n.a, cx, cy, score_at(child_level, n.a, cx, cy)});
        }
      std::sort(children.begin(), children.end(), by_bound);
      frames.push_back({std::move(children), child_level, 0});
    }
  }

  MatchResult result;
  result.num_points = static_cast<int>(points.rows());
  result.candidates_scored = scored;
  result.angular_steps = num_angles;
  result.angular_step = sp.step;
  if (best.a < 0) {  // no pose reached min_score
    result.found = false;
    result.pose = result.search_pose = prior;
    result.score = result.search_score = -std::numeric_limits<double>::infinity();
    result.covariance.setZero();
    return result;
  }
  result.search_pose = Eigen::Vector3d(prior.x() + best.cx * res, prior.y() + best.cy * res,
                                       wrap_angle(prior.z() + sp.theta_offset(best.a)));
  result.search_score = best.bound;
  result.pose = result.search_pose;
  refine_and_measure(points, prior, sp.use_prior ? &sp.info : nullptr, options, sp.step, result);
  return result;
}

}  // namespace probslam
