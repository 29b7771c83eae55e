// Inverse of a small symmetric positive definite block: the block-Jacobi preconditioner's and
// the multigrid smoothers' D^-1 (3x3 node blocks, 12x12 handle blocks), on the CPU and the
// device alike.
#pragma once

#include "gf_hd.h"

namespace gf {

/// Inverse of the SPD B x B block m (row-major; only its lower triangle is read) by Cholesky.
/// A block that is not numerically SPD (a pivot below 1e-13 of its largest diagonal entry, or
/// anything not finite) gets the inverse of its positive diagonal entries instead (1 where not
/// positive), so the inverse stays SPD whatever the matrix.
template <int B>
GF_HD void invertSpdBlock(const double* m, double* inv) {
  double scale = 0;
  for (int i = 0; i < B; ++i) scale = fmax(scale, fabs(m[(B + 1) * i]));
  const double tiny = 1e-13 * scale;
  bool ok = isFinite(scale) && scale > 0;
  double L[B * B];  // lower Cholesky factor
  for (int j = 0; j < B && ok; ++j) {
    double d = m[B * j + j];
    for (int k = 0; k < j; ++k) d -= L[B * j + k] * L[B * j + k];
    if (!(d > tiny)) {
      ok = false;
      break;
    }
    L[B * j + j] = sqrt(d);
    for (int i = j + 1; i < B; ++i) {
      double s = m[B * i + j];
      for (int k = 0; k < j; ++k) s -= L[B * i + k] * L[B * j + k];
      L[B * i + j] = s / L[B * j + j];
    }
  }
  if (ok) {
    // W = L^-1 by forward substitution, column by column.
    double W[B * B];
    for (int c = 0; c < B; ++c)
      for (int i = c; i < B; ++i) {
        double s = i == c ? 1.0 : 0.0;
        for (int k = c; k < i; ++k) s -= L[B * i + k] * W[B * k + c];
        W[B * i + c] = s / L[B * i + i];
      }
    // inv = W^T W.
    for (int i = 0; i < B; ++i)
      for (int j = i; j < B; ++j) {
        double s = 0;
        for (int k = j; k < B; ++k) s += W[B * k + i] * W[B * k + j];
        inv[B * i + j] = s;
        inv[B * j + i] = s;
      }
    for (int i = 0; i < B * B && ok; ++i) ok = isFinite(inv[i]);
    if (ok) return;
  }
  for (int i = 0; i < B * B; ++i) inv[i] = 0;
  for (int i = 0; i < B; ++i) {
    const double d = m[(B + 1) * i];
    inv[(B + 1) * i] = (d > 0 && isFinite(1 / d)) ? 1 / d : 1.0;
  }
}

}  // namespace gf
