#include "probslam/graph/eif_correspondence.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <unordered_map>
#include <utility>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/gaussian.hpp"
#include "feature_block.hpp"

namespace probslam {
namespace {

// The given rows of x, in order.
Eigen::MatrixXd rows_of(const Eigen::MatrixXd& x, const std::vector<int>& rows) {
  Eigen::MatrixXd out(static_cast<Eigen::Index>(rows.size()), x.cols());
  for (size_t i = 0; i < rows.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = x.row(rows[i]);
  return out;
}

}  // namespace

// What Table 11.8 needs of one feature j: A_j^-1 = Omega_jj^-1, the nonzero rows of
// B_j^T = Omega_{x,j} over the path coordinates, and X_j = Omega~^-1 B_j^T.
struct EifCorrespondenceTester::Feature {
  Eigen::MatrixXd a_inv;    // (d, d)
  std::vector<int> rows;    // path coordinates that share information with the feature
  Eigen::MatrixXd b;        // (rows, d): Omega_{rows, j}
  Eigen::MatrixXd x;        // (3 (T + 1), d)
  Eigen::MatrixXd marginal; // Sigma_jj = A^-1 + A^-1 B_j Sigma B_j^T A^-1
};

EifCorrespondenceTester::EifCorrespondenceTester(const InformationForm& form,
                                                 const SparseCholesky& path_factor,
                                                 const Eigen::Ref<const RowMatrixXd>& features)
    : form_(form), factor_(path_factor), features_(features) {
  require(path_factor.factorized() && path_factor.rows() == form.pose_dim(), "path_factor",
          "must hold the factor of the reduced information Omega~ (3 (T + 1) square)");
  require(form.omega.rows() == form.pose_dim() + form.feature_dim * features.rows() &&
              features.cols() == form.feature_dim,
          "features", "must have shape (N, d) matching omega");
  require_all_finite(features_, "features");
  cache_.resize(features.rows());
  cached_.assign(features.rows(), 0);
}

EifCorrespondenceTester::~EifCorrespondenceTester() = default;

const EifCorrespondenceTester::Feature& EifCorrespondenceTester::feature(int j) {
  if (cached_[j]) return cache_[j];
  const int p = form_.pose_dim(), d = form_.feature_dim;
  Feature& f = cache_[j];
  f.a_inv = graph_detail::feature_information_inverse(form_, j);
  std::vector<std::pair<int, Eigen::VectorXd>> entries;  // path row -> its row of B_j^T
  std::unordered_map<int, size_t> slot;
  for (int c = 0; c < d; ++c) {
    for (SparseMatrixd::InnerIterator it(form_.omega, p + d * j + c); it; ++it) {
      const int row = static_cast<int>(it.row());
      if (row >= p || it.value() == 0.0) continue;
      auto [pos, fresh] = slot.emplace(row, entries.size());
      if (fresh) entries.emplace_back(row, Eigen::VectorXd::Zero(d));
      entries[pos->second].second[c] = it.value();
    }
  }
  Eigen::MatrixXd bt = Eigen::MatrixXd::Zero(p, d);
  f.rows.resize(entries.size());
  f.b.resize(static_cast<Eigen::Index>(entries.size()), d);
  for (size_t i = 0; i < entries.size(); ++i) {
    f.rows[i] = entries[i].first;
    f.b.row(static_cast<Eigen::Index>(i)) = entries[i].second.transpose();
    bt.row(entries[i].first) = entries[i].second.transpose();
  }
  f.x = factor_.solve(bt);
  f.marginal = f.a_inv + f.a_inv * (f.b.transpose() * rows_of(f.x, f.rows)) * f.a_inv;
  cached_[j] = 1;
  return f;
}

// Table 11.8 with the errata.
CorrespondenceTest EifCorrespondenceTester::test(int j, int k) {
  const int n = num_features();
  require(j >= 0 && j < n, "j", "must index a feature 0 .. N-1");
  require(k >= 0 && k < n, "k", "must index a feature 0 .. N-1");
  require(j != k, "k", "must differ from j");
  const Feature& fj = feature(j);
  const Feature& fk = feature(k);
  // Lines 2-4: Sigma_Delta = Sigma_jj + Sigma_kk - Sigma_jk - Sigma_kj, where the cross block is
  // A_j^-1 (B_j Sigma B_k^T) A_k^-1 and B_j Sigma B_k^T = B_j X_k reads X_k at B_j's rows.
  const Eigen::MatrixXd cross = fj.a_inv * (fj.b.transpose() * rows_of(fk.x, fj.rows)) * fk.a_inv;
  CorrespondenceTest out;
  out.covariance = fj.marginal + fk.marginal - cross - cross.transpose();
  out.covariance = 0.5 * (out.covariance + out.covariance.transpose());
  out.mean = (features_.row(j) - features_.row(k)).transpose();
  // Line 7: the Gaussian density of Delta at 0.
  const Eigen::LLT<Eigen::MatrixXd> llt(out.covariance);
  if (llt.info() != Eigen::Success)
    throw_invalid_argument("omega", "the covariance of m_j - m_k is not positive definite");
  const Eigen::VectorXd white = llt.matrixL().solve(out.mean);
  out.distance2 = white.squaredNorm();
  out.probability = std::exp(-0.5 * (log_det_2pi(llt) + out.distance2));
  require(std::isfinite(out.probability) && std::isfinite(out.distance2) && out.covariance.allFinite(), "omega",
          "gives a non-finite correspondence test (information too large or too small?)");
  return out;
}

CorrespondenceTest eif_correspondence_test(const InformationForm& form,
                                           const SparseCholesky& path_factor,
                                           const Eigen::Ref<const RowMatrixXd>& features, int j, int k) {
  EifCorrespondenceTester tester(form, path_factor, features);
  return tester.test(j, k);
}

namespace {

// Pairs (j < k) of features whose (x, y) means lie within `radius`, from a uniform grid of
// cells `radius` wide: each feature is compared with its own and the 8 neighbouring cells.
std::vector<std::pair<int, int>> nearby_pairs(const RowMatrixXd& features, double radius) {
  auto cell_of = [&](int j) {
    return std::make_pair(static_cast<long long>(std::floor(features(j, 0) / radius)),
                          static_cast<long long>(std::floor(features(j, 1) / radius)));
  };
  auto key = [](long long cx, long long cy) { return cx * 73856093LL ^ cy * 19349663LL; };
  std::unordered_map<long long, std::vector<int>> grid;
  for (int j = 0; j < features.rows(); ++j) {
    const auto [cx, cy] = cell_of(j);
    grid[key(cx, cy)].push_back(j);
  }
  std::vector<std::pair<int, int>> pairs;
  for (int j = 0; j < features.rows(); ++j) {
    const auto [cx, cy] = cell_of(j);
    for (long long dx = -1; dx <= 1; ++dx)
      for (long long dy = -1; dy <= 1; ++dy) {
        const auto cell = grid.find(key(cx + dx, cy + dy));
        if (cell == grid.end()) continue;
        for (int k : cell->second)
          if (k > j && (features.row(j).head<2>() - features.row(k).head<2>()).norm() <= radius)
            pairs.emplace_back(j, k);
      }
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());  // hash collisions
  return pairs;
}

// Sorted time steps at which each feature is observed.
std::vector<std::vector<int>> feature_times(const FeatureMeasurements& meas, int n) {
  std::vector<std::vector<int>> times(n);
  for (Eigen::Index k = 0; k < meas.time.size(); ++k) times[meas.feature[k]].push_back(meas.time[k]);
  for (auto& t : times) {
    std::sort(t.begin(), t.end());
    t.erase(std::unique(t.begin(), t.end()), t.end());
  }
  return times;
}

bool share_a_time(const std::vector<int>& a, const std::vector<int>& b) {
  auto i = a.begin();
  auto j = b.begin();
  while (i != a.end() && j != b.end()) {
    if (*i == *j) return true;
    *i < *j ? ++i : ++j;
  }
  return false;
}

struct Candidate {
  int j, k;
  CorrespondenceTest test;
};

// Lines 8-10: the tested pairs above chi, the most probable first.
std::vector<Candidate> accepted_pairs(EifCorrespondenceTester& tester,
                                      const std::vector<std::vector<int>>& times,
                                      const RowMatrixXd& features, const CorrespondenceSearchOptions& search) {
  std::vector<Candidate> out;
  for (const auto& [j, k] : nearby_pairs(features, search.search_radius)) {
    if (share_a_time(times[j], times[k])) continue;
    CorrespondenceTest t = tester.test(j, k);
    if (t.probability > search.chi) out.push_back({j, k, std::move(t)});
  }
  std::sort(out.begin(), out.end(), [](const Candidate& a, const Candidate& b) {
    return a.test.probability > b.test.probability;
  });
  return out;
}

// Groups of features joined in one round (union-find). A group may absorb several features,
// so a well-established feature takes in single sightings one by one; merging only disjoint
// pairs instead grows many small clusters whose last merge is between two halves of one
// landmark's measurements, split along the noise, which the test then rightly finds apart.
class MergeGroups {
 public:
  MergeGroups(std::vector<std::vector<int>> times, std::vector<int> first)
      : parent_(times.size()), times_(std::move(times)), first_(std::move(first)) {
    std::iota(parent_.begin(), parent_.end(), 0);
  }
  int root(int j) {
    while (parent_[j] != j) j = parent_[j] = parent_[parent_[j]];
    return j;
  }
  // Joins the groups of j and k unless they are one already or share a time step; the group
  // seen first keeps its name.
  bool join(int j, int k) {
    int a = root(j), b = root(k);
    if (a == b || share_a_time(times_[a], times_[b])) return false;
    if (first_[b] < first_[a]) std::swap(a, b);
    parent_[b] = a;
    std::vector<int> both;
    std::merge(times_[a].begin(), times_[a].end(), times_[b].begin(), times_[b].end(), std::back_inserter(both));
    times_[a] = std::move(both);
    times_[b].clear();
    return true;
  }
  int first(int j) const { return first_[j]; }

