#pragma once
// The four-part mixture of the beam model of range finders (Probabilistic Robotics ch. 6.3,
// eq. 6.4-6.12): the density of a reading z given the range z* the map predicts.
#include <cstdint>
#include <random>

namespace probslam {

/// Weights z_hit, z_short, z_max, z_rand (>= 0, summing to 1 within kWeightSumTolerance) and
/// the parameters sigma_hit (m), lambda_short (1/m) and max_range (the book's z_max, m; named
/// apart from the weight z_max). Readings >= max_range are max readings.
struct BeamMixture {
  double z_hit = 0.85;
  double z_short = 0.05;
  double z_max = 0.05;
  double z_rand = 0.05;
  double sigma_hit = 0.05;
  double lambda_short = 1.0;
  double max_range = 5.0;

  /// The weights are typed in by hand (0.85 + 0.05 + ...), so their sum carries decimal
  /// rounding of a few ulps; anything beyond 1e-9 is a mistake, not rounding.
  static constexpr double kWeightSumTolerance = 1e-9;

  /// Throws std::invalid_argument naming the first bad parameter.
  void validate() const;

  template <class V>
  static void describe(V& v) {
    using B = BeamMixture;
    v("z_hit", &B::z_hit, "", "weight of the measurement noise around the expected range");
    v("z_short", &B::z_short, "", "weight of unexpected objects short of it");
    v("z_max", &B::z_max, "", "weight of max readings (failures)");
    v("z_rand", &B::z_rand, "", "weight of random readings");
    v("sigma_hit", &B::sigma_hit, "m", "std of a hit around the expected range");
    v("lambda_short", &B::lambda_short, "1/m", "rate of the short readings' exponential");
    v("max_range", &B::max_range, "m", "the sensor's largest reading (the book's z_max)");
  }

  /// Eq. 6.12: z_hit p_hit + z_short p_short + z_max p_max + z_rand p_rand for reading z and
  /// expected range z_expected in [0, max_range]. Densities per metre, except p_max, which is
  /// the indicator of a max reading (eq. 6.10), as in Table 6.1 line 5. z must be >= 0 and not
  /// NaN (callers check); z >= max_range is a max reading, evaluated at max_range.
  double probability(double z, double z_expected) const;
  /// log(probability(z, z_expected)); -inf where the probability is 0.
  double log_probability(double z, double z_expected) const;

  /// A reading drawn from the mixture: the component by its weight, then the component
  /// (eq. 6.4-6.11) exactly (truncated Gaussian by rejection, truncated exponential by its
  /// inverse CDF).
  double sample(double z_expected, std::mt19937_64& rng) const;
};

}  // namespace probslam
