// Energy of a damaged tetrahedron: the two models of SPEC §2 (thesis sec 4.2.4-4.2.5).
//
// Design. An element is damaged when one of its six edges (local order of edge_stress.h) is
// broken. Its energy then comes from one of two models:
//
// Projection (eq 4.25-4.27), built on the Green strain E = (F^T F - I)/2 instead of the
// thesis' linear strain, so it depends on F only through F^T F and is exactly rotation
// invariant. With e = Voigt(E) (tensor shear) the edge strains are e_d = T e, and
// (e_d)_k = N_k^T E N_k = ((l_k/L_k)^2 - 1)/2 (appendix E). A broken edge keeps only its
// compressive part, (e_d)_k <- min((e_d)_k, 0), so a closed crack still resists being pushed
// together while an open one carries nothing; back in Cartesian form E_frac = T^-1 e_d and
//   psi = 1/2 E_frac : C : E_frac = mu E_frac:E_frac + lambda/2 tr(E_frac)^2 (+ fibre),
// the StVK form (eq 4.31) in the Lamé parameters (eq 4.29), which is exactly StVK when no edge
// is broken. In Voigt this is psi = 1/2 e_f^T M e_f with M = 2 mu W + lambda m m^T,
// W = diag(1,1,1,2,2,2) (the shear entries count twice in E:E), m = [1 1 1 0 0 0]. An
// anisotropic material adds mu_f t t^T with t the T-row of the fibre direction a: that is
// mu_f/2 (a^T E a)^2, the small-strain form of the fibre energy (eq 4.36), so fibres also lose
// their tension across a broken edge.
//   Within a region where the signs of the broken edges' strains are fixed, the min() is
// linear, e_f = A e with A = I - sum_{k masked} Tinv(:,k) T(k,:), and
//   sigma_v = dpsi/de = A^T M A e,  S = Voigt^-1(sigma_v) with halved shear,  P = F S,
//   dP/dF = J^T (A^T M A) J + I (x) S,  J = de/dvec(F), J(ab, kl) = (d_al F_kb + F_ka d_bl)/2,
// where (I (x) S)(3k+l, 3m+n) = d_km S_ln. The Hessian is exact away from the kinks
// (e_d)_k = 0 of broken edges; projectPsd clamps it with projectPSD<9>. J^T A^T M A J is PSD
// for valid Lamé parameters, so only the I (x) S term (compression) can make it indefinite.
//   Known limit, inherited from StVK: the Green strain of an edge is bounded below by -1/2,
// so the closed-crack resistance weakens as an element is crushed towards zero volume.
//
// Degradation (eq 4.32-4.33): psi_frac = chi psi(F) with the element's own model, chi the ratio
// of summed absolute edge normal stresses after and before masking. chi is LAGGED: the caller
// computes it from the stresses at the start of the step and holds it constant during the
// step's Newton iterations, so the gradient and Hessian are chi times the undamaged ones (no
// dchi/dF term) and the Hessian stays exactly as consistent and as PSD as the undamaged one.
// chi = 0 when the element's corners fall into two or more groups not joined by an unbroken
// edge of this tet (the thesis' rule after eq 4.33): any chi > 0 would let the whole-element
// energy keep pulling the separated pieces together and the crack could never open.
#pragma once

#include <cstdint>

#include "edge_stress.h"
#include "eigen_sym.h"
#include "element.h"
#include "materials.h"
#include "math.h"

