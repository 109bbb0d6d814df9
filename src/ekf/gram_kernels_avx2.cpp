// EkfSlam's P -= W W^T compiled with -mavx2 -mfma (CMakeLists.txt), used only when the CPU has
// both (gram_kernels.hpp). Eigen is renamed in this file, as in the supernodal kernels' AVX2 copy,
// so that none of its functions compiled here is shared with the SSE2 code.
#define Eigen probslam_eigen_avx2
#define PROBSLAM_KERNEL_NAMESPACE kernels_avx2
#include "gram_kernels.inc"
