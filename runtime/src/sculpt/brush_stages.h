// The sculpting brushes' per-step work as stages (step/executor.h): the drag of the deform
// brushes per node (eq 7.7), the pull's springs per pulled node and the impulse they gave,
// written once for both executors like fem/node_stage.h.
#pragma once

#include <cstdint>

#include "kernels/clay.h"
#include "kernels/gf_hd.h"
#include "kernels/math.h"

namespace gf::detail {

/// A deform brush as the drag stage reads it (DeformBrush).
struct DeformBrushData {
  Vec3 centre;
  double radius = 0, k1 = 0, k2 = 0;
};

/// Node n's drag w for one substep (FemState::drag): a free node's velocity is scaled by the
/// product g of the brushes' G_d (eq 7.7) over the whole step, 1 / (1 + w) per substep. Far
/// from the tool g underflows (exp(k2 r) overflows beyond k2 r = 709): a node held at
/// minKernel of its velocity is as still as a frozen one, and w stays finite. Nodes prescribed
/// by a grip keep their zero.
struct DeformDragStage {
  const double* x = nullptr;
  const uint8_t* fixed = nullptr;
  const DeformBrushData* brushes = nullptr;
  int32_t brushCount = 0;
  double perSubstep = 1, minKernel = 0;
  double* drag = nullptr;

  GF_HD void operator()(int32_t n) const {
    if (fixed[n]) return;
    double g = 1;
    for (int32_t b = 0; b < brushCount; ++b) {
      const DeformBrushData& br = brushes[b];
      const double dx = x[3 * int64_t(n)] - br.centre.x, dy = x[3 * int64_t(n) + 1] - br.centre.y,
                   dz = x[3 * int64_t(n) + 2] - br.centre.z;
      g *= clayDamping(sqrt(dx * dx + dy * dy + dz * dz), br.radius, br.k1, br.k2);  // eq 7.7
    }
    drag[n] = pow(g < minKernel ? minKernel : g, -perSubstep) - 1;
  }
};

/// Pulled node nodes[i]'s spring for a substep of h (FemState::tether): stiffness k per unit
/// mass is the energy 1/2 m k |x - t|^2, held by the incremental potential times h^2, toward
/// the stiffness-weighted mean of its targets. A node prescribed by a grip is not pulled.
struct PullTetherStage {
  const int32_t* nodes = nullptr;
  const uint8_t* fixed = nullptr;
  const double* stiffness = nullptr;  ///< summed k per node
  const double* targetSum = nullptr;  ///< 3 per node: summed k t
  double h = 0;
  double* tether = nullptr;
  double* target = nullptr;

  GF_HD void operator()(int32_t i) const {
    const int32_t n = nodes[i];
    if (fixed[n]) return;
    const double k = stiffness[n];
    tether[n] = k * h * h;
    for (int c = 0; c < 3; ++c) target[3 * int64_t(n) + c] = targetSum[3 * int64_t(n) + c] / k;
  }
};

/// Component c of the impulse backward Euler gave pulled node nodes[i] over h: h times the
/// spring force m w / h^2 (t - x), as a reduction's term.
struct PullImpulseTerm {
  const int32_t* nodes = nullptr;
  const double* nodeMass = nullptr;
  const double* tether = nullptr;
  const double* target = nullptr;
  const double* x = nullptr;
  double h = 1;
  int c = 0;

  GF_HD double operator()(int32_t i) const {
    const int64_t n = nodes[i];
    return nodeMass[n] * tether[n] / h * (target[3 * n + c] - x[3 * n + c]);
  }
};

}  // namespace gf::detail
