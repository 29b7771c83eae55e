// Direct sparse Cholesky of a block-sparse matrix: the reference solver for error measurements.
#pragma once

#include <memory>

#include "graphfrac/status.h"
#include "solver/block_sparse.h"

namespace gf::detail {

/// Keeps the BLAS under CHOLMOD (OpenBLAS) on the calling thread; call before factorising.
/// Process-wide and once: sets OpenBLAS's thread count to 1 and stops the worker threads
/// OpenBLAS started when it was loaded (it starts them again if the application raises the
/// count with openblas_set_num_threads).
void blasOnOneThread();

/// While alive, OpenMP parallel regions that start on this thread run on it alone: CHOLMOD's
/// supernodal factorisation asks libgomp for four threads, which then spin between calls. The
/// setting (max-active-levels) belongs to the calling thread only, and its previous value
/// comes back on destruction, so an application's own OpenMP use is untouched.
class SerialOpenMpScope {
 public:
  SerialOpenMpScope();
  ~SerialOpenMpScope();
  SerialOpenMpScope(const SerialOpenMpScope&) = delete;
  SerialOpenMpScope& operator=(const SerialOpenMpScope&) = delete;

 private:
  int m_saved = -1;
};

/// Matrices of at most this many 3x3 block rows are factorised by Eigen's SimplicialLLT even
/// when CHOLMOD is there: at debris size (27-64 nodes) CHOLMOD's supernodal set-up and BLAS
/// calls cost more than the factorisation itself.
inline constexpr int32_t kSimplicialMaxBlocks = 128;

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
