#include "probslam/slam2d/correlative_scan_matcher.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/grid/ray_traversal.hpp"

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
/// Variance of a uniform distribution over an interval of unit width: the error of a quantity
/// known only to one cell (or one lattice step).
constexpr double kUniformVariance = 1.0 / 12.0;
/// The error of log p read from the field's table (LikelihoodField::tabulated: linear
/// interpolation of 2048 entries over the truncation, below 1e-6).
constexpr double kTableError = 1e-6;
/// Pose parameters (x, y, theta): the residuals at the fitted pose are smaller than the errors,
/// on average by this many degrees of freedom.
constexpr double kPoseDof = 3.0;
/// Numerical guard of the meat (the scatter of the per-point gradients): that many "window-sized
/// observations" keep it invertible in directions no point constrains. There the bread is zero
/// too, so the scan's information is zero whatever the guard; elsewhere it is 1e-9 of the
/// window's weight, far below the scatter of any real scan.
constexpr double kMeatRidge = 1e-9;
/// The profile of the score across the window (see widen_where_flat) starts this many of the
/// model's Laplace widths from the pose: beyond 4 widths a Gaussian basin holds 6e-5 of its
/// mass, so whatever mass the profile finds there is not the local basin's.
constexpr double kBasinWidths = 4.0;
/// Samples on each side of the pose in that profile: enough to see a flat run or a second
/// basin inside the window at a few evaluations of the score.
constexpr int kProfileSamples = 8;
/// evaluate() with a floor tests its bound every this many points: often enough to stop early
/// on a pose whose points miss their walls, rarely enough to cost nothing beside the points.
constexpr Eigen::Index kFloorCheckEvery = 16;
/// ...visiting the points this many apart, so that the points visited first span the scan.
constexpr Eigen::Index kFloorStride = 8;
/// Nats added to that bound: the sums' rounding (relative 1e-16 of a few thousand nats) is far
/// below it, so a pose given up on is certain to score below the floor.
constexpr double kFloorSlack = 1.0;
/// A profile sample is skipped (evaluate's floor) when its share of the profile's sums is
/// certainly below 2^-60 of the local basin's: adding it could not change a sum's last bit
/// (a share below 2^-54 of a double rounds away), so the profile is bit for bit the full one.
constexpr double kNegligibleShare = 0x1p-60;

/// One point's fit to the field: distance d (m), log p(d), exp(-d^2 / 2 sigma^2); with
/// linearisation also J = d(d)/d(pose) and the IRLS weight w of -log p (see evaluate).
struct PointFit {
  double d = 0.0, log_p = 0.0, hit = 0.0, weight = 0.0;
  Eigen::Vector3d J = Eigen::Vector3d::Zero();
};

/// q: the point in the field's frame; t: the pose's translation (the centre of rotation).
PointFit fit_point(const LikelihoodField& field, const Eigen::Vector2d& q, const Eigen::Vector2d& t,
                   bool linearise) {
  PointFit p;
  Eigen::Vector2d grad;
  p.d = field.interpolate_distance(q.x(), q.y(), linearise ? &grad : nullptr);
  field.tabulated(p.d, &p.log_p, &p.hit);
  if (!linearise) return p;
  // -log p(d) has gradient (d / sigma^2) w' J with w' the hit part's share of the mixture:
  // iteratively reweighted least squares on the distance, robust to stray points.
  const double sigma = field.options().sigma, p_rand = field.options().p_rand;
  p.weight = (1.0 - p_rand) * p.hit / std::exp(p.log_p) / (sigma * sigma);
  const Eigen::Vector2d dq_dtheta(-(q.y() - t.y()), q.x() - t.x());
  p.J = Eigen::Vector3d(grad.x(), grad.y(), grad.dot(dq_dtheta));
  return p;
}

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

void SearchWindow::validate() const {
  require(std::isfinite(linear) && linear >= 0.0, "linear", "must be finite and >= 0");
  require(std::isfinite(angular) && angular >= 0.0 && angular <= kPi, "angular", "must be finite and in [0, pi]");
  require(std::isfinite(angular_step), "angular_step", "must be finite (<= 0: automatic)");
}

void MatchOptions::validate() const {
  validate_group(window, "window");
  require(std::isfinite(min_translation_std) && std::isfinite(min_rotation_std), "min_translation_std",
          "and min_rotation_std must be finite");
  require(!std::isnan(min_score) && min_score < std::numeric_limits<double>::infinity(), "min_score",
          "must be a number below +inf (-inf: no minimum)");
  if (use_prior) require_symmetric_positive_definite(prior_covariance, "prior_covariance", 1e-9);
}

