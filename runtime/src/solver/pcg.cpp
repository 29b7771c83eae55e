// Preconditioned conjugate gradients (Hestenes-Stiefel form) with block-Jacobi.
//
// Design: every vector pass works on the fixed reduction chunks of vector_ops.h, and the passes
// are fused so that an iteration reads the vectors as few times as possible: one SpMV, one dot
// (p.Ap), one pass "x += a p, r -= a Ap, r.r", one pass "z = M r, r.z" and one "p = z + b p".
// The preconditioner inverts each node's 3x3 diagonal block (the coupling of a node's three
// displacement components dominates elasticity matrices); a block that is not numerically SPD
// falls back to scalar Jacobi, and a non-positive diagonal entry to 1, so M stays SPD.
// Convergence is declared on the true residual |b - A x| / |b|: when the recursive residual
// meets the tolerance the true one is computed, and PCG restarts from it if round-off has let
// the two drift apart.
#include "solver/pcg.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "solver/vector_ops.h"

namespace gf::detail {

namespace {

// Inverse of a symmetric 3x3 block through its Cholesky factor; false if it is not
// numerically positive definite (pivot below a relative threshold, or not finite).
bool invertSpd3(const double* m, double* inv) {
  const double scale = std::max({std::fabs(m[0]), std::fabs(m[4]), std::fabs(m[8])});
  const double tiny = 1e-13 * scale;
  // Lower factor L from the lower triangle of m (which equals the upper one for symmetric A).
  double l00 = m[0];
  if (!(l00 > tiny) || !std::isfinite(scale)) return false;
  l00 = std::sqrt(l00);
  const double l10 = m[3] / l00, l20 = m[6] / l00;
  double l11 = m[4] - l10 * l10;
  if (!(l11 > tiny)) return false;
  l11 = std::sqrt(l11);
  const double l21 = (m[7] - l20 * l10) / l11;
  double l22 = m[8] - l20 * l20 - l21 * l21;
  if (!(l22 > tiny)) return false;
  l22 = std::sqrt(l22);
  // W = L^-1 (lower), then inv = W^T W.
  const double w00 = 1 / l00, w11 = 1 / l11, w22 = 1 / l22;
  const double w10 = -l10 * w00 / l11;
  const double w21 = -l21 * w11 / l22;
  const double w20 = -(l20 * w00 + l21 * w10) / l22;
  inv[0] = w00 * w00 + w10 * w10 + w20 * w20;
  inv[1] = w10 * w11 + w20 * w21;
  inv[2] = w20 * w22;
  inv[4] = w11 * w11 + w21 * w21;
  inv[5] = w21 * w22;
  inv[8] = w22 * w22;
  inv[3] = inv[1];
  inv[6] = inv[2];
  inv[7] = inv[5];
  return true;
}

}  // namespace

void PcgSolver::buildPreconditioner(const BlockSparseMatrix& A, JobSystem& jobs) {
  double* invDiag = m_invDiag.data();
  forRanges(jobs, static_cast<uint32_t>(A.n), 256, [&](uint32_t begin, uint32_t end) {
    for (uint32_t r = begin; r < end; ++r) {
      double* inv = invDiag + 9 * static_cast<size_t>(r);
      const int32_t k = A.diagonal(static_cast<int32_t>(r));
      if (k >= 0 && invertSpd3(A.block(k), inv)) continue;
      // Scalar Jacobi fallback; identity where the diagonal is not positive.
      for (int i = 0; i < 9; ++i) inv[i] = 0;
      for (int i = 0; i < 3; ++i) {
        const double d = k >= 0 ? A.block(k)[4 * i] : 0.0;
        inv[4 * i] = (d > 0 && std::isfinite(1 / d)) ? 1 / d : 1.0;
      }
    }
  });
}

SolveReport PcgSolver::solve(const BlockSparseMatrix& A, const double* b, double* x,
                             int maxIterations, double relativeTolerance, JobSystem& jobs) {
  SolveReport report;
  const size_t n3 = 3 * static_cast<size_t>(A.n);
  if (m_r.size() < n3) {
    m_r.resize(n3);
    m_z.resize(n3);
    m_p.resize(n3);
    m_ap.resize(n3);
    m_invDiag.resize(3 * n3);
  }
  double* r = m_r.data();
  double* z = m_z.data();
  double* p = m_p.data();
  double* ap = m_ap.data();
  const double* invDiag = m_invDiag.data();

  const double bb = dot(b, b, n3, m_partials, jobs);
  if (!std::isfinite(bb)) {
    report.relativeResidual = std::numeric_limits<double>::infinity();
    return report;
  }
  if (bb == 0) {
    fill(0.0, x, n3, jobs);
    report.converged = true;
    return report;
  }
  if (!allFinite(x, n3)) fill(0.0, x, n3, jobs);
  const double bnorm = std::sqrt(bb);
  const double tol2 = relativeTolerance * relativeTolerance * bb;

  // r = b - A x; returns r.r.
  auto trueResidual = [&]() {
    A.multiply(x, ap, jobs);
    return chunkedReduce(n3, m_partials, jobs, [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) r[i] = b[i] - ap[i];
      return dotRange(r, r, begin, end);
    });
  };
  // z = M^-1 r (block-Jacobi); returns r.z. Chunks hold whole nodes (kReduceChunk % 3 == 0).
  auto precondition = [&]() {
    return chunkedReduce(n3, m_partials, jobs, [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; i += 3) {
        const double* m = invDiag + 3 * i;
        z[i + 0] = m[0] * r[i] + m[1] * r[i + 1] + m[2] * r[i + 2];
        z[i + 1] = m[3] * r[i] + m[4] * r[i + 1] + m[5] * r[i + 2];
        z[i + 2] = m[6] * r[i] + m[7] * r[i + 1] + m[8] * r[i + 2];
      }
      return dotRange(r, z, begin, end);
    });
  };

  double rr = trueResidual();
  bool breakdown = !std::isfinite(rr);
  bool converged = !breakdown && rr <= tol2;
  int it = 0;
  if (!converged && !breakdown) {
    buildPreconditioner(A, jobs);
    double rz = precondition();
    copy(z, p, n3, jobs);
    while (it < maxIterations) {
      if (!(rz > 0) || !std::isfinite(rz)) {
        breakdown = true;
        break;
      }
      A.multiply(p, ap, jobs);
      const double pap = dot(p, ap, n3, m_partials, jobs);
      const double alpha = rz / pap;
      if (!(pap > 0) || !std::isfinite(pap) || !std::isfinite(alpha)) {
        breakdown = true;
        break;
      }
      ++it;
      rr = chunkedReduce(n3, m_partials, jobs, [&](size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
          x[i] += alpha * p[i];
          r[i] -= alpha * ap[i];
        }
        return dotRange(r, r, begin, end);
      });
      if (!std::isfinite(rr)) {
        axpy(-alpha, p, x, n3, jobs);  // back to the last finite iterate
        breakdown = true;
        break;
      }
      if (rr <= tol2) {
        rr = trueResidual();
        if (rr <= tol2) {
          converged = true;
          break;
        }
        // Round-off drift: restart from the true residual.
        rz = precondition();
        copy(z, p, n3, jobs);
        continue;
      }
      const double rzNew = precondition();
      const double beta = rzNew / rz;
      rz = rzNew;
      if (!std::isfinite(beta)) {
        breakdown = true;
        break;
      }
      xpby(z, beta, p, n3, jobs);
    }
    // The iteration cap or a breakdown: report the true residual of what x now holds.
    if (!converged) rr = trueResidual();
  }
  report.iterations = it;
  report.converged = converged;
  report.relativeResidual =
      std::isfinite(rr) ? std::sqrt(rr) / bnorm : std::numeric_limits<double>::infinity();
  return report;
}

}  // namespace gf::detail
