#pragma once
// What the particle filters (landmark FastSLAM, grid FastSLAM) share: a random stream per
// particle, persistent pose paths, low-variance resampling and the log-weight bookkeeping.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <unordered_set>
#include <vector>

#include "probslam/core/types.hpp"
#include "probslam/fastslam/node_pool.hpp"
#include "probslam/fastslam/node_ref.hpp"

namespace probslam {

/// Particles per filter: 2^20 particles of ~250 bytes each before any map.
inline constexpr int kMaxParticles = 1 << 20;

/// A fast stream of random numbers per particle (xoshiro256**, seeded by splitmix64 from the
/// filter's seed and the stream number), with standard normal deviates by Box-Muller.
class ParticleRng {
 public:
  ParticleRng() : ParticleRng(0, 0) {}
  ParticleRng(std::uint64_t seed, std::uint64_t stream);
  std::uint64_t next();
  /// Uniform in [0, 1).
  double uniform();
  double normal();

 private:
  std::uint64_t s_[4];
  double spare_ = 0.0;
  bool has_spare_ = false;
};

/// A persistent list of poses (newest first): appending or copying is O(1), and a path is
/// shared by the particles that descend from one ancestor.
class PosePath {
 public:
  struct Node {
    Eigen::Vector3d pose;
    NodeRef<Node> prev;
    std::size_t length;
    mutable std::atomic<std::uint32_t> refs{1};
    Node(const Eigen::Vector3d& p, NodeRef<Node> before)
        : pose(p), prev(std::move(before)), length(1 + (prev ? prev->length : 0)) {}
    static void* operator new(std::size_t) { return NodePool<Node>::allocate(); }
    static void operator delete(void* p) noexcept { NodePool<Node>::release(p); }
    // Iterative: a path of a million poses must not recurse a million deep.
    static void destroy(const Node* n);
  };
  std::size_t size() const { return head_ ? head_->length : 0; }
  void push(const Eigen::Vector3d& pose) { head_ = NodeRef<Node>::adopt(new Node(pose, std::move(head_))); }
  /// Drops the newest pose (none: no-op).
  void pop() {
    if (head_) head_ = NodeRef<Node>(head_->prev);
  }
  /// Replaces the newest pose.
  void replace_last(const Eigen::Vector3d& pose) {
    NodeRef<Node> before = head_ ? head_->prev : NodeRef<Node>();
    head_ = NodeRef<Node>::adopt(new Node(pose, std::move(before)));
  }
  /// Oldest first, (size, 3).
  Poses2 poses() const;
  std::size_t collect_nodes(std::unordered_set<const void*>& seen) const;

 private:
  NodeRef<Node> head_;
};

/// Low-variance (systematic) resampling, Table 4.4: M = weights.size() draws at the positions
/// (offset + m) / M, m = 0..M-1, of the cumulative normalised weights; offset in [0, 1). Each
/// index k appears floor(M w_k) or ceil(M w_k) times. Weights need not be normalised.
std::vector<int> low_variance_resample(const Eigen::VectorXd& weights, double offset);

/// The particles' poses (M x 3), log weights (M,) and the index of the heaviest (the first of
/// equals), for any particle type with `pose` and `log_weight`.
template <class Particles>
Poses2 particle_poses(const Particles& particles) {
  Poses2 out(static_cast<Eigen::Index>(particles.size()), 3);
  Eigen::Index k = 0;
  for (const auto& p : particles) out.row(k++) = p.pose.transpose();
  return out;
}
template <class Particles>
Eigen::VectorXd particle_log_weights(const Particles& particles) {
  Eigen::VectorXd out(static_cast<Eigen::Index>(particles.size()));
  Eigen::Index k = 0;
  for (const auto& p : particles) out[k++] = p.log_weight;
  return out;
}
template <class Particles>
int heaviest_particle(const Particles& particles) {
  int best = 0, k = 0;
  for (const auto& p : particles) {
    if (p.log_weight > particles[static_cast<std::size_t>(best)].log_weight) best = k;
    ++k;
  }
  return best;
}

/// Normalises log weights in place by log-sum-exp and returns N_eff = 1 / sum w^2.
inline double normalise_log_weights(std::vector<double>& log_weights) {
  double top = -std::numeric_limits<double>::infinity();
  for (double lw : log_weights) top = std::max(top, lw);
  double sum = 0.0;
  for (double lw : log_weights) sum += std::exp(lw - top);
  const double lse = top + std::log(sum);
  double sum_sq = 0.0;
  for (double& lw : log_weights) {
    lw -= lse;
    sum_sq += std::exp(2.0 * lw);
  }
  return 1.0 / sum_sq;
}

/// The same for the `log_weight` of `particles`.
template <class Particles>
double normalise_log_weights(Particles& particles) {
  std::vector<double> lw;
  lw.reserve(particles.size());
  for (const auto& p : particles) lw.push_back(p.log_weight);
  const double n_eff = normalise_log_weights(lw);
  std::size_t k = 0;
  for (auto& p : particles) p.log_weight = lw[k++];
  return n_eff;
}

/// Low-variance resampling on log weights: the ancestor of each of the M new particles, the
/// offset drawn from `filter_rng`.
inline std::vector<int> resampling_ancestors(const std::vector<double>& log_weights, ParticleRng& filter_rng) {
  Eigen::VectorXd w(static_cast<Eigen::Index>(log_weights.size()));
  for (Eigen::Index k = 0; k < w.size(); ++k) w[k] = std::exp(log_weights[static_cast<std::size_t>(k)]);
  return low_variance_resample(w, filter_rng.uniform());
}

/// Low-variance resampling of `particles` (each with `log_weight` and `rng`): copies are O(1)
/// when a particle shares its map and path, the j-th new particle takes random stream
/// next_stream + j of `seed` (so a seed gives the same result for any number of threads) and
/// every weight becomes 1 / M. Returns the ancestors' indices.
template <class Particle>
std::vector<int> resample_particles(std::vector<Particle>& particles, ParticleRng& filter_rng, std::uint64_t seed,
                                    std::uint64_t& next_stream) {
  const Eigen::Index m = static_cast<Eigen::Index>(particles.size());
  std::vector<double> lw;
  lw.reserve(particles.size());
  for (const auto& p : particles) lw.push_back(p.log_weight);
  const std::vector<int> idx = resampling_ancestors(lw, filter_rng);
  std::vector<Particle> next;
  next.reserve(particles.size());
  const double log_weight = -std::log(static_cast<double>(m));
  for (Eigen::Index j = 0; j < m; ++j) {
    next.push_back(particles[static_cast<std::size_t>(idx[static_cast<std::size_t>(j)])]);
    next.back().rng = ParticleRng(seed, next_stream + static_cast<std::uint64_t>(j));
    next.back().log_weight = log_weight;
  }
  next_stream += static_cast<std::uint64_t>(m);
  particles.swap(next);
  return idx;
}

}  // namespace probslam
