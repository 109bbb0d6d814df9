#include "probslam/fastslam/particles.hpp"

#include <algorithm>

#include "probslam/core/check.hpp"

namespace probslam {
namespace {
constexpr double kTwoPi = 6.283185307179586;
}  // namespace

// ---- random streams and paths ----

ParticleRng::ParticleRng(std::uint64_t seed, std::uint64_t stream) {
  std::uint64_t x = mix64(seed) ^ mix64(stream ^ 0xd1b54a32d192ed03ULL);
  for (std::uint64_t& s : s_) {
    x += 0x9e3779b97f4a7c15ULL;
    s = mix64(x);
  }
}

std::uint64_t ParticleRng::next() {
  const auto rotl = [](std::uint64_t v, int k) { return (v << k) | (v >> (64 - k)); };
  const std::uint64_t result = rotl(s_[1] * 5, 7) * 9;
  const std::uint64_t t = s_[1] << 17;
  s_[2] ^= s_[0];
  s_[3] ^= s_[1];
  s_[1] ^= s_[2];
  s_[0] ^= s_[3];
  s_[2] ^= t;
  s_[3] = rotl(s_[3], 45);
  return result;
}

double ParticleRng::uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

double ParticleRng::normal() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  const double u1 = 1.0 - uniform();  // (0, 1]
  const double u2 = uniform();
  const double r = std::sqrt(-2.0 * std::log(u1));
  spare_ = r * std::sin(kTwoPi * u2);
  has_spare_ = true;
  return r * std::cos(kTwoPi * u2);
}

void PosePath::Chunk::destroy(const Chunk* c) {
  while (c) {
    Chunk* owned = const_cast<Chunk*>(c);
    const Chunk* prev = owned->prev.detach();
    delete owned;
    if (!prev || prev->refs.fetch_sub(1, std::memory_order_acq_rel) != 1) return;
    c = prev;
  }
}

Poses2 PosePath::poses() const {
  Poses2 out(static_cast<Eigen::Index>(size()), 3);
  Eigen::Index row = out.rows();
  int used = used_;
  for (const Chunk* c = head_.get(); c; used = c->prev_used, c = c->prev.get())
    for (int i = used - 1; i >= 0; --i) out.row(--row) = c->poses[i].transpose();
  return out;
}

std::vector<Eigen::Vector3d> PosePath::newest(std::size_t n) const {
  std::vector<Eigen::Vector3d> out;
  out.reserve(std::min(n, size()));
  int used = used_;
  for (const Chunk* c = head_.get(); c && out.size() < n; used = c->prev_used, c = c->prev.get())
    for (int i = used - 1; i >= 0 && out.size() < n; --i) out.push_back(c->poses[i]);
  std::reverse(out.begin(), out.end());
  return out;
}

std::size_t PosePath::collect_nodes(std::unordered_set<const void*>& seen) const {
  std::size_t added = 0;
  for (const Chunk* c = head_.get(); c && seen.insert(c).second; c = c->prev.get()) ++added;
  return added;
}

std::vector<int> low_variance_resample(const Eigen::VectorXd& weights, double offset) {
  require(weights.size() > 0, "weights", "must not be empty");
  require(weights.size() <= kMaxParticles, "weights", "must have at most 2^20 (kMaxParticles) entries");
  require(weights.allFinite() && (weights.array() >= 0.0).all(), "weights", "must be finite and >= 0");
  const double total = weights.sum();
  require(total > 0.0 && std::isfinite(total), "weights", "must have a finite positive sum");
  require(std::isfinite(offset) && offset >= 0.0 && offset < 1.0, "offset", "must be in [0, 1)");
  const Eigen::Index m = weights.size();
  std::vector<int> out(static_cast<std::size_t>(m));
  Eigen::Index i = 0;
  double c = weights[0] / total;
  for (Eigen::Index j = 0; j < m; ++j) {
    const double u = (offset + static_cast<double>(j)) / static_cast<double>(m);
    while (u > c && i < m - 1) c += weights[++i] / total;
    out[static_cast<std::size_t>(j)] = static_cast<int>(i);
  }
  return out;
}

}  // namespace probslam
