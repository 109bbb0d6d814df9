// The supernodal kernels compiled with -mavx2 -mfma (CMakeLists.txt), used only when the CPU
// has both (supernodal_numeric.cpp). Eigen is renamed in this file so that none of its
// functions compiled here is shared with the rest of the program (supernodal_kernels.hpp).
#define Eigen probslam_eigen_avx2
#define PROBSLAM_KERNEL_NAMESPACE kernels_avx2
#include "supernodal_kernels.inc"