namespace gf {

/// Damaged-energy model of an element; same order as gf::DamageModel in graphfrac/defs.h.
enum DamageKernel : int { kDamageProjection = 0, kDamageDegradation = 1 };

/// Below this summed absolute edge stress [Pa] the ratio of eq 4.33 is 0/0 noise and
/// degradationFactor falls back to the fraction of unbroken edges.
constexpr double kDegradationStressMin = 1e-12;

/// Lamé parameters (eq 4.29) of the material coefficients: undoes the stable Neo-Hookean
/// reparametrisation mu' = 4/3 mu, lambda' = lambda + 5/6 mu (sec 4.2.5.1); the other models
/// already store them.
GF_HD void lameParameters(const MaterialCoeffs& c, double& mu, double& lambda) {
  if (c.model == kStableNeoHookean) {
    mu = 0.75 * c.mu;
    lambda = c.lambda - 5.0 / 6.0 * mu;
  } else {
    mu = c.mu;
    lambda = c.lambda;
  }
}

/// Voigt stiffness M of the projection model, psi = 1/2 e^T M e on tensor-Voigt Green strain:
/// 2 mu diag(1,1,1,2,2,2) + lambda m m^T, plus mu_f t t^T for a fibre along the unit a.
GF_HD Mat<6, 6> projectionStiffness(double mu, double lambda, double fibreMu = 0,
                                    Vec3 fibreDir = Vec3{1, 0, 0}) {
  Mat<6, 6> M;
  for (int i = 0; i < 3; ++i) {
    M(i, i) = 2.0 * mu;
    M(i + 3, i + 3) = 4.0 * mu;
    for (int j = 0; j < 3; ++j) M(i, j) += lambda;
  }
  if (fibreMu > 0) {
    const Vec3 a = fibreDir;
    const double t[6] = {a.x * a.x,       a.y * a.y,       a.z * a.z,
                         2.0 * a.x * a.y, 2.0 * a.x * a.z, 2.0 * a.y * a.z};
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j) M(i, j) += fibreMu * t[i] * t[j];
  }
  return M;
}

/// Projection stiffness of the material: Lamé parameters and, when present, the fibre term.
GF_HD Mat<6, 6> projectionStiffness(const MaterialCoeffs& c) {
  double mu, lambda;
  lameParameters(c, mu, lambda);
  return projectionStiffness(mu, lambda, c.fibreMu, c.fibreDir);
}

namespace detail {

/// Tensor Voigt of the Green strain E = (F^T F - I)/2.
GF_HD void greenStrainVoigt(const Mat3& F, double e[6]) {
  const Mat3 C = transpose(F) * F;
  e[0] = 0.5 * (C(0, 0) - 1.0);
  e[1] = 0.5 * (C(1, 1) - 1.0);
  e[2] = 0.5 * (C(2, 2) - 1.0);
  e[3] = 0.5 * C(0, 1);
  e[4] = 0.5 * C(0, 2);
  e[5] = 0.5 * C(1, 2);
}

/// The linear map A = I - sum_{k masked} Tinv(:,k) T(k,:) of the current sign region, where
/// edge k is masked when it is broken and in tension ((T e)_k > 0). Returns false (A = I)
/// when nothing is masked, so the undamaged case is exact, not I up to round-off.
GF_HD bool projectionOperator(const Mat<6, 6>& Tinv, const Mat<6, 6>& T, const uint8_t broken[6],
                              const double e[6], Mat<6, 6>& A) {
  A = Mat<6, 6>::identity();
  bool any = false;
  for (int k = 0; k < 6; ++k) {
    if (broken[k] == 0) continue;
    double ed = 0;
    for (int j = 0; j < 6; ++j) ed += T(k, j) * e[j];
    if (!(ed > 0)) continue;  // compressive: the closed crack keeps this edge
    any = true;
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j) A(i, j) -= Tinv(i, k) * T(k, j);
  }
  return any;
}

}  // namespace detail

