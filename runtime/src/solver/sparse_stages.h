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

/// Element blocks the assembly asks the cache for ahead of the one it adds (AssembleStage): its
/// time is the latency of the element matrices' lines (21 MB on a 29k-tet body, read in the
/// blocks' order), which the out-of-order core alone hides only a few entries deep. 32 halved
/// the stage's time on one core (docs/validation.md); ElementGather::entry carries that many
/// entries of padding past its end.
constexpr int32_t kGatherLookahead = 32;

/// A hint that the line at p will be read soon: a no-op in device code, whose warps hide the
/// latency among themselves.
GF_HD void prefetchLine(const void* p) {
#if defined(__CUDA_ARCH__)
  (void)p;
#else
  __builtin_prefetch(p);
#endif
}

/// values[k] = (accumulate ? values[k] : 0) + scale * (the element blocks that land in block k),
/// one block per item, summed in the gather list's fixed order (ElementGather). Element matrices
/// are stored as their upper node blocks (kElementMatrixSize per tet, kernels/math.h): a block
/// (a, b) with a > b is read as the transpose of block (b, a), which for a symmetric element
/// matrix is the same numbers. Each entry names the upper block and whether it is read
/// transposed. The stage also takes over passes that would each stream the whole matrix again,
/// with their bits: without accumulate it replaces a zeroing pass (0 + x, not x: a -0 sum stays
/// +0); `sum`, when set, receives the plain sum (0 + sum, what a gather with scale 1 into a
/// zeroed matrix writes); `addAfter`, when set, is added last as addScale * addAfter[k] (an axpy
/// over the values; it may be `sum` itself).
struct AssembleStage {
  const int32_t* start = nullptr;  ///< blockCount + 1 offsets into entry
  const int32_t* entry = nullptr;  ///< 2 * upper block + transposed (ElementGather)
  const double* elementMatrices = nullptr;
  double scale = 1;
  double* values = nullptr;
  bool accumulate = true;
  double* sum = nullptr;             ///< 9 per block, or null
  const double* addAfter = nullptr;  ///< 9 per block, or null
  double addScale = 0;

  GF_HD void operator()(int32_t k) const {
    double total[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    for (int32_t q = start[k]; q < start[k + 1]; ++q) {
      // A 9-double block spans at most two lines.
      const double* ahead = elementMatrices + 9 * int64_t(entry[q + kGatherLookahead] >> 1);
      prefetchLine(ahead);
      prefetchLine(ahead + 8);
      const int32_t c = entry[q];
      const double* m = elementMatrices + 9 * int64_t(c >> 1);
      const bool t = c & 1;
      total[0] += m[0];
      total[1] += t ? m[3] : m[1];
      total[2] += t ? m[6] : m[2];
      total[3] += t ? m[1] : m[3];
      total[4] += m[4];
      total[5] += t ? m[7] : m[5];
      total[6] += t ? m[2] : m[6];
      total[7] += t ? m[5] : m[7];
      total[8] += m[8];
    }
    const int64_t b = 9 * int64_t(k);
    for (int i = 0; i < 9; ++i) {
      if (sum) sum[b + i] = 0.0 + total[i];
      double v = (accumulate ? values[b + i] : 0.0) + scale * total[i];
      if (addAfter) v += addScale * addAfter[b + i];
      values[b + i] = v;
    }
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
