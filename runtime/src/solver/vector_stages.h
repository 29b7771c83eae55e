// Element-wise vector stages and terms (step/executor.h) that the step's Newton loop and its
// iterative solvers share: each item reads and writes only entry i.
#pragma once

#include <cstdint>

#include "kernels/gf_hd.h"

namespace gf::detail {

/// out[i] = a[i] + alpha b[i] (out may be a or b).
struct AxpyStage {
  const double* a = nullptr;
  const double* b = nullptr;
  double alpha = 1;
  double* out = nullptr;

  GF_HD void operator()(int32_t i) const { out[i] = a[i] + alpha * b[i]; }
};

/// out[i] = a[i].
struct CopyStage {
  const double* a = nullptr;
  double* out = nullptr;

  GF_HD void operator()(int32_t i) const { out[i] = a[i]; }
};

/// x[i] *= s.
struct ScaleStage {
  double s = 1;
  double* x = nullptr;

  GF_HD void operator()(int32_t i) const { x[i] *= s; }
};

/// out[i] = value.
struct FillStage {
  double value = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t i) const { out[i] = value; }
};

/// 1 where v[i] is not finite, else 0: reduced with MaxOp, whether a vector holds any.
struct NonFiniteTerm {
  const double* v = nullptr;

  GF_HD double operator()(int32_t i) const { return isFinite(v[i]) ? 0.0 : 1.0; }
};

}  // namespace gf::detail
