// Eigen-decomposition of small symmetric matrices by cyclic Jacobi rotations.
//
// Jacobi is slower than a tridiagonal QR for large N but it is branch-light, needs no
// workspace beyond the matrix itself, runs the same on the GPU, and gives eigenvectors that
// are orthonormal to machine precision even for repeated eigenvalues, which is what the
// Hessian projection and the 3x3 scaling modes of the material kernels need.
#pragma once

#include "math.h"

namespace gf {

/// Maximum number of cyclic Jacobi sweeps; 3x3 converges in 4-6, 12x12 in about 8-10.
constexpr int kJacobiMaxSweeps = 50;

/// Eigen-decomposition A = Q diag(values) Q^T of a symmetric matrix (only the upper triangle
/// is read). Column k of `vectors` is the unit eigenvector of values[k]; values are sorted in
/// descending order.
template <int N>
GF_HD void symmetricEigen(const Mat<N, N>& a, double values[N], Mat<N, N>& vectors) {
  Mat<N, N> w;
  double scale = 0;
  for (int i = 0; i < N; ++i)
    for (int j = i; j < N; ++j) {
      w(i, j) = a(i, j);
      w(j, i) = a(i, j);
      scale += a(i, j) * a(i, j);
    }
  scale = sqrt(scale);
  vectors = Mat<N, N>::identity();
  // Off-diagonal entries below this are numerically zero: rotating them would only stir
  // round-off without improving the decomposition.
  const double tiny = 1e-18 * scale;

  for (int sweep = 0; sweep < kJacobiMaxSweeps; ++sweep) {
    bool rotated = false;
    for (int p = 0; p < N - 1; ++p) {
      for (int q = p + 1; q < N; ++q) {
        const double apq = w(p, q);
        if (fabs(apq) <= tiny) continue;
        rotated = true;
        // Rotation angle that zeroes w(p,q), with the smaller of the two roots for |t| <= 1
        // (Golub & Van Loan, sec 8.5); the large-theta branch avoids overflow of theta^2.
        const double theta = (w(q, q) - w(p, p)) / (2.0 * apq);
        double t;
        if (fabs(theta) > 1e150) {
          t = 0.5 / theta;
        } else {
          t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
        }
        const double c = 1.0 / sqrt(t * t + 1.0);
        const double s = t * c;
        w(p, p) -= t * apq;
        w(q, q) += t * apq;
        w(p, q) = 0;
        w(q, p) = 0;
        for (int r = 0; r < N; ++r) {
          if (r != p && r != q) {
            const double arp = w(r, p);
            const double arq = w(r, q);
            w(r, p) = c * arp - s * arq;
            w(p, r) = w(r, p);
            w(r, q) = s * arp + c * arq;
            w(q, r) = w(r, q);
          }
          const double vrp = vectors(r, p);
          const double vrq = vectors(r, q);
          vectors(r, p) = c * vrp - s * vrq;
          vectors(r, q) = s * vrp + c * vrq;
        }
      }
    }
    if (!rotated) break;
  }

  for (int i = 0; i < N; ++i) values[i] = w(i, i);
  // Selection sort, descending, moving eigenvector columns along with their values.
  for (int i = 0; i < N - 1; ++i) {
    int best = i;
    for (int j = i + 1; j < N; ++j)
      if (values[j] > values[best]) best = j;
    if (best == i) continue;
    const double tv = values[i];
    values[i] = values[best];
    values[best] = tv;
    for (int r = 0; r < N; ++r) {
      const double tq = vectors(r, i);
      vectors(r, i) = vectors(r, best);
      vectors(r, best) = tq;
    }
  }
}

/// Replaces a symmetric matrix by its nearest positive semi-definite matrix in the Frobenius
/// norm (negative eigenvalues clamped to zero), or with `absolute` by the matrix with the
/// absolute values of its eigenvalues (the same eigenvectors). The general fallback where no
/// analytic eigen-system is known (SPEC §1); returns true when an eigenvalue was negative.
template <int N>
GF_HD bool projectPSD(Mat<N, N>& a, bool absolute = false) {
  double values[N];
  Mat<N, N> q;
  symmetricEigen<N>(a, values, q);
  bool clamped = false;
  for (int k = 0; k < N; ++k) {
    if (values[k] < 0) {
      values[k] = absolute ? -values[k] : 0;
      clamped = true;
    }
  }
  if (!clamped) return false;
  for (int i = 0; i < N; ++i)
    for (int j = i; j < N; ++j) {
      double s = 0;
      for (int k = 0; k < N; ++k) s += q(i, k) * values[k] * q(j, k);
      a(i, j) = s;
      a(j, i) = s;
    }
  return true;
}

}  // namespace gf
