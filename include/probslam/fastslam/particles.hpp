#pragma once
// What the particle filters (landmark FastSLAM, grid FastSLAM) share: a random stream per
// particle, persistent pose paths, low-variance resampling and the log-weight bookkeeping.
#include <Eigen/Core>
#include <algorithm>
#include <atomic>
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

class StateWriter;
class StateReader;

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
  /// The stream's whole state (four words and the spare normal deviate), bit for bit.
  void write_state(StateWriter& w) const;
  static ParticleRng read_state(StateReader& r);

 private:
  std::uint64_t s_[4];
  double spare_ = 0.0;
  bool has_spare_ = false;
};

/// A persistent list of poses: appending or copying is O(1), and a path is shared by the
/// particles that descend from one ancestor.
///
/// Poses are stored in chunks of kChunkPoses, newest chunk first. A path is its newest chunk and
/// how many of that chunk's poses are its own (`used_`); each chunk records how many poses of
/// the chunk before it precede it. Slots of a chunk are taken in order, by an atomic claim: a
/// path appends in place when the next slot is the first free one (no path holding the chunk
/// reads a slot at or beyond its own count, so nobody else can see the write), and starts a new
/// chunk otherwise (another path already took that slot). So a chunk's taken slots never change,
/// and a particle's copies (resampling) share all poses while appending costs one allocation per
/// kChunkPoses poses of a lineage, not one per pose. A pose path of a whole MRCLAM robot (100
/// particles, 100 000 steps) spent a third of the run allocating and freeing one node per pose.
class PosePath {
 public:
  /// Poses per chunk: 16 x 24 bytes, so a chunk is a few cache lines and its header a tenth.
  static constexpr int kChunkPoses = 16;
  struct Chunk {
    NodeRef<Chunk> prev;      // the older poses
    std::size_t before = 0;   // poses on any path before this chunk's first
    int prev_used = 0;        // poses of prev on the paths through this chunk
    mutable std::atomic<int> claimed{1};  // slots taken (slot 0 by the path that made the chunk)
    mutable std::atomic<std::uint32_t> refs{1};
    mutable Eigen::Vector3d poses[kChunkPoses];  // written once each, by the path that claimed it
    Chunk(NodeRef<Chunk> older, int older_used, const Eigen::Vector3d& first)
        : prev(std::move(older)), before(prev ? prev->before + static_cast<std::size_t>(older_used) : 0),
          prev_used(older_used) {
      poses[0] = first;
    }
    static void* operator new(std::size_t) { return NodePool<Chunk>::allocate(); }
    static void operator delete(void* p) noexcept { NodePool<Chunk>::release(p); }
    // Iterative: a path of a million poses must not recurse through its chunks.
    static void destroy(const Chunk* c);
  };
  std::size_t size() const { return head_ ? head_->before + static_cast<std::size_t>(used_) : 0; }
  void push(const Eigen::Vector3d& pose) {
    if (head_ && used_ < kChunkPoses) {
      int expected = used_;
      if (head_->claimed.compare_exchange_strong(expected, used_ + 1, std::memory_order_acq_rel)) {
        head_->poses[used_++] = pose;
        return;
      }
    }
    head_ = NodeRef<Chunk>::adopt(new Chunk(std::move(head_), used_, pose));
    used_ = 1;
  }
  /// Drops the newest pose (none: no-op). Its slot stays taken: a copy may still hold it.
  void pop() {
    if (!head_) return;
    if (used_ > 1) {
      --used_;
      return;
    }
    used_ = head_->prev_used;
    head_ = NodeRef<Chunk>(head_->prev);
  }
  /// The newest n poses (at most size()), oldest first.
  std::vector<Eigen::Vector3d> newest(std::size_t n) const;
  /// Replaces the newest pose.
  void replace_last(const Eigen::Vector3d& pose) {
    pop();
    push(pose);
  }
  /// Oldest first, (size, 3).
  Poses2 poses() const;
  /// Adds this path's chunks to `seen`; returns how many were new.
  std::size_t collect_nodes(std::unordered_set<const void*>& seen) const;
  /// The poses, oldest first; read_state rebuilds a path of its own (no chunk shared with
  /// another path: the sharing between particles is not saved).
  void write_state(StateWriter& w) const;
  static PosePath read_state(StateReader& r);

 private:
  NodeRef<Chunk> head_;
  int used_ = 0;  // poses of head_ on this path
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
