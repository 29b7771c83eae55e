// The block-sparse matrix's per-step work as stages (step/executor.h): assembly from element
// matrices, Dirichlet rows, the product and the block-Jacobi inverse, over flat buffers the CPU
// and the CUDA executor run alike. Each item writes only its own block or block row, in a fixed
// order, so the result has the same bits for any thread count and on either executor.
#pragma once

#include <cstdint>

#include "kernels/gf_hd.h"
#include "kernels/math.h"
#include "kernels/spd_block.h"
#include "solver/block_row.h"

namespace gf::detail {

/// A block-sparse matrix of 3x3 blocks (block_sparse.h) as raw pointers: block-CSR with the
/// full symmetric pattern, 9 row-major values per block.
struct BlockMatrixView {
  int32_t n = 0;
  const int32_t* rowStart = nullptr;
  const int32_t* col = nullptr;
  const double* values = nullptr;
};

/// Block of (r, r) in row r, or -1: the pattern's columns are sorted within a row.
GF_HD int32_t diagonalBlock(const BlockMatrixView& A, int32_t r) {
  int32_t lo = A.rowStart[r], hi = A.rowStart[r + 1];
  while (lo < hi) {
    const int32_t mid = lo + (hi - lo) / 2;
    if (A.col[mid] < r)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo < A.rowStart[r + 1] && A.col[lo] == r ? lo : -1;
}

/// y = A x, one block row per item. x and y must not alias.
struct SpmvStage {
  BlockMatrixView A;
  const double* x = nullptr;
  double* y = nullptr;

  GF_HD void operator()(int32_t r) const {
    blockRowProduct3(A.col, A.values, A.rowStart[r], A.rowStart[r + 1], x, y + 3 * int64_t(r));
  }
};

/// values[k] += scale * (the element blocks that land in block k), one block per item, summed
/// in the gather list's fixed order (ElementGather). Element matrices are stored as their upper
/// node blocks (kElementMatrixSize per tet, kernels/math.h): block (a, b) with a > b is read as
/// the transpose of block (b, a), which for a symmetric element matrix is the same numbers.
struct AssembleStage {
  const int32_t* start = nullptr;  ///< blockCount + 1 offsets into entry
  const int32_t* entry = nullptr;  ///< elem * 16 + a * 4 + b
  const double* elementMatrices = nullptr;
  double scale = 1;
  double* values = nullptr;

  GF_HD void operator()(int32_t k) const {
    double sum[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    for (int32_t q = start[k]; q < start[k + 1]; ++q) {
      const int32_t c = entry[q];
      const int32_t a = (c >> 2) & 3, b = c & 3;
      const double* m = elementMatrices + kElementMatrixSize * int64_t(c >> 4);
      if (a <= b) {
        m += upperBlockOffset(a, b);
        for (int i = 0; i < 9; ++i) sum[i] += m[i];
      } else {
        m += upperBlockOffset(b, a);
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) sum[3 * i + j] += m[3 * j + i];
      }
    }
    double* out = values + 9 * int64_t(k);
    for (int i = 0; i < 9; ++i) out[i] += scale * sum[i];
  }
};

/// Dirichlet nodes (fixedNode != 0): their block rows and columns zeroed and the identity on
/// their diagonal, which keeps A symmetric positive definite; one block row per item.
struct DirichletStage {
  const int32_t* rowStart = nullptr;
  const int32_t* col = nullptr;
  const uint8_t* fixedNode = nullptr;
  double* values = nullptr;

  GF_HD void operator()(int32_t r) const {
    for (int32_t k = rowStart[r]; k < rowStart[r + 1]; ++k) {
      const int32_t c = col[k];
      if (!fixedNode[r] && !fixedNode[c]) continue;
      double* m = values + 9 * int64_t(k);
      for (int i = 0; i < 9; ++i) m[i] = 0;
      if (r == c) m[0] = m[4] = m[8] = 1;
    }
  }
};

/// The block-Jacobi preconditioner: the inverse of each row's diagonal block (invertSpdBlock's
/// diagonal fallback where it is not SPD, the identity where the row has none), 9 per row.
struct BlockJacobiStage {
  BlockMatrixView A;
  double* invDiag = nullptr;

  GF_HD void operator()(int32_t r) const {
    double* inv = invDiag + 9 * int64_t(r);
    const int32_t k = diagonalBlock(A, r);
    if (k >= 0) {
      invertSpdBlock<3>(A.values + 9 * int64_t(k), inv);
      return;
    }
    for (int i = 0; i < 9; ++i) inv[i] = (i % 4 == 0) ? 1.0 : 0.0;
  }
};

}  // namespace gf::detail