/// Projection-model energy density psi (returned), P = dpsi/dF and, when dPdF is non-null,
/// dP/dF (9x9, vec index 3*i+j), for the Voigt stiffness M (see the file comment). dPdF is the
/// exact Hessian within the current sign region of the broken edges; with projectPsd it is
/// replaced by its nearest PSD matrix.
GF_HD double projectionEvaluate(const Mat<6, 6>& M, const Mat<6, 6>& Tinv, const Mat<6, 6>& T,
                                const uint8_t broken[6], const Mat3& F, Mat3& P, Mat9* dPdF,
                                bool projectPsd) {
  double e[6];
  detail::greenStrainVoigt(F, e);
  Mat<6, 6> A;
  const bool masked = detail::projectionOperator(Tinv, T, broken, e, A);
  double ef[6];
  if (masked) {
    apply6(A, e, ef);
  } else {
    for (int i = 0; i < 6; ++i) ef[i] = e[i];
  }
  // eq 4.25 on the Green strain: psi = 1/2 e_f^T M e_f.
  double mef[6];
  apply6(M, ef, mef);
  double psi = 0;
  for (int i = 0; i < 6; ++i) psi += 0.5 * ef[i] * mef[i];
  // sigma_v = A^T M e_f; S halves the shear entries because each appears twice in S:dE.
  double sv[6];
  for (int j = 0; j < 6; ++j) {
    double s = 0;
    for (int i = 0; i < 6; ++i) s += (masked ? A(i, j) : (i == j ? 1.0 : 0.0)) * mef[i];
    sv[j] = s;
  }
  const double sHalf[6] = {sv[0], sv[1], sv[2], 0.5 * sv[3], 0.5 * sv[4], 0.5 * sv[5]};
  const Mat3 S = fromVoigt(sHalf);
  P = F * S;
  if (dPdF == nullptr) return psi;

  // Hv = A^T M A.
  Mat<6, 6> hv = M;
  if (masked) hv = transpose(A) * (M * A);
  // J = de/dvec(F): row p = (a, b), column 3k + l: (d_al F_kb + F_ka d_bl) / 2.
  const int va[6] = {0, 1, 2, 0, 0, 1};
  const int vb[6] = {0, 1, 2, 1, 2, 2};
  Mat<6, 9> J;
  for (int p = 0; p < 6; ++p) {
    const int a = va[p], b = vb[p];
    for (int k = 0; k < 3; ++k) {
      J(p, 3 * k + a) += 0.5 * F(k, b);
      J(p, 3 * k + b) += 0.5 * F(k, a);
    }
  }
  Mat9& H = *dPdF;
  H = transpose(J) * (hv * J);
  // Geometric term I (x) S.
  for (int k = 0; k < 3; ++k)
    for (int l = 0; l < 3; ++l)
      for (int n = 0; n < 3; ++n) H(3 * k + l, 3 * k + n) += S(l, n);
  if (projectPsd) projectPSD<9>(H);
  return psi;
}

/// Projection-model energy density (eq 4.25 on the Green strain) with Lamé parameters mu,
/// lambda; exactly StVK (eq 4.31) when no edge is broken.
GF_HD double projectionEnergy(double mu, double lambda, const Mat<6, 6>& Tinv, const Mat<6, 6>& T,
                              const uint8_t broken[6], const Mat3& F) {
  Mat3 P;
  return projectionEvaluate(projectionStiffness(mu, lambda), Tinv, T, broken, F, P, nullptr, false);
}

/// P = dpsi/dF of projectionEnergy (eq 4.26 in F).
GF_HD Mat3 projectionPiola(double mu, double lambda, const Mat<6, 6>& Tinv, const Mat<6, 6>& T,
                           const uint8_t broken[6], const Mat3& F) {
  Mat3 P;
  projectionEvaluate(projectionStiffness(mu, lambda), Tinv, T, broken, F, P, nullptr, false);
  return P;
}

/// dP/dF of projectionEnergy (eq 4.27 in F; 9x9, vec index 3*i+j), exact within the current
/// sign region of the broken edges, PSD-projected when projectPsd.
GF_HD Mat9 projectionHessian(double mu, double lambda, const Mat<6, 6>& Tinv, const Mat<6, 6>& T,
                             const uint8_t broken[6], const Mat3& F, bool projectPsd) {
  Mat3 P;
  Mat9 H;
  projectionEvaluate(projectionStiffness(mu, lambda), Tinv, T, broken, F, P, &H, projectPsd);
  return H;
}

