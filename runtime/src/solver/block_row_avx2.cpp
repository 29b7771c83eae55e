// The 3x3 block-row product in AVX2 + FMA (runtime/CMakeLists.txt adds the flags to this file
// alone); block_row.cpp calls it only on a CPU that has both. A block row of the matrix is one
// 4-wide fused multiply-add with x's node (its 4th lane masked to zero), so a block costs 3 FMAs,
// 4 loads and its column index instead of 9 multiplies, 9 adds and 12 scalar loads. A float
// matrix (the level-0 Gauss-Seidel copy) is widened to double as it loads, 4 entries at a time.
#if GF_HAVE_BLOCK_ROW_AVX2

#include <immintrin.h>

#include <cstdint>

namespace gf::detail {

namespace {

// 4 entries of a block from m, as doubles.
__m256d load4(const double* m) { return _mm256_loadu_pd(m); }
__m256d load4(const float* m) { return _mm256_cvtps_pd(_mm_loadu_ps(m)); }

// A block's last row, its 4th lane zero and never read: it may end the array.
__m256d loadLastRow(const double* m) {
  return _mm256_maskload_pd(m, _mm256_setr_epi64x(-1, -1, -1, 0));
}
__m256d loadLastRow(const float* m) {
  return _mm256_cvtps_pd(_mm_maskload_ps(m, _mm_setr_epi32(-1, -1, -1, 0)));
}

template <class T>
void product(const int32_t* col, const T* values, int32_t begin, int32_t end, const double* x,
             double* out) {
  // x's nodes and a block's last row are read 4 wide with the 4th lane masked: both may be the
  // last 3 entries of their array. The other rows' 4th lane is the next row's first entry.
  const __m256i three = _mm256_setr_epi64x(-1, -1, -1, 0);
  __m256d a0 = _mm256_setzero_pd(), a1 = a0, a2 = a0, b0 = a0, b1 = a0, b2 = a0;
  int32_t k = begin;
  // Two blocks per step into two sets of sums: the FMA's latency, not its throughput, bounds
  // one chain. Block k + 1 < end - 1 has a successor in the row, so its last row reads unmasked.
  for (; k + 2 < end; k += 2) {
    const T* m = values + 9 * int64_t(k);
    const __m256d xa = _mm256_maskload_pd(x + 3 * int64_t(col[k]), three);
    const __m256d xb = _mm256_maskload_pd(x + 3 * int64_t(col[k + 1]), three);
    a0 = _mm256_fmadd_pd(load4(m), xa, a0);
    a1 = _mm256_fmadd_pd(load4(m + 3), xa, a1);
    a2 = _mm256_fmadd_pd(load4(m + 6), xa, a2);
    b0 = _mm256_fmadd_pd(load4(m + 9), xb, b0);
    b1 = _mm256_fmadd_pd(load4(m + 12), xb, b1);
    b2 = _mm256_fmadd_pd(load4(m + 15), xb, b2);
  }
  for (; k < end; ++k) {
    const T* m = values + 9 * int64_t(k);
    const __m256d xa = _mm256_maskload_pd(x + 3 * int64_t(col[k]), three);
    a0 = _mm256_fmadd_pd(load4(m), xa, a0);
    a1 = _mm256_fmadd_pd(load4(m + 3), xa, a1);
    a2 = _mm256_fmadd_pd(loadLastRow(m + 6), xa, a2);
  }
  a0 = _mm256_add_pd(a0, b0);
  a1 = _mm256_add_pd(a1, b1);
  a2 = _mm256_add_pd(a2, b2);
  // out_i = (lane 0 + lane 1) + lane 2 of a_i; lane 3 holds other rows' entries times zero.
  const __m128d lo = _mm_hadd_pd(_mm256_castpd256_pd128(a0), _mm256_castpd256_pd128(a1));
  const __m128d hi = _mm_unpacklo_pd(_mm256_extractf128_pd(a0, 1), _mm256_extractf128_pd(a1, 1));
  _mm_storeu_pd(out, _mm_add_pd(lo, hi));
  const __m128d l2 = _mm256_castpd256_pd128(a2);
  out[2] = _mm_cvtsd_f64(
      _mm_add_sd(_mm_add_sd(l2, _mm_unpackhi_pd(l2, l2)), _mm256_extractf128_pd(a2, 1)));
}

}  // namespace

void blockRowProduct3Avx2(const int32_t* col, const double* values, int32_t begin, int32_t end,
                          const double* x, double* out) {
  product(col, values, begin, end, x, out);
}

void blockRowProduct3Avx2(const int32_t* col, const float* values, int32_t begin, int32_t end,
                          const double* x, double* out) {
  product(col, values, begin, end, x, out);
}

}  // namespace gf::detail

#endif
