// Energy of a damaged tetrahedron: the two models of SPEC §2 (thesis sec 4.2.4-4.2.5).
//
// Design. An element is damaged when one of its six edges (local order of edge_stress.h) is
// broken. Its energy then comes from one of two models:
//
// Projection (eq 4.25-4.27), built on the Green strain E = (F^T F - I)/2 instead of the
// thesis' linear strain, so it depends on F only through F^T F and is exactly rotation
// invariant. With e = Voigt(E) (tensor shear) the edge strains are d = T e, and
// d_k = N_k^T E N_k = ((l_k/L_k)^2 - 1)/2 (appendix E). Eq 4.25 keeps the edge strains of the
// unbroken edges and changes those of the broken ones: e_frac = T^-1 (d - w) with w nonzero
// only on broken edges. w is the crack opening: b_k = T^-1 u_k (u_k the k-th unit vector) is
// the strain that lengthens edge k alone, and w_k >= 0 says a crack only opens. The energy
//   psi = min_{w >= 0} 1/2 e_f^T M e_f,  e_f = e - sum_{k broken} w_k b_k
// is the StVK form (eq 4.31) in the Lamé parameters (eq 4.29): M = 2 mu W + lambda m m^T,
// W = diag(1,1,1,2,2,2) (the shear entries count twice in E:E), m = [1 1 1 0 0 0], plus
// mu_f t t^T for a fibre along a (t the T-row of a: mu_f/2 (a^T E a)^2, the small-strain form
// of eq 4.36). tau_k = b_k^T M e_f is the force the broken edge carries (V tau_k / L_k is its
// axial force when the tet's stress is resolved into its six edges as a truss), and the
// minimum is the unilateral contact of the crack faces: an open crack (w_k > 0) carries no
// force, a closed one (w_k = 0) only compression (tau_k <= 0). So a broken edge loses its
// tensile part and a closed crack still resists being pushed together (SPEC §2).
//   Why not w_k = max(d_k, 0) (mask the tensile edge strain, the previous version): at d_k = 0
// the other strains still load edge k (Poisson coupling), so that energy had a ridge there,
// its gradient jumping by tau_k b_k, and it could exceed the intact energy (at nu = 0.4999 the
// removed strain changed tr E, which lambda = 5000 mu weighs). An implicit step across such a
// ridge gains energy. The minimum has neither defect: w = 0 is admissible, so psi never
// exceeds the intact StVK energy; it is a partial minimum of a convex quadratic, so convex and
// C1 in e (w is continuous in e); it equals the edge-strain mask wherever that mask releases
// everything (all broken edge strains tensile and the rest of the strain carried by them,
// e.g. a corner cut off and pulled away); and nothing broken is exactly StVK.
//   The QP has at most six unknowns. For each subset S of the broken edges the stationary
// point of the face is G_SS w_S = g_S, G = T^-T M T^-1, g = T^-T M e; the minimum is the
// admissible one (w_S >= 0) that lowers the energy most, by 1/2 w_S . g_S (the true minimum
// is stationary on its own support, and every admissible point is at least the minimum).
// Within a region of fixed S (B_S the columns b_k, k in S):
//   sigma_v = dpsi/de = M e_f (envelope theorem),  S = Voigt^-1(sigma_v) with halved shear,
//   P = F S,  dP/dF = J^T Hv J + I (x) S,  Hv = M - M B_S G_SS^-1 B_S^T M,
// J = de/dvec(F), J(ab, kl) = (d_al F_kb + F_ka d_bl)/2, (I (x) S)(3k+l, 3m+n) = d_km S_ln.
// Hv is PSD (M^1/2 times an orthogonal projector times M^1/2), so only the I (x) S term
// (compression) can make dP/dF indefinite; projectPsd makes it PSD by the absolute values of
// its eigenvalues (projectPSD<9>, absolute), not by clamping them to zero. A cracked tet held
// in compression can release its energy by a small motion along such a concave direction;
// clamped, the direction has no curvature at all, and the Newton step along it is bounded only
// by the node's mass: at 60 Hz a torn steel bar's corner nodes were sent metres (and thrown at
// up to 3.4e4 J) where a few millimetres released the energy. The absolute value keeps the
// concavity's size as the step's scale (Chen et al. 2024, "Stabler Neo-Hookean Simulation:
// Absolute Eigenvalue Filtering for Projected Newton"; docs/validation.md). The Hessian is
// exact away from the region boundaries, where only it (not P) jumps.
//   A split tet (its broken edges part the corners into two sides, one side S) also has the
// branch of a crack that slides: S may move against the other side by a jump g across the
// plane of unit normal n ~ grad sum_{c in S} N_c (the plane parallel to both sides), which is
// the strain Voigt(sym(g (x) n)) (a relative translation of S, exactly, in the Green strain),
// with g.n >= 0. Its minimum is open (g.n > 0: no traction on the plane) or closed (g in the
// plane: only the normal traction n.sigma.n), and psi is the least of this branch over every
// such partition and the per-edge branch above. Per edge alone, touching faces were locked in
// shear: sliding shortens half of the edges across the plane, so a torn piece hung in the air
// (docs/validation.md). The per-edge branch is still needed: it alone frees a side that has
// turned (a tumbling piece), whose strain is no translation. The crack faces carry no friction.
// A min of two convex branches is continuous with a concave kink where they cross, which an
// energy-decreasing step passes.
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

