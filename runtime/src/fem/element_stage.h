// The per-element stages of a step, written once for both executors (runtime/src/step/executor.h
// on the CPU, gpu/launch.h on CUDA): plain structs of flat-buffer pointers whose GF_HD
// operator() handles one tet or one node. Layouts are those of FemModel, FemState and
// FractureBody, so a device mirror is a copy of the same buffers.
#pragma once

#include <cstdint>

#include "kernels/damage.h"
#include "kernels/edge_stress.h"
#include "kernels/element.h"
#include "kernels/plasticity.h"

namespace gf::detail {

/// The corners of tet t (tets: 4 node indices per tet; x: 3 coordinates per node).
GF_HD void tetCorners(const int32_t* tets, const double* x, int32_t t, Vec3 xe[4]) {
  for (int a = 0; a < 4; ++a) {
    const int64_t n = tets[4 * int64_t(t) + a];
    xe[a] = {x[3 * n], x[3 * n + 1], x[3 * n + 2]};
  }
}

/// The material coefficients of tet t: the body's, with the tet's own fibre direction when
/// the body has a fibre field (fibreDir non-null) and its own (mu, lambda) when the body holds
/// water (tetLame non-null, 2 per tet; FemState::tetLame).
GF_HD MaterialCoeffs tetCoeffs(const MaterialCoeffs& body, const Vec3* fibreDir, int32_t t,
                               const double* tetLame = nullptr) {
  MaterialCoeffs c = body;
  if (fibreDir) c.fibreDir = fibreDir[t];
  if (tetLame) {
    c.mu = tetLame[2 * int64_t(t)];
    c.lambda = tetLame[2 * int64_t(t) + 1];
  }
  return c;
}

/// Energy, gradient, PSD Hessian and criterion stress of every tet at x (SPEC §1; damaged
/// tets eq 4.25-4.27 or 4.32-4.33). Nullable inputs: fibreDir (no fibre field), tetMask (no
/// fracture), edgeMatrix/edgeMatrixInverse (no projection model: identity), rigidTet (no
/// detached fragment), tetLame (no water). Nullable outputs: grad (an energy-only pass: no
/// forces computed, then hess must be null too), hess, stress. svdCache (nullable, scratch of
/// the body's step state): undamaged tets take svd3(F) from it when F is the one it holds
/// (svd3.h), so a pass at a state an earlier pass saw does no SVD; same bits either way.
struct ElementStage {
  const int32_t* tets = nullptr;      ///< 4 per tet
  const double* x = nullptr;          ///< 3 per node
  const Mat3* restInverse = nullptr;  ///< per tet: Dm^-1, or Dm^-1 Fp^-1 when plastic (eq 2.3)
  const double* restVolume = nullptr;
  MaterialCoeffs coeffs;
  const Vec3* fibreDir = nullptr;
  const uint8_t* tetMask = nullptr;  ///< bit k: local edge k broken
  int damageModel = 0;
  const Mat<6, 6>* edgeMatrix = nullptr;
  const Mat<6, 6>* edgeMatrixInverse = nullptr;
  const double* chi = nullptr;
  const uint8_t* rigidTet = nullptr;
  const double* tetLame = nullptr;  ///< 2 per tet: (mu, lambda) of a wet body
  double* energy = nullptr;         ///< per tet
  double* grad = nullptr;           ///< 12 per tet
  double* hess = nullptr;           ///< kElementMatrixSize per tet: upper node blocks
  double* stress = nullptr;  ///< 6 per tet (Voigt), undamaged tets only: FractureBody does the rest
  double* svdCache = nullptr;  ///< kSvdCacheStride per tet (svd3.h), read and written
  /// Projection damage: Hessians with every crack closed, a majorant (damagedElementForces).
  bool closedCrackHessian = false;

  GF_HD void operator()(int32_t t) const {
    if (grad == nullptr && stress == nullptr) {
      energy[t] = evaluateEnergy(t);
      return;
    }
    double local[12];
    double* g = grad ? grad + 12 * int64_t(t) : local;
    Mat12 h;
    energy[t] = evaluate(t, g, hess ? &h : nullptr);
    if (hess) storeUpperBlocks(h.m, hess + kElementMatrixSize * int64_t(t));
  }

  /// Tet t's energy alone: the same bits as evaluate's return value.
  GF_HD double evaluateEnergy(int32_t t) const {
    if (rigidTet && rigidTet[t]) return 0;
    Vec3 xe[4];
    tetCorners(tets, x, t, xe);
    const MaterialCoeffs c = tetCoeffs(coeffs, fibreDir, t, tetLame);
    const uint8_t mask = tetMask ? tetMask[t] : 0;
    if (mask == 0)
      return elementEnergy(c, xe, restInverse[t], restVolume[t],
                           svdCache ? svdCache + kSvdCacheStride * int64_t(t) : nullptr);
    // Damaged tets are few: their forces are computed and dropped.
    double g[12];
    return evaluate(t, g, nullptr);
  }

