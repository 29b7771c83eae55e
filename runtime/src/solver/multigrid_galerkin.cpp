// Multigrid hierarchy, the numeric half: prolongator smoothing (smoothed aggregation, on the
// host: it runs after a set-up or a crack re-binding only), the Galerkin products A_{l+1} =
// P^T A_l P (galerkin_stages.h, on either executor) and the transfers P, P^T. The patterns
// these fill are built in multigrid_hierarchy.cpp; every product sums precomputed block pairs
// in a fixed order and every parallel loop writes disjoint blocks (the same bits for any
// thread count).
#include <algorithm>
#include <cmath>

#include "solver/galerkin_stages.h"
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
  const uint32_t handles = static_cast<uint32_t>(lv.ptStart.size()) - 1;
  forRanges(jobs, handles, kHandleGrain, [&](uint32_t begin, uint32_t end) {
    for (int32_t t = lv.ptStart[begin]; t < lv.ptStart[end]; ++t)
      std::copy_n(lv.pValues.data() + BC * static_cast<size_t>(lv.ptBlock[t]), BC,
                  lv.ptValues.data() + BC * static_cast<size_t>(t));
  });
  lv.prolongationFresh = true;
}

GalerkinLevelView MultigridHierarchy::galerkinView(int l) {
  CoarseLevel& lv = m_levels[static_cast<size_t>(l - 1)];
  GalerkinLevelView g;
  g.finerRows = static_cast<int32_t>(lv.qStart.size()) - 1;
  g.coarseRows = lv.A.n;
  g.P = prolongation(l - 1);
  g.qStart = lv.qStart.data();
  g.qcStart = lv.qcStart.data();
  g.qcA = lv.qcA.data();
  g.qcP = lv.qcP.data();
  g.qValues = lv.qValues.data();
  g.rowStart = lv.A.rowStart.data();
  g.col = lv.A.col.data();
  g.mirror = lv.mirror.data();
  g.gatherStart = lv.gatherStart.data();
  g.gatherP = lv.gatherP.data();
  g.gatherQ = lv.gatherQ.data();
  g.nullProjector = l == 1 ? lv.nullProjector.data() : nullptr;
  return g;
}

void MultigridHierarchy::assemble(const BlockSparseMatrix& A, JobSystem& jobs) {
  for (int l = 1; l <= coarseLevelCount(); ++l) {
    const bool fresh = m_levels[static_cast<size_t>(l - 1)].prolongationFresh;
    if (l == 1) {
      if (!fresh) smoothProlongation<3>(l, A, jobs);
      galerkinProduct<3>(CpuExecutor(jobs), galerkinView(l), A.values.data(),
                         m_levels[0].A.values.data());
    } else {
      if (!fresh) smoothProlongation<12>(l, A, jobs);
      galerkinProduct<12>(CpuExecutor(jobs), galerkinView(l),
                          m_levels[static_cast<size_t>(l - 2)].A.values.data(),
                          m_levels[static_cast<size_t>(l - 1)].A.values.data());
    }
  }
}

std::vector<CoarseLevelValues> MultigridHierarchy::values(bool operators) const {
  std::vector<CoarseLevelValues> out(m_levels.size());
  for (int l = 1; l <= coarseLevelCount(); ++l) {
    const CoarseLevel& lv = m_levels[static_cast<size_t>(l - 1)];
    CoarseLevelValues& v = out[static_cast<size_t>(l - 1)];
    if (operators) v.A = lv.A.values;
    if (smoothesLevel(l) && lv.prolongationFresh) {
      v.P = lv.pValues;
      v.omega = lv.omega;
      v.lambdaMax = lv.lambdaMax;
    }
  }
  return out;
}

bool MultigridHierarchy::setValues(const std::vector<CoarseLevelValues>& values) {
  if (values.size() != m_levels.size()) return false;
  for (size_t k = 0; k < m_levels.size(); ++k) {
    const CoarseLevel& lv = m_levels[k];
    const CoarseLevelValues& v = values[k];
    if ((!v.A.empty() && v.A.size() != lv.A.values.size()) ||
        (!v.P.empty() && v.P.size() != lv.pValues.size()))
      return false;
  }
  for (size_t k = 0; k < m_levels.size(); ++k) {
    CoarseLevel& lv = m_levels[k];
    const CoarseLevelValues& v = values[k];
    if (!v.A.empty()) lv.A.values = v.A;
    if (v.P.empty()) continue;
    lv.pValues = v.P;
    lv.omega = v.omega;
    lv.lambdaMax = v.lambdaMax;
    const size_t bc = static_cast<size_t>(k == 0 ? 3 : 12) * 12;
    for (size_t t = 0; t < lv.ptBlock.size(); ++t)
      std::copy_n(lv.pValues.data() + bc * static_cast<size_t>(lv.ptBlock[t]), bc,
                  lv.ptValues.data() + bc * t);
    lv.prolongationFresh = true;
  }
  return true;
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
  P.ptRow = lv.ptRow.data();
  P.ptValues = lv.ptValues.data();
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
