// Galerkin multigrid V-cycles and flexible CG (thesis sec 6.2, eq 6.1-6.4).
//
// Design: level 0 is the fine 3x3-block matrix, levels 1..L the 12x12-block Galerkin operators;
// the smoothers are written once for both block sizes. Every pass writes disjoint rows (the
// Gauss-Seidel sweeps go colour by colour of a greedy colouring, so a colour's rows never
// touch each other) and every reduction uses the fixed chunks of vector_ops.h: the same bits
// for any thread count. Symmetry: pre-smoothing runs forward Gauss-Seidel, post-smoothing the
// same number of backward sweeps, Jacobi and Chebyshev are symmetric polynomials, and the coarse
// solve is an exact Cholesky of an SPD matrix, so with preSweeps == postSweeps the V-cycle is
// an SPD preconditioner. CG still uses the flexible (Polak-Ribiere) beta, one extra dot per
// iteration, so unequal sweep counts cannot break it.
// Gauss-Seidel sweeps read a copy of each level's matrix stored in colour order (refreshed with
// the diagonal inverses, one streaming pass): a colour's rows lie scattered through the whole
// matrix, and sweeping them in place ran at a quarter of a product's speed at 160k tets.
// The coarsest level is factorised by a sparse LL^T (CHOLMOD's supernodal one when the build
// has it, about 20x faster at a thousand handles, else Eigen's simplicial one): elongated
// bodies give banded coarse graphs, and fragments that gain handles after cracks give
// block-diagonal ones, which a dense factor would pay for in full. Neither depends on the
// JobSystem's thread count.
#include "solver/multigrid.h"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "solver/cholesky.h"
#if GF_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#endif
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "solver/pcg_stages.h"
#include "solver/vector_ops.h"
#include "step/executor.h"
#include "step/timing.h"

namespace gf::detail {

namespace {

// Power iterations for the largest eigenvalue of D^-1 A, and the margin put on the estimate
// (the Rayleigh quotient approaches it from below).
constexpr int kPowerIterations = 12;
constexpr double kLambdaMargin = 1.1;
// Chebyshev targets [kChebyshevLow, 1] x lambda_max: the upper part of the spectrum, which the
// coarse levels do not represent (the interval PETSc's Chebyshev smoother uses).
constexpr double kChebyshevLow = 0.1;

// A level's block-CSR matrix, block size B.
// Entries per parallel range of an element-wise vector pass.
constexpr uint32_t kEntryGrain = 2048;

// Rows per parallel range for a level of block size B: a few thousand flops each.
template <int B>
constexpr uint32_t rowGrain() {
  return B == 3 ? 128 : 8;
}

// Smoother data of one level: inverse diagonal blocks, colouring, spectral bound, work vectors.
struct Level {
  int blockSize = 3;
  int32_t n = 0;
  std::vector<double> invDiag;
  std::vector<int32_t> diagIndex;
  std::vector<int32_t> colourStart, colourRows;
  // Gauss-Seidel's copy of the matrix in colour order: row q of it is row colourRows[q], so a
  // colour's sweep streams its blocks (a sweep over rows scattered through the whole matrix
  // defeats the prefetcher: 4-5x a product's time at 160k tets). gsBlock: the source block.
  std::vector<int32_t> gsRowStart, gsCol, gsBlock;
  std::vector<double> gsValues;
  double lambdaMax = 2;
  std::vector<double> b, x, r, t;  // rhs, iterate, residual, temporary (B n each)
};

// Greedy colouring in row order: adjacent rows never share a colour.
void colour(int32_t n, const int32_t* rowStart, const int32_t* col, Level& lv) {
  std::vector<int32_t> c(static_cast<size_t>(n), -1);
  std::vector<int32_t> seen;
  int32_t colours = 0;
  for (int32_t r = 0; r < n; ++r) {
    for (int32_t k = rowStart[r]; k < rowStart[r + 1]; ++k) {
      const int32_t cc = c[col[k]];
      if (cc >= 0) {
        if (static_cast<size_t>(cc) >= seen.size()) seen.resize(static_cast<size_t>(cc) + 1, -1);
        seen[cc] = r;
      }
    }
    int32_t pick = 0;
    while (static_cast<size_t>(pick) < seen.size() && seen[pick] == r) ++pick;
    c[r] = pick;
    colours = std::max(colours, pick + 1);
  }
  lv.colourStart.assign(static_cast<size_t>(colours) + 1, 0);
  for (int32_t r = 0; r < n; ++r) ++lv.colourStart[c[r] + 1];
  for (int32_t k = 0; k < colours; ++k) lv.colourStart[k + 1] += lv.colourStart[k];
  lv.colourRows.resize(static_cast<size_t>(n));
  std::vector<int32_t> fill(lv.colourStart.begin(), lv.colourStart.end() - 1);
  for (int32_t r = 0; r < n; ++r) lv.colourRows[fill[c[r]]++] = r;
}

}  // namespace

struct MultigridSolver::Impl {
  MultigridSettings settings;
  MultigridHierarchy hierarchy;
  MultigridStats stats;
  std::vector<double> cycleResiduals;
  std::vector<Level> levels;  // 0 = fine
  int32_t fineBlocks = -1;
  int solvesSinceRefresh = 0;
  bool needRefresh = true;
  bool patternsChanged = true;
  std::vector<double> partials;

