// Edge-frame stresses of a tetrahedron (thesis sec 4.2.3, SPEC §2).
//
// Design. The six edges of a tet, in local order 01, 02, 03, 12, 13, 23, carry unit REST
// directions N_k. The edge matrix T maps a symmetric tensor s (tensor Voigt [xx yy zz xy xz yz],
// shear NOT doubled) to its six edge normal components (T s)_k = N_k^T s N_k (eq 4.8-4.9, with
// the factor 2 on the shear columns that eq 4.9 omits). T is built from rest directions, so it
// and T^-1 are constant per element and precomputed once; the stress or strain fed to it is the
// material-frame one (rotation invariant), which makes the edge values rotation invariant too.
//
// T is invertible for every non-degenerate tet: if N_k^T s N_k = 0 for all six edges, then with
// edge vectors e1, e2, e3 from corner 0 the quadratic form q(v) = v^T s v vanishes on e1, e2, e3
// and on e_j - e_i, so the bilinear form b(e_i, e_j) = (q(e_i) + q(e_j) - q(e_j - e_i)) / 2 = 0
// on a basis of R^3, hence s = 0. Slivers make T ill-conditioned, which the pivot bound in
// invertEdgeMatrix reports as singular.
#pragma once

#include <cstdint>

#include "materials.h"
#include "math.h"
#include "svd3.h"

