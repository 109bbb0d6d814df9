#include "probslam/grid/beam_index.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"

namespace probslam {
namespace {

// Bucket edges are widened by this much so that rounding in wrap(phi) (about 1e-15 rad) can
// never move a query out of the range its bucket's candidate list covers.
constexpr double kBucketMargin = 1e-9;
constexpr int kMinBuckets = 64;
constexpr int kMaxBuckets = 1 << 16;
constexpr int kBucketsPerBeam = 8;  // mostly two candidates per bucket

struct SortedBeam {
  double angle;  // wrapped, possibly shifted by +-2pi
  int index;
};

}  // namespace

BeamIndex::BeamIndex(const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                     const std::vector<std::uint8_t>& valid)
    : angles_(beam_angles.data(), beam_angles.data() + beam_angles.size()) {
  require(valid.size() == angles_.size(), "beam_angles", "must have one entry per range reading");
  require_all_finite(beam_angles, "beam_angles");

  std::vector<SortedBeam> sorted;
  for (std::size_t j = 0; j < angles_.size(); ++j)
    if (valid[j]) sorted.push_back({wrap_angle(angles_[j]), static_cast<int>(j)});
  count_ = static_cast<int>(sorted.size());
  if (count_ == 0) return;
  std::sort(sorted.begin(), sorted.end(), [](const SortedBeam& a, const SortedBeam& b) {
    return a.angle < b.angle || (a.angle == b.angle && a.index < b.index);
  });
  for (std::size_t p = 0; p < sorted.size(); ++p) {
    const double next = p + 1 < sorted.size() ? sorted[p + 1].angle : sorted.front().angle + kTwoPi;
    if (next - sorted[p].angle > gap_width_) {
      gap_width_ = next - sorted[p].angle;
      gap_start_ = sorted[p].angle;
    }
  }
  // Three turns of the circle, so that neighbours across +-pi are plain neighbours.
  std::vector<SortedBeam> ring;
  ring.reserve(3 * sorted.size());
  for (double shift : {-kTwoPi, 0.0, kTwoPi})
    for (const SortedBeam& s : sorted) ring.push_back({s.angle + shift, s.index});

  const int buckets = std::clamp(kBucketsPerBeam * count_, kMinBuckets, kMaxBuckets);
  buckets_per_radian_ = buckets / kTwoPi;
  bucket_start_.assign(1, 0);
  const auto less_angle = [](const SortedBeam& s, double a) { return s.angle < a; };
  const auto greater_angle = [](double a, const SortedBeam& s) { return a < s.angle; };
  std::vector<std::int32_t> bucket;
  for (int b = 0; b < buckets; ++b) {
    const double a0 = -kPi + b / buckets_per_radian_ - kBucketMargin;
    const double a1 = -kPi + (b + 1) / buckets_per_radian_ + kBucketMargin;
    // The nearest beam to any angle in [a0, a1] lies between the last beam before a0 and the
    // first beam after a1; equal angles are taken as whole runs so ties stay visible.
    auto lo = std::lower_bound(ring.begin(), ring.end(), a0, less_angle) - ring.begin() - 1;
    auto hi = std::upper_bound(ring.begin(), ring.end(), a1, greater_angle) - ring.begin();
    while (lo > 0 && ring[lo - 1].angle == ring[lo].angle) --lo;
    while (hi + 1 < static_cast<long>(ring.size()) && ring[hi + 1].angle == ring[hi].angle) ++hi;
    bucket.clear();
    if (hi - lo + 1 >= count_) {
      for (const SortedBeam& s : sorted) bucket.push_back(s.index);
    } else {
      for (auto p = lo; p <= hi; ++p) bucket.push_back(ring[p].index);
    }
    std::sort(bucket.begin(), bucket.end());  // ascending index: strict '<' keeps the lowest
    bucket.erase(std::unique(bucket.begin(), bucket.end()), bucket.end());
    candidates_.insert(candidates_.end(), bucket.begin(), bucket.end());
    bucket_start_.push_back(static_cast<std::int32_t>(candidates_.size()));
  }
}

// Table 9.2 line 5.
BeamIndex::Nearest BeamIndex::nearest(double phi) const {
  if (count_ == 0) return {-1, std::numeric_limits<double>::infinity()};
  const int buckets = static_cast<int>(bucket_start_.size()) - 1;
  int b = static_cast<int>((wrap_angle(phi) + kPi) * buckets_per_radian_);
  b = std::clamp(b, 0, buckets - 1);
  int best = -1;
  double best_distance = std::numeric_limits<double>::infinity();
  for (std::int32_t c = bucket_start_[b]; c < bucket_start_[b + 1]; ++c) {
    const int j = candidates_[c];
    const double d = std::fabs(wrap_angle(phi - angles_[j]));
    if (d < best_distance) {
      best_distance = d;
      best = j;
    }
  }
  return {best, best_distance};
}

}  // namespace probslam