CorrelativeScanMatcher::CorrelativeScanMatcher(LikelihoodField field, int max_level)
    : field_(std::make_shared<const LikelihoodField>(std::move(field))) {
  require(max_level >= 0 && max_level <= kMaxLevel, "max_level", "must be in [0, 10]");
  floor_ = field_->floor_value();
  pyramid_.resize(1);
  Level& base = pyramid_[0];
  base.width = field_->width();
  base.height = field_->height();
  extend_levels(max_level);
}

int CorrelativeScanMatcher::levels_for_window(double linear_window, double resolution) {
  require(std::isfinite(linear_window) && linear_window >= 0.0, "linear_window", "must be finite and >= 0");
  require_positive(resolution, "resolution");
  // As match() picks its top level: the first whose node spans the 2W + 1 cells of the window.
  const double cells = 2.0 * std::ceil(linear_window / resolution) + 1.0;
  int levels = 0;
  while (levels < kMaxLevel && (1 << levels) < cells) ++levels;
  return levels;
}

double CorrelativeScanMatcher::bytes_for(int width, int height, int max_level) {
  double b = 2.0 * sizeof(float) * width * height;  // the field's distances and log p
  for (int k = 1; k <= max_level; ++k) b += sizeof(float) * double(width + (1 << k) - 1) * (height + (1 << k) - 1);
  return b;
}

double CorrelativeScanMatcher::bytes() const { return bytes_for(field_->width(), field_->height(), max_level()); }

CorrelativeScanMatcher CorrelativeScanMatcher::with_levels(int max_level) const {
  CorrelativeScanMatcher deeper(*this);  // shares the field; copies the levels built
  deeper.extend_levels(max_level);
  return deeper;
}

void CorrelativeScanMatcher::extend_levels(int max_level) {
  require(max_level >= 0 && max_level <= kMaxLevel, "max_level", "must be in [0, 10]");
  const int built = static_cast<int>(pyramid_.size()) - 1;
  if (max_level <= built) return;
  pyramid_.resize(static_cast<std::size_t>(max_level) + 1);
  const Level& base = pyramid_[0];
  for (int k = built + 1; k <= max_level; ++k) {
    // Level k at (r, c): the maximum over rows [r, r + 2^k) and cols [c, c + 2^k), stored for
    // every window that meets the table (r, c >= -(2^k - 1)), from four level k-1 windows.
    Level& L = pyramid_[static_cast<std::size_t>(k)];
    const int half = 1 << (k - 1);
    L.pad = (1 << k) - 1;
    L.width = base.width + L.pad;
    L.height = base.height + L.pad;
    L.values.resize(static_cast<std::size_t>(L.width) * L.height);
    // In stored indices level k's (i, j) is the maximum of level k-1's (i - half | i, j - half | j)
    // (the pads differ by half); outside level k-1 the floor. Rows first, then the column pair,
    // each a branch-free loop over a row padded with the floor on both sides (it vectorises).
    const LevelView P = level_view(k - 1);
    std::vector<float> pair(static_cast<std::size_t>(P.width) + 2 * half, floor_);
    float* mid = pair.data() + half;
    for (int i = 0; i < L.height; ++i) {
      const float* a = i - half >= 0 ? P.values + static_cast<std::size_t>(i - half) * P.width : nullptr;
      const float* b = i < P.height ? P.values + static_cast<std::size_t>(i) * P.width : nullptr;
      if (a && b) {
        for (int j = 0; j < P.width; ++j) mid[j] = std::max(a[j], b[j]);
      } else if (a || b) {
        const float* one = a ? a : b;
        for (int j = 0; j < P.width; ++j) mid[j] = std::max(one[j], floor_);
      } else {  // an empty field
        std::fill(mid, mid + P.width, floor_);
      }
      float* out = &L.values[static_cast<std::size_t>(i) * L.width];
      // out[j] = max(pair[j - half], pair[j]) with pair the floor outside [0, P.width).
      for (int j = 0; j < L.width; ++j) out[j] = std::max(pair[j], mid[j]);
    }
  }
}