  /// Tet t's energy, its gradient into g (12, node-major; -g are the element's nodal forces)
  /// and, when h is non-null, its Hessian; writes the stress buffer as operator() does.
  GF_HD double evaluate(int32_t t, double* g, Mat12* h) const {
    if (rigidTet && rigidTet[t]) {
      // A tet of a fragment handed to rigid physics moves rigidly: no strain, no force.
      for (int k = 0; k < 12; ++k) g[k] = 0;
      if (h) *h = Mat12{};
      if (stress)
        for (int k = 0; k < 6; ++k) stress[6 * int64_t(t) + k] = 0;
      return 0;
    }
    Vec3 xe[4];
    tetCorners(tets, x, t, xe);
    const MaterialCoeffs c = tetCoeffs(coeffs, fibreDir, t, tetLame);
    const uint8_t mask = tetMask ? tetMask[t] : 0;
    if (mask == 0) {
      Mat3 S;
      const double e = elementForces(c, xe, restInverse[t], restVolume[t], g, h,
                                     /*projectPsd=*/true, stress ? &S : nullptr,
                                     svdCache ? svdCache + kSvdCacheStride * int64_t(t) : nullptr);
      if (stress) toVoigt(S, stress + 6 * int64_t(t));
      return e;
    }
    uint8_t brokenLocal[6];
    for (int k = 0; k < 6; ++k) brokenLocal[k] = (mask >> k) & 1;
    const Mat<6, 6> identity = Mat<6, 6>::identity();
    return damagedElementForces(damageModel, c, edgeMatrix ? edgeMatrix[t] : identity,
                                edgeMatrixInverse ? edgeMatrixInverse[t] : identity, chi[t],
                                brokenLocal, xe, restInverse[t], restVolume[t], g, h,
                                /*projectPsd=*/true, closedCrackHessian);
  }
};

/// 1 when tet t can store elastic energy, else 0, as ElementStage::evaluate decides: a max-
/// reduction term. A tet moving with a fragment handed to rigid physics cannot, nor, in the
/// degradation model, one whose lagged chi is 0 (a crack split it: eq 4.33 and the rule after).
struct LiveTetTerm {
  const uint8_t* rigidTet = nullptr;  ///< null: none
  const uint8_t* tetMask = nullptr;   ///< null: no fracture
  const double* chi = nullptr;
  bool degradation = false;

  GF_HD double operator()(int32_t t) const {
    if (rigidTet && rigidTet[t]) return 0.0;
    return degradation && tetMask && tetMask[t] && chi[t] <= 0 ? 0.0 : 1.0;
  }
};

/// Node gradient of the elastic energy: the element gradients of each node's tets summed in
/// element order (nodeRef = tet * 4 + corner, CSR by node), so the result does not depend on
/// how nodes are split between threads.
struct GatherStage {
  const int32_t* nodeRefStart = nullptr;  ///< nodeCount + 1
  const int32_t* nodeRef = nullptr;
  const double* elemGrad = nullptr;  ///< 12 per tet
  double* nodeGrad = nullptr;        ///< 3 per node

  GF_HD void operator()(int32_t n) const {
    double g0 = 0, g1 = 0, g2 = 0;
    for (int32_t k = nodeRefStart[n]; k < nodeRefStart[n + 1]; ++k) {
      const int32_t ref = nodeRef[k];
      const double* eg = elemGrad + 12 * int64_t(ref / 4) + 3 * (ref % 4);
      g0 += eg[0];
      g1 += eg[1];
      g2 += eg[2];
    }
    nodeGrad[3 * int64_t(n)] = g0;
    nodeGrad[3 * int64_t(n) + 1] = g1;
    nodeGrad[3 * int64_t(n) + 2] = g2;
  }
};

/// Multiplicative plasticity after a step of h (eq 2.3-2.5): each tet's elastic stress at x
/// through its effective rest inverse; a yielding tet updates Fp, Fp^-1, its hardening
/// accumulator and the effective rest inverse Dm^-1 Fp^-1 the element pass reads.
struct PlasticityStage {
  const int32_t* tets = nullptr;
  const double* x = nullptr;
  const Mat3* restInverse = nullptr;  ///< Dm^-1
  MaterialCoeffs coeffs;
  const Vec3* fibreDir = nullptr;   ///< per tet, or null
  const double* tetLame = nullptr;  ///< 2 per tet, or null (see ElementStage)
  PlasticParams params;
  double h = 0;
  Mat3* Fp = nullptr;
  Mat3* FpInv = nullptr;
  double* delta = nullptr;
  Mat3* plasticInverse = nullptr;

  GF_HD void operator()(int32_t t) const {
    Vec3 xe[4];
    tetCorners(tets, x, t, xe);
    const MaterialCoeffs c = tetCoeffs(coeffs, fibreDir, t, tetLame);
    const Mat3 Fe = deformationGradient(xe, plasticInverse[t]);
    if (plasticUpdate(params, materialStress(c, Fe), Fe, h, Fp[t], FpInv[t], delta[t]))
      plasticInverse[t] = restInverse[t] * FpInv[t];
  }
};

}  // namespace gf::detail
