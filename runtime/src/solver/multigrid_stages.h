// The V-cycle's per-row work as stages (step/executor.h): the smoothers, the residual and the
// transfers between levels (eq 6.1, 6.3, 6.6-6.8), over flat buffers, so the CPU and the
// device executor run one source. Level 0 has 3x3 node blocks, deeper levels 12x12 handle
// blocks (B). Each item writes only its own row.
#pragma once

#include <cstdint>
#include <type_traits>

#include "kernels/gf_hd.h"
#include "solver/block_row.h"

namespace gf::detail {

/// A level's matrix: block-CSR of B x B row-major blocks of T.
template <int B, class T = double>
struct LevelMatrix {
  int32_t n = 0;
  const int32_t* rowStart = nullptr;
  const int32_t* col = nullptr;
  const T* values = nullptr;
};

/// The entries of a level's Gauss-Seidel copy: single precision on level 0, whose sweep is bound
/// by reading it from the cache (validation.md, issue 14 item 2); A_ij and A_ji round alike, so
/// the V-cycle stays symmetric. The handle levels keep double.
template <int B>
using GsValue = std::conditional_t<B == 3, float, double>;

/// out = (A x)_r for block row r.
template <int B, class T>
GF_HD void rowProduct(const LevelMatrix<B, T>& A, int32_t r, const double* x, double* out) {
  if constexpr (B == 3) {
    blockRowProduct3(A.col, A.values, A.rowStart[r], A.rowStart[r + 1], x, out);
  } else {
    static_assert(std::is_same_v<T, double>, "the handle levels' product reads doubles");
    for (int i = 0; i < B; ++i) out[i] = 0;
    for (int32_t k = A.rowStart[r]; k < A.rowStart[r + 1]; ++k) {
      const double* m = A.values + int64_t(B * B) * k;
      const double* xc = x + int64_t(B) * A.col[k];
      for (int i = 0; i < B; ++i) {
        double s = 0;
        for (int j = 0; j < B; ++j) s += m[B * i + j] * xc[j];
        out[i] += s;
      }
    }
  }
}

/// out = b_r - (A x)_r for block row r.
template <int B>
GF_HD void rowResidual(const LevelMatrix<B>& A, int32_t r, const double* b, const double* x,
                       double* out) {
  rowProduct<B>(A, r, x, out);
  for (int i = 0; i < B; ++i) out[i] = b[B * r + i] - out[i];
}

/// out = m v for a B x B block.
template <int B>
GF_HD void blockApply(const double* m, const double* v, double* out) {
  for (int i = 0; i < B; ++i) {
    double s = 0;
    for (int j = 0; j < B; ++j) s += m[B * i + j] * v[j];
    out[i] = s;
  }
}

/// out = A x, one block row per item.
template <int B>
struct LevelProductStage {
  LevelMatrix<B> A;
  const double* x = nullptr;
  double* out = nullptr;

  GF_HD void operator()(int32_t row) const { rowProduct<B>(A, row, x, out + B * row); }
};

/// out_i = M_i v_i with M_i the B x B block blocks[index[i]] (index null: blocks[i]).
template <int B>
struct BlockDiagonalApplyStage {
  const double* blocks = nullptr;
  const int32_t* index = nullptr;
  const double* v = nullptr;
  double* out = nullptr;

  GF_HD void operator()(int32_t i) const {
    const int64_t k = index ? index[i] : i;
    blockApply<B>(blocks + int64_t(B * B) * k, v + B * i, out + B * i);
  }
};

/// The power iterations' start: fixed and non-smooth, so deterministic and rich in the high
/// modes they look for.
struct PowerStartStage {
  double* v = nullptr;

  GF_HD void operator()(int32_t i) const { v[i] = 1.0 + 0.37 * double((int64_t(i) * 7919) % 13); }
};

/// r = b - A x, one block row per item.
template <int B>
struct LevelResidualStage {
  LevelMatrix<B> A;
  const double* b = nullptr;
  const double* x = nullptr;
  double* r = nullptr;

  GF_HD void operator()(int32_t row) const { rowResidual<B>(A, row, b, x, r + B * row); }
};

/// One colour of a block Gauss-Seidel sweep: x_row += D^-1 (b - A x)_row for the rows of the
/// colour (no two adjacent, so they update in parallel), read from the matrix's copy in colour
/// order (gs*) whose rows stream. Item q is the colour's q-th row.
template <int B>
struct GaussSeidelColourStage {
  const int32_t* colourRows = nullptr;  ///< row of each colour-ordered position
  const int32_t* gsRowStart = nullptr;  ///< the colour-ordered copy
  const int32_t* gsCol = nullptr;
  const GsValue<B>* gsValues = nullptr;
  const double* invDiag = nullptr;  ///< B x B per row
  const double* b = nullptr;
  double* x = nullptr;
  int32_t first = 0;  ///< the colour's first position

  GF_HD void operator()(int32_t q) const {
    const int32_t pos = first + q, row = colourRows[pos];
    double res[B], dx[B];
    rowProduct(LevelMatrix<B, GsValue<B>>{0, gsRowStart, gsCol, gsValues}, pos, x, res);
    for (int i = 0; i < B; ++i) res[i] = b[B * row + i] - res[i];
    blockApply<B>(invDiag + int64_t(B * B) * row, res, dx);
    for (int i = 0; i < B; ++i) x[B * row + i] += dx[i];
  }
};

/// d = keep d + scale D^-1 (b - A x), one block row per item: the damped-Jacobi correction
/// (keep 0, scale 1) and the Chebyshev recurrence's direction (Saad, Alg. 12.1).
template <int B>
struct JacobiDirectionStage {
  LevelMatrix<B> A;
  const double* invDiag = nullptr;
  const double* b = nullptr;
  const double* x = nullptr;
  double* d = nullptr;
  double keep = 0, scale = 1;

