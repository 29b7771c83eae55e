// The multigrid's numeric set-up as stages (step/executor.h), run whenever the fine matrix's
// values changed: the coarse operators A_l = P^T A_{l-1} P (eq 6.4) and each level's diagonal
// inverses with its Gauss-Seidel copy in colour order. The patterns they fill come from
// multigrid_hierarchy.cpp. Each item writes only its own blocks and sums its terms in a fixed
// order: the same bits on every executor and thread count. B is the finer level's block size
// (3 below level 1, 12 deeper).
#pragma once

#include <cstdint>

#include "kernels/gf_hd.h"
#include "kernels/spd_block.h"
#include "solver/multigrid_stages.h"

namespace gf::detail {

/// out (B x C) += a (B x B) b (B x C).
template <int B, int C>
GF_HD void mulAdd(const double* a, const double* b, double* out) {
  for (int i = 0; i < B; ++i) {
    double* o = out + C * i;
    for (int m = 0; m < B; ++m) {
      const double am = a[B * i + m];
      if (am == 0) continue;
      const double* bm = b + C * m;
      for (int j = 0; j < C; ++j) o[j] += am * bm[j];
    }
  }
}

/// out (B x 12) += a (B x B) T_j, T_j the tentative block of finer row j (eq 6.6-6.8).
template <int B>
GF_HD void tentativeRight(const ProlongationView& T, const double* a, int32_t j, double* out) {
  if constexpr (B == 3) {
    const double* x = T.coord + 3 * int64_t(j);
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k) {
        const double v = a[3 * i + k];
        double* o = out + 12 * i;
        o[k] += x[0] * v;
        o[3 + k] += x[1] * v;
        o[6 + k] += x[2] * v;
        o[9 + k] += v;
      }
  } else {
    const double* d = T.childOffset + 3 * int64_t(j);
    const double ratio = T.childRatio;
    for (int i = 0; i < 12; ++i) {
      const double* ai = a + 12 * i;
      double* o = out + 12 * i;
      for (int c = 0; c < 9; ++c) o[c] += ratio * ai[c] + ai[9 + c % 3] * d[c / 3];
      for (int k = 0; k < 3; ++k) o[9 + k] += ai[9 + k];
    }
  }
}

/// out (12 x 12) += T_r^T q, q = Q_rK (B x 12), T_r the tentative block of finer row r.
template <int B>
GF_HD void tentativeLeft(const ProlongationView& T, int32_t r, const double* q, double* out) {
  if constexpr (B == 3) {
    const double* x = T.coord + 3 * int64_t(r);
    for (int k = 0; k < 3; ++k) {
      const double* qk = q + 12 * k;
      for (int a = 0; a < 3; ++a) {
        double* o = out + 12 * (3 * a + k);
        for (int c = 0; c < 12; ++c) o[c] += x[a] * qk[c];
      }
      double* o = out + 12 * (9 + k);
      for (int c = 0; c < 12; ++c) o[c] += qk[c];
    }
  } else {
    const double* d = T.childOffset + 3 * int64_t(r);
    const double ratio = T.childRatio;
    for (int j = 0; j < 9; ++j) {
      const double* qj = q + 12 * j;
      const double* qt = q + 12 * (9 + j % 3);
      double* o = out + 12 * j;
      for (int c = 0; c < 12; ++c) o[c] += ratio * qj[c] + d[j / 3] * qt[c];
    }
    for (int k = 0; k < 3; ++k) {
      const double* qk = q + 12 * (9 + k);
      double* o = out + 12 * (9 + k);
      for (int c = 0; c < 12; ++c) o[c] += qk[c];
    }
  }
}