/// Crack openings below this fraction of the largest Green strain component are round-off
/// of a closed crack (see detail::crackOpening).
constexpr double kCrackOpeningRoundOff = 1e-8;

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

/// Cholesky factor L (lower triangle, row stride 6) of the n x n SPD matrix in a, in place.
/// False when a pivot is not positive relative to its diagonal: a singular face of the
/// crack-opening problem (a degenerate edge frame), which the caller skips.
GF_HD bool choleskyFactor6(double a[36], int n) {
  for (int j = 0; j < n; ++j) {
    double d = a[6 * j + j];
    const double diag = d;
    for (int k = 0; k < j; ++k) d -= a[6 * j + k] * a[6 * j + k];
    if (!(d > 1e-13 * diag)) return false;  // also catches NaN
    d = sqrt(d);
    a[6 * j + j] = d;
    for (int i = j + 1; i < n; ++i) {
      double s = a[6 * i + j];
      for (int k = 0; k < j; ++k) s -= a[6 * i + k] * a[6 * j + k];
      a[6 * i + j] = s / d;
    }
  }
  return true;
}

/// Solves L L^T x = b in place for the factor of choleskyFactor6.
GF_HD void choleskySolve6(const double l[36], int n, double b[6]) {
  for (int i = 0; i < n; ++i) {
    double s = b[i];
    for (int k = 0; k < i; ++k) s -= l[6 * i + k] * b[k];
    b[i] = s / l[6 * i + i];
  }
  for (int i = n - 1; i >= 0; --i) {
    double s = b[i];
    for (int k = i + 1; k < n; ++k) s -= l[6 * k + i] * b[k];
    b[i] = s / l[6 * i + i];
  }
}

/// Makes h exactly symmetric, as the PSD projection and the assembly expect.
GF_HD void symmetrize6(Mat<6, 6>& h) {
  for (int i = 0; i < 6; ++i)
    for (int j = i + 1; j < 6; ++j) {
      const double s = 0.5 * (h(i, j) + h(j, i));
      h(i, j) = s;
      h(j, i) = s;
    }
}

