// Preconditioned conjugate gradients with a block-Jacobi preconditioner (solver/pcg_stages.h).
#pragma once

#include <vector>

#include "graphfrac/jobs.h"
#include "solver/block_sparse.h"

namespace gf::detail {

/// PCG for symmetric positive definite block-sparse systems. Keeps its work vectors between
/// calls, so a solve allocates nothing once it has seen the largest system. Deterministic: the
/// same bits for any thread count.
class PcgSolver {
 public:
  /// Solves A x = b. x holds the initial guess on entry and the solution on return. Stops when
  /// |b - A x| / |b| <= relativeTolerance (checked on the true residual) or after maxIterations.
  /// Breakdown (p^T A p <= 0, a non-finite value) stops early with converged = false and the last
  /// finite iterate in x. If |b| == 0, x = 0 and the solve has converged.
  SolveReport solve(const BlockSparseMatrix& A, const double* b, double* x, int maxIterations,
                    double relativeTolerance, JobSystem& jobs);

 private:
  // Work vectors, 3 n each, and the inverse diagonal blocks, 9 n.
  std::vector<double> m_r, m_z, m_p, m_ap, m_invDiag, m_partials;
};

}  // namespace gf::detail
