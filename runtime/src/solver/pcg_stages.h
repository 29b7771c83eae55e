// Preconditioned conjugate gradients (Hestenes-Stiefel form), written once over an executor
// (step/executor.h's CpuExecutor, gpu/executor.h's device one), an operator (a block-sparse
// matrix, or Integrator::coupledSolve's with the self pairs' matrix-free cross terms) and a
// preconditioner: the block-Jacobi one below (PcgSolver), a multigrid V-cycle (MultigridSolver,
// as flexible CG) or the body's own solve (coupledSolve, flexible).
// Every vector pass is a stage or a fused reduction term; only the scalars of the recurrence
// live on the host. An iteration reads the vectors as few times as possible: one product, one
// dot (p.Ap), one pass "x += a p, r -= a Ap, r.r", one "z = M r, r.z" and one "p = z + b p".
// Convergence is declared on the true residual |b - A x| / |b|: when the recursive residual
// meets the tolerance the true one is computed, and PCG restarts from it if round-off has let
// the two drift apart.
#pragma once

#include <cmath>
#include <limits>
#include <type_traits>

#include "solver/block_sparse.h"
#include "solver/sparse_stages.h"
#include "solver/vector_stages.h"
#include "step/reduce.h"

namespace gf::detail {

/// CG's work vectors, 3 n each; rOld only for a flexible preconditioner.
struct CgBuffers {
  double* r = nullptr;
  double* z = nullptr;
  double* p = nullptr;
  double* ap = nullptr;
  double* rOld = nullptr;
};

/// r = b - ax, summing r.r.
struct ResidualTerm {
  const double* b = nullptr;
  const double* ax = nullptr;
  double* r = nullptr;

  GF_HD double operator()(int32_t i) const {
    r[i] = b[i] - ax[i];
    return r[i] * r[i];
  }
};

/// x += alpha p and r -= alpha ap (keeping the old r in rOld unless null), summing the new r.r.
struct CgUpdateTerm {
  double alpha = 0;
  const double* p = nullptr;
  const double* ap = nullptr;
  double* x = nullptr;
  double* r = nullptr;
  double* rOld = nullptr;

  GF_HD double operator()(int32_t i) const {
    x[i] += alpha * p[i];
    if (rOld) rOld[i] = r[i];
    r[i] -= alpha * ap[i];
    return r[i] * r[i];
  }
};

/// z = M^-1 r with the 3x3 block inverses, one node per item, summing r.z.
struct BlockPreconditionTerm {
  const double* invDiag = nullptr;
  const double* r = nullptr;
  double* z = nullptr;

  GF_HD double operator()(int32_t n) const {
    const double* m = invDiag + 9 * int64_t(n);
    const double* rn = r + 3 * int64_t(n);
    double* zn = z + 3 * int64_t(n);
    zn[0] = m[0] * rn[0] + m[1] * rn[1] + m[2] * rn[2];
    zn[1] = m[3] * rn[0] + m[4] * rn[1] + m[5] * rn[2];
    zn[2] = m[6] * rn[0] + m[7] * rn[1] + m[8] * rn[2];
    return rn[0] * zn[0] + rn[1] * zn[1] + rn[2] * zn[2];
  }
};

/// The block-Jacobi preconditioner on an executor: the inverse of each node's 3x3 diagonal
/// block (the coupling of a node's three displacement components dominates elasticity
/// matrices), scalar Jacobi where a block is not numerically SPD.
template <class Exec>
struct BlockJacobi {
  bool flexible = false;
  const Exec& exec;
  BlockMatrixView A;
  double* invDiag;  ///< 9 per node

