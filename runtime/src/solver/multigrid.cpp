// Galerkin multigrid V-cycles and flexible CG (thesis sec 6.2, eq 6.1-6.4): the levels' data
// and their set-up on the host; the solve itself is multigrid_cycle.h's, which the device
// backend runs too.
//
// Design: level 0 is the fine 3x3-block matrix, levels 1..L the 12x12-block Galerkin operators;
// the smoothers are written once for both block sizes. Every pass writes disjoint rows (the
// Gauss-Seidel sweeps go colour by colour of a greedy colouring, so a colour's rows never
// touch each other) and every reduction uses the executor's fixed chunks: the same bits for
// any thread count. Symmetry: pre-smoothing runs forward Gauss-Seidel, post-smoothing the
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
#include <atomic>
#include <cmath>
#include <limits>
#include <string>

#include "solver/multigrid_cycle.h"
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

// Entries per parallel range of an element-wise vector pass.
constexpr uint32_t kEntryGrain = 2048;

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
  std::vector<double> gsValues;       // B = 12
  std::vector<float> gsValuesSingle;  // B = 3 (GsValue)
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
  // MG-CG iterations of the first solve after the last refresh (-1: none yet) and of the last
  // solve: the early-refresh test of coarseRefreshSlack.
  int refreshIterations = -1;
  int lastIterations = 0;
  // Deferred crack re-binding (a refresh interval above 1): the broken state of the last
  // rebind() call, applied with the next refresh. Until then the hierarchy of the previous
  // binding preconditions CG (still SPD, so CG converges to the current system's solution); a
  // crack that weakens it raises the iteration count, which brings the refresh forward.
  std::vector<int32_t> pendingEdgeNodes;
  std::vector<uint8_t> pendingBroken;
  bool rebindPending = false;

  std::vector<int32_t> appliedRebinds;  // broken-edge count of each re-binding applied

  void applyRebind(JobSystem& jobs) {
    const auto t0 = Clock::now();
    appliedRebinds.push_back(
        static_cast<int32_t>(std::count(pendingBroken.begin(), pendingBroken.end(), uint8_t{1})));
    hierarchy.rebind(pendingEdgeNodes.data(), pendingBroken.data(),
                     static_cast<int32_t>(pendingBroken.size()), jobs);
    rebindPending = false;
    patternsChanged = true;
    needRefresh = true;
    stats.rebindMs = msSince(t0);
  }
  bool needRefresh = true;
  bool patternsChanged = true;
  std::vector<double> partials;

  // Coarsest level: lower triangle of its scalar expansion and the map into its values.
  using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
  SpMat coarseLower;
  std::vector<int64_t> coarseMap;  // -1: an analysed block the current operator lacks
  std::vector<int32_t> analysedRowStart, analysedCol;  // the pattern coarseLower expands
#if GF_HAVE_CHOLMOD
  Eigen::CholmodSupernodalLLT<SpMat, Eigen::Lower> coarseLlt;
#else
  Eigen::SimplicialLLT<SpMat, Eigen::Lower, Eigen::AMDOrdering<int> > coarseLlt;
