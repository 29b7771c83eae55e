// The element pass's lanes built with AVX2 and FMA (runtime/CMakeLists.txt adds the flags to
// this file alone); element_lanes.cpp calls it only on a CPU that has both.
#if GF_HAVE_XSIMD_AVX2

#include "fem/element_lanes_batch.h"

namespace gf::detail {

void runLanesAvx2(const ElementStage& st, const int32_t* tets, int lanes) {
  LanePass<xsimd::avx2>::run(st, tets, lanes);
}

}  // namespace gf::detail

#endif
