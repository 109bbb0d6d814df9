// The supernodal kernels for any x86-64 (and other targets): supernodal_kernels.hpp.
#define PROBSLAM_KERNEL_NAMESPACE kernels_generic
#include "supernodal_kernels.inc"