 private:
  std::vector<int> parent_;
  std::vector<std::vector<int>> times_;
  std::vector<int> first_;
};

// Line 11: relabels the measurements onto compact indices of the groups' roots and returns the
// warm-start means (the observation-weighted average of each group). `first` names each feature
// by its first measurement.
RowMatrixXd merge(MergeGroups& groups, const RowMatrixXd& features, FeatureMeasurements& meas,
                  std::vector<int>& first) {
  const int n = static_cast<int>(features.rows());
  std::vector<int> index(n, -1);
  int next = 0;
  for (int j = 0; j < n; ++j)
    if (groups.root(j) == j) index[j] = next++;
  std::vector<double> count(n, 0.0);
  for (Eigen::Index k = 0; k < meas.feature.size(); ++k) count[meas.feature[k]] += 1.0;
  RowMatrixXd merged = RowMatrixXd::Zero(next, features.cols());
  Eigen::VectorXd weight = Eigen::VectorXd::Zero(next);
  std::vector<int> new_first(next);
  for (int j = 0; j < n; ++j) {
    const int to = index[groups.root(j)];
    merged.row(to) += count[j] * features.row(j);
    weight[to] += count[j];
    if (groups.root(j) == j) new_first[to] = first[j];
  }
  for (int j = 0; j < next; ++j) merged.row(j) /= weight[j];
  for (Eigen::Index k = 0; k < meas.feature.size(); ++k) meas.feature[k] = index[groups.root(meas.feature[k])];
  first = std::move(new_first);
  return merged;
}

}  // namespace

// Table 11.9.
GraphSlamUnknownResult graph_slam_unknown(const Eigen::Ref<const RowMatrixXd>& controls,
                                          const Eigen::VectorXd& dt, const FeatureMeasurements& measurements,
                                          const Eigen::Matrix3d& R, const Eigen::MatrixXd& Q,
                                          const GraphSlamOptions& options,
                                          const CorrespondenceSearchOptions& search) {
  require(search.chi >= 0.0 && std::isfinite(search.chi), "chi", "must be finite and >= 0");
  require(search.search_radius > 0.0 && std::isfinite(search.search_radius), "search_radius",
          "must be finite and > 0");
  require(search.max_rounds >= 0, "max_rounds", "must be >= 0");
  const int m = static_cast<int>(measurements.z.rows());
  // Line 2: a feature per measurement.
  FeatureMeasurements meas = measurements;
  meas.feature = Eigen::VectorXi::LinSpaced(m, 0, m - 1);
  std::vector<int> first(m);
  std::iota(first.begin(), first.end(), 0);

  GraphSlamUnknownResult out;
  GraphSlamOptions round_options = options;
  round_options.path_covariances = false;
  SparseCholesky cholesky(options.linear_solver);
  Poses2 poses = eif_initialize(controls, dt, options.initial_pose);  // line 3
  RowMatrixXd features = eif_initial_features(poses, meas, m);
  for (int round = 1;; ++round) {
    InformationForm form;  // lines 4-6 and 12-14
    out.slam = graph_slam_from(controls, dt, meas, R, Q, std::move(poses), std::move(features),
                               round_options, cholesky, &form);
    if (round > search.max_rounds) break;
    out.rounds = round;
    EifCorrespondenceTester tester(form, cholesky, out.slam.features);
    const int n = static_cast<int>(out.slam.features.rows());
    auto times = feature_times(meas, n);
    const auto accepted = accepted_pairs(tester, times, out.slam.features, search);
    MergeGroups groups(std::move(times), first);
    bool merged = false;
    for (const Candidate& c : accepted) {
      const int a = groups.first(groups.root(c.j)), b = groups.first(groups.root(c.k));
      if (!groups.join(c.j, c.k)) continue;
      merged = true;
      out.merges.push_back({round, std::min(a, b), std::max(a, b), c.test.probability, c.test.distance2});
    }
    if (!merged) {  // line 17
      out.converged = true;
      break;
    }
    features = merge(groups, out.slam.features, meas, first);
    poses = std::move(out.slam.poses);
  }
  if (options.path_covariances)
    out.slam.pose_covariances = eif_pose_covariances(cholesky, static_cast<int>(out.slam.poses.rows()));
  out.correspondences = meas.feature;
  return out;
}

}  // namespace probslam