double CorrelativeScanMatcher::evaluate(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& pose,
                                        const Eigen::Vector3d& prior, const Eigen::Matrix3d* prior_info,
                                        Eigen::Matrix3d* hessian, Eigen::Vector3d* gradient,
                                        double* quality, double floor) const {
  const Eigen::Matrix2d R = rotation_matrix(pose.z());
  const Eigen::Vector2d t = pose.head<2>();
  if (hessian) hessian->setZero();
  if (gradient) gradient->setZero();
  Eigen::Vector3d d_prior = Eigen::Vector3d::Zero();
  double prior_term = 0.0;
  if (prior_info) {
    d_prior = pose - prior;
    d_prior.z() = wrap_angle(d_prior.z());
    prior_term = 0.5 * d_prior.dot(*prior_info * d_prior);
  }
  if (floor > -std::numeric_limits<double>::infinity() && !hessian && !quality)
    return score_above(points, R, t, prior_term, floor);
  double sum = 0.0, fit = 0.0;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const PointFit p = fit_point(*field_, R * points.row(i).transpose() + t, t, hessian != nullptr);
    sum += p.log_p;
    fit += p.hit;
    if (!hessian) continue;
    *gradient += (p.weight * p.d) * p.J;
    *hessian += p.weight * p.J * p.J.transpose();
  }
  if (prior_info) {
    sum -= prior_term;
    if (hessian) {
      *gradient += *prior_info * d_prior;
      *hessian += *prior_info;
    }
  }
  if (quality) *quality = fit / static_cast<double>(points.rows());
  return sum;
}

double CorrelativeScanMatcher::score_above(const Eigen::Ref<const Points2>& points, const Eigen::Matrix2d& R,
                                           const Eigen::Vector2d& t, double prior_term, double floor) const {
  // The points are visited kFloorStride apart (0, s, 2s, ..., then 1, 1 + s, ...), so that the
  // terms summed so far sample the whole scan: a rotation moves the far points most, and they
  // lie together. Every kFloorCheckEvery points the score's upper bound (those terms plus the
  // largest term for each point left, less the prior's) is tested; kFloorSlack covers rounding.
  const Eigen::Index n = points.rows();
  const double max_term = field_->max_tabulated_log_p();
  thread_local std::vector<double> terms;
  terms.resize(static_cast<std::size_t>(n));
  double partial = 0.0;
  Eigen::Index done = 0;
  for (Eigen::Index start = 0; start < kFloorStride; ++start)
    for (Eigen::Index i = start; i < n; i += kFloorStride) {
      const double log_p = fit_point(*field_, R * points.row(i).transpose() + t, t, false).log_p;
      terms[static_cast<std::size_t>(i)] = log_p;
      partial += log_p;
      if (++done % kFloorCheckEvery == 0 &&
          partial + static_cast<double>(n - done) * max_term - prior_term + kFloorSlack < floor)
        return -std::numeric_limits<double>::infinity();
    }
  // Summed in evaluate's order, so the score is evaluate's to the bit (without a prior,
  // prior_term is 0 and x - 0 is x).
  double sum = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) sum += terms[static_cast<std::size_t>(i)];
  return sum - prior_term;
}

CorrelativeScanMatcher::ScanMoments CorrelativeScanMatcher::scan_moments(const Eigen::Ref<const Points2>& points,
                                                                         const Eigen::Vector3d& pose) const {
  const Eigen::Matrix2d R = rotation_matrix(pose.z());
  const Eigen::Vector2d t = pose.head<2>();
  ScanMoments m;
  // Kish's effective count of the points that constrain the pose, weighted by their information.
  double info_sum = 0.0, info_sq_sum = 0.0;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const PointFit p = fit_point(*field_, R * points.row(i).transpose() + t, t, true);
    const Eigen::Vector3d g = (p.weight * p.d) * p.J;  // this point's gradient of -log p
    m.bread += p.weight * p.J * p.J.transpose();
    m.meat += g * g.transpose();
    const double info = p.weight * p.J.head<2>().squaredNorm();
    info_sum += info;
    info_sq_sum += info * info;
  }
  m.effective_points = info_sq_sum > 0.0 ? info_sum * info_sum / info_sq_sum : 0.0;
  return m;
}

double CorrelativeScanMatcher::smooth_score(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& pose,
                                            const Eigen::Vector3d& prior, const MatchOptions& options,
                                            double floor) const {
  options.validate();
  require_all_finite(points, "points");
  require_all_finite(pose, "pose");
  require_all_finite(prior, "prior");
  require(!std::isnan(floor), "floor", "must not be NaN");
  const Eigen::Matrix3d info = options.prior_covariance.inverse();
  return evaluate(points, pose, prior, options.use_prior ? &info : nullptr, nullptr, nullptr, nullptr, floor);
}

