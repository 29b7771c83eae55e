// Linear tetrahedron: rest-shape precompute, deformation gradient, and the element energy,
// gradient and Hessian (SPEC §1).
//
// Nodes 0..3; Ds = [x1-x0, x2-x0, x3-x0] (columns) and F = Ds Dm^-1 is constant over the
// element. Position vectors of 12 entries are node-major: index 3*a + i is coordinate i of
// node a. F is linear in x: dF(i,j)/dx(a,l) = delta_il B(a,j) with B the rest-space gradients
// of the shape functions (rows 1..3 of B are the rows of Dm^-1, row 0 is minus their sum).
// The element Hessian V D^T dPdF D therefore splits into 3x3 blocks (i,l) of dPdF, each
// mapped by B: H(3a+i, 3b+l) = V sum_jm B(a,j) dPdF(3i+j, 3l+m) B(b,m), never forming D
// (the damaged-element kernels). The undamaged kernel, the hot loop of a step, never forms
// dPdF either: the material gives it as at most 13 rank-1 terms (materials.h, HessianModes),
// each of which maps to one 12-vector (hessianFromModes).
#pragma once

#include "materials.h"
#include "math.h"

namespace gf {

/// Dm^-1 of a rest tetrahedron and its signed volume det(Dm)/6 (the caller rejects
/// volume <= 0). Returns the zero matrix for a degenerate element instead of dividing by 0.
GF_HD Mat3 restShapeInverse(const Vec3 X[4], double& volume) {
  const Mat3 dm = fromColumns(X[1] - X[0], X[2] - X[0], X[3] - X[0]);
  const double d = det(dm);
  volume = d / 6.0;
  if (d == 0) return Mat3{};
  return inverse(dm);
}

/// F = Ds Dm^-1.
template <class T>
GF_HD Mat3T<T> deformationGradient(const Vec3T<T> x[4], const Mat3T<T>& DmInv) {
  return fromColumns(x[1] - x[0], x[2] - x[0], x[3] - x[0]) * DmInv;
}

/// Largest principal value of the Lagrangian finite strain E = (F^T F - I) / 2 (thesis sec
/// 2.1.1.1, E_FS): the stretch measure of the strain colour map (figs 4.2, 5.14).
GF_HD double maxPrincipalStrain(const Mat3& F) {
  Mat3 E = transpose(F) * F;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) E(i, j) = 0.5 * (E(i, j) - (i == j ? 1.0 : 0.0));
  double values[3];
  Mat3 vectors;
  symmetricEigen(E, values, vectors);
  const double m = values[0] > values[1] ? values[0] : values[1];
  return m > values[2] ? m : values[2];
}

/// Rest-space gradients of the four linear shape functions, B(a, j) = dN_a/dX_j.
template <class T>
GF_HD Mat<4, 3, T> shapeGradients(const Mat3T<T>& DmInv) {
  Mat<4, 3, T> b;
  for (int j = 0; j < 3; ++j) {
    b(1, j) = DmInv(0, j);
    b(2, j) = DmInv(1, j);
    b(3, j) = DmInv(2, j);
    b(0, j) = -(DmInv(0, j) + DmInv(1, j) + DmInv(2, j));
  }
  return b;
}