#endif
  bool coarseOk = false;
  // The refresh of a solve left the coarsest factorisation to its first V-cycle (overlapped).
  bool factorPending = false;

  // CG vectors (3 n each).
  std::vector<double> r, z, p, ap, rOld;

  int coarseCount() const { return hierarchy.coarseLevelCount(); }

  // fineKept: a crack re-binding, which leaves the fine pattern, its colouring and its
  // Gauss-Seidel copy as they were (rebuilding them was a serial pass over every fine block).
  void buildLevels(const BlockSparseMatrix& A, bool fineKept = false) {
    levelsVersion = nextLevelsVersion();
    const int first = fineKept && !levels.empty() && levels[0].n == A.n ? 1 : 0;
    levels.resize(static_cast<size_t>(coarseCount()) + 1);
    for (int l = first; l <= coarseCount(); ++l) {
      Level& lv = levels[static_cast<size_t>(l)];
      lv = Level{};
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
      lv.gsValuesSingle.clear();
      if (settings.smoother == Smoother::GaussSeidel) {
        for (int32_t q = 0; q < n; ++q) {
          const int32_t row = lv.colourRows[q];
          for (int32_t k = rs[row]; k < rs[row + 1]; ++k) {
            lv.gsCol.push_back(cl[k]);
            lv.gsBlock.push_back(k);
          }
          lv.gsRowStart.push_back(static_cast<int32_t>(lv.gsCol.size()));
        }
        const size_t entries = lv.gsBlock.size() * static_cast<size_t>(B * B);
        if (B == 3)
          lv.gsValuesSingle.assign(entries, 0.0F);
        else
          lv.gsValues.assign(entries, 0.0);
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

  // Whether every block of C lies in the analysed pattern (same handles).
  bool withinAnalysed(const CoarseMatrix& C) const {
    if (analysedRowStart.size() != static_cast<size_t>(C.n) + 1) return false;
    for (int32_t r = 0; r < C.n; ++r) {
      const int32_t* first = analysedCol.data() + analysedRowStart[r];
      const int32_t* last = analysedCol.data() + analysedRowStart[r + 1];
      for (int32_t k = C.rowStart[r]; k < C.rowStart[r + 1]; ++k) {
        first = std::lower_bound(first, last, C.col[k]);
        if (first == last || *first != C.col[k]) return false;
      }
    }
    return true;
  }

  // Column 12c + j of the scalar expansion holds rows 12r + i >= 12c + j of blocks (r, c) of
  // the analysed pattern. A re-binding mostly moves fine nodes between aggregates: the
  // coarsest level keeps its handles and its couplings stay within those analysed before
  // (a lost one enters the factorisation as explicit zeros), so the expansion and the
  // symbolic analysis still hold and only the map into the values is rebuilt.
  void buildCoarsestPattern() {
    coarseMap.clear();
    coarseOk = false;
    if (coarseCount() == 0) {
      analysedRowStart.clear();
      analysedCol.clear();
      return;
    }
    const CoarseMatrix& C = hierarchy.level(coarseCount()).A;
    const bool reanalyse = !withinAnalysed(C);
    if (reanalyse) {
      analysedRowStart = C.rowStart;
      analysedCol = C.col;
      const int64_t size = 12 * static_cast<int64_t>(C.n);
      coarseLower.resize(size, size);
      coarseLower.resizeNonZeros(0);
      coarseLower.reserve(static_cast<int64_t>(C.col.size()) * 72 + 12 * C.n);
    }
    for (int32_t c = 0; c < C.n; ++c)
      for (int j = 0; j < 12; ++j) {
        if (reanalyse) coarseLower.startVec(12 * c + j);
        for (int32_t k = analysedRowStart[c]; k < analysedRowStart[c + 1]; ++k) {
          const int32_t rr = analysedCol[k];
          if (rr < c) continue;
          const int64_t blk = C.find(rr, c);
          for (int i = 0; i < 12; ++i) {
            if (rr == c && i < j) continue;
            if (reanalyse) coarseLower.insertBack(12 * rr + i, 12 * c + j) = 0.0;
            coarseMap.push_back(blk < 0 ? -1 : 144 * blk + 12 * i + j);
          }
        }
      }
    if (!reanalyse) return;
    coarseLower.finalize();
#if GF_HAVE_CHOLMOD
    coarseLlt.cholmod().print = 0;  // a failed factorisation is retried below, not printed
#endif
    blasOnOneThread();
    const SerialOpenMpScope serial;
    if (coarseLower.cols() > 0) coarseLlt.analyzePattern(coarseLower);
  }

  // values: the coarsest operator's blocks (the hierarchy's, or a copy of them).
  void factorCoarsest(const double* values) {
    coarseOk = false;
    if (coarseCount() == 0 || coarseLower.cols() == 0) return;
    double* v = coarseLower.valuePtr();
    for (size_t i = 0; i < coarseMap.size(); ++i)
      v[i] = coarseMap[i] < 0 ? 0.0 : values[coarseMap[i]];
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
    setUpDiagonals<B>(CpuExecutor(jobs), cycleLevel(l, A),
                      settings.smoother == Smoother::GaussSeidel);
  }

  template <int B>
  void estimateLambda(int l, const BlockSparseMatrix& A, JobSystem& jobs) {
    levels[static_cast<size_t>(l)].lambdaMax = detail::estimateLambda<B>(
        CpuExecutor(jobs, &partials), cycleLevel(l, A), kPowerIterations, kLambdaMargin);
  }

  // deferFactor: the coarsest factorisation is left to the caller (factorPending).
  void refresh(const BlockSparseMatrix& A, JobSystem& jobs, bool deferFactor) {
    auto t0 = Clock::now();
    hierarchy.assemble(A, jobs);
    stats.galerkinMs = msSince(t0);
    for (int l = 1; l <= coarseCount(); ++l) invertDiagonals<12>(l, A, jobs);
    if (settings.smoother != Smoother::GaussSeidel) {
      estimateLambda<3>(0, A, jobs);
      for (int l = 1; l < coarseCount(); ++l) estimateLambda<12>(l, A, jobs);
    }
    coarseOk = false;
    factorPending = coarseCount() > 0;
    stats.coarseFactorOk = !factorPending;
    if (!deferFactor) finishFactor();
  }

  // A solve's start (the last solve's statistics cleared) and end (the refresh schedule's
  // iteration counts), for solve() and solveWith() alike.
  void startSolve();
  void endSolve(const MultigridRun& run, const SolveReport& report);

  void finishFactor() {
    if (!factorPending) return;
    const auto t0 = Clock::now();
    factorCoarsest(hierarchy.level(coarseCount()).A.values.data());
    factorPending = false;
    stats.factorMs = msSince(t0);
    stats.coarseFactorOk = coarseOk;
  }

  // Level l as the cycle and its set-up read it (valid until the next buildLevels).
  CycleLevel cycleLevel(int l, const BlockSparseMatrix& A) {
    Level& lv = levels[static_cast<size_t>(l)];
    CycleLevel c;
    c.n = lv.n;
    if (l == 0) {
      c.rowStart = A.rowStart.data();
      c.col = A.col.data();
      c.values = A.values.data();
    } else {
      const CoarseMatrix& C = hierarchy.level(l).A;
      c.rowStart = C.rowStart.data();
      c.col = C.col.data();
      c.values = C.values.data();
    }
    c.diagIndex = lv.diagIndex.data();
    c.invDiag = lv.invDiag.data();
    c.colourStart = lv.colourStart.data();
    c.colours = static_cast<int32_t>(lv.colourStart.size()) - 1;
    c.colourRows = lv.colourRows.data();
    c.gsRowStart = lv.gsRowStart.data();
    c.gsCol = lv.gsCol.data();
    c.gsBlock = lv.gsBlock.data();
    c.gsValues = lv.gsValues.data();
    c.gsValuesSingle = lv.gsValuesSingle.data();
    c.lambdaMax = lv.lambdaMax;
    c.b = lv.b.data();
    c.x = lv.x.data();
    c.r = lv.r.data();
    c.t = lv.t.data();
    if (l < coarseCount()) c.P = hierarchy.prolongation(l);
    return c;
  }

  std::vector<CycleLevel> cycleLevels(const BlockSparseMatrix& A) {
    std::vector<CycleLevel> out;
    for (int l = 0; l <= coarseCount(); ++l) out.push_back(cycleLevel(l, A));
    return out;
  }

  CycleSettings cycleSettings() const {
    static_assert(int(Smoother::Jacobi) == int(CycleSmoother::kJacobi) &&
                  int(Smoother::GaussSeidel) == int(CycleSmoother::kGaussSeidel) &&
                  int(Smoother::Chebyshev) == int(CycleSmoother::kChebyshev));
    return {static_cast<CycleSmoother>(settings.smoother),
            settings.preSweeps,
            settings.postSweeps,
            settings.coarsePreSweeps < 0 ? settings.preSweeps : settings.coarsePreSweeps,
            settings.coarsePostSweeps < 0 ? settings.postSweeps : settings.coarsePostSweeps,
            kChebyshevLow,
            kPowerIterations,
            kLambdaMargin};
  }

  // The coarsest level's exact solve (zero where it has no factor or the result is not finite).
  void solveCoarsest(const double* b, double* x, JobSystem& jobs) {
    const int32_t len = 12 * levels.back().n;
    if (coarseOk) {
      Eigen::Map<const Eigen::VectorXd> bm(b, len);
      Eigen::Map<Eigen::VectorXd> xm(x, len);
      const SerialOpenMpScope serial;
      xm = coarseLlt.solve(bm);
      if (allFinite(x, size_t(len))) return;
    }
    CpuExecutor(jobs).run(len, kEntryGrain, FillStage{0.0, x});
  }

  // The passes of a V-cycle's descent, which descend() issues in a fixed order whatever the
  // values, split between two executors. Taking (`stop` given): passes run in order until
  // stop is set, and `taken` counts them. Resuming: the first `skip` passes, which ran
  // already, are left out. Every pass writes disjoint rows and none reduces, so where the
  // split falls does not change the bits.
  struct PassSplit {
    const CpuExecutor* exec;
    const std::atomic<bool>* stop = nullptr;
    int32_t skip = 0;
    mutable int32_t next = 0;
    mutable int32_t taken = 0;
    mutable bool stopped = false;

    template <class Stage>
    void run(int32_t count, uint32_t grain, const Stage& stage) const {
      if (next++ < skip || stopped) return;
      if (stop && stop->load(std::memory_order_acquire)) {
        stopped = true;
        return;
      }
      exec->run(count, grain, stage);
      ++taken;
    }
  };

  // The V-cycle on level 0 as multigridSolve runs it. The first cycle after a refresh starts
  // its descent to the coarsest level while the coarsest operator is factorised: two items side
  // by side on the JobSystem, the descent serial inside and only until the factor is done; the
  // rest of the descent then runs on all threads. Neither side reads what the other writes,
  // so the bits are those of factorising first.
  template <class Coarse>
  struct OverlappedFactor {
    const CpuExecutor* exec;
    const std::vector<CycleLevel>* levels;
    CycleSettings settings;
    const Coarse* coarse;
    CycleTimes* times;
    Impl* s;
    JobSystem* jobs;

    template <int B>
    void cycle(int l, const double* b, double* x) const {
      const VCycle<CpuExecutor, Coarse> full(*exec, *levels, settings, *coarse, *times);
      if (!s->factorPending) {
        full.template cycle<B>(l, b, x);
        return;
      }
      using Split = VCycle<PassSplit, Coarse>;
      std::atomic<bool> factored{false};
      const CpuExecutor serial(serialJobs());
      const PassSplit taking{&serial, &factored};
      forRanges(*jobs, 2, 1, [&](uint32_t begin, uint32_t end) {
        for (uint32_t part = begin; part < end; ++part)
          if (part == 0) {
            s->finishFactor();
            factored.store(true, std::memory_order_release);
          } else {
            Split(taking, *levels, settings, *coarse, *times).template descend<B>(l, b, x);
          }
      });
      const PassSplit rest{exec, nullptr, taking.taken};
      Split(rest, *levels, settings, *coarse, *times).template descend<B>(l, b, x);
      full.template ascend<B>(l, b, x);
    }
  };

  // Solves between refreshes: MultigridSettings::coarseRefreshInterval, or when 0 (the
  // default) 10 for MG-CG, where CG converges whatever the coarse levels and a drift that
  // costs iterations brings the refresh forward, and 1 when cycling alone, where nothing would.
  int refreshInterval() const {
    if (settings.coarseRefreshInterval > 0) return settings.coarseRefreshInterval;
    return settings.preconditionCG ? 10 : 1;
  }

  // Whether the next solve recomputes the coarse operators. Iteration counts are the same for
  // any thread count, so this choice is deterministic.
  bool refreshDue() const {
    const bool drifted = settings.preconditionCG && refreshIterations >= 0 &&
                         lastIterations > refreshIterations + settings.coarseRefreshSlack;
    return needRefresh || drifted || solvesSinceRefresh >= refreshInterval();
  }

  // A solve's preparation: the refresh schedule and the re-bindings it applies (structure),
  // whose value work (the fine diagonal every solve, the coarse operators on a refresh) is then
  // done on the host (prepare, onHost) or by a device (solveWith). Returns whether it refreshes.
  bool plan(const BlockSparseMatrix& A, JobSystem& jobs, bool onHost) {
    // Values a device computed are not the host's: a host solve refreshes them first.
    const bool due = refreshDue() || (onHost && valuesElsewhere);
    valuesElsewhere = !onHost;
    if (due) operatorsHeld = onHost;
    if (due && rebindPending) applyRebind(jobs);
    if (patternsChanged) buildLevels(A, true);
    if (due) {
      needRefresh = false;
      solvesSinceRefresh = 0;
      stats.refreshed = true;
    }
    ++solvesSinceRefresh;
    return due;
  }

  void prepare(const BlockSparseMatrix& A, JobSystem& jobs, bool deferFactor) {
    const auto t0 = Clock::now();
    const bool due = plan(A, jobs, true);
    invertDiagonals<3>(0, A, jobs);
    // Jacobi and Chebyshev are tuned to lambda_max of the fine D^-1 A; with a stale estimate
    // below the current one (a longer step, fracture) they amplify the top modes and the
    // V-cycle is no longer SPD, so CG breaks down. The coarse levels' estimates stay
    // consistent with their (stale) operators.
    if (!due && settings.smoother != Smoother::GaussSeidel) estimateLambda<3>(0, A, jobs);
    if (due) refresh(A, jobs, deferFactor);
    stats.refreshMs = msSince(t0);
  }

  // The levels' structure changes (buildLevels, restore): a device's mirror of them is stale.
  // Unique in the process, so that a solver set up again (a body's fixed nodes changed) never
  // repeats one.
  uint64_t levelsVersion = 0;
  static uint64_t nextLevelsVersion() {
    static std::atomic<uint64_t> next{1};
    return next.fetch_add(1, std::memory_order_relaxed);
  }
  // A device prepared the levels' values since the host last did: the host's are stale, but
  // for the coarse operators where takeValues() read them back (operatorsHeld).
  bool valuesElsewhere = false;
  bool operatorsHeld = true;
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
          s.hierarchy.build(counts, restPositions, fixedNode, A, settings.smoothedProlongation,
                            settings.prolongationFilter);
      !r.ok())
    return r;
  s.settings = settings;
  s.fineBlocks = A.blockCount();
  s.buildLevels(A);
  s.needRefresh = true;
  s.valuesElsewhere = false;
  s.operatorsHeld = true;
  s.rebindPending = false;
  s.appliedRebinds.clear();
  s.solvesSinceRefresh = 0;
  s.refreshIterations = -1;
  s.lastIterations = 0;
  s.stats.setupMs = msSince(t0);
  return {};
}

void MultigridSolver::rebind(const int32_t* edgeNodes, const uint8_t* broken, int32_t edgeCount,
                             JobSystem& jobs) {
  Impl& s = *m_impl;
  if (!s.settings.crackRebinding || s.fineBlocks < 0) return;
  s.pendingEdgeNodes.assign(edgeNodes, edgeNodes + 2 * static_cast<size_t>(edgeCount));
  s.pendingBroken.assign(broken, broken + edgeCount);
  s.rebindPending = true;
  s.stats.rebindMs = 0;
  if (s.refreshInterval() <= 1) s.applyRebind(jobs);
}

void MultigridSolver::takeValues(
    const std::function<bool(uint64_t version, int level, double* values, size_t count)>& read) {
  Impl& s = *m_impl;
  if (!s.valuesElsewhere || s.operatorsHeld) return;
  std::vector<CoarseLevelValues> values(static_cast<size_t>(s.coarseCount()));
  for (int l = 1; l <= s.coarseCount(); ++l) {
    std::vector<double>& A = values[static_cast<size_t>(l - 1)].A;
    A.resize(s.hierarchy.level(l).A.values.size());
    if (!read(s.levelsVersion, l, A.data(), A.size())) return;
  }
  s.operatorsHeld = s.hierarchy.setValues(values);
}

MultigridState MultigridSolver::state() const {
  const Impl& s = *m_impl;
  MultigridState st;
  st.rebinds = s.appliedRebinds;
  if (s.rebindPending)
    st.pendingRebind = static_cast<int32_t>(
        std::count(s.pendingBroken.begin(), s.pendingBroken.end(), uint8_t{1}));
  // Operators a device computed and takeValues() did not read back are not held here: the
  // restored solver refreshes them.
  const bool lost = s.valuesElsewhere && !s.operatorsHeld;
  st.needRefresh = s.needRefresh || lost;
  st.solvesSinceRefresh = s.solvesSinceRefresh;
  st.refreshIterations = s.refreshIterations;
  st.lastIterations = s.lastIterations;
  if (s.fineBlocks < 0) return st;
  // A due refresh recomputes the operators, not a smoothed prolongator still fresh.
  const bool keepOperators = !s.refreshDue() && !lost;
  if (keepOperators || s.hierarchy.smoothed()) st.levels = s.hierarchy.values(keepOperators);
  return st;
}

bool MultigridSolver::canRestore(const MultigridState& st) const {
  const std::vector<int32_t>& applied = m_impl->appliedRebinds;
  return applied.size() <= st.rebinds.size() &&
         std::equal(applied.begin(), applied.end(), st.rebinds.begin());
}

Result<void> MultigridSolver::restore(const MultigridState& st, const BlockSparseMatrix& A,
                                      const int32_t* edgeNodes, int32_t edgeCount,
                                      const int32_t* breakOrder, int32_t breakCount,
                                      JobSystem& jobs) {
  Impl& s = *m_impl;
  if (!ready(A)) return fail("multigrid state: the solver is not set up for this matrix");
  if (!canRestore(st)) return fail("multigrid state: re-bindings differ from the solver's");
  const size_t applied = s.appliedRebinds.size();
  for (int32_t k : st.rebinds)
    if (k < 0 || k > breakCount) return fail("multigrid state: more broken edges than broke");
  if (st.pendingRebind > breakCount) return fail("multigrid state: more broken edges than broke");
  auto brokenAfter = [&](int32_t k) {
    s.pendingEdgeNodes.assign(edgeNodes, edgeNodes + 2 * static_cast<size_t>(edgeCount));
    s.pendingBroken.assign(static_cast<size_t>(edgeCount), 0);
    for (int32_t i = 0; i < k; ++i) s.pendingBroken[static_cast<size_t>(breakOrder[i])] = 1;
  };
  for (size_t r = applied; r < st.rebinds.size(); ++r) {
    brokenAfter(st.rebinds[r]);
    s.applyRebind(jobs);
  }
  s.rebindPending = st.pendingRebind >= 0;
  if (s.rebindPending) brokenAfter(st.pendingRebind);
  if (s.patternsChanged) s.buildLevels(A, true);
  s.levelsVersion = Impl::nextLevelsVersion();  // the restored values, for a device's mirror
  s.valuesElsewhere = false;
  s.operatorsHeld = true;
  if (!st.levels.empty() && !s.hierarchy.setValues(st.levels))
    return fail("multigrid state: coarse levels differ from the solver's");
  s.needRefresh = st.needRefresh;
  s.solvesSinceRefresh = st.solvesSinceRefresh;
  s.refreshIterations = st.refreshIterations;
  s.lastIterations = st.lastIterations;
  // What a refresh derives from the operators it kept: their smoothers and the factorisation.
  if (!st.levels.empty() && !st.levels[0].A.empty()) {
    for (int l = 1; l <= s.coarseCount(); ++l) s.invertDiagonals<12>(l, A, jobs);
    if (s.settings.smoother != Smoother::GaussSeidel)
      for (int l = 1; l < s.coarseCount(); ++l) s.estimateLambda<12>(l, A, jobs);
    s.factorPending = s.coarseCount() > 0;
    s.finishFactor();
  } else {
    s.needRefresh = true;
  }
  return {};
}

bool MultigridSolver::ready(const BlockSparseMatrix& A) const {
  const Impl& s = *m_impl;
  return s.fineBlocks == A.blockCount() && !s.levels.empty() && s.levels[0].n == A.n;
}

void MultigridSolver::prepare(const BlockSparseMatrix& A, JobSystem& jobs) {
  m_impl->prepare(A, jobs, false);
}

std::vector<CycleLevel> MultigridSolver::cycleLevels(const BlockSparseMatrix& A) {
  return m_impl->cycleLevels(A);
}

std::vector<GalerkinLevelView> MultigridSolver::galerkinLevels() {
  std::vector<GalerkinLevelView> out;
  for (int l = 1; l <= m_impl->coarseCount(); ++l) out.push_back(m_impl->hierarchy.galerkinView(l));
  return out;
}

void MultigridSolver::factorCoarsest(const double* values) { m_impl->factorCoarsest(values); }

CycleSettings MultigridSolver::cycleSettings() const { return m_impl->cycleSettings(); }

void MultigridSolver::solveCoarsest(const double* b, double* x, JobSystem& jobs) {
  m_impl->solveCoarsest(b, x, jobs);
}

void MultigridSolver::Impl::startSolve() {
  stats.refreshMs = stats.galerkinMs = stats.factorMs = stats.smoothMs = stats.coarseSolveMs =
      stats.transferMs = 0;
  stats.iterations = stats.cycles = 0;
  stats.refreshed = false;
  cycleResiduals.clear();
}

void MultigridSolver::Impl::endSolve(const MultigridRun& run, const SolveReport& report) {
  finishFactor();  // no V-cycle ran after the refresh
  stats.cycles = run.vCycles;
  stats.iterations = settings.preconditionCG ? report.iterations : 0;
  if (stats.refreshed) refreshIterations = stats.iterations;
  lastIterations = stats.iterations;
}

// What a solve for a matrix the solver is not set up for returns: x zeroed, an infinite residual.
static SolveReport notSetUp(int32_t n, double* x, JobSystem& jobs) {
  CpuExecutor(jobs).run(3 * std::max(n, 0), kEntryGrain, FillStage{0.0, x});
  SolveReport report;
  report.relativeResidual = std::numeric_limits<double>::infinity();
  return report;
}

SolveReport MultigridSolver::solveWith(const BlockSparseMatrix& A, double* x, JobSystem& jobs,
                                       const ExternalSolve& external, bool& ok,
                                       const std::function<bool()>& hostValues) {
  Impl& s = *m_impl;
  const auto tStart = Clock::now();
  s.startSolve();
  ok = true;
  if (!ready(A)) return notSetUp(A.n, x, jobs);
  MultigridMirror mirror;
  auto prepareLevels = [&]() -> const MultigridMirror* {
    // Smoothing the prolongator is host code: with it the host prepares every value.
    const bool onHost = s.hierarchy.smoothed();
    bool refresh = false;
    if (onHost) {
      if (hostValues && !hostValues()) return nullptr;
      s.prepare(A, jobs, false);
    } else {
      refresh = s.plan(A, jobs, false);
    }
    mirror = {s.cycleLevels(A), galerkinLevels(), s.cycleSettings(),
              [&s](const double* values) { s.factorCoarsest(values); },
              [&s, &jobs](const double* b, double* xc) { s.solveCoarsest(b, xc, jobs); }};
    mirror.valuesOnHost = onHost;
    mirror.refresh = refresh;
    mirror.version = s.levelsVersion;
    return &mirror;
  };
  MultigridRun run;
  run.preconditionCG = s.settings.preconditionCG;
  run.cycles = s.settings.cycles;
  run.cycleResiduals = &s.cycleResiduals;
  SolveReport report;
  ok = external(s.cycleSettings(), prepareLevels, run, report);
  s.endSolve(run, report);
  s.stats.totalMs = msSince(tStart);
  return report;
}

SolveReport MultigridSolver::solve(const BlockSparseMatrix& A, const double* b, double* x,
                                   int maxIterations, double relativeTolerance, JobSystem& jobs) {
  Impl& s = *m_impl;
  const auto tStart = Clock::now();
  MultigridStats& st = s.stats;
  s.startSolve();
  const size_t n3 = 3 * static_cast<size_t>(std::max(A.n, 0));
  if (!ready(A)) return notSetUp(A.n, x, jobs);
  if (s.r.size() < n3) {
    s.r.resize(n3);
    s.z.resize(n3);
    s.p.resize(n3);
    s.ap.resize(n3);
    s.rOld.resize(n3);
  }
  const CpuExecutor exec(jobs, &s.partials);
  // The level views are taken once the levels exist for this pattern (prepare may rebuild
  // them after a crack re-binding), i.e. inside prepare.
  std::vector<CycleLevel> levels;
  auto prepareLevels = [&]() {
    s.prepare(A, jobs, true);
    levels = s.cycleLevels(A);
  };
  auto coarse = [&](const double* cb, double* cx) { s.solveCoarsest(cb, cx, jobs); };
  CycleTimes times;
  const Impl::OverlappedFactor<decltype(coarse)> cycle{
      &exec, &levels, s.cycleSettings(), &coarse, &times, &s, &jobs};
  MultigridRun run;
  run.preconditionCG = s.settings.preconditionCG;
  run.cycles = s.settings.cycles;
  run.cycleResiduals = &s.cycleResiduals;
  const SolveReport report = multigridSolve(
      exec, A.view(), b, x, {s.r.data(), s.z.data(), s.p.data(), s.ap.data(), s.rOld.data()}, cycle,
      prepareLevels, maxIterations, relativeTolerance, run);
  s.endSolve(run, report);
  st.smoothMs = times.smoothMs;
  st.transferMs = times.transferMs;
  st.coarseSolveMs = times.coarseSolveMs;
  st.totalMs = msSince(tStart);
  return report;
}

}  // namespace gf::detail