bool CorrelativeScanMatcher::refine(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                    const Eigen::Matrix3d* prior_info, const MatchOptions& options, double angular_step,
                                    MatchResult& result, long* evaluations) const {
  const double res = field_->resolution();
  Eigen::Matrix3d H;
  Eigen::Vector3d g;
  double quality = 0.0;
  long count = 1;
  result.score = evaluate(points, result.pose, prior, prior_info, &H, &g, &quality);
  result.match_quality = quality;
  if (!options.refine) return false;
  Eigen::Vector3d x = result.pose;
  double sx = result.score, qx = quality;
  bool stationary = false;  // ended at a (numerically) stationary point of the smooth score
  for (int it = 0; it < kMaxRefineIterations; ++it) {
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(H);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive() || ldlt.vectorD().minCoeff() <= 0.0) break;
    const Eigen::Vector3d step = -ldlt.solve(g);
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
      ++count;
      if (sc > sx) {
        x = cand, H = Hc, g = gc, sx = sc, qx = qc;
        accepted = true;
      }
    }
    // No ascent along the Newton direction, or a step below the tolerance: converged.
    if (!accepted || (scale * step).cwiseAbs().maxCoeff() < kRefineStepTolerance) {
      stationary = true;
      break;
    }
  }
  if (evaluations) *evaluations += count;
  // A refinement that wanders out of the window has left the basin the search found.
  const Eigen::Vector3d moved(x.x() - prior.x(), x.y() - prior.y(), wrap_angle(x.z() - prior.z()));
  if (std::abs(moved.x()) > options.window.linear + res || std::abs(moved.y()) > options.window.linear + res ||
      std::abs(moved.z()) > options.window.angular + angular_step)
    return false;
  result.pose = x, result.score = sx, result.match_quality = qx;
  return stationary;
}

Eigen::Matrix3d CorrelativeScanMatcher::scan_meat(const ScanMoments& m) {
  // With no more informative points than pose parameters the residuals say nothing about the
  // scatter: fall back to the field's own sigma (the model, meat = bread).
  if (m.effective_points <= kPoseDof) return m.bread;
  // The residuals at the fitted pose underestimate the errors by the fitted degrees of freedom.
  return m.meat * (m.effective_points / (m.effective_points - kPoseDof));
}

Eigen::Matrix3d CorrelativeScanMatcher::pose_covariance(const Eigen::Ref<const Points2>& points,
                                                        const Eigen::Vector3d& prior,
                                                        const Eigen::Matrix3d* prior_info, const MatchOptions& options,
                                                        double angular_step, const MatchResult& result,
                                                        bool stationary, const ScanMoments* moments,
                                                        bool widen) const {
  const ScanMoments scan = moments ? *moments : scan_moments(points, result.pose);
  // The scan's information is the inverse of the sandwich H^-1 B H^-1 (Huber 1967; White 1982),
  // H the Gauss-Newton Hessian of the negative score, B the sum of the outer products of the
  // per-point gradients. It equals the Laplace approximation H^-1 when the points scatter about
  // the field as its sigma says, and corrects it when they do not: the field's sigma is a
  // blur chosen for the search, not the range noise, so H^-1 alone is off by their ratio
  // squared. The prior is taken as exact: it weighs in H as the score weighs it, and its mean
  // is off the truth by its covariance P, so its gradient scatters by P^-1 P P^-1 = P^-1 in B.
  // This is the covariance of the estimate the score defines, which weighs the scan by the
  // field's sigma; with no scan information it is the prior's.
  const Eigen::Matrix3d none = Eigen::Matrix3d::Zero();
  const Eigen::Matrix3d& prior_part = prior_info ? *prior_info : none;
  const Eigen::Matrix3d H = scan.bread + prior_part;
  const Eigen::Matrix3d B = scan_meat(scan) + prior_part;
  // The search only looked inside the window: the truth is taken as uniform over the box the
  // refinement may reach (a Gaussian of the same variance, (2 half-width)^2 / 12). This is what
  // bounds the covariance along a direction the scan does not constrain (a corridor); elsewhere
  // it is negligible against the scan.
  const double res = field_->resolution();
  const Eigen::Vector3d half(options.window.linear + res, options.window.linear + res,
                             options.window.angular + angular_step);
  const Eigen::Matrix3d window_info = (4.0 * kUniformVariance * half.cwiseAbs2()).cwiseInverse().asDiagonal();
  const Eigen::LDLT<Eigen::Matrix3d> meat(B + kMeatRidge * window_info);
  const Eigen::Matrix3d info = H * meat.solve(H);
  Eigen::Matrix3d cov = (info + window_info).ldlt().solve(Eigen::Matrix3d::Identity());
  // Shifting the map by s moves the scan's optimum by s and so this estimate by share * s: the
  // scan's part of the information, zero along directions the scan does not constrain.
  const Eigen::Matrix<double, 3, 2> share = cov * H * meat.solve(scan.bread.leftCols<2>());
  if (widen) cov = widen_where_flat(points, prior, prior_info, result, half, H, cov);
  cov += unseen_errors(share, options, angular_step, stationary);
  return 0.5 * (cov + cov.transpose());
}

