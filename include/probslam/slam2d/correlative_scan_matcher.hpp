#pragma once
// Correlative scan matching (Olson 2009) with branch and bound over a max-pooled pyramid of
// the likelihood field (Hess et al. 2016), a Gauss-Newton refinement on the interpolated field,
// and a covariance of the refined pose (the Gaussian that ch. 11.7 turns into a constraint):
// the robust sandwich of the score, the map's cell quantization and the search window.
#include <Eigen/Core>
#include <limits>
#include <memory>
#include <vector>

#include "probslam/core/options_description.hpp"
#include "probslam/core/types.hpp"
#include "probslam/core/uninitialized_vector.hpp"
#include "probslam/slam2d/likelihood_field.hpp"

namespace probslam {

/// The search window around the prior pose: every (x, y, theta) with |x - x0|, |y - y0| <=
/// linear (on the field's lattice) and |theta - theta0| <= angular (in angular_step steps).
struct SearchWindow {
  double linear = 0.3;    ///< half-width, m
  double angular = 0.35;  ///< half-width, rad
  /// rad; <= 0 picks the step at which the scan's farthest point moves one cell.
  double angular_step = 0.0;

  void validate() const;
  template <class V>
  static void describe(V& v) {
    using O = SearchWindow;
    v("linear", &O::linear, "m", "half-width in x and y around the prior");
    v("angular", &O::angular, "rad", "half-width in heading, in [0, pi]");
    v("angular_step", &O::angular_step, "rad", "heading step (<= 0: the scan's farthest point moves one cell)");
  }
};

struct MatchOptions {
  SearchWindow window;
  /// The odometry prior p(x_t | u_t, x_t-1): N(prior pose, prior_covariance) joins the score
  /// (the lecture's argmax p(z | x, m) p(x | u, x_t-1)) when use_prior is set.
  bool use_prior = false;
  Eigen::Matrix3d prior_covariance = Eigen::Matrix3d::Identity();
  bool refine = true;       ///< Gauss-Newton on the interpolated field after the search
  bool brute_force = false; ///< score every pose of the window (the oracle of the tests)
  /// Floors of the returned covariance (m, m, rad): their squares are added to the translation
  /// (both axes) and rotation variances, for errors the scan cannot show (how well the map
  /// itself is known, a miscalibrated sensor), so that every marginal std is at least this.
  /// <= 0 (default): translation: the map's cell quantization, a uniform offset over one cell
  /// (resolution / sqrt(12)) carried by the scan's share of the estimate; rotation: nothing.
  double min_translation_std = 0.0;
  double min_rotation_std = 0.0;
  /// Lattice poses scoring below this are not wanted (search score: sum of log p + log prior);
  /// when none reaches it the result has found = false. -inf: always return the best.
  double min_score = -std::numeric_limits<double>::infinity();

  void validate() const;
  /// use_prior and prior_covariance are not described: every owner (the frontend, the loop
  /// closures) sets them per match from its odometry model, so they are no setting of the run.
  template <class V>
  static void describe(V& v) {
    using O = MatchOptions;
    v("window", &O::window, "", "the search window around the prior");
    v("refine", &O::refine, "", "Gauss-Newton on the interpolated field after the search");
    v("brute_force", &O::brute_force, "", "score every pose of the window (the tests' oracle)");
    v("min_translation_std", &O::min_translation_std, "m", "floor of the returned covariance (<= 0: the map's cell quantization)");
    v("min_rotation_std", &O::min_rotation_std, "rad", "floor of the returned covariance (<= 0: none)");
    v("min_score", &O::min_score, "", "lattice poses scoring below this are not wanted (-inf: always the best)");
  }
};

struct MatchResult {
  bool found = true;  ///< false: no lattice pose reached options.min_score (pose = prior)
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();         ///< best pose (refined if asked)
  Eigen::Vector3d search_pose = Eigen::Vector3d::Zero();  ///< best pose on the search lattice
  /// Of `pose`: symmetric positive definite; at least the window's variance along a direction
  /// the scan does not constrain (see CorrelativeScanMatcher::match).
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  double score = 0.0;         ///< sum of log p over the points (+ log prior) at `pose`
  double search_score = 0.0;  ///< the same on the lattice at search_pose
  /// Mean over the points of exp(-d^2 / 2 sigma^2) at `pose`: 1 when every point lies on an
  /// obstacle, 0 when none is near one. Comparable across scans; the acceptance test uses it.
  double match_quality = 0.0;
  int num_points = 0;
  long candidates_scored = 0;  ///< poses and pyramid nodes scored by the search
  int angular_steps = 0;       ///< rotations searched
  double angular_step = 0.0;   ///< rad
};

class CorrelativeScanMatcher {
 public:
  /// Keeps the field and its max-pooled pyramid: level k holds the maximum of the table over
  /// 2^k x 2^k cells, k = 0..max_level (a window wider than 2^max_level cells starts with
  /// several top-level nodes). Throws std::invalid_argument unless 0 <= max_level <= kMaxLevel.
  explicit CorrelativeScanMatcher(LikelihoodField field, int max_level = 6);
  const LikelihoodField& field() const { return *field_; }