  // Coarsest level: lower triangle of its scalar expansion and the map into its values.
  using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
  SpMat coarseLower;
  std::vector<int64_t> coarseMap;
#if GF_HAVE_CHOLMOD
  Eigen::CholmodSupernodalLLT<SpMat, Eigen::Lower> coarseLlt;
#else
  Eigen::SimplicialLLT<SpMat, Eigen::Lower, Eigen::AMDOrdering<int> > coarseLlt;
#endif
  bool coarseOk = false;

  // CG vectors (3 n each).
  std::vector<double> r, z, p, ap, rOld;

  int coarseCount() const { return hierarchy.coarseLevelCount(); }

  template <int B>
  LevelMatrix<B> matrix(int l, const BlockSparseMatrix& A) const {
    LevelMatrix<B> m;
    if constexpr (B == 3) {
      (void)l;
      m.n = A.n;
      m.rowStart = A.rowStart.data();
      m.col = A.col.data();
      m.values = A.values.data();
    } else {
      const CoarseMatrix& C = hierarchy.level(l).A;
      m.n = C.n;
      m.rowStart = C.rowStart.data();
      m.col = C.col.data();
      m.values = C.values.data();
    }
    return m;
  }

  void buildLevels(const BlockSparseMatrix& A) {
    levels.assign(static_cast<size_t>(coarseCount()) + 1, Level{});
    for (int l = 0; l <= coarseCount(); ++l) {
      Level& lv = levels[static_cast<size_t>(l)];
      const int B = l == 0 ? 3 : 12;
      const int32_t n = l == 0 ? A.n : hierarchy.level(l).A.n;
      const int32_t* rs = l == 0 ? A.rowStart.data() : hierarchy.level(l).A.rowStart.data();
      const int32_t* cl = l == 0 ? A.col.data() : hierarchy.level(l).A.col.data();
      lv.blockSize = B;
      lv.n = n;
      lv.invDiag.assign(static_cast<size_t>(B * B) * n, 0.0);
      lv.diagIndex.resize(static_cast<size_t>(n));
      for (int32_t row = 0; row < n; ++row)
        lv.diagIndex[row] = l == 0 ? A.diagonal(row) : hierarchy.level(l).A.find(row, row);
      colour(n, rs, cl, lv);
      lv.gsRowStart.assign(1, 0);
      lv.gsCol.clear();
      lv.gsBlock.clear();
      lv.gsValues.clear();
      if (settings.smoother == Smoother::GaussSeidel) {
        for (int32_t q = 0; q < n; ++q) {
          const int32_t row = lv.colourRows[q];
          for (int32_t k = rs[row]; k < rs[row + 1]; ++k) {
            lv.gsCol.push_back(cl[k]);
            lv.gsBlock.push_back(k);
          }
          lv.gsRowStart.push_back(static_cast<int32_t>(lv.gsCol.size()));
        }
        lv.gsValues.assign(lv.gsBlock.size() * static_cast<size_t>(B * B), 0.0);
      }
      const size_t len = static_cast<size_t>(B) * n;
      lv.b.assign(len, 0.0);
      lv.x.assign(len, 0.0);
      lv.r.assign(len, 0.0);
      lv.t.assign(len, 0.0);
    }
    stats.handles.clear();
    for (int l = coarseCount(); l >= 1; --l) stats.handles.push_back(hierarchy.handleCount(l));
    buildCoarsestPattern();
    patternsChanged = false;
  }