  GF_HD void operator()(int32_t row) const {
    double res[B], z[B];
    rowResidual<B>(A, row, b, x, res);
    blockApply<B>(invDiag + int64_t(B * B) * row, res, z);
    for (int i = 0; i < B; ++i) d[B * row + i] = keep * d[B * row + i] + scale * z[i];
  }
};

/// How a level's prolongator P maps coarse handles to its finer rows.
enum class Prolongation : int {
  kTentativeNodes,    ///< level 1, unsmoothed: x_i = T_h [x; 1] (eq 6.6)
  kTentativeHandles,  ///< deeper, unsmoothed: the coarser affine map from the finer origin (eq 6.8)
  kSmoothed,          ///< stored B x 12 blocks (eq 6.3)
};

/// The prolongator of one level as the transfers read it (MultigridHierarchy's CoarseLevel).
struct ProlongationView {
  Prolongation kind = Prolongation::kSmoothed;
  int blockRows = 3;                    ///< B: 3 from the fine level, 12 deeper
  const int32_t* pStart = nullptr;      ///< per finer row, its blocks
  const int32_t* pCol = nullptr;        ///< handle of each block
  const int32_t* pRow = nullptr;        ///< finer row of each block
  const double* pValues = nullptr;      ///< kSmoothed: B x 12 per block
  const int32_t* ptStart = nullptr;     ///< per handle, its blocks by increasing finer row
  const int32_t* ptRow = nullptr;       ///< finer row of each
  const double* ptValues = nullptr;     ///< kSmoothed: each one's B x 12 block, in this order
  const double* coord = nullptr;        ///< kTentativeNodes: 3 per fine node
  const double* childOffset = nullptr;  ///< kTentativeHandles: 3 per finer handle
  double childRatio = 1;
};

/// coarse_H = sum over its blocks of P_rH^T fine_r, rows increasing (eq 6.1); one handle per
/// item. The blocks are read from P's transposed copy, which streams per handle (gathering
/// them from P's rows took 2.6x the prolongation).
struct RestrictStage {
  ProlongationView P;
  const double* fine = nullptr;
  double* coarse = nullptr;

  GF_HD void operator()(int32_t h) const {
    double s[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    const int B = P.blockRows;
    for (int32_t t = P.ptStart[h]; t < P.ptStart[h + 1]; ++t) {
      const int64_t r = P.ptRow[t];
      const double* f = fine + B * r;
      if (P.kind == Prolongation::kTentativeNodes) {
        // U^T of a fine node: [x; 1] (x) r_i (eq 6.7).
        const double* x = P.coord + 3 * r;
        for (int a = 0; a < 3; ++a)
          for (int i = 0; i < 3; ++i) s[3 * a + i] += x[a] * f[i];
        for (int i = 0; i < 3; ++i) s[9 + i] += f[i];
      } else if (P.kind == Prolongation::kTentativeHandles) {
        // Transpose of eq 6.8's change of reference point.
        const double* d = P.childOffset + 3 * r;
        for (int a = 0; a < 3; ++a)
          for (int i = 0; i < 3; ++i) s[3 * a + i] += P.childRatio * f[3 * a + i] + d[a] * f[9 + i];
        for (int i = 0; i < 3; ++i) s[9 + i] += f[9 + i];
      } else {
        const double* pb = P.ptValues + int64_t(12 * B) * t;
        for (int m = 0; m < B; ++m) {
          const double fm = f[m];
          const double* pm = pb + 12 * m;
          for (int i = 0; i < 12; ++i) s[i] += pm[i] * fm;
        }
      }
    }
    for (int i = 0; i < 12; ++i) coarse[12 * int64_t(h) + i] = s[i];
  }
};

/// fine_r += sum over its blocks of P_rK coarse_K (eq 6.3); one finer row per item.
struct ProlongAddStage {
  ProlongationView P;
  const double* coarse = nullptr;
  double* fine = nullptr;

  GF_HD void operator()(int32_t r) const {
    const int B = P.blockRows;
    double* out = fine + int64_t(B) * r;
    for (int32_t p = P.pStart[r]; p < P.pStart[r + 1]; ++p) {
      const double* q = coarse + 12 * int64_t(P.pCol[p]);
      if (P.kind == Prolongation::kTentativeNodes) {
        // eq 6.6: x_i = T_h [x; 1].
        const double* x = P.coord + 3 * int64_t(r);
        for (int k = 0; k < 3; ++k)
          out[k] += x[0] * q[k] + x[1] * q[3 + k] + x[2] * q[6 + k] + q[9 + k];
      } else if (P.kind == Prolongation::kTentativeHandles) {
        // eq 6.8: the coarser affine map seen from the finer handle's origin.
        const double* d = P.childOffset + 3 * int64_t(r);
        for (int j = 0; j < 9; ++j) out[j] += P.childRatio * q[j];
        for (int k = 0; k < 3; ++k)
          out[9 + k] += d[0] * q[k] + d[1] * q[3 + k] + d[2] * q[6 + k] + q[9 + k];
      } else {
        const double* pb = P.pValues + int64_t(12 * B) * p;
        for (int m = 0; m < B; ++m) {
          double s = 0;
          for (int i = 0; i < 12; ++i) s += pb[12 * m + i] * q[i];
          out[m] += s;
        }
      }
    }
  }
};

}  // namespace gf::detail