/// What the coarse operator of one level is computed from besides the two matrices: P, the
/// pattern of Q = A_{l-1} P with the (A block, P block) pairs each Q block sums, and the
/// (P block, Q block) pairs of each block of A_l on or above the diagonal (the blocks below
/// mirror them). Built by MultigridHierarchy; host or device memory.
struct GalerkinLevelView {
  int32_t finerRows = 0, coarseRows = 0;
  ProlongationView P;
  const int32_t* qStart = nullptr;
  const int32_t* qcStart = nullptr;
  const int32_t* qcA = nullptr;
  const int32_t* qcP = nullptr;
  double* qValues = nullptr;          ///< B x 12 per Q block (scratch)
  const int32_t* rowStart = nullptr;  ///< A_l's pattern
  const int32_t* col = nullptr;
  const int32_t* mirror = nullptr;  ///< per block below the diagonal its transpose, else -1
  const int32_t* gatherStart = nullptr;
  const int32_t* gatherP = nullptr;
  const int32_t* gatherQ = nullptr;
  const double* nullProjector = nullptr;  ///< level 1: 16 per handle; deeper null
};

/// Q = A_{l-1} P (block-CSR like P), one finer row per item: each Q block sums its listed
/// (A block, P block) pairs. A tentative P is applied from its coordinates: a third of the
/// flops and none of P's memory.
template <int B>
struct GalerkinRightStage {
  GalerkinLevelView g;
  const double* finer = nullptr;  ///< A_{l-1}'s values, B x B blocks

  GF_HD void operator()(int32_t r) const {
    constexpr int BC = B * 12;
    const bool smoothed = g.P.kind == Prolongation::kSmoothed;
    for (int32_t q = g.qStart[r]; q < g.qStart[r + 1]; ++q) {
      double* out = g.qValues + BC * int64_t(q);
      for (int i = 0; i < BC; ++i) out[i] = 0;
      for (int32_t c = g.qcStart[q]; c < g.qcStart[q + 1]; ++c) {
        const double* a = finer + int64_t(B * B) * g.qcA[c];
        if (smoothed)
          mulAdd<B, 12>(a, g.P.pValues + BC * int64_t(g.qcP[c]), out);
        else
          tentativeRight<B>(g.P, a, g.P.pRow[g.qcP[c]], out);
      }
    }
  }
};

/// A_l = P^T Q on and above the diagonal (eq 6.4), one coarse row per item: each block sums its
/// (P block, Q block) pairs of one finer row each, rows increasing. On level 1 the diagonal
/// blocks also get the aggregate's near-null directions times the block's mean diagonal: P
/// maps them to zero, so A_l would be singular there, and no correction changes.
template <int B>
struct GalerkinLeftStage {
  GalerkinLevelView g;
  double* values = nullptr;  ///< A_l's, 144 per block

  GF_HD void operator()(int32_t h) const {
    constexpr int BC = B * 12;
    const bool smoothed = g.P.kind == Prolongation::kSmoothed;
    for (int32_t kc = g.rowStart[h]; kc < g.rowStart[h + 1]; ++kc) {
      if (g.mirror[kc] >= 0) continue;  // the lower triangle: GalerkinMirrorStage
      double out[144];
      for (int i = 0; i < 144; ++i) out[i] = 0;
      for (int32_t k = g.gatherStart[kc]; k < g.gatherStart[kc + 1]; ++k) {
        const double* qb = g.qValues + BC * int64_t(g.gatherQ[k]);
        if (!smoothed) {
          tentativeLeft<B>(g.P, g.P.pRow[g.gatherP[k]], qb, out);
          continue;
        }
        // out += P_rH^T Q_rK.
        const double* pb = g.P.pValues + BC * int64_t(g.gatherP[k]);
        for (int m = 0; m < B; ++m) {
          const double* pm = pb + 12 * m;
          const double* qm = qb + 12 * m;
          for (int i = 0; i < 12; ++i) {
            const double a = pm[i];
            if (a == 0) continue;
            double* o = out + 12 * i;
            for (int j = 0; j < 12; ++j) o[j] += a * qm[j];
          }
        }
      }
      if (g.nullProjector && g.col[kc] == h) {
        double trace = 0;
        for (int i = 0; i < 12; ++i) trace += out[13 * i];
        const double delta = trace > 0 && gf::isFinite(trace) ? trace / 12 : 1.0;
        const double* proj = g.nullProjector + 16 * int64_t(h);
        for (int a = 0; a < 4; ++a)
          for (int c = 0; c < 4; ++c)
            for (int i = 0; i < 3; ++i)
              out[(3 * a + i) * 12 + 3 * c + i] += delta * proj[4 * a + c];
      }
      double* dst = values + 144 * int64_t(kc);
      for (int i = 0; i < 144; ++i) dst[i] = out[i];
    }
  }
};