  // Column 12c + j of the scalar expansion holds rows 12r + i >= 12c + j of blocks (r, c).
  void buildCoarsestPattern() {
    coarseMap.clear();
    coarseOk = false;
    if (coarseCount() == 0) return;
    const CoarseMatrix& C = hierarchy.level(coarseCount()).A;
    const int64_t size = 12 * static_cast<int64_t>(C.n);
    coarseLower.resize(size, size);
    coarseLower.resizeNonZeros(0);
    coarseLower.reserve(static_cast<int64_t>(C.col.size()) * 72 + 12 * C.n);
    for (int32_t c = 0; c < C.n; ++c)
      for (int j = 0; j < 12; ++j) {
        coarseLower.startVec(12 * c + j);
        for (int32_t k = C.rowStart[c]; k < C.rowStart[c + 1]; ++k) {
          const int32_t rr = C.col[k];
          if (rr < c) continue;
          const int64_t blk = C.find(rr, c);
          for (int i = 0; i < 12; ++i) {
            if (rr == c && i < j) continue;
            coarseLower.insertBack(12 * rr + i, 12 * c + j) = 0.0;
            coarseMap.push_back(144 * blk + 12 * i + j);
          }
        }
      }
    coarseLower.finalize();
#if GF_HAVE_CHOLMOD
    coarseLlt.cholmod().print = 0;  // a failed factorisation is retried below, not printed
#endif
    blasOnOneThread();
    const SerialOpenMpScope serial;
    if (coarseLower.cols() > 0) coarseLlt.analyzePattern(coarseLower);
  }

  void factorCoarsest() {
    coarseOk = false;
    if (coarseCount() == 0 || coarseLower.cols() == 0) return;
    const CoarseMatrix& C = hierarchy.level(coarseCount()).A;
    double* v = coarseLower.valuePtr();
    for (size_t i = 0; i < coarseMap.size(); ++i) v[i] = C.values[coarseMap[i]];
    const SerialOpenMpScope serial;
    coarseLlt.factorize(coarseLower);
    // Round-off can leave a regularised null direction a hair below zero: retry with a growing
    // diagonal shift (still SPD, so the V-cycle stays symmetric positive definite).
    double meanDiag = 0;
    for (int64_t i = 0; i < coarseLower.cols(); ++i) meanDiag += coarseLower.coeff(i, i);
    meanDiag /= std::max<int64_t>(1, coarseLower.cols());
    for (int attempt = 0; coarseLlt.info() != Eigen::Success && attempt < 6; ++attempt) {
      const double shift = std::pow(100.0, attempt) * 1e-12 * meanDiag;
      for (int64_t i = 0; i < coarseLower.cols(); ++i) coarseLower.coeffRef(i, i) += shift;
      coarseLlt.factorize(coarseLower);
    }
    coarseOk = coarseLlt.info() == Eigen::Success;
  }

  template <int B>
  void invertDiagonals(int l, const BlockSparseMatrix& A, JobSystem& jobs) {
    Level& lv = levels[static_cast<size_t>(l)];
    const LevelMatrix<B> m = matrix<B>(l, A);
    const bool gs = !lv.gsValues.empty();
    forRanges(jobs, static_cast<uint32_t>(lv.n), rowGrain<B>(), [&](uint32_t begin, uint32_t end) {
      for (uint32_t row = begin; row < end; ++row)
        invertSpdBlock<B>(m.values + static_cast<size_t>(B * B) * lv.diagIndex[row],
                          lv.invDiag.data() + static_cast<size_t>(B * B) * row);
      // The colour-ordered copy, position by position (q indexes the copy's rows).
      for (uint32_t q = begin; gs && q < end; ++q)
        for (int32_t k = lv.gsRowStart[q]; k < lv.gsRowStart[q + 1]; ++k)
          std::copy_n(m.values + static_cast<size_t>(B * B) * lv.gsBlock[k], B * B,
                      lv.gsValues.data() + static_cast<size_t>(B * B) * k);
    });
  }