Eigen::Matrix3d CorrelativeScanMatcher::widen_where_flat(const Eigen::Ref<const Points2>& points,
                                                         const Eigen::Vector3d& prior,
                                                         const Eigen::Matrix3d* prior_info, const MatchResult& result,
                                                         const Eigen::Vector3d& half, const Eigen::Matrix3d& hessian,
                                                         const Eigen::Matrix3d& cov) const {
  // The sandwich is local: it reads cell-sized steps of a wall in the map as information along
  // the wall, and it cannot see a second basin. So the model's own likelihood exp(score) is
  // profiled across the window along each principal axis of the covariance (in units of the
  // window's half-widths), beyond the basin the model itself predicts there (kBasinWidths of
  // its Laplace width). The field's sigma is a blur at least as wide as the points' scatter, so
  // this likelihood overstates no difference of score. The variance along the axis becomes
  // that of the mixture of the local basin (its mass from the model, its spread from the
  // sandwich) and the mass the profile finds beyond it: unchanged in a basin, about the
  // window's along a flat run (see profile_variance for a basin as wide as the window).
  const Eigen::Matrix3d to_unit = half.cwiseInverse().asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> axes(to_unit * cov * to_unit);
  const Eigen::Matrix3d unit_hessian = half.asDiagonal() * hessian * half.asDiagonal();
  Eigen::Vector3d var = axes.eigenvalues();
  for (int j = 0; j < 3; ++j) {
    const Eigen::Vector3d v = axes.eigenvectors().col(j);
    const double curvature = v.dot(unit_hessian * v);
    if (!(curvature > 0.0)) continue;  // no basin: the window already bounds this axis
    var[j] = profile_variance(points, prior, prior_info, result, half.asDiagonal() * v, 1.0 / std::sqrt(curvature),
                              var[j]);
  }
  const Eigen::Matrix3d V = half.asDiagonal() * axes.eigenvectors();
  return V * var.asDiagonal() * V.transpose();
}

double CorrelativeScanMatcher::profile_variance(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                                const Eigen::Matrix3d* prior_info, const MatchResult& result,
                                                const Eigen::Vector3d& direction, double width,
                                                double local_variance) const {
  // Beyond `start` the local basin has no mass to speak of. When that is past the window, the
  // window cannot tell the basin from a flat run: the whole profile is the answer, and the
  // sandwich's sharpening (fitted to the points' scatter, not to a flat score) is not applied.
  const double start = kBasinWidths * width;
  const bool basin_fills_window = !(start < 1.0);
  const double from = basin_fills_window ? 0.0 : start;
  const double dt = (1.0 - from) / kProfileSamples;
  std::array<double, 2 * kProfileSamples> t{}, score{};
  double top = result.score;
  // Beyond the basin the sums below start at its mass and moment, and a sample adds
  // exp(score - top) dt (times t^2): one whose score is certain to leave that below
  // kNegligibleShare of them changes no bit of either, so its evaluation stops at that certainty
  // (score -infinity, which adds exactly 0). Within the basin (moment from 0) none is skipped.
  const bool may_skip = !basin_fills_window && local_variance > 0.0;
  const double log_basin = std::log(kNegligibleShare * std::sqrt(2.0 * kPi) * width / dt);
  for (int k = 0; k < 2 * kProfileSamples; ++k) {
    const double side = k < kProfileSamples ? -1.0 : 1.0;
    // Uniform over [from, 1]: cell ends when starting at the pose, cell midpoints beyond the basin.
    const double offset = basin_fills_window ? k % kProfileSamples + 1.0 : k % kProfileSamples + 0.5;
    const double tk = side * (from + dt * offset);
    t[static_cast<std::size_t>(k)] = tk;
    Eigen::Vector3d p = result.pose + tk * direction;
    p.z() = wrap_angle(p.z());
    const double floor = may_skip ? result.score + log_basin - std::log(std::max(1.0, tk * tk / local_variance))
                                  : -std::numeric_limits<double>::infinity();
    score[static_cast<std::size_t>(k)] = evaluate(points, p, prior, prior_info, nullptr, nullptr, nullptr, floor);
    top = std::max(top, score[static_cast<std::size_t>(k)]);
  }
  // exp(score) relative to its largest value. The pose holds one sample's mass when the profile
  // starts there, else the local basin's: a Gaussian of the model's width, peak exp(score).
  const double peak = std::exp(result.score - top);
  const double local_mass = basin_fills_window ? peak * dt : std::sqrt(2.0 * kPi) * width * peak;
  double mass = local_mass, moment = basin_fills_window ? 0.0 : local_mass * local_variance;
  for (std::size_t k = 0; k < t.size(); ++k) {
    const double m = std::exp(score[k] - top) * dt;
    mass += m;
    moment += m * t[k] * t[k];
  }
  return basin_fills_window ? std::max(local_variance, moment / mass) : moment / mass;
}

