// A dense Cholesky factorisation A = L L^T and its two triangular solves as stages
// (step/executor.h), so that the multigrid's coarsest level can be factorised and solved by the
// executor that runs the cycle (gpu/multigrid.cu on a device) from the same source as on the
// CPU. Right-looking, one column at a time: a column costs three launches (pivot, column,
// trailing update) and each solve two per unknown, so the cost is launch-bound and only small
// matrices belong here (kDenseCholeskyMaxSize); larger ones keep the sparse host factor
// (solver/cholesky.h). No pivoting: A must be symmetric positive definite.
#pragma once

#include <cmath>
#include <cstdint>

#include "kernels/gf_hd.h"
#include "solver/vector_stages.h"
#include "step/reduce.h"

namespace gf::detail {

/// Largest scalar size factorised densely: 64 coarsest handles of 12 unknowns, a 4.7 MB factor,
/// n^3 / 3 = 1.5e8 multiply-adds and 3 n = 2304 launches per factorisation.
inline constexpr int32_t kDenseCholeskyMaxSize = 768;

/// The lower triangle of the scalar expansion of a symmetric matrix of 12x12 blocks (block CSR,
/// each row's blocks with their columns), row-major into a zeroed n x n array (n = 12 rows),
/// plus `shift` on the diagonal. Item r writes scalar rows 12 r .. 12 r + 11.
struct DenseFromBlocksStage {
  const int32_t* rowStart = nullptr;
  const int32_t* col = nullptr;
  const double* values = nullptr;  // 144 per block, row-major
  int32_t n = 0;                   // scalar size
  double shift = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t r) const {
    for (int32_t k = rowStart[r]; k < rowStart[r + 1]; ++k) {
      const int32_t c = col[k];
      if (c > r) continue;
      for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12 && (c < r || j <= i); ++j)
          out[int64_t(12 * r + i) * n + 12 * c + j] = values[144 * int64_t(k) + 12 * i + j];
    }
    for (int i = 0; i < 12; ++i) out[int64_t(12 * r + i) * n + 12 * r + i] += shift;
  }
};

/// Column k's pivot: L_kk = sqrt(a_kk), NaN where a_kk is not positive (A is not positive
/// definite; the NaN runs into the rest of the factor, where DenseDiagonalTerm finds it).
struct CholeskyPivotStage {
  double* a = nullptr;
  int32_t n = 0, k = 0;

  GF_HD void operator()(int32_t) const {
    double& d = a[int64_t(k) * n + k];
    d = d > 0 ? sqrt(d) : NAN;
  }
};

/// Column k below the pivot: L_ik = a_ik / L_kk for i = k + 1 + t.
struct CholeskyColumnStage {
  double* a = nullptr;
  int32_t n = 0, k = 0;

  GF_HD void operator()(int32_t t) const {
    const int32_t i = k + 1 + t;
    a[int64_t(i) * n + k] /= a[int64_t(k) * n + k];
  }
};

/// The trailing update of row i = k + 1 + t: a_ij -= L_ik L_jk for k < j <= i. Rows are
/// disjoint and read only column k, which the column stage finished.
struct CholeskyUpdateStage {
  double* a = nullptr;
  int32_t n = 0, k = 0;

  GF_HD void operator()(int32_t t) const {
    const int32_t i = k + 1 + t;
    double* row = a + int64_t(i) * n;
    const double lik = row[k];
    for (int32_t j = k + 1; j <= i; ++j) row[j] -= lik * a[int64_t(j) * n + k];
  }
};

/// 1 where the factor's diagonal entry i is not a positive finite number: reduced with MaxOp,
/// whether the factorisation failed.
struct DenseDiagonalTerm {
  const double* a = nullptr;
  int32_t n = 0;

  GF_HD double operator()(int32_t i) const {
    const double d = a[int64_t(i) * n + i];
    return isFinite(d) && d > 0 ? 0.0 : 1.0;
  }
};

/// The diagonal entry i of a (reduced with SumOp: the trace, for a relative shift).
struct DenseDiagonalValueTerm {
  const double* a = nullptr;
  int32_t n = 0;