  // Largest eigenvalue of D^-1 A by power iteration with the Rayleigh quotient v.Av / v.Dv.
  template <int B>
  void estimateLambda(int l, const BlockSparseMatrix& A, JobSystem& jobs) {
    Level& lv = levels[static_cast<size_t>(l)];
    const LevelMatrix<B> m = matrix<B>(l, A);
    const size_t len = static_cast<size_t>(B) * lv.n;
    double* v = lv.x.data();
    double* w = lv.r.data();
    // A fixed, non-smooth start vector: deterministic and rich in the high modes sought.
    for (size_t i = 0; i < len; ++i) v[i] = 1.0 + 0.37 * static_cast<double>((i * 7919) % 13);
    double lambda = 0;
    for (int it = 0; it < kPowerIterations; ++it) {
      forRanges(jobs, static_cast<uint32_t>(lv.n), rowGrain<B>(),
                [&](uint32_t begin, uint32_t end) {
                  for (uint32_t row = begin; row < end; ++row)
                    rowProduct<B>(m, static_cast<int32_t>(row), v, w + B * row);
                });
      const CpuExecutor exec(jobs, &partials);
      const double vav = exec.dot(v, w, int32_t(len));
      double* t = lv.t.data();
      forRanges(jobs, static_cast<uint32_t>(lv.n), rowGrain<B>(),
                [&](uint32_t begin, uint32_t end) {
                  for (uint32_t row = begin; row < end; ++row)
                    blockApply<B>(m.values + static_cast<size_t>(B * B) * lv.diagIndex[row],
                                  v + B * row, t + B * row);
                });
      const double vdv = exec.dot(v, t, int32_t(len));
      if (!(vdv > 0) || !std::isfinite(vav)) break;
      lambda = vav / vdv;
      // v = D^-1 A v, normalised.
      forRanges(jobs, static_cast<uint32_t>(lv.n), rowGrain<B>(),
                [&](uint32_t begin, uint32_t end) {
                  for (uint32_t row = begin; row < end; ++row)
                    blockApply<B>(lv.invDiag.data() + static_cast<size_t>(B * B) * row, w + B * row,
                                  v + B * row);
                });
      const double nv = std::sqrt(exec.dot(v, v, int32_t(len)));
      if (!(nv > 0) || !std::isfinite(nv)) break;
      exec.run(int32_t(len), kEntryGrain, ScaleStage{1 / nv, v});
    }
    lv.lambdaMax = lambda > 0 && std::isfinite(lambda) ? kLambdaMargin * lambda : 2.0;
  }

  void refresh(const BlockSparseMatrix& A, JobSystem& jobs) {
    auto t0 = Clock::now();
    hierarchy.assemble(A, jobs);
    stats.galerkinMs = msSince(t0);
    for (int l = 1; l <= coarseCount(); ++l) invertDiagonals<12>(l, A, jobs);
    if (settings.smoother != Smoother::GaussSeidel) {
      estimateLambda<3>(0, A, jobs);
      for (int l = 1; l < coarseCount(); ++l) estimateLambda<12>(l, A, jobs);
    }
    t0 = Clock::now();
    factorCoarsest();
    stats.factorMs = msSince(t0);
    stats.coarseFactorOk = coarseOk || coarseCount() == 0;
  }