namespace detail {

/// grad = V D^T vec(P): grad(3a + i) = V sum_j P(i,j) B(a,j).
template <class T>
GF_HD void elementGradient(const Mat<4, 3, T>& B, T volume, const Mat3T<T>& P, T grad[12]) {
  for (int a = 0; a < 4; ++a)
    for (int i = 0; i < 3; ++i)
      grad[3 * a + i] = volume * (P(i, 0) * B(a, 0) + P(i, 1) * B(a, 1) + P(i, 2) * B(a, 2));
}

/// grad = V D^T vec(P) and, when hessian is non-null, V D^T dPdF D for an element with shape
/// gradients B (see the file comment). Shared by elementForces and the damaged-element kernels
/// so all of them map P and dP/dF to nodes the same way. The upper triangle is summed and
/// mirrored: the element buffers keep the upper node blocks only, and the diagonal blocks whole
/// (kElementMatrixSize), so the Hessian must be exactly symmetric, not to round-off.
GF_HD void scatterElementDerivatives(const Mat<4, 3>& B, double volume, const Mat3& P,
                                     const Mat9& dPdF, double grad[12], Mat12* hessian) {
  if (hessian != nullptr) {
    Mat12& h = *hessian;
    for (int i = 0; i < 3; ++i)
      for (int l = 0; l < 3; ++l) {
        // K = dPdF block (i, l); T = B K (4x3); H block (i, l) = V T B^T (4x4).
        Mat<4, 3> t;
        for (int a = 0; a < 4; ++a)
          for (int m = 0; m < 3; ++m)
            t(a, m) = B(a, 0) * dPdF(3 * i + 0, 3 * l + m) + B(a, 1) * dPdF(3 * i + 1, 3 * l + m) +
                      B(a, 2) * dPdF(3 * i + 2, 3 * l + m);
        for (int a = 0; a < 4; ++a)
          for (int b = 0; b < 4; ++b)
            if (3 * a + i <= 3 * b + l)
              h(3 * a + i, 3 * b + l) =
                  volume * (t(a, 0) * B(b, 0) + t(a, 1) * B(b, 1) + t(a, 2) * B(b, 2));
      }
    for (int r = 1; r < 12; ++r)
      for (int c = 0; c < r; ++c) h(r, c) = h(c, r);
  }
  elementGradient(B, volume, P, grad);
}

/// hessian = V D^T dPdF D for dPdF given as rank-1 terms w_m vec(Q_m) vec(Q_m)^T: each term
/// maps to the 12-vector g_m = D^T vec(Q_m), g_m(3a + i) = (Q_m B^T)(i, a), so the Hessian is
/// V sum_m w_m g_m g_m^T. Node 0's shape gradient is minus the sum of the others', so g_m's
/// node-0 entries are minus the sum of its node 1..3 entries and H = E^T K E with K the 9x9
/// block of nodes 1..3 and E = [-I -I -I; I 0 0; 0 I 0; 0 0 I]: the modes are summed into
/// K's upper triangle only (15 2x2 tiles of a 10x10 padding, 60 entries a mode against 84
/// for the 12x12 upper triangle) and node 0's rows follow by sums. Every entry below the
/// diagonal is a copy of its mirror, so the Hessian is exactly symmetric.
template <class T>
GF_HD void hessianFromModes(const Mat3T<T>& DmInv, T volume, const HessianModesT<T>& modes,
                            Mat<12, 12, T>& h) {
  constexpr int kPad = 10;  // 9 rows of K padded to whole 2x2 tiles
  T g[kMaxHessianModes][kPad];
  T wg[kMaxHessianModes][kPad];
  for (int m = 0; m < modes.count; ++m) {
    const T* q = modes.q[m];
    const T vw = volume * modes.w[m];
    // Row a of Dm^-1 is the shape gradient of node a + 1.
    for (int a = 0; a < 3; ++a)
      for (int i = 0; i < 3; ++i) {
        const T v =
            q[3 * i] * DmInv(a, 0) + q[3 * i + 1] * DmInv(a, 1) + q[3 * i + 2] * DmInv(a, 2);
        g[m][3 * a + i] = v;
        wg[m][3 * a + i] = vw * v;
      }
    g[m][9] = 0;
    wg[m][9] = 0;
  }
  T k[kPad][kPad];  // K, upper triangle (and the diagonal tiles' lower entry)
  for (int i = 0; i < kPad; i += 2)
    for (int j = i; j < kPad; j += 2) {
      T a00 = 0, a01 = 0, a10 = 0, a11 = 0;
      for (int m = 0; m < modes.count; ++m) {
        const T w0 = wg[m][i], w1 = wg[m][i + 1], g0 = g[m][j], g1 = g[m][j + 1];
        a00 += w0 * g0;
        a01 += w0 * g1;
        a10 += w1 * g0;
        a11 += w1 * g1;
      }
      if (i == j) a10 = a01;  // the same entry of the diagonal tile, summed twice
      k[i][j] = a00;
      k[i][j + 1] = a01;
      k[i + 1][j] = a10;
      k[i + 1][j + 1] = a11;
    }
  for (int r = 0; r < 9; ++r)
    for (int c = 0; c < r; ++c) k[r][c] = k[c][r];
  // Rows 0..2 of H, columns 3..11: minus the sums of K's rows i, 3 + i and 6 + i.
  for (int i = 0; i < 3; ++i)
    for (int c = 0; c < 9; ++c) h(i, 3 + c) = -(k[i][c] + k[3 + i][c] + k[6 + i][c]);
  // The node-0 block: minus the sums of the three blocks of row i just formed, upper triangle.
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) {
      const T v = -(h(i, 3 + j) + h(i, 6 + j) + h(i, 9 + j));
      h(i, j) = v;
      h(j, i) = v;
    }
  for (int r = 0; r < 9; ++r) {
    for (int i = 0; i < 3; ++i) h(3 + r, i) = h(i, 3 + r);
    for (int c = 0; c < 9; ++c) h(3 + r, 3 + c) = k[r][c];
  }
}

}  // namespace detail