/// True when no corner of the tet is joined to another by an unbroken edge: all six edges are
/// broken.
GF_HD bool allCornersSeparated(const uint8_t broken[6]) {
  for (int k = 0; k < 6; ++k)
    if (broken[k] == 0) return false;
  return true;
}

/// True when the unbroken edges of the tet leave its corners in two or more disconnected
/// groups (the element is split into disjoint fragments).
GF_HD bool cornersDisconnected(const uint8_t broken[6]) {
  int group[4] = {0, 1, 2, 3};
  // Three relabelling passes over the six edges reach the fixed point of a 4-node graph.
  for (int pass = 0; pass < 3; ++pass)
    for (int k = 0; k < 6; ++k) {
      if (broken[k] != 0) continue;
      const int a = tetEdgeCorner(k, 0), b = tetEdgeCorner(k, 1);
      const int g = group[a] < group[b] ? group[a] : group[b];
      group[a] = g;
      group[b] = g;
    }
  return group[0] != 0 || group[1] != 0 || group[2] != 0 || group[3] != 0;
}

/// chi of eq 4.33: sum of |sigma_n| over unbroken edges / sum over all edges. 1 when nothing is
/// broken, 0 when the corners are disconnected (see the file comment); where the summed stress
/// is below kDegradationStressMin the ratio is undefined and the fraction of unbroken edges is
/// used instead. Always in [0, 1].
GF_HD double degradationFactor(const double sigmaN[6], const uint8_t broken[6]) {
  int unbroken = 0;
  double all = 0, kept = 0;
  for (int k = 0; k < 6; ++k) {
    const double a = fabs(sigmaN[k]);
    all += a;
    if (broken[k] == 0) {
      kept += a;
      ++unbroken;
    }
  }
  if (unbroken == 6) return 1.0;
  if (cornersDisconnected(broken)) return 0.0;
  if (!(all > kDegradationStressMin)) return unbroken / 6.0;  // also catches NaN
  return kept / all;
}

/// Energy V psi_frac of a damaged element, to be called in place of elementForces (same
/// outputs: grad = dE/dx, node-major, and the 12x12 Hessian when non-null). damageModel is a
/// DamageKernel. Projection uses T, Tinv and broken and ignores chi; degradation uses the lagged
/// chi (held constant during the step, so grad and Hessian are chi times the undamaged ones)
/// and ignores T, Tinv and broken. With plasticity pass the effective DmInv * FpInv.
GF_HD double damagedElementForces(int damageModel, const MaterialCoeffs& c, const Mat<6, 6>& T,
                                  const Mat<6, 6>& Tinv, double chi, const uint8_t broken[6],
                                  const Vec3 x[4], const Mat3& DmInv, double volume,
                                  double grad[12], Mat12* hessian, bool projectPsd) {
  const Mat<4, 3> B = shapeGradients(DmInv);
  Mat3 P;
  Mat9 dPdF;
  Mat9* h = hessian != nullptr ? &dPdF : nullptr;
  double psi = 0;
  if (damageModel == kDamageProjection) {
    const Mat3 F = deformationGradient(x, DmInv);
    psi = projectionEvaluate(projectionStiffness(c), Tinv, T, broken, F, P, h, projectPsd);
  } else if (chi > 0) {
    const Mat3 F = deformationGradient(x, DmInv);
    // eq 4.32 with chi lagged: every derivative scales by the same constant.
    psi = chi * evaluateMaterial(c, F, P, h, projectPsd);
    P = chi * P;
    if (h != nullptr) dPdF = chi * dPdF;
  }
  // chi <= 0 leaves psi, P and dPdF zero: the element carries nothing.
  detail::scatterElementDerivatives(B, volume, P, dPdF, grad, hessian);
  return volume * psi;
}

}  // namespace gf
