// The element pass on a SIMD batch of tets (fem/element_lanes.h): xsimd's batch of doubles as
// a kernel scalar type (kernels/lanes.h) and the lanes' gather, SVD cache and scatter. Included
// by the translation units that instantiate it for one instruction set each
// (element_lanes.cpp: the build's flags; element_lanes_avx2.cpp: AVX2, chosen at run time).
// Nothing here may call a scalar inline kernel: a translation unit built with other flags would
// emit its own copy of that function, and the linker could keep that copy for the whole program.
#pragma once

#include <xsimd/xsimd.hpp>

#include "fem/element_stage.h"

namespace gf {

/// symmetricEigen<3>, out of line (element_lanes.cpp).
void symmetricEigen3(const Mat3& a, double values[3], Mat3& vectors);

template <class A>
struct Lanes<xsimd::batch<double, A>> {
  using B = xsimd::batch<double, A>;
  using Mask = xsimd::batch_bool<double, A>;
  static constexpr int kWidth = int(B::size);
  static bool any(const Mask& m) { return xsimd::any(m); }
  static bool all(const Mask& m) { return xsimd::all(m); }
  static B select(const Mask& m, const B& a, const B& b) { return xsimd::select(m, a, b); }
  static double lane(const B& v, int l) { return v.get(size_t(l)); }
  static bool lane(const Mask& m, int l) { return m.get(size_t(l)); }
  static void setLane(B& v, int l, double x) {
    alignas(64) double t[kWidth];
    v.store_aligned(t);
    t[l] = x;
    v = B::load_aligned(t);
  }
  /// symmetricEigen<3> of one lane, out of line (element_lanes.cpp, see the file comment).
  static void eigen3(const Mat3& a, double values[3], Mat3& vectors) {
    symmetricEigen3(a, values, vectors);
  }
};

namespace detail {

/// ElementStage::operator() for the undamaged, non-rigid tets tets[0..lanes) of a body
/// without a fibre term; tets[lanes..width) repeat a tet and write nothing.
template <class A>
struct LanePass {
  using B = xsimd::batch<double, A>;
  static constexpr int kW = Lanes<B>::kWidth;

  /// A batch of one value per tet of `tets`.
  template <class Get>
  static B gather(const int32_t* tets, Get get) {
    alignas(64) double v[kW];
    for (int l = 0; l < kW; ++l) v[l] = get(int64_t(tets[l]));
    return B::load_aligned(v);
  }

  /// svd3(F) of every lane through the tets' SVD cache entries (svd3.h's cachedSvd3, a lane at
  /// a time): an entry holding its lane's F to the bit gives the stored result; the batch svd3
  /// runs unless every lane hits, and a missed lane's entry takes its result.
  static Svd3T<B> cachedSvd3Lanes(const Mat3T<B>& F, double* cache, const int32_t* tets,
                                  int lanes) {
    if (cache == nullptr) return svd3(F);
    alignas(64) double f[9][kW];
    for (int k = 0; k < 9; ++k) F.m[k].store_aligned(f[k]);
    bool hit[kW];
    bool all = true;
    for (int l = 0; l < kW; ++l) {
      const double* entry = cache + kSvdCacheStride * int64_t(tets[l]);
      bool same = true;
      for (int k = 0; k < 9; ++k)
        same = same && entry[k] == f[k][l] && copysign(1.0, entry[k]) == copysign(1.0, f[k][l]);
      hit[l] = same;
      all = all && same;
    }
    // Rows 0..8 U, 9..11 s, 12..20 V, as the entry stores them from its index 9 on.
    alignas(64) double r[21][kW];
    if (!all) {
      const Svd3T<B> s = svd3(F);
      for (int k = 0; k < 9; ++k) {
        s.U.m[k].store_aligned(r[k]);
        s.V.m[k].store_aligned(r[12 + k]);
      }
      s.s.x.store_aligned(r[9]);
      s.s.y.store_aligned(r[10]);
      s.s.z.store_aligned(r[11]);
    }
    for (int l = 0; l < kW; ++l) {
      double* entry = cache + kSvdCacheStride * int64_t(tets[l]);
      if (hit[l]) {
        for (int k = 0; k < 21; ++k) r[k][l] = entry[9 + k];
      } else if (l < lanes) {  // a padding lane repeats a tet: only its own lane writes
        for (int k = 0; k < 9; ++k) entry[k] = f[k][l];
        for (int k = 0; k < 21; ++k) entry[9 + k] = r[k][l];
      }
    }
    Svd3T<B> s;
    for (int k = 0; k < 9; ++k) {
      s.U.m[k] = B::load_aligned(r[k]);
      s.V.m[k] = B::load_aligned(r[12 + k]);
    }
    s.s = {B::load_aligned(r[9]), B::load_aligned(r[10]), B::load_aligned(r[11])};
    return s;
  }