namespace gf {

/// Corner `end` (0 or 1) of local edge k in the tet's edge order 01, 02, 03, 12, 13, 23 (the
/// order of detail::kTetEdgeNodes in mesh/edge_graph.h). A function, not a namespace-scope
/// array, so device code can index it without relaxed-constexpr flags.
GF_HD int tetEdgeCorner(int k, int end) {
  const int first[6] = {0, 0, 0, 1, 1, 2};
  const int second[6] = {1, 2, 3, 2, 3, 3};
  return end == 0 ? first[k] : second[k];
}

/// Smallest pivot magnitude accepted by invertEdgeMatrix. Entries of T are bounded by 1 (unit
/// directions), so this bounds the condition number at roughly 1e12.
constexpr double kEdgeMatrixPivotMin = 1e-12;

/// Symmetric 3x3 tensor to tensor Voigt [xx yy zz xy xz yz] (off-diagonals averaged).
template <class T>
GF_HD void toVoigt(const Mat3T<T>& s, T v[6]) {
  v[0] = s(0, 0);
  v[1] = s(1, 1);
  v[2] = s(2, 2);
  v[3] = 0.5 * (s(0, 1) + s(1, 0));
  v[4] = 0.5 * (s(0, 2) + s(2, 0));
  v[5] = 0.5 * (s(1, 2) + s(2, 1));
}

/// Tensor Voigt [xx yy zz xy xz yz] to the symmetric 3x3 tensor.
GF_HD Mat3 fromVoigt(const double v[6]) {
  Mat3 s;
  s(0, 0) = v[0];
  s(1, 1) = v[1];
  s(2, 2) = v[2];
  s(0, 1) = s(1, 0) = v[3];
  s(0, 2) = s(2, 0) = v[4];
  s(1, 2) = s(2, 1) = v[5];
  return s;
}

/// Unit rest directions N (corner a to corner b of each local edge) and rest lengths L of the
/// six edges of the rest tet X. A zero-length edge gets N = 0 (then T is singular).
GF_HD void restEdgeDirections(const Vec3 X[4], Vec3 N[6], double L[6]) {
  for (int k = 0; k < 6; ++k) {
    const Vec3 d = X[tetEdgeCorner(k, 1)] - X[tetEdgeCorner(k, 0)];
    L[k] = norm(d);
    N[k] = L[k] > 0 ? (1.0 / L[k]) * d : Vec3{0, 0, 0};
  }
}

/// Edge matrix T (eq 4.9 with tensor Voigt): row k is [Nx^2 Ny^2 Nz^2 2NxNy 2NxNz 2NyNz], so
/// (T s)_k = N_k^T s N_k for a symmetric s in tensor Voigt.
GF_HD Mat<6, 6> edgeMatrix(const Vec3 N[6]) {
  Mat<6, 6> t;
  for (int k = 0; k < 6; ++k) {
    const Vec3 n = N[k];
    t(k, 0) = n.x * n.x;
    t(k, 1) = n.y * n.y;
    t(k, 2) = n.z * n.z;
    t(k, 3) = 2.0 * n.x * n.y;
    t(k, 4) = 2.0 * n.x * n.z;
    t(k, 5) = 2.0 * n.y * n.z;
  }
  return t;
}

/// T^-1 by Gauss-Jordan elimination with partial pivoting. Returns false (Tinv unspecified)
/// when a pivot falls below kEdgeMatrixPivotMin: a degenerate or sliver tet.
GF_HD bool invertEdgeMatrix(const Mat<6, 6>& T, Mat<6, 6>& Tinv) {
  Mat<6, 6> a = T;
  Tinv = Mat<6, 6>::identity();
  for (int col = 0; col < 6; ++col) {
    int piv = col;
    for (int r = col + 1; r < 6; ++r)
      if (fabs(a(r, col)) > fabs(a(piv, col))) piv = r;
    if (!(fabs(a(piv, col)) >= kEdgeMatrixPivotMin)) return false;  // also catches NaN
    if (piv != col) {
      for (int j = 0; j < 6; ++j) {
        double t = a(col, j);
        a(col, j) = a(piv, j);
        a(piv, j) = t;
        t = Tinv(col, j);
        Tinv(col, j) = Tinv(piv, j);
        Tinv(piv, j) = t;
      }
    }
    const double inv = 1.0 / a(col, col);
    for (int j = 0; j < 6; ++j) {
      a(col, j) *= inv;
      Tinv(col, j) *= inv;
    }
    for (int r = 0; r < 6; ++r) {
      if (r == col) continue;
      const double f = a(r, col);
      if (f == 0) continue;
      for (int j = 0; j < 6; ++j) {
        a(r, j) -= f * a(col, j);
        Tinv(r, j) -= f * Tinv(col, j);
      }
    }
  }
  return true;
}

/// y = M v for a 6x6 matrix and 6-vectors (Voigt or edge values).
GF_HD void apply6(const Mat<6, 6>& M, const double v[6], double y[6]) {
  for (int i = 0; i < 6; ++i) {
    double s = 0;
    for (int j = 0; j < 6; ++j) s += M(i, j) * v[j];
    y[i] = s;
  }
}

/// Material-frame stress that drives fracture: the symmetric part of R^T P (the Biot stress,
/// work-conjugate to the right stretch U of F = R U), with R = U_svd V_svd^T from the
/// rotation-variant SVD and P the full first Piola stress including the fibre term. It is
/// rotation invariant, zero for a pure rotation, and equals the linear-elastic stress
/// 2 mu eps + lambda tr(eps) I (eq 4.28) at small strain. For an isotropic model it is
/// V diag(dpsi/ds) V^T. svd must be svd3(F) (e.g. from an SVD cache, svd3.h).
GF_HD Mat3 materialStress(const MaterialCoeffs& c, const Mat3& F, const Svd3& svd) {
  Mat3 P;
  detail::isotropicEvaluate(c, svd, P, nullptr, false);
  if (c.fibreMu > 0) detail::addFibre(c, F, svd, P, nullptr, false);
  const Mat3 R = svd.U * transpose(svd.V);
  const Mat3 rp = transpose(R) * P;
  Mat3 s;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) s(i, j) = 0.5 * (rp(i, j) + rp(j, i));
  return s;
}

/// materialStress with the SVD of F computed here.
GF_HD Mat3 materialStress(const MaterialCoeffs& c, const Mat3& F) {
  return materialStress(c, F, svd3(F));
}

/// Normal stress N_k^T S N_k along each rest edge direction (eq 4.6-4.8); positive = tension.
GF_HD void edgeNormalStresses(const Mat3& S, const Vec3 N[6], double out[6]) {
  for (int k = 0; k < 6; ++k) out[k] = dot(N[k], S * N[k]);
}

}  // namespace gf