  GF_HD double operator()(int32_t i) const { return a[int64_t(i) * n + i]; }
};

/// y_k /= L_kk, one item (forward substitution's column k).
struct ForwardPivotStage {
  const double* L = nullptr;
  double* y = nullptr;
  int32_t n = 0, k = 0;

  GF_HD void operator()(int32_t) const { y[k] /= L[int64_t(k) * n + k]; }
};

/// y_i -= L_ik y_k for i = k + 1 + t.
struct ForwardEliminateStage {
  const double* L = nullptr;
  double* y = nullptr;
  int32_t n = 0, k = 0;

  GF_HD void operator()(int32_t t) const {
    const int32_t i = k + 1 + t;
    y[i] -= L[int64_t(i) * n + k] * y[k];
  }
};

/// x_i -= (L^T)_ik x_k = L_ki x_k for i = t < k (backward substitution's column k).
struct BackwardEliminateStage {
  const double* L = nullptr;
  double* x = nullptr;
  int32_t n = 0, k = 0;

  GF_HD void operator()(int32_t i) const { x[i] -= L[int64_t(k) * n + i] * x[k]; }
};

/// Overwrites the lower triangle of a (n x n, row-major; the upper triangle is not read) with
/// L. False when A is not positive definite (the factor then holds NaN).
template <class Exec>
bool denseCholeskyFactor(const Exec& exec, int32_t n, double* a) {
  for (int32_t k = 0; k < n; ++k) {
    exec.run(1, 1, CholeskyPivotStage{a, n, k});
    exec.run(n - k - 1, 16, CholeskyColumnStage{a, n, k});
    exec.run(n - k - 1, 4, CholeskyUpdateStage{a, n, k});
  }
  return n == 0 || exec.template reduce<MaxOp>(n, DenseDiagonalTerm{a, n}) == 0.0;
}

/// x = A^-1 b = L^-T L^-1 b with the factor of denseCholeskyFactor; b and x must not overlap.
template <class Exec>
void denseCholeskySolve(const Exec& exec, int32_t n, const double* L, const double* b, double* x) {
  exec.run(n, 2048, CopyStage{b, x});
  for (int32_t k = 0; k < n; ++k) {
    exec.run(1, 1, ForwardPivotStage{L, x, n, k});
    exec.run(n - k - 1, 256, ForwardEliminateStage{L, x, n, k});
  }
  for (int32_t k = n - 1; k >= 0; --k) {
    exec.run(1, 1, ForwardPivotStage{L, x, n, k});
    exec.run(k, 256, BackwardEliminateStage{L, x, n, k});
  }
}

/// The coarsest multigrid level (12x12 blocks) factorised as MultigridSolver factorises it on
/// the host: unshifted first, then, while the factorisation fails, with a diagonal shift of
/// 1e-12, 1e-10, ... (six more tries, each added to the last) times the mean diagonal, which
/// keeps round-off below a regularised null direction from failing it. `dense` holds n^2
/// doubles (n = 12 rows). False when every try failed.
template <class Exec>
bool denseCholeskyFactorBlocks(const Exec& exec, int32_t rows, const int32_t* rowStart,
                               const int32_t* col, const double* values, double* dense) {
  const int32_t n = 12 * rows;
  const int64_t nn = int64_t(n) * n;
  if (nn > INT32_MAX) return false;
  double shift = 0, meanDiag = 0;
  for (int attempt = -1; attempt < 6; ++attempt) {
    if (attempt >= 0) shift += std::pow(100.0, attempt) * 1e-12 * meanDiag;
    exec.run(int32_t(nn), 2048, FillStage{0.0, dense});
    exec.run(rows, 4, DenseFromBlocksStage{rowStart, col, values, n, shift, dense});
    if (attempt < 0)
      meanDiag = exec.template reduce<SumOp>(n, DenseDiagonalValueTerm{dense, n}) / (n > 0 ? n : 1);
    if (denseCholeskyFactor(exec, n, dense)) return true;
  }
  return false;
}

}  // namespace gf::detail
