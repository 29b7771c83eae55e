// Rotation-variant SVD of a 3x3 deformation gradient: F = U diag(s) V^T with U and V proper
// rotations (det = +1). Where F is inverted the sign of det F goes to the singular value of
// smallest magnitude, so s0 >= s1 >= |s2| and sign(s2) = sign(det F) (Irving et al. 2004,
// Kim & Eberle "Dynamic Deformables" sec 5.3). Inversion-safe energies are written in these
// signed singular values.
//
// V comes from Jacobi rotations that diagonalise F^T F, applied one-sided (Hestenes): the
// rotations are computed from the columns of B = F V instead of from a formed F^T F, which
// gives the same V without squaring the condition number, so B's columns end up orthogonal
// to full relative precision even when two singular values are tiny. U then follows from B by
// Gram-Schmidt with fallbacks for zero columns (rank-deficient F).
#pragma once

#include "math.h"

namespace gf {

/// Result of svd3(): F = U diag(s) V^T, det U = det V = +1, s sorted s0 >= s1 >= |s2|.
template <class T>
struct Svd3T {
  Mat3T<T> U;
  Vec3T<T> s;
  Mat3T<T> V;
};
using Svd3 = Svd3T<double>;

namespace detail {

/// A unit vector orthogonal to the unit vector u: cross u with the axis it is least
/// aligned with, which keeps the cross product well away from zero.
template <class T>
GF_HD Vec3T<T> anyOrthogonal(Vec3T<T> u) {
  using L = Lanes<T>;
  const T ax = fabs(u.x), ay = fabs(u.y), az = fabs(u.z);
  const MaskOf<T> ex = ax <= ay && ax <= az;
  const MaskOf<T> ey = !ex && ay <= az;
  const Vec3T<T> e{L::select(ex, T(1), T(0)), L::select(ey, T(1), T(0)),
                   L::select(ex || ey, T(0), T(1))};
  const Vec3T<T> w = cross(u, e);
  return (1.0 / norm(w)) * w;
}

/// Swaps columns i and j of m in the lanes of `swap`.
template <class T>
GF_HD void swapColumns(Mat3T<T>& m, int i, int j, MaskOf<T> swap) {
  for (int r = 0; r < 3; ++r) {
    const T a = m(r, i), b = m(r, j);
    m(r, i) = Lanes<T>::select(swap, b, a);
    m(r, j) = Lanes<T>::select(swap, a, b);
  }
}

/// One Jacobi rotation of columns P < Q of B = F V (and of V) that makes them orthogonal;
/// false in the lanes where they already are. The column pair is a template argument so B and
/// V stay in registers through a sweep.
template <int P, int Q, class T>
GF_HD MaskOf<T> jacobiRotate(Mat3T<T>& B, Mat3T<T>& V) {
  using L = Lanes<T>;
  T alpha = 0, beta = 0, gamma = 0;  // (F^T F) entries pp, qq, pq in the basis V
  for (int r = 0; r < 3; ++r) {
    alpha += B(r, P) * B(r, P);
    beta += B(r, Q) * B(r, Q);
    gamma += B(r, P) * B(r, Q);
  }
  // Orthogonal to working precision relative to the columns' own lengths: |gamma| <= 1e-15
  // sqrt(alpha beta), squared, as a square root here cost a fifth of svd3.
  const MaskOf<T> rotate = !(gamma * gamma <= 1e-30 * (alpha * beta) || fabs(gamma) < 1e-300);
  if (!L::any(rotate)) return rotate;
  // The rotation's tangent is t = sign(zeta) / (|zeta| + sqrt(1 + zeta^2)), zeta = d / g2,
  // and c = 1 / sqrt(1 + t^2), s = c t. Multiplied through by |g2|, t = num / den with den
  // = |d| + hypot(d, g2), so c = den / w and s = num / w, w = hypot(den, num): two square
  // roots and one division on the sweep's critical path instead of two and three. The
  // squares are safe for column lengths far from over- and underflow; elsewhere the zeta form.
  const T d = beta - alpha, g2 = 2.0 * gamma;
  const T scale = alpha + beta;
  // Where g2^2 is below round-off of d^2 and t^2 below that of 1: the same c and s to the
  // last bit or so, without a square root (most rotations of a sweep near convergence).
  const MaskOf<T> tiny = fabs(g2) < 1e-8 * fabs(d);
  T c = 1.0;
  T s = gamma / d;
  const MaskOf<T> moderate = !tiny && scale > 1e-100 && scale < 1e100;
  if (L::any(moderate)) {
    const T den = fabs(d) + sqrt(d * d + g2 * g2);
    // sign(zeta) |g2|, zeta = +-0: +
    const T num = L::select(d == 0, fabs(g2), L::select(d > 0, g2, -g2));
    const T iw = 1.0 / sqrt(den * den + num * num);
    c = L::select(moderate, den * iw, c);
    s = L::select(moderate, num * iw, s);
  }
  const MaskOf<T> extreme = !tiny && !moderate;
  if (L::any(extreme)) {
    const T zeta = d / g2;
    const T t =
        L::select(fabs(zeta) > 1e150, 0.5 / zeta,
                  L::select(zeta >= 0, T(1.0), T(-1.0)) / (fabs(zeta) + sqrt(1.0 + zeta * zeta)));
    const T ce = 1.0 / sqrt(1.0 + t * t);
    c = L::select(extreme, ce, c);
    s = L::select(extreme, ce * t, s);
  }
  for (int r = 0; r < 3; ++r) {
    const T bp = B(r, P), bq = B(r, Q);
    B(r, P) = L::select(rotate, c * bp - s * bq, bp);
    B(r, Q) = L::select(rotate, s * bp + c * bq, bq);
    const T vp = V(r, P), vq = V(r, Q);
    V(r, P) = L::select(rotate, c * vp - s * vq, vp);
    V(r, Q) = L::select(rotate, s * vp + c * vq, vq);
  }
  return rotate;
}

}  // namespace detail

/// Rotation-variant SVD of F (see the file comment). Robust for rank-deficient, inverted and
/// repeated-singular-value F; reconstructs F to round-off. Each lane of a batch gets the SVD of
/// its own F: lanes that converged earlier skip the rotations the others still do.
template <class T>
GF_HD Svd3T<T> svd3(const Mat3T<T>& F) {
  using L = Lanes<T>;
  Mat3T<T> B = F;
  Mat3T<T> V = Mat3T<T>::identity();

  // One-sided Jacobi: rotate column pairs of B (and V) until all are mutually orthogonal.
  for (int sweep = 0; sweep < 30; ++sweep) {
    const MaskOf<T> r01 = detail::jacobiRotate<0, 1>(B, V);
    const MaskOf<T> r02 = detail::jacobiRotate<0, 2>(B, V);
    const MaskOf<T> r12 = detail::jacobiRotate<1, 2>(B, V);
    if (!L::any(r01 || r02 || r12)) break;
  }

  // Sort columns by length (the singular magnitudes), descending: a selection sort whose
  // first pass takes the first longest column to the front.
  T len[3];
  for (int j = 0; j < 3; ++j) len[j] = dot(column(B, j), column(B, j));
  const MaskOf<T> take1 = len[1] > len[0];
  const MaskOf<T> take2 = len[2] > L::select(take1, len[1], len[0]);
  const MaskOf<T> swap01 = take1 && !take2;
  for (int pass = 0; pass < 3; ++pass) {
    // (0, 1) where column 1 is first longest, (0, 2) where column 2 is, then (1, 2).
    const int i = pass == 2 ? 1 : 0, j = pass == 0 ? 1 : 2;
    const MaskOf<T> swap = pass == 0 ? swap01 : (pass == 1 ? take2 : len[2] > len[1]);
    if (!L::any(swap)) continue;
    const T li = len[i];
    len[i] = L::select(swap, len[j], li);
    len[j] = L::select(swap, li, len[j]);
    detail::swapColumns(B, i, j, swap);
    detail::swapColumns(V, i, j, swap);
  }
  // Proper rotation V; flipping v2 flips b2 = F v2 with it, so F = B V^T still holds.
  const MaskOf<T> flip = det(V) < 0;
  if (L::any(flip)) {
    for (int r = 0; r < 3; ++r) {
      V(r, 2) = L::select(flip, -V(r, 2), V(r, 2));
      B(r, 2) = L::select(flip, -B(r, 2), B(r, 2));
    }
  }

  const Vec3T<T> b0 = column(B, 0), b1 = column(B, 1), b2 = column(B, 2);
  const T n0 = norm(b0);
  const MaskOf<T> zero0 = !(n0 > 1e-300);  // F = 0: any rotation U works
  Vec3T<T> u0 = (1.0 / n0) * b0;
  if (L::any(zero0)) {
    u0.x = L::select(zero0, T(1), u0.x);
    u0.y = L::select(zero0, T(0), u0.y);
    u0.z = L::select(zero0, T(0), u0.z);
  }
  Vec3T<T> u1 = b1 - dot(u0, b1) * u0;
  const T n1 = norm(u1);
  const MaskOf<T> zero1 = !(n1 > 1e-300);  // rank <= 1
  u1 = (1.0 / n1) * u1;
  if (L::any(zero1)) {
    const Vec3T<T> o = detail::anyOrthogonal(u0);
    u1.x = L::select(zero1, o.x, u1.x);
    u1.y = L::select(zero1, o.y, u1.y);
    u1.z = L::select(zero1, o.z, u1.z);
  }
  const Vec3T<T> u2 = cross(u0, u1);  // proper U; the sign of det F lands on s2

  Svd3T<T> r;
  r.U = fromColumns(u0, u1, u2);
  r.V = V;
  r.s = Vec3T<T>{dot(u0, b0), dot(u1, b1), dot(u2, b2)};
  return r;
}

/// Doubles per entry of an SVD cache (one entry per tet, in the body's step state): the key F
/// (9, row-major) and svd3 of it (U 9, s 3, V 9).
constexpr int kSvdCacheStride = 30;

/// Makes `entry` (kSvdCacheStride doubles) a valid cache entry: the key F = 0 with its SVD.
/// Zero-filled memory is not one (its U and V are not rotations).
GF_HD void initSvdCacheEntry(double* entry) {
  const Svd3 r = svd3(Mat3{});
  for (int k = 0; k < 9; ++k) {
    entry[k] = 0;
    entry[9 + k] = r.U.m[k];
    entry[21 + k] = r.V.m[k];
  }
  entry[18] = r.s.x;
  entry[19] = r.s.y;
  entry[20] = r.s.z;
}

/// svd3(F) through a per-tet cache entry (kSvdCacheStride doubles; null: plain svd3): the
/// stored result when the stored key is F to the bit, else svd3(F), stored with F as the new
/// key. svd3 is a pure function of F's bits, so the result is bit-identical to svd3(F) either
/// way. The key test is value equality with equal signs, which is bit equality for every
/// double but NaN; a NaN never matches, so it is recomputed (a miss is always exact).
GF_HD Svd3 cachedSvd3(const Mat3& F, double* entry) {
  if (entry == nullptr) return svd3(F);
  bool same = true;
  for (int k = 0; k < 9; ++k)
    same = same && entry[k] == F.m[k] && copysign(1.0, entry[k]) == copysign(1.0, F.m[k]);
  Svd3 r;
  if (same) {
    for (int k = 0; k < 9; ++k) {
      r.U.m[k] = entry[9 + k];
      r.V.m[k] = entry[21 + k];
    }
    r.s = Vec3{entry[18], entry[19], entry[20]};
    return r;
  }
  r = svd3(F);
  for (int k = 0; k < 9; ++k) {
    entry[k] = F.m[k];
    entry[9 + k] = r.U.m[k];
    entry[21 + k] = r.V.m[k];
  }
  entry[18] = r.s.x;
  entry[19] = r.s.y;
  entry[20] = r.s.z;
  return r;
}

}  // namespace gf