Eigen::Matrix3d CorrelativeScanMatcher::unseen_errors(const Eigen::Matrix<double, 3, 2>& map_share,
                                                      const MatchOptions& options, double angular_step,
                                                      bool stationary) const {
  const double res = field_->resolution();
  Eigen::Matrix3d extra = Eigen::Matrix3d::Zero();
  if (options.min_translation_std > 0.0) {
    extra.topLeftCorner<2, 2>().diagonal().setConstant(options.min_translation_std * options.min_translation_std);
  } else {
    // The map holds each wall only to a cell: the field is measured from cell centres, so a
    // wall sits off its true place by up to half a cell, uniformly (res^2 / 12 per axis). Walls
    // on a common lattice share that offset, which moves the scan's optimum with the map: no
    // residual shows it, so the sandwich cannot.
    extra += kUniformVariance * res * res * map_share * map_share.transpose();
  }
  if (options.min_rotation_std > 0.0) extra(2, 2) += options.min_rotation_std * options.min_rotation_std;
  // Without a converged refinement the pose is a lattice point, off the optimum by up to half a
  // cell and half an angular step.
  if (!stationary)
    extra += kUniformVariance * Eigen::Vector3d(res * res, res * res, angular_step * angular_step).asDiagonal();
  // The refinement stops at steps below kRefineStepTolerance: the optimum is located to that.
  extra.diagonal().array() += kRefineStepTolerance * kRefineStepTolerance;
  return extra;
}

MatchResult CorrelativeScanMatcher::match(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                          const MatchOptions& options) const {
  return search(points, prior, options, nullptr);
}

void CorrelativeScanMatcher::check_match_input(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                               const MatchOptions& options) {
  options.validate();
  require(points.rows() > 0, "points", "must not be empty (a scan with no valid reading cannot be matched)");
  require(points.rows() <= kMaxPoints, "points", "has more than 2^20 rows; decimate the scan first");
  require_all_finite(points, "points");
  require_all_finite(prior, "prior");
}

Eigen::Matrix3d CorrelativeScanMatcher::prior_information(const MatchOptions& options) {
  if (!options.use_prior) return Eigen::Matrix3d::Zero();
  const Eigen::Matrix3d info = options.prior_covariance.inverse();
  return 0.5 * (info + info.transpose());
}

double CorrelativeScanMatcher::angular_step_for(const Eigen::Ref<const Points2>& points,
                                                const MatchOptions& options) const {
  if (options.window.angular_step > 0.0) return options.window.angular_step;
  // The step at which the farthest point moves one cell (law of cosines).
  const double res = field_->resolution();
  const double max_range = std::max(points.rowwise().norm().maxCoeff(), res);
  return std::acos(std::clamp(1.0 - res * res / (2.0 * max_range * max_range), -1.0, 1.0));
}

CorrelativeScanMatcher::Linearization CorrelativeScanMatcher::linearize(const Eigen::Ref<const Points2>& points,
                                                                        const Eigen::Vector3d& pose,
                                                                        const Eigen::Vector3d& prior,
                                                                        const MatchOptions& options) const {
  check_match_input(points, prior, options);
  require_all_finite(pose, "pose");
  const Eigen::Matrix3d info = prior_information(options);
  Linearization l;
  l.score = evaluate(points, pose, prior, options.use_prior ? &info : nullptr, &l.hessian, &l.gradient,
                     &l.match_quality);
  return l;
}

