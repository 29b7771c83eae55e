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

/// A symmetric matrix of scalars in compressed-column form, 0-based, rows ascending within each
/// column (Eigen's compressed SparseMatrix<double> has this layout). Only the lower triangle
/// (row >= column) is read, so either the full matrix or its lower half may be given.
struct SymmetricCsc {
  int32_t n = 0;                      ///< Rows and columns.
  const int32_t* colStart = nullptr;  ///< n + 1 offsets into row and value.
  const int32_t* row = nullptr;       ///< colStart[n] row indices.
  const double* value = nullptr;      ///< colStart[n] values.
};

/// The last factorisation: how much fill the ordering left (for measurements).
struct CholeskyFactorInfo {
  int64_t matrixNonZeros = 0;  ///< Stored entries of A's lower triangle.
  int64_t factorNonZeros = 0;  ///< Entries of L, diagonal included (without supernodal padding).
  double flops = 0;            ///< Factorisation flop count (CHOLMOD's; 0 for the Eigen path).
  const char* ordering = "";   ///< Fill-reducing ordering used: "amd", "metis", "nesdis", ...
  bool supernodal = false;     ///< CHOLMOD supernodal rather than Eigen SimplicialLLT.
};

/// Sparse LL^T (CHOLMOD supernodal, or Eigen SimplicialLLT) of the scalar expansion of a
/// BlockSparseMatrix, or of a scalar SymmetricCsc. The symbolic analysis runs once per pattern;
/// solve() copies the values through a precomputed map and refactorises. A matrix that stays
/// constant is factorised once (factorize) and then only back-substituted (solveFactored).
/// Eigen stays inside cholesky.cpp.
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
  /// Factorises A (same pattern as analyze) for solveFactored(). False, and no factor kept, when
  /// A is not positive definite or its pattern was not analysed.
  bool factorize(const BlockSparseMatrix& A);

  /// Analyses and factorises a scalar symmetric positive definite matrix for solveFactored().
  /// Fails, keeping no factor, on a malformed pattern (naming the column) or a matrix that is
  /// not positive definite.
  Result<void> factorize(const SymmetricCsc& A);

  /// x = A^-1 b by back-substitution with the last successful factorize() (3 n scalars for a
  /// block matrix, n for a scalar one); b and x must not overlap. False when there is no factor
  /// (x is not written: its size is unknown), or with x = 0 when the result is not finite (a
  /// non-finite b).
  bool solveFactored(const double* b, double* x);
  /// Scalar unknowns of the current factor (0 without one).
  int64_t factoredSize() const;
  /// Fill and ordering of the current factor (zeros without one).
  CholeskyFactorInfo factorInfo() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

}  // namespace gf::detail
