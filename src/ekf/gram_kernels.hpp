#pragma once
// Private to src/ekf: EkfSlam's covariance update P -= W W^T (its one O(n^2) step per call),
// behind an interface of plain arrays so that it can be compiled twice, as the supernodal kernels
// are (src/graph/supernodal_kernels.hpp says why and how): for any x86-64 (SSE2) and with AVX2 +
// FMA, chosen when the program runs. The product runs about 2.5x faster with AVX2 + FMA (Victoria
// Park's 871-dimensional state, 14 factor columns: 0.82 -> 0.36 ms a call). FMA rounds each
// product-sum once instead of twice, so the two copies differ by rounding (docs/victoria_park.md
// shows the run's result is unchanged).
namespace probslam::ekf_detail {

/// p (n x n, column-major, leading dimension ldp, symmetric) -= w w^T for w (n x c, column-major,
/// leading dimension ldw): the lower triangle computed, the upper mirrored from it (symmetric to
/// the bit).
using SubtractGram = void (*)(double* p, long n, long ldp, const double* w, long ldw, long c);

namespace kernels_generic {
void subtract_gram(double* p, long n, long ldp, const double* w, long ldw, long c);
}  // namespace kernels_generic

#ifdef PROBSLAM_AVX2_KERNELS
namespace kernels_avx2 {
void subtract_gram(double* p, long n, long ldp, const double* w, long ldw, long c);
}  // namespace kernels_avx2
#endif

/// The copy for this CPU: AVX2 + FMA when it has both, unless PROBSLAM_EKF_KERNELS=generic.
SubtractGram subtract_gram_kernel();

}  // namespace probslam::ekf_detail
