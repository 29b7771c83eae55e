// Direct sparse Cholesky of a block-sparse matrix: the reference solver for error measurements.
#pragma once

#include <memory>

#include "graphfrac/status.h"
#include "solver/block_sparse.h"

namespace gf::detail {

/// Keeps the BLAS under CHOLMOD (OpenBLAS) on the calling thread; call before factorising.
void blasOnOneThread();

/// Sparse LL^T (CHOLMOD supernodal, or Eigen SimplicialLLT) of the scalar expansion of a
/// BlockSparseMatrix. The symbolic analysis runs once per pattern; solve() copies the values
/// through a precomputed map and refactorises. Eigen stays inside cholesky.cpp.
class CholeskySolver {
 public:
  CholeskySolver();
  ~CholeskySolver();
  CholeskySolver(CholeskySolver&&) noexcept;
  CholeskySolver& operator=(CholeskySolver&&) noexcept;

  /// Symbolic analysis of A's pattern (values are not read). Fails on a malformed pattern.
  Result<void> analyze(const BlockSparseMatrix& A);
  /// Factorises A (same pattern as analyze) and solves A x = b. A matrix that is not positive
  /// definite, or a pattern that was not analysed, gives converged = false and x = 0, never NaN.
  SolveReport solve(const BlockSparseMatrix& A, const double* b, double* x);

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

}  // namespace gf::detail