/// elementForces from F and svd = svd3(F) (one tet, or a batch of tets without a fibre term
/// a lane each: fem/element_lanes.cpp).
template <class T>
GF_HD T elementForcesSvd(const MaterialCoeffsT<T>& c, const Mat3T<T>& F, const Svd3T<T>& svd,
                         const Mat3T<T>& DmInv, T volume, T grad[12],
                         Mat<12, 12, NoDeduce<T>>* hessian, bool projectPsd,
                         Mat<3, 3, NoDeduce<T>>* materialStress) {
  Mat3T<T> P;
  HessianModesT<T> modes;
  const T psi =
      evaluateMaterialModes(c, F, svd, P, hessian != nullptr ? &modes : nullptr, projectPsd);
  if (materialStress != nullptr) {
    const Mat3T<T> rp = transpose(svd.U * transpose(svd.V)) * P;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) (*materialStress)(i, j) = 0.5 * (rp(i, j) + rp(j, i));
  }
  if (hessian != nullptr) detail::hessianFromModes(DmInv, volume, modes, *hessian);
  detail::elementGradient(shapeGradients(DmInv), volume, P, grad);
  return volume * psi;
}

/// Element elastic energy V psi(F). Fills grad = dE/dx (12, node-major; the internal force is
/// -grad) and, when hessian is non-null, d2E/dx2 = V D^T dPdF D with D = dvec(F)/dx,
/// projected to PSD when projectPsd.
/// When materialStress is non-null it also receives the material-frame (Biot) stress
/// sym(R^T P) that drives fracture, from the same SVD. svdCache: the tet's SVD cache entry
/// (svd3.h), or null; the results have the same bits either way.
GF_HD double elementForces(const MaterialCoeffs& c, const Vec3 x[4], const Mat3& DmInv,
                           double volume, double grad[12], Mat12* hessian, bool projectPsd,
                           Mat3* materialStress = nullptr, double* svdCache = nullptr) {
  const Mat3 F = deformationGradient(x, DmInv);
  return elementForcesSvd(c, F, cachedSvd3(F, svdCache), DmInv, volume, grad, hessian, projectPsd,
                          materialStress);
}

/// Element elastic energy V psi(F) alone, for passes that need no forces (line-search trials,
/// the final energy): no stress, no shape gradients, no scatter. The same bits as
/// elementForces' return value. svdCache as there.
GF_HD double elementEnergy(const MaterialCoeffs& c, const Vec3 x[4], const Mat3& DmInv,
                           double volume, double* svdCache = nullptr) {
  const Mat3 F = deformationGradient(x, DmInv);
  return volume * energyDensitySvd(c, F, cachedSvd3(F, svdCache));
}

}  // namespace gf
