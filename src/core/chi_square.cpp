#include "probslam/core/chi_square.hpp"

#include <cmath>
#include <limits>
#include <string>

#include "probslam/core/check.hpp"

namespace probslam {
namespace {

// Relative accuracy of the incomplete gamma function's series and continued fraction: the
// terms are summed until they change the result by less than this.
constexpr double kGammaEpsilon = 1e-15;
constexpr int kGammaMaxTerms = 1000;
// Quantile bisection stops when the bracket is this narrow relative to its upper end.
constexpr double kQuantileTolerance = 1e-13;
// Smallest number the continued fraction's modified Lentz iteration may divide by.
constexpr double kTiny = 1e-300;

// Regularised lower incomplete gamma P(a, x): its power series below x = a + 1, where it converges
// fast, and one minus the continued fraction of Q(a, x) above.
double regularized_gamma_p(double a, double x) {
  if (x <= 0.0) return 0.0;
  const double log_prefactor = a * std::log(x) - x - std::lgamma(a);
  if (x < a + 1.0) {
    double term = 1.0 / a, sum = term;
    for (int n = 1; n < kGammaMaxTerms; ++n) {
      term *= x / (a + n);
      sum += term;
      if (std::fabs(term) < std::fabs(sum) * kGammaEpsilon) break;
    }
    return sum * std::exp(log_prefactor);
  }
  double b = x + 1.0 - a, c = 1.0 / kTiny, d = 1.0 / b, h = d;
  for (int n = 1; n < kGammaMaxTerms; ++n) {
    const double an = -n * (n - a);
    b += 2.0;
    d = an * d + b;
    if (std::fabs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::fabs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::fabs(delta - 1.0) < kGammaEpsilon) break;
  }
  return 1.0 - std::exp(log_prefactor) * h;
}

}  // namespace

double chi_square_cdf(double x, int dof) {
  require(dof >= 1, "dof", "must be >= 1");
  require(!std::isnan(x), "x", "must not be NaN");
  if (x == std::numeric_limits<double>::infinity()) return 1.0;
  return regularized_gamma_p(0.5 * dof, 0.5 * x);
}

double chi_square_quantile(double p, int dof) {
  require_probability(p, "p");
  require(dof >= 1, "dof", "must be >= 1");
  double lo = 0.0, hi = static_cast<double>(dof);
  while (chi_square_cdf(hi, dof) < p) {
    lo = hi;
    hi *= 2.0;
  }
  // The CDF is increasing: bisection is slow but cannot fail, and gates are computed rarely.
  while (hi - lo > kQuantileTolerance * hi) {
    const double mid = 0.5 * (lo + hi);
    if (chi_square_cdf(mid, dof) < p) lo = mid;
    else hi = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace probslam
