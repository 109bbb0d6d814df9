// EkfSlam's P -= W W^T for any x86-64 (and other targets), and the choice of copy
// (gram_kernels.hpp).
#include <cstdlib>
#include <cstring>

#define PROBSLAM_KERNEL_NAMESPACE kernels_generic
#include "gram_kernels.inc"

namespace probslam::ekf_detail {

SubtractGram subtract_gram_kernel() {
#ifdef PROBSLAM_AVX2_KERNELS
  static const bool avx2 = [] {
    const char* forced = std::getenv("PROBSLAM_EKF_KERNELS");
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
           !(forced && std::strcmp(forced, "generic") == 0);
  }();
  if (avx2) return kernels_avx2::subtract_gram;
#endif
  return kernels_generic::subtract_gram;
}

}  // namespace probslam::ekf_detail
