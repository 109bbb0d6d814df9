#include "probslam/grid/beam_mixture.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "probslam/core/check.hpp"

namespace probslam {
namespace {

constexpr double kSqrt2 = 1.41421356237309504880;
constexpr double kSqrt2Pi = 2.50662827463100050242;

// Phi(b) - Phi(a) of the standard normal, from erfc for accuracy in the tails.
double normal_mass(double a, double b) {
  if (a >= 0.0) return 0.5 * (std::erfc(a / kSqrt2) - std::erfc(b / kSqrt2));
  if (b <= 0.0) return 0.5 * (std::erfc(-b / kSqrt2) - std::erfc(-a / kSqrt2));
  return 1.0 - 0.5 * (std::erfc(-a / kSqrt2) + std::erfc(b / kSqrt2));
}

// A truncated normal with less mass than this on [0, max_range] is sampled by rejection from
// the uniform on [0, max_range] instead of from the normal (the acceptance rate of either
// proposal then stays above ~0.3).
constexpr double kMinNormalAcceptance = 0.3;

}  // namespace

void BeamMixture::validate() const {
  const auto weight = [](double w, const char* name) {
    require(std::isfinite(w) && w >= 0.0, name, "must be a finite weight >= 0");
  };
  weight(z_hit, "z_hit");
  weight(z_short, "z_short");
  weight(z_max, "z_max");
  weight(z_rand, "z_rand");
  require(std::fabs(z_hit + z_short + z_max + z_rand - 1.0) <= kWeightSumTolerance, "z_hit",
          "+ z_short + z_max + z_rand must sum to 1 (within 1e-9, BeamMixture::kWeightSumTolerance)");
  require_positive(sigma_hit, "sigma_hit");
  require_positive(lambda_short, "lambda_short");
  require_positive(max_range, "max_range");
}

double BeamMixture::probability(double z, double z_expected) const {
  const double zs = std::clamp(z_expected, 0.0, max_range);
  if (z >= max_range) {
    // Eq. 6.10: the max reading. p_hit's support [0, z_max] includes z_max (eq. 6.4), p_rand's
    // [0, z_max) does not (eq. 6.11); p_short is 0 there unless z* = z_max.
    z = max_range;
  }
  double p = 0.0;
  // Eq. 6.4-6.6: N(z; z*, sigma^2) normalised over [0, z_max].
  const double mass = normal_mass(-zs / sigma_hit, (max_range - zs) / sigma_hit);
  if (mass > 0.0) {
    const double u = (z - zs) / sigma_hit;
    p += z_hit * std::exp(-0.5 * u * u) / (kSqrt2Pi * sigma_hit * mass);
  }
  // Eq. 6.7-6.8: lambda e^{-lambda z} normalised over [0, z*]; with z* = 0 it is the point mass
  // at 0 (its limit), counted like p_max.
  if (zs > 0.0) {
    if (z <= zs) p += z_short * lambda_short * std::exp(-lambda_short * z) / -std::expm1(-lambda_short * zs);
  } else if (z == 0.0) {
    p += z_short;
  }
  if (z >= max_range) p += z_max;                    // eq. 6.10
  if (z < max_range) p += z_rand / max_range;        // eq. 6.11
  return p;
}

double BeamMixture::log_probability(double z, double z_expected) const {
  const double p = probability(z, z_expected);
  return p > 0.0 ? std::log(p) : -std::numeric_limits<double>::infinity();
}

double BeamMixture::sample(double z_expected, std::mt19937_64& rng) const {
  const double zs = std::clamp(z_expected, 0.0, max_range);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double pick = unit(rng) * (z_hit + z_short + z_max + z_rand);
  if (pick < z_hit) {
    // Eq. 6.4: the truncated normal, by rejection from the cheaper of two proposals.
    const double mass = normal_mass(-zs / sigma_hit, (max_range - zs) / sigma_hit);
    if (mass >= kMinNormalAcceptance) {
      std::normal_distribution<double> normal(zs, sigma_hit);
      for (;;) {
        const double z = normal(rng);
        if (z >= 0.0 && z <= max_range) return z;
      }
    }
    for (;;) {
      const double z = unit(rng) * max_range;
      const double u = (z - zs) / sigma_hit;
      // The uniform proposal is used when sigma is wide against [0, z_max] (mass < 0.3 means
      // max_range < 0.85 sigma), so the acceptance exp(-u^2/2) stays above 0.69.
      if (unit(rng) <= std::exp(-0.5 * u * u)) return z;
    }
  }
  if (pick < z_hit + z_short) {
    if (zs <= 0.0) return 0.0;
    // Eq. 6.7: the inverse CDF of the exponential truncated to [0, z*].
    const double u = unit(rng);
    return std::min(zs, -std::log1p(u * std::expm1(-lambda_short * zs)) / lambda_short);
  }
  if (pick < z_hit + z_short + z_max) return max_range;  // eq. 6.10
  return unit(rng) * max_range;                           // eq. 6.11
}

}  // namespace probslam