MatchResult CorrelativeScanMatcher::local_match(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& start,
                                                const Eigen::Vector3d& prior, const MatchOptions& options) const {
  check_match_input(points, prior, options);
  require_all_finite(start, "start");
  const Eigen::Matrix3d info = prior_information(options);
  const Eigen::Matrix3d* prior_info = options.use_prior ? &info : nullptr;
  const double step = angular_step_for(points, options);
  MatchResult result;
  result.num_points = static_cast<int>(points.rows());
  result.angular_step = step;
  result.pose = Eigen::Vector3d(start.x(), start.y(), wrap_angle(start.z()));
  MatchOptions refined = options;
  refined.refine = true;
  const bool stationary = refine(points, prior, prior_info, refined, step, result, &result.candidates_scored);
  result.search_pose = result.pose;
  result.search_score = result.score;
  result.covariance.setZero();
  // The basin test: in units of the window's half-widths (as the covariance's), every principal
  // curvature of the Hessian at least kBasinWidths^2, i.e. kBasinWidths Laplace widths inside
  // the window; a smaller one is a flat run (a corridor without a prior) the local optimiser
  // cannot place.
  const double res = field_->resolution();
  const Eigen::Vector3d half(options.window.linear + res, options.window.linear + res, options.window.angular + step);
  bool basin = false;
  ScanMoments scan;  // at the pose: the Hessian's scan part here, the covariance's below
  if (stationary) {
    scan = scan_moments(points, result.pose);
    ++result.candidates_scored;
    const Eigen::Matrix3d hessian = prior_info ? Eigen::Matrix3d(scan.bread + *prior_info) : scan.bread;
    const Eigen::Matrix3d unit = half.asDiagonal() * hessian * half.asDiagonal();
    const double smallest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(unit, Eigen::EigenvaluesOnly).eigenvalues()(0);
    basin = smallest >= kBasinWidths * kBasinWidths;
  }
  result.found = stationary && basin;
  if (!result.found) return result;
  // With the profile of exp(score) across the window (48 of the 55 evaluations of a local
  // match): without it (the sandwich alone) Intel's corrected-log agreement moved from 0.072 /
  // 0.066 to 0.076 / 0.071 m mean / median (docs/performance.md), so it stays.
  result.covariance = pose_covariance(points, prior, prior_info, options, step, result, true, &scan);
  return result;
}

MatchResult CorrelativeScanMatcher::runner_up(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                              const MatchOptions& options, const MatchResult& best,
                                              double distinct_chi2, const Eigen::Matrix3d& admitted) const {
  require(std::isfinite(distinct_chi2) && distinct_chi2 >= 0.0, "distinct_chi2", "must be finite and >= 0");
  require(best.found, "best", "must be a match that was found");
  require_all_finite(best.pose, "best.pose");
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(0.5 * (best.covariance + best.covariance.transpose()));
  require(ldlt.info() == Eigen::Success && (ldlt.vectorD().array() > 0.0).all(), "best.covariance",
          "must be positive definite");
  require_all_finite(admitted, "admitted");
  Exclusion ex;
  ex.centre = best.pose;
  ex.prior = prior;
  ex.admitted = 0.5 * (admitted + admitted.transpose());
  // The poses best's spread admits: chi2 under its covariance within distinct_chi2.
  const Eigen::Matrix3d info = ldlt.solve(Eigen::Matrix3d::Identity());
  ex.spread = 0.5 * (info + info.transpose()) / std::max(distinct_chi2, std::numeric_limits<double>::min());
  // The poses that move the scan's points by less than the field's reach (rms, to first order
  // in the turn): there the points still see the obstacles they hit at best, so the score
  // there is best's peak's flank, not another place.
  const Eigen::Matrix2d R = rotation_matrix(best.pose.z());
  Eigen::Matrix3d moved = Eigen::Matrix3d::Zero();
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const Eigen::Vector2d q = R * points.row(i).transpose();
    const Eigen::Vector3d row_x(1.0, 0.0, -q.y()), row_y(0.0, 1.0, q.x());
    moved += row_x * row_x.transpose() + row_y * row_y.transpose();
  }
  const double reach = field_->options().truncation();
  ex.reach = moved / (static_cast<double>(points.rows()) * reach * reach);
  return search(points, prior, options, &ex);
}

bool CorrelativeScanMatcher::Exclusion::contains(const Eigen::Vector3d& pose, bool by_spread) const {
  Eigen::Vector3d d = pose - centre;
  d.z() = wrap_angle(d.z());
  return d.dot((by_spread ? spread : reach) * d) <= 1.0;
}

bool CorrelativeScanMatcher::Exclusion::contains(const Eigen::Vector3d& pose) const {
  Eigen::Vector3d d = pose - prior;
  d.z() = wrap_angle(d.z());
  return contains(pose, true) || contains(pose, false) || d.dot(admitted * d) > 1.0;
}

double CorrelativeScanMatcher::closeness(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& a,
                                         const Eigen::Vector3d& b) const {
  require(points.rows() > 1, "points", "must hold at least two points");
  require_all_finite(points, "points");
  require_all_finite(a, "a");
  require_all_finite(b, "b");
  const Eigen::Matrix2d Ra = rotation_matrix(a.z()), Rb = rotation_matrix(b.z());
  const double n = static_cast<double>(points.rows());
  double sum = 0.0, sum_sq = 0.0;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const Eigen::Vector2d p = points.row(i).transpose();
    const double la = fit_point(*field_, Ra * p + a.head<2>(), a.head<2>(), false).log_p;
    const double lb = fit_point(*field_, Rb * p + b.head<2>(), b.head<2>(), false).log_p;
    sum += la - lb;
    sum_sq += (la - lb) * (la - lb);
  }
  // Vuong (1989): the sum of the pointwise log-likelihood ratios over its standard error. Each
  // difference also carries the table's error (two lookups): two poses that explain the scan
  // alike up to it are alike, not told apart by their rounding.
  const double variance = std::max(0.0, sum_sq / n - (sum / n) * (sum / n)) + 2.0 * kTableError * kTableError;
  return sum / std::sqrt(n * variance);
}

