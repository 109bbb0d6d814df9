#pragma once
// The chi-square distribution's CDF and quantile: association gates for any number of degrees
// of freedom (joint compatibility tests k measurements at once, with k times the dof of one).

namespace probslam {

/// P(X <= x) for X ~ chi-square with `dof` >= 1 degrees of freedom; 0 for x <= 0.
double chi_square_cdf(double x, int dof);

/// The x with chi_square_cdf(x, dof) = p, for 0 < p < 1.
double chi_square_quantile(double p, int dof);

}  // namespace probslam