  /// Matches hit points (N, 2, sensor frame, metres) against the field around `prior` (the
  /// sensor pose (x, y, theta) in the field's frame). Throws std::invalid_argument for no
  /// points, non-finite input, or a window of more than kMaxCandidates poses.
  /// The covariance is the sandwich H^-1 B H^-1 of the score at the refined pose (H its
  /// Gauss-Newton Hessian, B the scatter of the per-point gradients: calibrated to the actual
  /// scatter of the points, not to the field's sigma), with the prior as information, fused with
  /// a uniform distribution over the window, widened along an axis where exp(score) stays high
  /// across the window (a corridor, a second basin), plus the map's cell quantization (see
  /// MatchOptions::min_translation_std) and, when the pose was not refined, the lattice cell.
  MatchResult match(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                    const MatchOptions& options = {}) const;

  /// The best pose of the window that is another place than `best` (match()'s result for the
  /// same points, prior and options): the lattice pose of highest score whose Mahalanobis chi2
  /// from best.pose under best.covariance exceeds distinct_chi2 (the poses best's own spread
  /// admits are best's hypothesis) and that moves the scan's points by more than the field's
  /// reach (truncation(), rms over the points, to first order in the turn: nearer, the points
  /// still see best's obstacles, the flank of best's peak), refined. found = false when none reaches options.min_score
  /// or its refinement climbs back into best's region (the flank of best's peak); covariance
  /// is not computed (zero). For a uniqueness test of the match (Olson 2009): see closeness().
  /// Only poses p with (p - prior)^T admitted (p - prior) <= 1 are considered (the heading
  /// difference wrapped): where another estimate, independent of the scan, allows the scan to
  /// be; a zero matrix admits the whole window.
  MatchResult runner_up(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                        const MatchOptions& options, const MatchResult& best, double distinct_chi2,
                        const Eigen::Matrix3d& admitted = Eigen::Matrix3d::Zero()) const;

  /// Vuong's (1989) closeness statistic of two poses of one scan on the interpolated field: the
  /// sum over the points of log p(at a) - log p(at b), over its standard error (sqrt(N) times the
  /// points' sd of the difference). Asymptotically standard normal when the two poses explain
  /// the scan equally well; large and positive when a explains it better. The table's error of
  /// log p (1e-6) is part of each difference's spread: differences within it count as none.
  double closeness(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& a, const Eigen::Vector3d& b) const;

  /// The score (sum of log p over points, + log prior when options.use_prior) of `pose` on the
  /// interpolated field: the function the refinement maximises. floor: -infinity as soon as the
  /// score is certain to be below it (what the covariance's profile skips), else the score.
  double smooth_score(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& pose,
                      const Eigen::Vector3d& prior, const MatchOptions& options,
                      double floor = -std::numeric_limits<double>::infinity()) const;

  /// The refinement's linearisation at `pose`: smooth_score, the gradient of -smooth_score (the
  /// points' sum of w d J, w the IRLS weight of -log p, d the distance, J its Jacobian in the
  /// pose, plus the prior's information times the offset) and its Gauss-Newton Hessian.
  struct Linearization {
    double score = 0.0, match_quality = 0.0;
    Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
    Eigen::Matrix3d hessian = Eigen::Matrix3d::Zero();
  };
  Linearization linearize(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& pose,
                          const Eigen::Vector3d& prior, const MatchOptions& options) const;

