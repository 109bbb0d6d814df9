#pragma once
// Private to src/graph: the dense work of the supernodal Cholesky factorisation
// (supernodal_numeric.hpp), behind an interface of plain arrays so that it can be compiled twice:
// for any x86-64 (SSE2) and with AVX2 + FMA, chosen when the program runs. Eigen's kernels run at
// about 10 GFlop/s with SSE2 here and 2-3x that with AVX2 + FMA (sphere2500's factorisation
// 31 ms -> 17 ms, torus3D's 124 ms -> 42 ms); builds for distribution cannot assume AVX2.
//
// The AVX2 copy compiles Eigen under another namespace name (supernodal_kernels_avx2.cpp), so no
// Eigen function compiled with AVX2 can stand in for the SSE2 one elsewhere in the program (the
// linker keeps one copy of each inline function, whichever object it comes from); it uses no
// std:: template the rest of the library instantiates, for the same reason. What remains: the
// small std:: helpers Eigen calls (std::min, std::max), inlined at -O1 and above; an -O0 build
// might emit them out of line with AVX encodings and have the linker pick those, which matters
// only on a CPU without AVX2 running a debug build.
namespace probslam::graph_detail {

/// CHOLMOD's supernodal analysis and the lower triangle of P A P^T, as arrays.
struct SupernodalPlanView {
  int n = 0, nsuper = 0;
  const int* perm = nullptr;   ///< row i of P A P^T is row perm[i] of A
  const int* super = nullptr;  ///< supernode k: columns super[k] .. super[k + 1] - 1
  const int* pi = nullptr;     ///< its rows: rows[pi[k]] .. rows[pi[k + 1] - 1], its own columns first
  const int* px = nullptr;     ///< its values: column-major rows x columns at lx + px[k]
  const int* rows = nullptr;
  const int* child_start = nullptr;  ///< children of k: child_list[child_start[k]] ..
  const int* child_list = nullptr;
  const int* a_start = nullptr;  ///< P A P^T column j's lower entries: rows a_row[a_start[j]] ..
  const int* a_row = nullptr;
  const int* a_value = nullptr;  ///< and the index of each value in A's value array
};

/// Factors into lx; returns the first column whose pivot is not positive, or -1.
using SupernodalFactorize = int (*)(const SupernodalPlanView& plan, const double* a_values, double* lx);
/// b (n x nrhs, column-major) <- A^-1 b.
using SupernodalSolve = void (*)(const SupernodalPlanView& plan, const double* lx, double* b, int nrhs);

namespace kernels_generic {
int factorize(const SupernodalPlanView& plan, const double* a_values, double* lx);
void solve(const SupernodalPlanView& plan, const double* lx, double* b, int nrhs);
}  // namespace kernels_generic

#ifdef PROBSLAM_AVX2_KERNELS
namespace kernels_avx2 {
int factorize(const SupernodalPlanView& plan, const double* a_values, double* lx);
void solve(const SupernodalPlanView& plan, const double* lx, double* b, int nrhs);
}  // namespace kernels_avx2
#endif

}  // namespace probslam::graph_detail
