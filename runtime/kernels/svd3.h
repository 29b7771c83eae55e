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
struct Svd3 {
  Mat3 U;
  Vec3 s;
  Mat3 V;
};

namespace detail {

/// A unit vector orthogonal to the unit vector u: cross u with the axis it is least
/// aligned with, which keeps the cross product well away from zero.
GF_HD Vec3 anyOrthogonal(Vec3 u) {
  const double ax = fabs(u.x), ay = fabs(u.y), az = fabs(u.z);
  Vec3 e{0, 0, 0};
  if (ax <= ay && ax <= az) {
    e.x = 1;
  } else if (ay <= az) {
    e.y = 1;
  } else {
    e.z = 1;
  }
  const Vec3 w = cross(u, e);
  return (1.0 / norm(w)) * w;
}

GF_HD void swapColumns(Mat3& m, int i, int j) {
  for (int r = 0; r < 3; ++r) {
    const double t = m(r, i);
    m(r, i) = m(r, j);
    m(r, j) = t;
  }
}

/// One Jacobi rotation of columns P < Q of B = F V (and of V) that makes them orthogonal;
/// false when they already are. The column pair is a template argument so B and V stay in
/// registers through a sweep.
template <int P, int Q>
GF_HD bool jacobiRotate(Mat3& B, Mat3& V) {
  double alpha = 0, beta = 0, gamma = 0;  // (F^T F) entries pp, qq, pq in the basis V
  for (int r = 0; r < 3; ++r) {
    alpha += B(r, P) * B(r, P);
    beta += B(r, Q) * B(r, Q);
    gamma += B(r, P) * B(r, Q);
  }
  // Orthogonal to working precision relative to the columns' own lengths: |gamma| <= 1e-15
  // sqrt(alpha beta), squared, as a square root here cost a fifth of svd3.
  if (gamma * gamma <= 1e-30 * (alpha * beta) || fabs(gamma) < 1e-300) return false;
  // The rotation's tangent is t = sign(zeta) / (|zeta| + sqrt(1 + zeta^2)), zeta = d / g2,
  // and c = 1 / sqrt(1 + t^2), s = c t. Multiplied through by |g2|, t = num / den with den
  // = |d| + hypot(d, g2), so c = den / w and s = num / w, w = hypot(den, num): two square
  // roots and one division on the sweep's critical path instead of two and three. The
  // squares are safe for column lengths far from over- and underflow; elsewhere the zeta form.
  const double d = beta - alpha, g2 = 2.0 * gamma;
  const double scale = alpha + beta;
  double c, s;
  if (fabs(g2) < 1e-8 * fabs(d)) {
    // g2^2 is below round-off of d^2 and t^2 below that of 1: the same c and s to the last
    // bit or so, without a square root (most rotations of a sweep near convergence).
    c = 1.0;
    s = gamma / d;
  } else if (scale > 1e-100 && scale < 1e100) {
    const double den = fabs(d) + sqrt(d * d + g2 * g2);
    const double num = d == 0 ? fabs(g2) : (d > 0 ? g2 : -g2);  // sign(zeta) |g2|, zeta = +-0: +
    const double iw = 1.0 / sqrt(den * den + num * num);
    c = den * iw;
    s = num * iw;
  } else {
    const double zeta = d / g2;
    const double t = fabs(zeta) > 1e150
                         ? 0.5 / zeta
                         : (zeta >= 0 ? 1.0 : -1.0) / (fabs(zeta) + sqrt(1.0 + zeta * zeta));
    c = 1.0 / sqrt(1.0 + t * t);
    s = c * t;
  }
  for (int r = 0; r < 3; ++r) {
    const double bp = B(r, P), bq = B(r, Q);
    B(r, P) = c * bp - s * bq;
    B(r, Q) = s * bp + c * bq;
    const double vp = V(r, P), vq = V(r, Q);
    V(r, P) = c * vp - s * vq;
    V(r, Q) = s * vp + c * vq;
  }
  return true;
}

}  // namespace detail

/// Rotation-variant SVD of F (see the file comment). Robust for rank-deficient, inverted and
/// repeated-singular-value F; reconstructs F to round-off.
GF_HD Svd3 svd3(const Mat3& F) {
  Mat3 B = F;
  Mat3 V = Mat3::identity();

  // One-sided Jacobi: rotate column pairs of B (and V) until all are mutually orthogonal.
  for (int sweep = 0; sweep < 30; ++sweep) {
    const bool r01 = detail::jacobiRotate<0, 1>(B, V);
    const bool r02 = detail::jacobiRotate<0, 2>(B, V);
    const bool r12 = detail::jacobiRotate<1, 2>(B, V);
    if (!(r01 || r02 || r12)) break;
  }

  // Sort columns by length (the singular magnitudes), descending.
  double len[3];
  for (int j = 0; j < 3; ++j) len[j] = dot(column(B, j), column(B, j));
  for (int i = 0; i < 2; ++i) {
    int best = i;
    for (int j = i + 1; j < 3; ++j)
      if (len[j] > len[best]) best = j;
    if (best != i) {
      const double t = len[i];
      len[i] = len[best];
      len[best] = t;
      detail::swapColumns(B, i, best);
      detail::swapColumns(V, i, best);
    }
  }
  // Proper rotation V; flipping v2 flips b2 = F v2 with it, so F = B V^T still holds.
  if (det(V) < 0) {
    for (int r = 0; r < 3; ++r) {
      V(r, 2) = -V(r, 2);
      B(r, 2) = -B(r, 2);
    }
  }

  const Vec3 b0 = column(B, 0), b1 = column(B, 1), b2 = column(B, 2);
  Vec3 u0;
  const double n0 = norm(b0);
  if (n0 > 1e-300) {
    u0 = (1.0 / n0) * b0;
  } else {
    u0 = Vec3{1, 0, 0};  // F = 0: any rotation U works
  }
  Vec3 u1 = b1 - dot(u0, b1) * u0;
  const double n1 = norm(u1);
  if (n1 > 1e-300) {
    u1 = (1.0 / n1) * u1;
  } else {
    u1 = detail::anyOrthogonal(u0);  // rank <= 1
  }
  const Vec3 u2 = cross(u0, u1);  // proper U; the sign of det F lands on s2

  Svd3 r;
  r.U = fromColumns(u0, u1, u2);
  r.V = V;
  r.s = Vec3{dot(u0, b0), dot(u1, b1), dot(u2, b2)};
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