  void prepare() const { exec.run(A.n, 128, BlockJacobiStage{A, invDiag}); }
  /// z = M^-1 r; returns r.z.
  double apply(const double* r, double* z) const {
    return exec.template reduce<SumOp>(A.n, BlockPreconditionTerm{invDiag, r, z});
  }
};

/// Solves A x = b for SPD A (a BlockMatrixView, or an operator on A.n nodes with
/// A.apply(x, y) setting y = A x) with preconditioner M: M.prepare() once before the first
/// iteration, M.apply(r, z) sets z = M^-1 r and returns r.z; with M.flexible, beta is
/// z_new.(r_new - r_old) / (z_old.r_old) (flexible CG, for a preconditioner that is not a fixed
/// linear map, such as a V-cycle). x holds the initial guess on entry and the solution on
/// return. Stops when |b - A x| / |b| <= relativeTolerance (on the true residual) or after
/// maxIterations. Breakdown (p^T A p <= 0, a non-finite value) stops early with converged =
/// false and the last finite iterate in x. If |b| == 0, x = 0 and the solve has converged.
/// The same bits on every executor and thread count.
template <class Exec, class Op, class Precond>
SolveReport conjugateGradients(const Exec& exec, const Op& A, const double* b, double* x,
                               const CgBuffers& w, const Precond& M, int maxIterations,
                               double relativeTolerance) {
  constexpr uint32_t kRows = 128, kEntries = 2048;
  SolveReport report;
  const int32_t n3 = 3 * A.n;
  const double bb = exec.template reduce<SumOp>(n3, DotTerm{b, b});
  if (!std::isfinite(bb)) {
    report.relativeResidual = std::numeric_limits<double>::infinity();
    return report;
  }
  if (bb == 0) {
    exec.run(n3, kEntries, FillStage{0.0, x});
    report.converged = true;
    return report;
  }
  if (exec.template reduce<MaxOp>(n3, NonFiniteTerm{x}) > 0)
    exec.run(n3, kEntries, FillStage{0.0, x});
  const double bnorm = std::sqrt(bb);
  const double tol2 = relativeTolerance * relativeTolerance * bb;

  auto product = [&](const double* v, double* y) {
    if constexpr (std::is_same_v<Op, BlockMatrixView>)
      exec.run(A.n, kRows, SpmvStage{A, v, y});
    else
      A.apply(v, y);
  };
  auto trueResidual = [&]() {
    product(x, w.ap);
    return exec.template reduce<SumOp>(n3, ResidualTerm{b, w.ap, w.r});
  };

  double rr = trueResidual();
  bool breakdown = !std::isfinite(rr);
  bool converged = !breakdown && rr <= tol2;
  int it = 0;
  if (!converged && !breakdown) {
    M.prepare();
    double rz = M.apply(w.r, w.z);
    exec.run(n3, kEntries, CopyStage{w.z, w.p});
    while (it < maxIterations) {
      if (!(rz > 0) || !std::isfinite(rz)) {
        breakdown = true;
        break;
      }
      product(w.p, w.ap);
      const double pap = exec.template reduce<SumOp>(n3, DotTerm{w.p, w.ap});
      const double alpha = rz / pap;
      if (!(pap > 0) || !std::isfinite(pap) || !std::isfinite(alpha)) {
        breakdown = true;
        break;
      }
      ++it;
      rr = exec.template reduce<SumOp>(
          n3, CgUpdateTerm{alpha, w.p, w.ap, x, w.r, M.flexible ? w.rOld : nullptr});
      if (!std::isfinite(rr)) {
        exec.run(n3, kEntries, AxpyStage{x, w.p, -alpha, x});  // the last finite iterate
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
        rz = M.apply(w.r, w.z);
        exec.run(n3, kEntries, CopyStage{w.z, w.p});
        continue;
      }
      if (it == maxIterations) break;  // no preconditioner solve for a direction never taken
      const double rzNew = M.apply(w.r, w.z);
      const double beta =
          (M.flexible ? rzNew - exec.template reduce<SumOp>(n3, DotTerm{w.z, w.rOld}) : rzNew) / rz;
      rz = rzNew;
      if (!std::isfinite(beta)) {
        breakdown = true;
        break;
      }
      exec.run(n3, kEntries, AxpyStage{w.z, w.p, beta, w.p});
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
