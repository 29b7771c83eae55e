#include "fem/element_lanes.h"

#if GF_HAVE_XSIMD

#include "fem/element_lanes_batch.h"

namespace gf {

void symmetricEigen3(const Mat3& a, double values[3], Mat3& vectors) {
  symmetricEigen<3>(a, values, vectors);
}

namespace detail {

#if GF_HAVE_XSIMD_AVX2
/// LanePass<xsimd::avx2>::run, built with AVX2 and FMA (element_lanes_avx2.cpp).
void runLanesAvx2(const ElementStage& st, const int32_t* tets, int lanes);
#endif

namespace {

/// The build's own batch (SSE2, 2 doubles, on a plain x86-64 build), or AVX2's 4 where the
/// CPU has AVX2 and FMA and the library holds that translation unit.
struct Dispatch {
  int width = LanePass<xsimd::default_arch>::kW;
  void (*run)(const ElementStage&, const int32_t*, int) = &LanePass<xsimd::default_arch>::run;
  Dispatch() {
#if GF_HAVE_XSIMD_AVX2
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
      width = 4;  // doubles in an AVX2 register
      run = &runLanesAvx2;
    }
#endif
  }
};

const Dispatch& dispatch() {
  static const Dispatch d;
  return d;
}

}  // namespace

void evaluateElementRange(const ElementStage& st, int32_t begin, int32_t end) {
  if (st.coeffs.fibreMu > 0) {
    for (int32_t t = begin; t < end; ++t) st(t);
    return;
  }
  const Dispatch& d = dispatch();
  int32_t group[8];
  int n = 0;
  for (int32_t t = begin; t < end; ++t) {
    if ((st.rigidTet && st.rigidTet[t]) || (st.tetMask && st.tetMask[t])) {
      st(t);
      continue;
    }
    group[n++] = t;
    if (n == d.width) {
      d.run(st, group, n);
      n = 0;
    }
  }
  // The last few tets go through the lanes too (padded with a repeat), so every undamaged
  // tet's bits are the lanes' whatever the range.
  if (n > 0) {
    for (int l = n; l < d.width; ++l) group[l] = group[n - 1];
    d.run(st, group, n);
  }
}

int elementLaneWidth() { return dispatch().width; }

}  // namespace detail
}  // namespace gf

#else

namespace gf::detail {

void evaluateElementRange(const ElementStage& stage, int32_t begin, int32_t end) {
  for (int32_t t = begin; t < end; ++t) stage(t);
}

int elementLaneWidth() { return 1; }

}  // namespace gf::detail

#endif
