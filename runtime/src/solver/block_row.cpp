// The host's choice of the 3x3 block-row product (block_row.h).
#include "solver/block_row.h"

namespace gf::detail {

#if GF_HAVE_BLOCK_ROW_AVX2
/// block_row_avx2.cpp, built with AVX2 and FMA.
void blockRowProduct3Avx2(const int32_t* col, const double* values, int32_t begin, int32_t end,
                          const double* x, double* out);
void blockRowProduct3Avx2(const int32_t* col, const float* values, int32_t begin, int32_t end,
                          const double* x, double* out);

namespace {
// Zero (the scalar formula) for a call made before dynamic initialisation.
const bool kAvx2Fma = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
}  // namespace
#endif

void blockRowProduct3Host(const int32_t* col, const double* values, int32_t begin, int32_t end,
                          const double* x, double* out) {
#if GF_HAVE_BLOCK_ROW_AVX2
  if (kAvx2Fma) return blockRowProduct3Avx2(col, values, begin, end, x, out);
#endif
  blockRowProduct3Scalar(col, values, begin, end, x, out);
}

void blockRowProduct3Host(const int32_t* col, const float* values, int32_t begin, int32_t end,
                          const double* x, double* out) {
#if GF_HAVE_BLOCK_ROW_AVX2
  if (kAvx2Fma) return blockRowProduct3Avx2(col, values, begin, end, x, out);
#endif
  blockRowProduct3Scalar(col, values, begin, end, x, out);
}

}  // namespace gf::detail