  /// The local optimiser alone (issue 54): Gauss-Newton on the interpolated field from `start`
  /// (a prediction), the prior as a residual when options.use_prior, to the nearest stationary
  /// point of smooth_score; no search. found = false (covariance zero; pose, score and quality
  /// where the optimiser stopped: `start` if it left the window) unless it
  /// converged there inside the window around `prior` and the Hessian there (with the prior)
  /// holds the pose within the window: along every principal axis the Laplace basin's
  /// kBasinWidths widths lie inside the window's half-width (the test widen_where_flat uses to
  /// tell a basin from a flat run). When found, the covariance is match()'s for a refined pose
  /// (the sandwich, widened where the score stays flat across the window) and search_pose is
  /// the pose too; candidates_scored counts the score evaluations and angular_steps is 0.
  MatchResult local_match(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& start,
                          const Eigen::Vector3d& prior, const MatchOptions& options) const;

  /// Largest number of lattice poses a window may hold: 2e9 would take minutes even pruned.
  static constexpr double kMaxCandidates = 2e9;
  /// Largest number of points in a scan (a long scan is decimated first).
  static constexpr long kMaxPoints = 1 << 20;
  /// Largest number of rotated scan points, and of top-level search nodes, held at once (2^27:
  /// 1 GiB of cells).
  static constexpr double kMaxStoredCells = 134217728.0;
  /// 2^10 cells is wider than any search window at a sensible resolution.
  static constexpr int kMaxLevel = 10;
  int max_level() const { return static_cast<int>(pyramid_.size()) - 1; }
  /// The lowest pyramid level whose nodes span a window of +-linear_window (m) on this lattice
  /// (resolution, m), at most kMaxLevel: a deeper pyramid changes nothing in a search of it.
  static int levels_for_window(double linear_window, double resolution);
  /// Adds pyramid levels up to max_level (those built are kept; nothing happens when it has
  /// them already): a field built for small windows, then asked for a large one. Not
  /// thread-safe, unlike match(). std::invalid_argument unless max_level <= kMaxLevel.
  void extend_levels(int max_level);
  /// A copy with levels up to max_level that shares this one's field (extend_levels without
  /// changing this object: a field built for the local optimiser, then searched).
  CorrelativeScanMatcher with_levels(int max_level) const;
  /// Bytes held: the field's two tables and the pyramid's levels above the base.
  double bytes() const;
  /// What bytes() would be with levels up to max_level (for a cache's budget before it builds).
  static double bytes_for(int width, int height, int max_level);

