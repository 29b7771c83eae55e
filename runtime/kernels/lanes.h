// The lane operations the kernels are written in, so that one source runs on a double (the
// GPU, and on the CPU damaged, rigid and fibre tets) and on a SIMD batch of tets (the CPU's
// element pass: fem/element_lanes_batch.h specialises Lanes for its batch type). A branch
// whose side may differ between tets becomes a select of both sides; a side all lanes skip is
// not computed (Lanes::any), so a double does the work its branch did and gets the same bits.
#pragma once

#include "gf_hd.h"

namespace gf {

template <class T>
struct Lanes;

template <>
struct Lanes<double> {
  using Mask = bool;
  static constexpr int kWidth = 1;
  GF_HD static bool any(bool m) { return m; }
  GF_HD static bool all(bool m) { return m; }
  GF_HD static double select(bool m, double a, double b) { return m ? a : b; }
  GF_HD static double lane(double v, int) { return v; }
  GF_HD static bool lane(bool m, int) { return m; }
  GF_HD static void setLane(double& v, int, double x) { v = x; }
};

template <class T>
using MaskOf = typename Lanes<T>::Mask;

}  // namespace gf