  // `sweeps` smoothing steps on level l; forward selects the Gauss-Seidel colour order.
  template <int B>
  void smooth(int l, const BlockSparseMatrix& A, const double* b, double* x, int sweeps,
              bool forward, JobSystem& jobs) {
    if (sweeps <= 0) return;
    Level& lv = levels[static_cast<size_t>(l)];
    const LevelMatrix<B> m = matrix<B>(l, A);
    const double* inv = lv.invDiag.data();
    const uint32_t grain = rowGrain<B>();
    const CpuExecutor exec(jobs);
    switch (settings.smoother) {
      case Smoother::GaussSeidel: {
        const int32_t colours = static_cast<int32_t>(lv.colourStart.size()) - 1;
        GaussSeidelColourStage<B> sweep{lv.colourRows.data(),
                                        lv.gsRowStart.data(),
                                        lv.gsCol.data(),
                                        lv.gsValues.data(),
                                        inv,
                                        b,
                                        x,
                                        0};
        for (int s = 0; s < sweeps; ++s)
          for (int32_t cc = 0; cc < colours; ++cc) {
            const int32_t c = forward ? cc : colours - 1 - cc;
            sweep.first = lv.colourStart[c];
            exec.run(lv.colourStart[c + 1] - sweep.first, grain, sweep);
          }
        break;
      }
      case Smoother::Jacobi: {
        // Damping 4 / (3 lambda_max) of D^-1 A: 2/3 at the classic lambda_max = 2.
        const double omega = 4.0 / (3.0 * lv.lambdaMax);
        double* t = lv.t.data();
        const int32_t len = B * lv.n;
        for (int s = 0; s < sweeps; ++s) {
          exec.run(lv.n, grain, JacobiDirectionStage<B>{m, inv, b, x, t, 0.0, 1.0});
          exec.run(len, 2048, AxpyStage{x, t, omega, x});
        }
        break;
      }
      case Smoother::Chebyshev: {
        // Chebyshev iteration (Saad, Alg. 12.1) on D^-1 A over [low, high]; degree = sweeps.
        const double high = lv.lambdaMax, low = kChebyshevLow * lv.lambdaMax;
        const double theta = 0.5 * (high + low), delta = 0.5 * (high - low);
        const double sigma = theta / delta;
        double rho = 1 / sigma;
        double* d = lv.t.data();
        const int32_t len = B * lv.n;
        exec.run(lv.n, grain, JacobiDirectionStage<B>{m, inv, b, x, d, 0.0, 1 / theta});
        for (int k = 1;; ++k) {
          exec.run(len, 2048, AxpyStage{x, d, 1.0, x});
          if (k == sweeps) break;
          const double rhoNew = 1 / (2 * sigma - rho);
          exec.run(lv.n, grain,
                   JacobiDirectionStage<B>{m, inv, b, x, d, rhoNew * rho, 2 * rhoNew / delta});
          rho = rhoNew;
        }
        break;
      }
    }
  }

  template <int B>
  void residual(int l, const BlockSparseMatrix& A, const double* b, const double* x, double* r,
                JobSystem& jobs) {
    const LevelMatrix<B> m = matrix<B>(l, A);
    CpuExecutor(jobs).run(m.n, rowGrain<B>(), LevelResidualStage<B>{m, b, x, r});
  }