 private:
  /// The poses a runner-up search leaves out: d^T Q d <= 1 (d the pose's offset from centre)
  /// for one of two quadratic forms Q, each convex in translation at a given turn.
  struct Exclusion {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();  ///< the best's information / distinct_chi2
    Eigen::Matrix3d reach = Eigen::Matrix3d::Zero();   ///< the points' mean squared shift / reach^2
    Eigen::Vector3d prior = Eigen::Vector3d::Zero();
    Eigen::Matrix3d admitted = Eigen::Matrix3d::Zero();  ///< around prior; outside is left out
    /// In the spread's (by_spread) or the reach's ellipse.
    bool contains(const Eigen::Vector3d& pose, bool by_spread) const;
    /// In either ellipse, or outside the admitted one.
    bool contains(const Eigen::Vector3d& pose) const;
  };
  /// The angular step of a search of `points` (options.window.angular_step, or the step at
  /// which the farthest point moves one cell).
  double angular_step_for(const Eigen::Ref<const Points2>& points, const MatchOptions& options) const;
  /// The checks match() makes of its input.
  static void check_match_input(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                const MatchOptions& options);
  /// The prior's information (symmetrised inverse covariance) when options.use_prior.
  static Eigen::Matrix3d prior_information(const MatchOptions& options);
  /// match(), or with an exclusion runner_up()'s search (without its covariance).
  MatchResult search(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                     const MatchOptions& options, const Exclusion* exclusion) const;
  struct Level {
    int pad = 0;  // stored rows/cols start at -pad
    int width = 0, height = 0;
    // Written whole by extend_levels; empty for level 0: the field's own table (not copied).
    UninitializedVector<float> values;
  };
  /// One level's values, read in place (level 0 is the field's table).
  struct LevelView {
    const float* values;
    int pad, width, height;
  };
  LevelView level_view(int k) const {
    const Level& L = pyramid_[static_cast<std::size_t>(k)];
    return {k == 0 ? field_->log_likelihood().data() : L.values.data(), L.pad, L.width, L.height};
  }
  // In the header so that the search's inner loop inlines it (it is most of a match's time).
  float level_value(const LevelView& L, int row, int col) const {
    const int i = row + L.pad, j = col + L.pad;
    if (static_cast<unsigned>(i) >= static_cast<unsigned>(L.height) ||
        static_cast<unsigned>(j) >= static_cast<unsigned>(L.width))
      return floor_;
    return L.values[static_cast<std::size_t>(i) * L.width + j];
  }
  /// Score (sum of log p + log prior) at pose; with hessian/gradient also the Gauss-Newton
  /// terms of the negative score; quality: mean exp(-d^2 / 2 sigma^2). floor (score only, no
  /// hessian or quality): -infinity as soon as the score is certain to fall below it (the
  /// points summed so far plus the largest term for each point left), else the score as without
  /// a floor, bit for bit.
  double evaluate(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& pose,
                  const Eigen::Vector3d& prior, const Eigen::Matrix3d* prior_info, Eigen::Matrix3d* hessian,
                  Eigen::Vector3d* gradient, double* quality,
                  double floor = -std::numeric_limits<double>::infinity()) const;
  /// evaluate's score at the pose (R, t), or -infinity once it is certain to fall below floor.
  double score_above(const Eigen::Ref<const Points2>& points, const Eigen::Matrix2d& R, const Eigen::Vector2d& t,
                     double prior_term, double floor) const;
  /// Sums over the points at a pose of the scan alone (no prior): bread = sum w J J^T (the
  /// Gauss-Newton Hessian of -score), meat = sum g g^T (g the per-point gradients of -log p),
  /// and Kish's effective number of points that constrain the pose.
  struct ScanMoments {
    Eigen::Matrix3d bread = Eigen::Matrix3d::Zero();
    Eigen::Matrix3d meat = Eigen::Matrix3d::Zero();
    double effective_points = 0.0;
  };
  ScanMoments scan_moments(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& pose) const;
  /// Gauss-Newton from result.pose (when options.refine); sets pose, score and match_quality.
  /// True when it ended at a stationary point of the smooth score inside the window.
  /// evaluations (if given) counts the score's evaluations.
  bool refine(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
              const Eigen::Matrix3d* prior_info, const MatchOptions& options, double angular_step,
              MatchResult& result, long* evaluations = nullptr) const;
  static Eigen::Matrix3d scan_meat(const ScanMoments& scan);
  /// The covariance of a refined pose (see match()); scan: scan_moments at result.pose when
  /// computed already; widen: profile exp(score) across the window (widen_where_flat).
  Eigen::Matrix3d pose_covariance(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                  const Eigen::Matrix3d* prior_info, const MatchOptions& options,
                                  double angular_step, const MatchResult& result, bool stationary,
                                  const ScanMoments* scan = nullptr, bool widen = true) const;
  /// cov widened along its principal axes where exp(score) keeps mass beyond the local basin
  /// across the window (half: the window's half-widths, m, m, rad; hessian: Gauss-Newton, with
  /// the prior).
  Eigen::Matrix3d widen_where_flat(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                   const Eigen::Matrix3d* prior_info, const MatchResult& result,
                                   const Eigen::Vector3d& half, const Eigen::Matrix3d& hessian,
                                   const Eigen::Matrix3d& cov) const;
  /// Variance, in units of `direction`, of the mixture of the local basin (model width `width`,
  /// variance local_variance) and exp(score) sampled along result.pose + t direction for
  /// kBasinWidths width <= |t| <= 1; when that basin reaches the window's edge, the larger of
  /// local_variance and the moment of exp(score) over |t| <= 1.
  double profile_variance(const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                          const Eigen::Matrix3d* prior_info, const MatchResult& result,
                          const Eigen::Vector3d& direction, double width, double local_variance) const;
  /// The errors no residual shows: the map's offset (map_share: d(estimate) / d(map shift)), the
  /// user's floors, the lattice when unrefined, the refinement's tolerance.
  Eigen::Matrix3d unseen_errors(const Eigen::Matrix<double, 3, 2>& map_share, const MatchOptions& options,
                                double angular_step, bool stationary) const;

  /// Immutable, shared by copies (with_levels): a deeper pyramid needs no copy of the field.
  std::shared_ptr<const LikelihoodField> field_;
  float floor_ = 0.0f;  // field_->floor_value(), kept beside the pyramid
  std::vector<Level> pyramid_;  // immutable after construction: match() is thread-safe
};

}  // namespace probslam