/// The crack opening of the broken edges at tensor-Voigt Green strain e (see the file
/// comment): e_f = e - sum_k w_k T^-1(:,k), the w >= 0 on broken edges that minimises
/// 1/2 e_f^T M e_f. Returns the number of open edges (0: e_f = e, exactly). When hv is non-null
/// it receives d2psi/de2 = M - M B_S G_SS^-1 B_S^T M of the open set S.
GF_HD int crackOpening(const Mat<6, 6>& M, const Mat<6, 6>& Tinv, const uint8_t broken[6],
                       const double e[6], double ef[6], Mat<6, 6>* hv) {
  for (int i = 0; i < 6; ++i) ef[i] = e[i];
  if (hv != nullptr) *hv = M;
  int brokenMask = 0;
  for (int k = 0; k < 6; ++k)
    if (broken[k] != 0) brokenMask |= 1 << k;
  if (brokenMask == 0) return 0;
  // mb(:,k) = M b_k; g_k = b_k . M e (the force edge k carries at w = 0);
  // G_kl = b_k . M b_l.
  double me[6];
  apply6(M, e, me);
  double mb[6][6] = {}, g[6] = {}, G[6][6] = {};
  for (int k = 0; k < 6; ++k) {
    if (!((brokenMask >> k) & 1)) continue;
    for (int i = 0; i < 6; ++i) {
      double s = 0;
      for (int j = 0; j < 6; ++j) s += M(i, j) * Tinv(j, k);
      mb[k][i] = s;
      g[k] += Tinv(i, k) * me[i];
    }
  }
  for (int k = 0; k < 6; ++k)
    for (int l = 0; l < 6; ++l) {
      if (!((brokenMask >> k) & 1) || !((brokenMask >> l) & 1)) continue;
      double s = 0;
      for (int i = 0; i < 6; ++i) s += Tinv(i, k) * mb[l][i];
      G[k][l] = s;
    }
  // Every face of the orthant w >= 0 spanned by a subset of the broken edges: the admissible
  // stationary point that lowers psi most. An opening within round-off of zero counts as
  // closed, so a crack exactly at the switch (w_k = tau_k = 0, which symmetric loads give)
  // takes the same face, and the same Hessian, whatever the order of the tet's corners.
  double eScale = 0;
  for (int i = 0; i < 6; ++i) eScale = fmax(eScale, fabs(e[i]));
  const double wMin = kCrackOpeningRoundOff * eScale;
  int bestSet = 0, bestN = 0, bestIdx[6] = {};
  double bestGain = 0, bestW[6] = {}, bestL[36] = {};
  for (int set = brokenMask; set > 0; set = (set - 1) & brokenMask) {
    int idx[6], n = 0;
    for (int k = 0; k < 6; ++k)
      if ((set >> k) & 1) idx[n++] = k;
    double l[36], w[6];
    for (int i = 0; i < n; ++i) {
      w[i] = g[idx[i]];
      for (int j = 0; j < n; ++j) l[6 * i + j] = G[idx[i]][idx[j]];
    }
    if (!choleskyFactor6(l, n)) continue;
    choleskySolve6(l, n, w);
    bool admissible = true;
    double gain = 0;
    for (int i = 0; i < n; ++i) {
      admissible = admissible && w[i] > wMin;
      gain += w[i] * g[idx[i]];
    }
    if (!admissible || !(gain > bestGain)) continue;
    bestSet = set;
    bestN = n;
    bestGain = gain;
    for (int i = 0; i < n; ++i) {
      bestIdx[i] = idx[i];
      bestW[i] = w[i];
    }
    for (int i = 0; i < 36; ++i) bestL[i] = l[i];
  }
  if (bestSet == 0) return 0;
  for (int a = 0; a < bestN; ++a)
    for (int i = 0; i < 6; ++i) ef[i] -= bestW[a] * Tinv(i, bestIdx[a]);
  if (hv != nullptr) {
    // Hv = M - (M B_S) G_SS^-1 (M B_S)^T, one column of (M B_S)^T at a time.
    for (int j = 0; j < 6; ++j) {
      double y[6];
      for (int a = 0; a < bestN; ++a) y[a] = mb[bestIdx[a]][j];
      choleskySolve6(bestL, bestN, y);
      for (int i = 0; i < 6; ++i) {
        double s = 0;
        for (int a = 0; a < bestN; ++a) s += mb[bestIdx[a]][i] * y[a];
        (*hv)(i, j) -= s;
      }
    }
    symmetrize6(*hv);
  }
  return bestN;
}