  static void run(const ElementStage& st, const int32_t* tets, int lanes) {
    Vec3T<B> xe[4];
    for (int a = 0; a < 4; ++a)
      for (int i = 0; i < 3; ++i)
        xe[a][i] =
            gather(tets, [&](int64_t t) { return st.x[3 * int64_t(st.tets[4 * t + a]) + i]; });
    Mat3T<B> dmInv;
    for (int k = 0; k < 9; ++k)
      dmInv.m[k] = gather(tets, [&](int64_t t) { return st.restInverse[t].m[k]; });
    const B volume = gather(tets, [&](int64_t t) { return st.restVolume[t]; });
    MaterialCoeffsT<B> c;
    c.model = st.coeffs.model;
    c.mu =
        st.tetLame ? gather(tets, [&](int64_t t) { return st.tetLame[2 * t]; }) : B(st.coeffs.mu);
    c.lambda = st.tetLame ? gather(tets, [&](int64_t t) { return st.tetLame[2 * t + 1]; })
                          : B(st.coeffs.lambda);

    const Mat3T<B> F = deformationGradient(xe, dmInv);
    const Svd3T<B> svd = cachedSvd3Lanes(F, st.svdCache, tets, lanes);
    alignas(64) double out[kW];
    if (st.grad == nullptr && st.stress == nullptr) {
      (volume * energyDensitySvd(c, F, svd)).store_aligned(out);
      for (int l = 0; l < lanes; ++l) st.energy[tets[l]] = out[l];
      return;
    }
    B grad[12];
    Mat<12, 12, B> hess;
    Mat3T<B> stress;
    const B energy = elementForcesSvd(c, F, svd, dmInv, volume, grad, st.hess ? &hess : nullptr,
                                      /*projectPsd=*/true, st.stress ? &stress : nullptr);
    energy.store_aligned(out);
    for (int l = 0; l < lanes; ++l) st.energy[tets[l]] = out[l];
    if (st.grad) {
      alignas(64) double g[12][kW];
      for (int k = 0; k < 12; ++k) grad[k].store_aligned(g[k]);
      for (int l = 0; l < lanes; ++l)
        for (int k = 0; k < 12; ++k) st.grad[12 * int64_t(tets[l]) + k] = g[k][l];
    }
    if (st.hess) {
      // The upper node blocks only (kElementMatrixSize, kernels/math.h).
      alignas(64) double h[kElementMatrixSize][kW];
      int k = 0;
      for (int a = 0; a < 4; ++a)
        for (int b = a; b < 4; ++b)
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) hess(3 * a + i, 3 * b + j).store_aligned(h[k++]);
      for (int l = 0; l < lanes; ++l) {
        double* dst = st.hess + kElementMatrixSize * int64_t(tets[l]);
        for (k = 0; k < kElementMatrixSize; ++k) dst[k] = h[k][l];
      }
    }
    if (st.stress) {
      B voigt[6];
      toVoigt(stress, voigt);
      alignas(64) double s[6][kW];
      for (int k = 0; k < 6; ++k) voigt[k].store_aligned(s[k]);
      for (int l = 0; l < lanes; ++l)
        for (int k = 0; k < 6; ++k) st.stress[6 * int64_t(tets[l]) + k] = s[k][l];
    }
  }
};

}  // namespace detail
}  // namespace gf
