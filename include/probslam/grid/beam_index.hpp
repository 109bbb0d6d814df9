#pragma once
// Nearest-beam lookup for Table 9.2 line 5, in O(1) per query.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace probslam {

/// Answers k = argmin_j |wrap(phi - theta_j)| over the beams marked valid, lowest index on
/// ties, exactly as the loop over all beams does: angles are bucketed, each bucket keeps the
/// few beams that can be nearest to an angle in it, and those are compared with the same
/// arithmetic as the loop.
class BeamIndex {
 public:
  /// `valid[j] == 0` leaves beam j out (e.g. a NaN reading). Angles must be finite (radians).
  BeamIndex(const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const std::vector<std::uint8_t>& valid);

  struct Nearest {
    int index;        // -1 if there is no valid beam
    double distance;  // |wrap(phi - theta_index)|, radians
  };
  /// The nearest valid beam to bearing phi (radians, any range).
  Nearest nearest(double phi) const;
  bool empty() const { return count_ == 0; }
  /// The widest angular gap between neighbouring valid beams: it starts at the wrapped angle
  /// `gap_start` and spans `gap_width` radians counter-clockwise (2 pi for a single beam).
  double gap_start() const { return gap_start_; }
  double gap_width() const { return gap_width_; }

 private:
  std::vector<double> angles_;  // as given, for the exact comparison
  std::vector<std::int32_t> bucket_start_;
  std::vector<std::int32_t> candidates_;
  double buckets_per_radian_ = 0.0;
  int count_ = 0;
  double gap_start_ = 0.0, gap_width_ = 0.0;
};

}  // namespace probslam