/// Projects e onto the complement of the span of the k <= 3 strain columns c in the M metric:
/// w = G^-1 C^T M e with G = C^T M C, ef = e - C w, and, when hv is non-null, d2psi/de2 =
/// M - M C G^-1 C^T M. False when G is singular (a degenerate normal).
GF_HD bool projectOutColumns(const Mat<6, 6>& M, const double c[3][6], int k, const double e[6],
                             double w[3], double ef[6], Mat<6, 6>* hv) {
  double me[6], mc[3][6], l[36] = {};
  apply6(M, e, me);
  for (int a = 0; a < k; ++a) {
    apply6(M, c[a], mc[a]);
    w[a] = 0;
    for (int i = 0; i < 6; ++i) w[a] += c[a][i] * me[i];
    for (int b = 0; b < k; ++b) {
      double s = 0;
      for (int i = 0; i < 6; ++i) s += c[b][i] * mc[a][i];
      l[6 * a + b] = s;
    }
  }
  if (!choleskyFactor6(l, k)) return false;
  choleskySolve6(l, k, w);
  for (int i = 0; i < 6; ++i) {
    ef[i] = e[i];
    for (int a = 0; a < k; ++a) ef[i] -= w[a] * c[a][i];
  }
  if (hv == nullptr) return true;
  *hv = M;
  for (int j = 0; j < 6; ++j) {
    double y[3];
    for (int a = 0; a < k; ++a) y[a] = mc[a][j];
    choleskySolve6(l, k, y);
    for (int i = 0; i < 6; ++i)
      for (int a = 0; a < k; ++a) (*hv)(i, j) -= mc[a][i] * y[a];
  }
  symmetrize6(*hv);
  return true;
}

/// Tensor Voigt of sym(g (x) n).
GF_HD void symOuterVoigt(const Vec3& g, const Vec3& n, double v[6]) {
  v[0] = g.x * n.x;
  v[1] = g.y * n.y;
  v[2] = g.z * n.z;
  v[3] = 0.5 * (g.x * n.y + g.y * n.x);
  v[4] = 0.5 * (g.x * n.z + g.z * n.x);
  v[5] = 0.5 * (g.y * n.z + g.z * n.y);
}

/// The sliding branch of a split tet (see the file comment): the jump g across the crack plane
/// of unit normal n that minimises 1/2 e_f^T M e_f, e_f = e - Voigt(sym(g (x) n)), g.n >= 0.
/// Returns psi; fills ef and, when hv is non-null, d2psi/de2. A negative return: G singular.
GF_HD double crackSlide(const Mat<6, 6>& M, const Vec3& n, const double e[6], double ef[6],
                        Mat<6, 6>* hv) {
  double c[3][6], w[3];
  const Vec3 axes[3] = {Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
  for (int a = 0; a < 3; ++a) symOuterVoigt(axes[a], n, c[a]);
  double eScale = 0;
  for (int i = 0; i < 6; ++i) eScale = fmax(eScale, fabs(e[i]));
  if (!projectOutColumns(M, c, 3, e, w, ef, hv)) return -1;
  // Open (the jump points away from the other side): the crack plane carries no traction.
  // Otherwise closed: the jump stays in the plane and only the normal traction is carried.
  if (!(w[0] * n.x + w[1] * n.y + w[2] * n.z > kCrackOpeningRoundOff * eScale)) {
    const Vec3 a = fabs(n.x) < 0.6 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    Vec3 t1 = cross(n, a);
    t1 = (1.0 / norm(t1)) * t1;
    symOuterVoigt(t1, n, c[0]);
    symOuterVoigt(cross(n, t1), n, c[1]);
    if (!projectOutColumns(M, c, 2, e, w, ef, hv)) return -1;
  }
  double sv[6];
  apply6(M, ef, sv);
  double psi = 0;
  for (int i = 0; i < 6; ++i) psi += 0.5 * ef[i] * sv[i];
  return psi;
}

}  // namespace detail