/// The blocks below A_l's diagonal as the transposes of those above: symmetric to the last bit.
struct GalerkinMirrorStage {
  const int32_t* rowStart = nullptr;
  const int32_t* mirror = nullptr;
  double* values = nullptr;

  GF_HD void operator()(int32_t h) const {
    for (int32_t kc = rowStart[h]; kc < rowStart[h + 1]; ++kc) {
      if (mirror[kc] < 0) continue;
      const double* src = values + 144 * int64_t(mirror[kc]);
      double* dst = values + 144 * int64_t(kc);
      for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j) dst[12 * i + j] = src[12 * j + i];
    }
  }
};

/// A_l = P^T A_{l-1} P (eq 6.4) from the finer level's values into the coarse level's.
template <int B, class Exec>
void galerkinProduct(const Exec& exec, const GalerkinLevelView& g, const double* finer,
                     double* coarse) {
  exec.run(g.finerRows, B == 3 ? 64 : 8, GalerkinRightStage<B>{g, finer});
  exec.run(g.coarseRows, 8, GalerkinLeftStage<B>{g, coarse});
  exec.run(g.coarseRows, 8, GalerkinMirrorStage{g.rowStart, g.mirror, coarse});
}

/// Item i: the inverse of a row's diagonal block (block-Jacobi part of every smoother). Without
/// a Gauss-Seidel copy (gsRowStart null) that is row i's; with one, position i of the copy in
/// colour order is filled and its row's inverse written.
///   A single-precision copy (level 0) rounds each entry by up to 2^-24 of itself. A node whose
/// diagonal block holds only its mass in some direction (an open crack, a free chip) has block
/// entries many orders larger, whose rounding alone then moves that direction's residual by
/// more than the diagonal can correct: the sweep diverges there, and the V-cycle, no longer
/// positive definite, broke CG down (r.z <= 0 after 2 iterations on the torn steel bar). So the
/// row's inverse is that of D + diag(s), s_k the summed rounding of row k of the block row: then
/// M + M^T - A~ >= D for the sweep M = D + diag(s) + L~ on the rounded A~ (Gershgorin), and the
/// symmetric V-cycle is positive definite whatever the rounding. A double copy has s = 0.
template <int B>
struct DiagonalSetupStage {
  const double* values = nullptr;  ///< the level's matrix, B x B blocks
  const int32_t* diagIndex = nullptr;
  double* invDiag = nullptr;
  const int32_t* gsRowStart = nullptr;
  const int32_t* gsBlock = nullptr;     ///< source block of each copied position
  const int32_t* colourRows = nullptr;  ///< row of each copied position
  GsValue<B>* gsValues = nullptr;

  GF_HD void operator()(int32_t i) const {
    constexpr int BB = B * B;
    if (!gsRowStart) {
      invertSpdBlock<B>(values + BB * int64_t(diagIndex[i]), invDiag + BB * int64_t(i));
      return;
    }
    const int32_t row = colourRows[i];
    double shift[B] = {};
    for (int32_t k = gsRowStart[i]; k < gsRowStart[i + 1]; ++k) {
      const double* src = values + BB * int64_t(gsBlock[k]);
      GsValue<B>* dst = gsValues + BB * int64_t(k);
      for (int a = 0; a < B; ++a) {
        double rounding = 0;
        for (int l = 0; l < B; ++l) {
          const GsValue<B> v = GsValue<B>(src[B * a + l]);
          dst[B * a + l] = v;
          rounding += fabs(double(v) - src[B * a + l]);
        }
        shift[a] += rounding;
      }
    }
    double diagonal[BB];
    const double* d = values + BB * int64_t(diagIndex[row]);
    for (int j = 0; j < BB; ++j) diagonal[j] = d[j];
    for (int a = 0; a < B; ++a) diagonal[a * B + a] += shift[a];
    invertSpdBlock<B>(diagonal, invDiag + BB * int64_t(row));
  }
};

}  // namespace gf::detail
