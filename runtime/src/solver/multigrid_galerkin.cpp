// Multigrid hierarchy, the numeric half: prolongator smoothing (smoothed aggregation), the
// Galerkin products A_{l+1} = P^T A_l P and the transfers P, P^T. The patterns these fill are
// built in multigrid_hierarchy.cpp; every product sums precomputed block pairs in a fixed
// order and every parallel loop writes disjoint blocks (the same bits for any thread count).
#include <algorithm>
#include <cmath>

#include "solver/multigrid_hierarchy.h"
#include "solver/vector_ops.h"
#include "step/executor.h"

namespace gf::detail {

namespace {

// Power iterations for rho(D^-1 A_F) of the prolongator smoothing.
constexpr int kPowerIterations = 10;
// Handles per parallel range of the coarse assembly and the transfers.
constexpr uint32_t kHandleGrain = 8;
constexpr uint32_t kNodeGrain = 256;

}  // namespace

namespace {

// The finer level's matrix values (B x B blocks, row-major) and its diagonal block per row.
template <int B>
struct FinerValues {
  const double* values = nullptr;
  const double* block(int32_t k) const { return values + static_cast<size_t>(B * B) * k; }
};

// out (B x C) = a (B x B) * b (B x C), or += with add.
template <int B, int C>
inline void mulAdd(const double* a, const double* b, double* out) {
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

// out (B x 12) += a (B x B) T_j, T_j the tentative block of finer row j (eq 6.6-6.8).
template <int B>
inline void tentativeRight(const CoarseLevel& lv, const double* a, int32_t j, double* out) {
  if constexpr (B == 3) {
    const double* x = lv.coord.data() + 3 * static_cast<size_t>(j);
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
    const double* d = lv.childOffset.data() + 3 * static_cast<size_t>(j);
    const double ratio = lv.childRatio;
    for (int i = 0; i < 12; ++i) {
      const double* ai = a + 12 * i;
      double* o = out + 12 * i;
      for (int c = 0; c < 9; ++c) o[c] += ratio * ai[c] + ai[9 + c % 3] * d[c / 3];
      for (int k = 0; k < 3; ++k) o[9 + k] += ai[9 + k];
    }
  }
}

// out (12 x 12) += T_r^T q, q = Q_rK (B x 12), T_r the tentative block of finer row r.
template <int B>
inline void tentativeLeft(const CoarseLevel& lv, int32_t r, const double* q, double* out) {
  if constexpr (B == 3) {
    const double* x = lv.coord.data() + 3 * static_cast<size_t>(r);
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
    const double* d = lv.childOffset.data() + 3 * static_cast<size_t>(r);
    const double ratio = lv.childRatio;
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

}  // namespace

// Smoothed aggregation (Vanek, Mandel & Brezina 1996): P = (I - omega D^-1 A_F) T with
// omega = 4 / (3 rho(D^-1 A_F)), which damps the high-energy part of each tentative basis
// function (the jumps at aggregate borders) while a near-null field T q (here an affine one)
// keeps |D^-1 A_F T q| small: P keeps the affine modes in the interior of a stiff body (A T q
// = 0 there up to the mass term). A_F drops the blocks across broken edges, so no basis
// function reaches across a crack.
template <int B>
void MultigridHierarchy::smoothProlongation(int l, const BlockSparseMatrix& A, JobSystem& jobs) {
  CoarseLevel& lv = m_levels[static_cast<size_t>(l - 1)];
  const FinerValues<B> F{B == 3 ? A.values.data()
                                : m_levels[static_cast<size_t>(l - 2)].A.values.data()};
  const int32_t rows = static_cast<int32_t>(lv.pStart.size()) - 1;
  const size_t len = static_cast<size_t>(B) * rows;
  constexpr int BB = B * B;
  constexpr int BC = B * 12;
  if (!smoothesLevel(l)) {
    forRanges(jobs, static_cast<uint32_t>(rows), kNodeGrain, [&](uint32_t begin, uint32_t end) {
      for (uint32_t r = begin; r < end; ++r)
        for (int32_t p = lv.pStart[r]; p < lv.pStart[r + 1]; ++p)
          tentativeBlock(l, static_cast<int32_t>(r),
                         lv.pValues.data() + BC * static_cast<size_t>(p));
    });
    lv.omega = 0;
    lv.prolongationFresh = true;
    return;
  }
  // D^-1: the diagonal blocks (fStart's first entry of each row).
  double* inv = m_invDiag.data();
  forRanges(jobs, static_cast<uint32_t>(rows), kHandleGrain, [&](uint32_t begin, uint32_t end) {
    for (uint32_t r = begin; r < end; ++r)
      invertSpdBlock<B>(F.block(lv.fBlock[lv.fStart[r]]), inv + BB * static_cast<size_t>(r));
  });
  // rho(D^-1 A_F) by power iteration with the Rayleigh quotient v.A_F v / v.D v from a fixed,
  // non-smooth start (deterministic; fixed-chunk reductions).
  double* v = m_v.data();
  double* w = m_w.data();
  double* t = m_t.data();
  for (size_t i = 0; i < len; ++i) v[i] = 1.0 + 0.37 * static_cast<double>((i * 7919) % 13);
  double lambda = 0;
  for (int it = 0; it < kPowerIterations; ++it) {
    forRanges(jobs, static_cast<uint32_t>(rows), kHandleGrain, [&](uint32_t begin, uint32_t end) {
      for (uint32_t r = begin; r < end; ++r) {
        double* wr = w + B * static_cast<size_t>(r);
        double* tr = t + B * static_cast<size_t>(r);
        std::fill(wr, wr + B, 0.0);
        std::fill(tr, tr + B, 0.0);
        for (int32_t f = lv.fStart[r]; f < lv.fStart[r + 1]; ++f) {
          mulAdd<B, 1>(F.block(lv.fBlock[f]), v + B * static_cast<size_t>(lv.fCol[f]), wr);
          if (f == lv.fStart[r])
            mulAdd<B, 1>(F.block(lv.fBlock[f]), v + B * static_cast<size_t>(r), tr);
        }
      }
    });
    const CpuExecutor exec(jobs, &m_partials);
    const double vav = exec.dot(v, w, int32_t(len));
    const double vdv = exec.dot(v, t, int32_t(len));
    if (!(vdv > 0) || !std::isfinite(vav)) break;
    lambda = vav / vdv;
    forRanges(jobs, static_cast<uint32_t>(rows), kHandleGrain, [&](uint32_t begin, uint32_t end) {
      for (uint32_t r = begin; r < end; ++r) {
        double* vr = v + B * static_cast<size_t>(r);
        std::fill(vr, vr + B, 0.0);
        mulAdd<B, 1>(inv + BB * static_cast<size_t>(r), w + B * static_cast<size_t>(r), vr);
      }
    });
    const double nv = std::sqrt(exec.dot(v, v, int32_t(len)));
    if (!(nv > 0) || !std::isfinite(nv)) break;
    const double s = 1 / nv;
    for (size_t i = 0; i < len; ++i) v[i] *= s;
  }
  lv.lambdaMax = lambda > 0 && std::isfinite(lambda) ? lambda : 0.0;
  lv.omega = lv.lambdaMax > 0 ? 4.0 / (3.0 * lv.lambdaMax) : 0.0;
  const double omega = lv.omega;
  const std::vector<int32_t>& parent = l == 1 ? lv.nodeHandle : lv.finerParent;
  // P_rK = [K = parent(r)] T_r - omega D_r^-1 sum_j A_rj T_j over the filtered j of parent K.
  forRanges(jobs, static_cast<uint32_t>(rows), B == 3 ? kNodeGrain / 4 : kHandleGrain,
            [&](uint32_t begin, uint32_t end) {
              double tj[BC], acc[BC];
              for (uint32_t r = begin; r < end; ++r) {
                for (int32_t p = lv.pStart[r]; p < lv.pStart[r + 1]; ++p) {
                  std::fill(acc, acc + BC, 0.0);
                  const int32_t K = lv.pCol[p];
                  for (int32_t s = lv.sStart[p]; s < lv.sStart[p + 1]; ++s) {
                    tentativeBlockFor(l, lv.sRow[s], K, tj);
                    mulAdd<B, 12>(F.block(lv.sBlock[s]), tj, acc);
                  }
                  double* out = lv.pValues.data() + BC * static_cast<size_t>(p);
                  tentativeBlock(l, static_cast<int32_t>(r), out);
                  if (K != parent[r]) std::fill(out, out + BC, 0.0);
                  double corr[BC] = {};
                  mulAdd<B, 12>(inv + BB * static_cast<size_t>(r), acc, corr);
                  for (int i = 0; i < BC; ++i) out[i] -= omega * corr[i];
                }
              }
            });
  lv.prolongationFresh = true;
}

// A_l = P^T (A_{l-1} P) (eq 6.4): Q row by row, then each coarse block from its listed pairs.
template <int B>
void MultigridHierarchy::galerkin(int l, const BlockSparseMatrix& A, JobSystem& jobs) {
  CoarseLevel& lv = m_levels[static_cast<size_t>(l - 1)];
  const FinerValues<B> F{B == 3 ? A.values.data()
                                : m_levels[static_cast<size_t>(l - 2)].A.values.data()};
  constexpr int BC = B * 12;
  // A tentative P (one structured block per row, eq 6.6-6.8) is applied from its coordinates:
  // a third of the flops and none of P's memory.
  const bool tentative = !smoothesLevel(l);
  const int32_t rows = static_cast<int32_t>(lv.qStart.size()) - 1;
  forRanges(jobs, static_cast<uint32_t>(rows), B == 3 ? kNodeGrain / 4 : kHandleGrain,
            [&](uint32_t begin, uint32_t end) {
              for (uint32_t r = begin; r < end; ++r)
                for (int32_t q = lv.qStart[r]; q < lv.qStart[r + 1]; ++q) {
                  double* out = lv.qValues.data() + BC * static_cast<size_t>(q);
                  std::fill(out, out + BC, 0.0);
                  for (int32_t c = lv.qcStart[q]; c < lv.qcStart[q + 1]; ++c) {
                    if (tentative) {
                      tentativeRight<B>(lv, F.block(lv.qcA[c]), lv.pRow[lv.qcP[c]], out);
                    } else {
                      mulAdd<B, 12>(F.block(lv.qcA[c]),
                                    lv.pValues.data() + BC * static_cast<size_t>(lv.qcP[c]), out);
                    }
                  }
                }
            });
  CoarseMatrix& C = lv.A;
  forRanges(jobs, static_cast<uint32_t>(C.n), kHandleGrain, [&](uint32_t begin, uint32_t end) {
    for (uint32_t h = begin; h < end; ++h) {
      for (int32_t kc = C.rowStart[h]; kc < C.rowStart[h + 1]; ++kc) {
        if (lv.mirror[kc] >= 0) continue;  // the lower triangle, below
        double out[144] = {};
        for (int32_t g = lv.gatherStart[kc]; g < lv.gatherStart[kc + 1]; ++g) {
          const double* pb = lv.pValues.data() + BC * static_cast<size_t>(lv.gatherP[g]);
          const double* qb = lv.qValues.data() + BC * static_cast<size_t>(lv.gatherQ[g]);
          if (tentative) {
            tentativeLeft<B>(lv, lv.pRow[lv.gatherP[g]], qb, out);
            continue;
          }
          // out += P_rH^T Q_rK.
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
        if (l == 1 && C.col[kc] == static_cast<int32_t>(h)) {
          // Null directions of the aggregate get the block's mean diagonal (see nullProjector).
          double trace = 0;
          for (int i = 0; i < 12; ++i) trace += out[13 * i];
          const double delta = trace > 0 && std::isfinite(trace) ? trace / 12 : 1.0;
          const double* proj = lv.nullProjector.data() + 16 * static_cast<size_t>(h);
          for (int a = 0; a < 4; ++a)
            for (int c = 0; c < 4; ++c)
              for (int i = 0; i < 3; ++i)
                out[(3 * a + i) * 12 + 3 * c + i] += delta * proj[4 * a + c];
        }
        std::copy(out, out + 144, C.block(kc));
      }
    }
  });
  // The lower triangle is the transpose of the upper: A_l is symmetric to the last bit.
  forRanges(jobs, static_cast<uint32_t>(C.n), kHandleGrain, [&](uint32_t begin, uint32_t end) {
    for (uint32_t h = begin; h < end; ++h)
      for (int32_t kc = C.rowStart[h]; kc < C.rowStart[h + 1]; ++kc) {
        if (lv.mirror[kc] < 0) continue;
        const double* src = C.block(lv.mirror[kc]);
        double* dst = C.block(kc);
        for (int i = 0; i < 12; ++i)
          for (int j = 0; j < 12; ++j) dst[12 * i + j] = src[12 * j + i];
      }
  });
}

void MultigridHierarchy::assemble(const BlockSparseMatrix& A, JobSystem& jobs) {
  for (int l = 1; l <= coarseLevelCount(); ++l) {
    const bool fresh = m_levels[static_cast<size_t>(l - 1)].prolongationFresh;
    if (l == 1) {
      if (!fresh) smoothProlongation<3>(l, A, jobs);
      galerkin<3>(l, A, jobs);
    } else {
      if (!fresh) smoothProlongation<12>(l, A, jobs);
      galerkin<12>(l, A, jobs);
    }
  }
}

ProlongationView MultigridHierarchy::prolongation(int level) const {
  const CoarseLevel& lv = m_levels[static_cast<size_t>(level)];
  ProlongationView P;
  P.kind = smoothesLevel(level + 1) ? Prolongation::kSmoothed
           : level == 0             ? Prolongation::kTentativeNodes
                                    : Prolongation::kTentativeHandles;
  P.blockRows = level == 0 ? 3 : 12;
  P.pStart = lv.pStart.data();
  P.pCol = lv.pCol.data();
  P.pRow = lv.pRow.data();
  P.pValues = lv.pValues.data();
  P.ptStart = lv.ptStart.data();
  P.ptBlock = lv.ptBlock.data();
  P.coord = lv.coord.data();
  P.childOffset = lv.childOffset.data();
  P.childRatio = lv.childRatio;
  return P;
}

void MultigridHierarchy::restrictTo(int level, const double* fine, double* coarse,
                                    JobSystem& jobs) const {
  const int32_t handles =
      static_cast<int32_t>(m_levels[static_cast<size_t>(level)].handleNode.size());
  CpuExecutor(jobs).run(handles, kHandleGrain, RestrictStage{prolongation(level), fine, coarse});
}

void MultigridHierarchy::prolongAdd(int level, const double* coarse, double* fine,
                                    JobSystem& jobs) const {
  const int32_t rows = static_cast<int32_t>(m_levels[static_cast<size_t>(level)].pStart.size()) - 1;
  CpuExecutor(jobs).run(rows, level == 0 ? kNodeGrain : kHandleGrain * 8,
                        ProlongAddStage{prolongation(level), coarse, fine});
}

}  // namespace gf::detail