MatchResult CorrelativeScanMatcher::search(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                           const MatchOptions& options, const Exclusion* exclusion) const {
  check_match_input(points, prior, options);
  const double res = field_->resolution();

  SearchSpace sp;
  sp.res = res;
  sp.prior = prior;
  sp.use_prior = options.use_prior;
  sp.step = angular_step_for(points, options);
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
    sp.info = prior_information(options);
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
  // The field's col_of / row_of, inlined: this runs for every point at every rotation.
  const Eigen::Vector2d field_origin = field_->origin();
  const double inv_res = 1.0 / res;
  for (int a = 0; a < num_angles; ++a) {
    const Eigen::Matrix2d R = rotation_matrix(prior.z() + sp.theta_offset(a));
    auto& cells = sp.scans[static_cast<std::size_t>(a)];
    cells.resize(static_cast<std::size_t>(points.rows()));
    for (Eigen::Index i = 0; i < points.rows(); ++i) {
      const Eigen::Vector2d q = R * points.row(i).transpose() + prior.head<2>();
      cells[static_cast<std::size_t>(i)] = {saturated_key((q.x() - field_origin.x()) * inv_res),
                                            saturated_key((q.y() - field_origin.y()) * inv_res)};
    }
  }

  long scored = 0;
  auto score_at = [&](int level, int a, int cx, int cy) {
    ++scored;
    double sum = 0.0;
    const LevelView L = level_view(level);
    for (const Cell& p : sp.scans[static_cast<std::size_t>(a)]) sum += level_value(L, p.row + cy, p.col + cx);
    if (level == 0) return sum + sp.prior_term(a, cx, cy);
    const double bound = sum + sp.prior_bound(a, cx, cy, 1 << level);
    return bound + kBoundSlack * std::abs(bound);
  };

  // A runner-up search leaves out every pose of the best's region (a node when its four corners
  // lie in one of its two ellipses: each is convex in translation at each rotation) and every
  // pose outside the admitted one (at the leaves: its outside is not convex).
  auto excluded = [&](int a, int cx, int cy, int size) {
    if (!exclusion) return false;
    const int hi = size - 1;
    for (const bool by_spread : {true, false}) {
      bool all = true;
      for (int dx = 0; dx <= hi && all; dx += std::max(hi, 1))
        for (int dy = 0; dy <= hi && all; dy += std::max(hi, 1))
          all = exclusion->contains(
              Eigen::Vector3d(prior.x() + (cx + dx) * res, prior.y() + (cy + dy) * res, prior.z() + sp.theta_offset(a)),
              by_spread);
      if (all) return true;
    }
    return false;
  };

  const int W = sp.linear_cells;
  // Nothing below min_score is wanted: B&B prunes against it from the start (Hess et al.'s
  // minimum score), so a scan that fits nowhere ends after the coarse levels.
  Node best{-1, 0, 0, options.min_score};
  if (options.brute_force) {
    for (int a = 0; a < num_angles; ++a)
      for (int cx = -W; cx <= W; ++cx)
        for (int cy = -W; cy <= W; ++cy) {
          if (exclusion && exclusion->contains(Eigen::Vector3d(prior.x() + cx * res, prior.y() + cy * res,
                                                               prior.z() + sp.theta_offset(a))))
            continue;
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
      if (excluded(n.a, n.cx, n.cy, 1 << f.level)) continue;
      if (f.level == 0) {
        if (exclusion && exclusion->contains(Eigen::Vector3d(prior.x() + n.cx * res, prior.y() + n.cy * res,
                                                             prior.z() + sp.theta_offset(n.a))))
          continue;
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
  const Eigen::Matrix3d* prior_info = sp.use_prior ? &sp.info : nullptr;
  const bool stationary = refine(points, prior, prior_info, options, sp.step, result);
  if (exclusion) {
    // A runner-up whose refinement climbs into the best's region was the flank of its peak.
    result.covariance.setZero();
    if (exclusion->contains(result.pose)) {
      result.found = false;
      result.pose = prior;
      result.score = result.search_score = -std::numeric_limits<double>::infinity();
    }
    return result;
  }
  result.covariance = pose_covariance(points, prior, prior_info, options, sp.step, result, stationary);
  return result;
}

}  // namespace probslam
