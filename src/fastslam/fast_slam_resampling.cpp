// FastSLAM's particle bookkeeping: the weights normalised after a staged update, resampling
// (Table 4.4) and the particles' replacement by copies of their ancestors.
#include "fast_slam_internal.hpp"

#include "probslam/fastslam/particles.hpp"

namespace probslam {
using namespace fastslam_detail;

void FastSlam::drop_spare_if_serial() {
  // With workers, the next call's workers let go of spare_ as they overwrite it; alone, at once.
  if (!pool_)
    for (FastSlamParticle& p : spare_) p.drop_shared();
}

std::vector<int> FastSlam::commit() {
  // Table 4.4's resampling when N_eff is low; the weights normalised by log-sum-exp.
  const double n_eff = normalise_log_weights(weights_);
  std::vector<int> ancestors;
  if (n_eff < o_.resample_threshold * num_particles()) ancestors = resampling_ancestors(weights_, rng_);
  settle(ancestors);
  return ancestors;
}

void FastSlam::settle(const std::vector<int>& ancestors) {
  last_ancestors_ = ancestors;
  last_resampled_ = !ancestors.empty();
  if (ancestors.empty()) {
    for_particles([&](int k) { particles_[static_cast<std::size_t>(k)].log_weight = weights_[static_cast<std::size_t>(k)]; });
    return;
  }
  // Copies share their ancestor's map and path: O(1) each. The j-th new particle takes random
  // stream next_stream_ + j, so a seed gives the same result for any number of threads.
  const double log_weight = -std::log(static_cast<double>(num_particles()));
  const std::uint64_t first_stream = next_stream_;
  for_particles([&](int k) {
    const auto i = static_cast<std::size_t>(k);
    FastSlamParticle& p = spare_[i];
    p = particles_[static_cast<std::size_t>(ancestors[i])];
    p.rng = ParticleRng(o_.seed, first_stream + static_cast<std::uint64_t>(k));
    p.log_weight = log_weight;
  });
  particles_.swap(spare_);
  drop_spare_if_serial();
  next_stream_ += static_cast<std::uint64_t>(num_particles());
  ++resamples_;
}

void FastSlam::resample() {
  weights_.resize(particles_.size());
  for (std::size_t k = 0; k < particles_.size(); ++k) weights_[k] = particles_[k].log_weight;
  if (spare_.size() != particles_.size()) spare_.resize(particles_.size());
  settle(resampling_ancestors(weights_, rng_));
}

}  // namespace probslam