  // x = V b on level l (x is overwritten; eq 6.1-6.3).
  template <int B>
  void cycle(int l, const BlockSparseMatrix& A, const double* b, double* x, JobSystem& jobs) {
    const int L = coarseCount();
    const size_t len = static_cast<size_t>(B) * levels[static_cast<size_t>(l)].n;
    if (l == L && L > 0) {
      auto t0 = Clock::now();
      if (coarseOk) {
        Eigen::Map<const Eigen::VectorXd> bm(b, static_cast<Eigen::Index>(len));
        Eigen::Map<Eigen::VectorXd> xm(x, static_cast<Eigen::Index>(len));
        const SerialOpenMpScope serial;
        xm = coarseLlt.solve(bm);
        if (!allFinite(x, len)) CpuExecutor(jobs).run(int32_t(len), kEntryGrain, FillStage{0.0, x});
      } else {
        CpuExecutor(jobs).run(int32_t(len), kEntryGrain, FillStage{0.0, x});
      }
      stats.coarseSolveMs += msSince(t0);
      return;
    }
    CpuExecutor(jobs).run(int32_t(len), kEntryGrain, FillStage{0.0, x});
    if (L == 0) {
      auto t0 = Clock::now();
      smooth<B>(l, A, b, x, settings.preSweeps, true, jobs);
      smooth<B>(l, A, b, x, settings.postSweeps, false, jobs);
      stats.smoothMs += msSince(t0);
      return;
    }
    Level& lv = levels[static_cast<size_t>(l)];
    Level& next = levels[static_cast<size_t>(l) + 1];
    auto t0 = Clock::now();
    smooth<B>(l, A, b, x, settings.preSweeps, true, jobs);
    stats.smoothMs += msSince(t0);
    t0 = Clock::now();
    residual<B>(l, A, b, x, lv.r.data(), jobs);
    hierarchy.restrictTo(l, lv.r.data(), next.b.data(), jobs);  // eq 6.1
    stats.transferMs += msSince(t0);
    cycle<12>(l + 1, A, next.b.data(), next.x.data(), jobs);
    t0 = Clock::now();
    hierarchy.prolongAdd(l, next.x.data(), x, jobs);  // eq 6.3
    stats.transferMs += msSince(t0);
    t0 = Clock::now();
    smooth<B>(l, A, b, x, settings.postSweeps, false, jobs);
    stats.smoothMs += msSince(t0);
  }
};

MultigridSolver::MultigridSolver() : m_impl(std::make_unique<Impl>()) {}
MultigridSolver::~MultigridSolver() = default;
MultigridSolver::MultigridSolver(MultigridSolver&&) noexcept = default;
MultigridSolver& MultigridSolver::operator=(MultigridSolver&&) noexcept = default;

const MultigridStats& MultigridSolver::stats() const { return m_impl->stats; }
const MultigridHierarchy& MultigridSolver::hierarchy() const { return m_impl->hierarchy; }
const std::vector<double>& MultigridSolver::cycleResiduals() const {
  return m_impl->cycleResiduals;
}

Result<void> MultigridSolver::setup(const MultigridSettings& settings, const double* restPositions,
                                    const uint8_t* fixedNode, const BlockSparseMatrix& A) {
  const auto t0 = Clock::now();
  Impl& s = *m_impl;
  s.fineBlocks = -1;
  if (Result<void> r = settings.check(); !r) return fail("multigrid.", r.error().message);
  // Settings list the coarsest level first; the hierarchy wants the finest coarse level first.
  // No levels: chosen from the free node count.
  std::vector<int32_t> counts(settings.levels.rbegin(), settings.levels.rend());
  if (counts.empty()) {
    int32_t freeNodes = 0;
    for (int32_t i = 0; i < A.n; ++i) freeNodes += fixedNode[i] ? 0 : 1;
    counts = MultigridHierarchy::defaultCounts(freeNodes, settings.smoothedProlongation);
  }
  if (Result<void> r =
          s.hierarchy.build(counts, restPositions, fixedNode, A, settings.smoothedProlongation);
      !r.ok())
    return r;
  s.settings = settings;
  s.fineBlocks = A.blockCount();
  s.buildLevels(A);
  s.needRefresh = true;
  s.stats.setupMs = msSince(t0);
  return {};
}

void MultigridSolver::rebind(const int32_t* edgeNodes, const uint8_t* broken, int32_t edgeCount) {
  Impl& s = *m_impl;
  if (!s.settings.crackRebinding || s.fineBlocks < 0) return;
  const auto t0 = Clock::now();
  s.hierarchy.rebind(edgeNodes, broken, edgeCount);
  s.patternsChanged = true;
  s.needRefresh = true;
  s.stats.rebindMs = msSince(t0);
}

SolveReport MultigridSolver::solve(const BlockSparseMatrix& A, const double* b, double* x,
                                   int maxIterations, double relativeTolerance, JobSystem& jobs) {
  Impl& s = *m_impl;
  const auto tStart = Clock::now();
  SolveReport report;
  report.relativeResidual = std::numeric_limits<double>::infinity();
  MultigridStats& st = s.stats;
  st.refreshMs = st.galerkinMs = st.factorMs = st.smoothMs = st.coarseSolveMs = st.transferMs = 0;
  st.iterations = st.cycles = 0;
  st.refreshed = false;
  s.cycleResiduals.clear();
  const size_t n3 = 3 * static_cast<size_t>(std::max(A.n, 0));
  if (s.fineBlocks != A.blockCount() || s.levels.empty() || s.levels[0].n != A.n) {
    CpuExecutor(jobs).run(int32_t(n3), kEntryGrain,
                          FillStage{0.0, x});  // not set up for this pattern
    return report;
  }
  if (s.r.size() < n3) {
    s.r.resize(n3);
    s.z.resize(n3);
    s.p.resize(n3);
    s.ap.resize(n3);
    s.rOld.resize(n3);
  }
  double* r = s.r.data();
  double* z = s.z.data();
  const CpuExecutor exec(jobs, &s.partials);

  // Sets up what depends on A, once a solve needs a cycle: coarse operators on refresh, the
  // fine diagonal every solve.
  auto setUp = [&]() {
    auto t0 = Clock::now();
    if (s.patternsChanged) s.buildLevels(A);
    s.invertDiagonals<3>(0, A, jobs);
    if (s.needRefresh || s.solvesSinceRefresh >= s.settings.coarseRefreshInterval) {
      s.refresh(A, jobs);
      s.needRefresh = false;
      s.solvesSinceRefresh = 0;
      st.refreshed = true;
    }
    ++s.solvesSinceRefresh;
    st.refreshMs = msSince(t0);
  };
  auto trueResidual = [&]() {
    A.multiply(x, s.ap.data(), jobs);
    return exec.reduce<SumOp>(int32_t(n3), ResidualTerm{b, s.ap.data(), r});
  };

  int it = 0;
  if (s.settings.preconditionCG) {
    // One V-cycle per iteration of flexible CG (the cycle is not a fixed linear map).
    struct VCycle {
      bool flexible = true;
      Impl* s;
      const BlockSparseMatrix* A;
      JobSystem* jobs;
      const CpuExecutor* exec;
      const decltype(setUp)* setUpLevels;
      void prepare() const { (*setUpLevels)(); }
      double apply(const double* r, double* z) const {
        s->cycle<3>(0, *A, r, z, *jobs);
        ++s->stats.cycles;
        return exec->dot(r, z, 3 * A->n);
      }
    };
    report = conjugateGradients(
        exec, A.view(), b, x, {r, z, s.p.data(), s.ap.data(), s.rOld.data()},
        VCycle{true, &s, &A, &jobs, &exec, &setUp}, maxIterations, relativeTolerance);
    it = report.iterations;
  } else {
    const double bb = exec.dot(b, b, int32_t(n3));
    if (!std::isfinite(bb)) return report;
    if (bb == 0) {
      exec.run(int32_t(n3), kEntryGrain, FillStage{0.0, x});
      report.converged = true;
      report.relativeResidual = 0;
      return report;
    }
    if (exec.reduce<MaxOp>(int32_t(n3), NonFiniteTerm{x}) > 0)
      exec.run(int32_t(n3), kEntryGrain, FillStage{0.0, x});
    const double bnorm = std::sqrt(bb);
    const double tol2 = relativeTolerance * relativeTolerance * bb;
    double rr = trueResidual();
    bool converged = std::isfinite(rr) && rr <= tol2;
    if (!converged) {
      setUp();
      s.cycleResiduals.push_back(std::sqrt(rr) / bnorm);
    }
    while (!converged && it < s.settings.cycles) {
      s.cycle<3>(0, A, r, z, jobs);  // error equation A e = r
      ++it;
      ++st.cycles;
      exec.run(int32_t(n3), kEntryGrain, AxpyStage{x, z, 1.0, x});
      rr = trueResidual();
      s.cycleResiduals.push_back(std::sqrt(rr) / bnorm);
      if (!std::isfinite(rr)) {
        exec.run(int32_t(n3), kEntryGrain, AxpyStage{x, z, -1.0, x});  // the last finite iterate
        rr = trueResidual();
        break;
      }
      converged = rr <= tol2;
    }
    report.iterations = it;
    report.converged = converged && std::isfinite(rr);
    report.relativeResidual =
        std::isfinite(rr) ? std::sqrt(rr) / bnorm : std::numeric_limits<double>::infinity();
  }
  if (const double bb = exec.dot(b, b, int32_t(n3));
      !std::isfinite(report.relativeResidual) && std::isfinite(bb) && bb > 0) {
    // Nothing finite came out: the zero vector, whose residual is |b| (relative 1).
    exec.run(int32_t(n3), kEntryGrain, FillStage{0.0, x});
    report.converged = false;
    report.relativeResidual = 1;
  }
  st.iterations = s.settings.preconditionCG ? it : 0;
  st.totalMs = msSince(tStart);
  return report;
}

}  // namespace gf::detail
