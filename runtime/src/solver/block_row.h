// The 3x3 block-row product, the inner loop of the level-0 smoother and residual and of CG's
// A p (multigrid_stages.h, sparse_stages.h): one formula for every executor, and on the CPU a
// build of it for AVX2 + FMA chosen at run time (block_row_avx2.cpp). The matrix may be double or
// float (the level-0 Gauss-Seidel copy, GsValue in multigrid_stages.h); x and the sums are double.
#pragma once

#include <cstdint>

#include "kernels/gf_hd.h"

namespace gf::detail {

/// out = sum over k in [begin, end) of block k (9 row-major entries of `values`, T double or
/// float) times node col[k] of x, in double. out must not alias x.
template <class T>
GF_HD void blockRowProduct3Scalar(const int32_t* col, const T* values, int32_t begin, int32_t end,
                                  const double* x, double* out) {
  double s0 = 0, s1 = 0, s2 = 0;
  for (int32_t k = begin; k < end; ++k) {
    const T* m = values + 9 * int64_t(k);
    const double* xc = x + 3 * int64_t(col[k]);
    s0 += double(m[0]) * xc[0] + double(m[1]) * xc[1] + double(m[2]) * xc[2];
    s1 += double(m[3]) * xc[0] + double(m[4]) * xc[1] + double(m[5]) * xc[2];
    s2 += double(m[6]) * xc[0] + double(m[7]) * xc[1] + double(m[8]) * xc[2];
  }
  out[0] = s0;
  out[1] = s1;
  out[2] = s2;
}

#if !defined(__CUDACC__)
/// blockRowProduct3Scalar's contract, in AVX2 + FMA where the CPU has both (then rounded
/// differently: fused products, sums per column) and as the scalar formula elsewhere.
void blockRowProduct3Host(const int32_t* col, const double* values, int32_t begin, int32_t end,
                          const double* x, double* out);
void blockRowProduct3Host(const int32_t* col, const float* values, int32_t begin, int32_t end,
                          const double* x, double* out);
#endif

/// blockRowProduct3Scalar's contract; the host's own build on the CPU.
template <class T>
GF_HD void blockRowProduct3(const int32_t* col, const T* values, int32_t begin, int32_t end,
                            const double* x, double* out) {
#if defined(__CUDACC__)
  blockRowProduct3Scalar(col, values, begin, end, x, out);
#else
  blockRowProduct3Host(col, values, begin, end, x, out);
#endif
}

}  // namespace gf::detail