/// Projection-model energy density psi (returned), P = dpsi/dF and, when dPdF is non-null,
/// dP/dF (9x9, vec index 3*i+j), for the Voigt stiffness M (see the file comment). With
/// closedHessian, dPdF takes every crack as closed (Hv = M): a majorant, not the Hessian. T is not
/// needed by the minimum (only T^-1, whose columns are the opening strains); it stays in the
/// signature so every caller passes the same edge frame. dPdF is the exact Hessian within the
/// current set of open cracks; with projectPsd its negative eigenvalues are replaced by their
/// absolute values (see the file comment).
GF_HD double projectionEvaluate(const Mat<6, 6>& M, const Mat<6, 6>& Tinv, const Mat<6, 6>& T,
                                const uint8_t broken[6], const Mat3& F, Mat3& P, Mat9* dPdF,
                                bool projectPsd, bool closedHessian = false,
                                const Vec3* cornerGradients = nullptr) {
  (void)T;
  double e[6];
  detail::greenStrainVoigt(F, e);
  double ef[6];
  Mat<6, 6> hv;
  Mat<6, 6>* hvOut = dPdF != nullptr && !closedHessian ? &hv : nullptr;
  detail::crackOpening(M, Tinv, broken, e, ef, hvOut);
  if (cornerGradients != nullptr) {
    // Every way to part the corners along broken edges only: side S (corner 0 on the other)
    // slides on the plane normal to grad of its barycentric sum. The lowest branch wins.
    double efe[6];
    apply6(M, ef, efe);
    double best = 0;
    for (int i = 0; i < 6; ++i) best += 0.5 * ef[i] * efe[i];
    for (int side = 1; side < 16; side += 2) {
      // side: bit c set when corner c is on corner 0's side; bit 0 always set.
      bool parted = true;
      for (int k = 0; k < 6; ++k) {
        const int a = tetEdgeCorner(k, 0), b = tetEdgeCorner(k, 1);
        if (((side >> a) & 1) != ((side >> b) & 1) && broken[k] == 0) parted = false;
      }
      if (!parted || side == 15) continue;
      Vec3 n{0, 0, 0};
      for (int c = 1; c < 4; ++c)
        if (!((side >> c) & 1)) n = n + cornerGradients[c];
      n = (1.0 / norm(n)) * n;
      double efs[6];
      Mat<6, 6> hvs;
      const double psi = detail::crackSlide(M, n, e, efs, hvOut != nullptr ? &hvs : nullptr);
      // A tie goes to the slide: at rest both branches are 0, and only the slide's Hessian lets
      // the first Newton step move a side along the plane.
      if (!(psi >= 0) || !(psi <= best)) continue;
      best = psi;
      for (int i = 0; i < 6; ++i) ef[i] = efs[i];
      if (hvOut != nullptr) hv = hvs;
    }
  }
  // The closed-crack Hessian M bounds the curvature of psi in e from above (psi(e + d) <=
  // psi(e) + sigma_v . d + 1/2 d^T M d with the openings held), so a step built on it cannot
  // overshoot a crack that closes within it (Integrator::solve's retry).
  if (closedHessian) hv = M;
  // eq 4.25 on the Green strain: psi = 1/2 e_f^T M e_f.
  double sv[6];
  apply6(M, ef, sv);
  double psi = 0;
  for (int i = 0; i < 6; ++i) psi += 0.5 * ef[i] * sv[i];
  // sigma_v = M e_f (envelope theorem: w is optimal); S halves the shear entries because each
  // appears twice in S:dE.
  const double sHalf[6] = {sv[0], sv[1], sv[2], 0.5 * sv[3], 0.5 * sv[4], 0.5 * sv[5]};
  const Mat3 S = fromVoigt(sHalf);
  P = F * S;
  if (dPdF == nullptr) return psi;

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
  if (projectPsd) projectPSD<9>(H, /*absolute=*/true);
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
/// set of open cracks, made PSD by absolute eigenvalues when projectPsd.
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
/// closedHessian (projection only): the Hessian with every crack closed (projectionEvaluate).
GF_HD double damagedElementForces(int damageModel, const MaterialCoeffs& c, const Mat<6, 6>& T,
                                  const Mat<6, 6>& Tinv, double chi, const uint8_t broken[6],
                                  const Vec3 x[4], const Mat3& DmInv, double volume,
                                  double grad[12], Mat12* hessian, bool projectPsd,
                                  bool closedHessian = false) {
  const Mat<4, 3> B = shapeGradients(DmInv);
  Mat3 P;
  Mat9 dPdF;
  Mat9* h = hessian != nullptr ? &dPdF : nullptr;
  double psi = 0;
  if (damageModel == kDamageProjection) {
    const Mat3 F = deformationGradient(x, DmInv);
    Vec3 grads[4];
    for (int a = 0; a < 4; ++a) grads[a] = Vec3{B(a, 0), B(a, 1), B(a, 2)};
    psi = projectionEvaluate(projectionStiffness(c), Tinv, T, broken, F, P, h, projectPsd,
                             closedHessian, grads);
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
