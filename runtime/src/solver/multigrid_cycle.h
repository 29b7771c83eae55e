// The Galerkin multigrid's solve (thesis sec 6.2, eq 6.1-6.3) written once over an executor:
// the V-cycle with its three smoothers, and the two ways of using it (flexible CG with one
// V-cycle per iteration, or V-cycles alone). MultigridSolver runs it with the CPU executor on
// its host buffers, gpu::DeviceMultigrid with the device executor on device copies of the same
// buffers. The coarsest level's solve is the one callback: its sparse Cholesky factor lives on
// the host. What depends on the matrix's values (coarse operators, diagonal inverses, the
// Gauss-Seidel copies, the coarsest factor) is set up before a cycle runs, by the caller's
// `prepare`.
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

#include "solver/galerkin_stages.h"
#include "solver/multigrid_stages.h"
#include "solver/pcg_stages.h"
#include "solver/vector_stages.h"
#include "step/timing.h"

namespace gf::detail {

/// MultigridSettings::smoother, in the same order.
enum class CycleSmoother : uint8_t { kJacobi, kGaussSeidel, kChebyshev };

/// One level as the cycle reads it: B x B blocks, B = 3 on level 0 and 12 deeper. Pointers are
/// in the executor's memory except colourStart, which the host reads for launch sizes.
struct CycleLevel {
  int32_t n = 0;  ///< block rows
  const int32_t* rowStart = nullptr;
  const int32_t* col = nullptr;
  const double* values = nullptr;
  const int32_t* diagIndex = nullptr;  ///< the diagonal block of each row
  double* invDiag = nullptr;           ///< B x B per row
  /// Gauss-Seidel: the colours (host memory) and the matrix's copy in colour order, position
  /// q holding row colourRows[q] with the blocks gsBlock of the matrix.
  const int32_t* colourStart = nullptr;
  int32_t colours = 0;
  const int32_t* colourRows = nullptr;
  const int32_t* gsRowStart = nullptr;
  const int32_t* gsCol = nullptr;
  const int32_t* gsBlock = nullptr;
  double* gsValues = nullptr;       ///< the handle levels' copy (B = 12)
  float* gsValuesSingle = nullptr;  ///< level 0's copy (B = 3), single precision: GsValue
  double lambdaMax = 2;             ///< bound on the spectrum of D^-1 A (Jacobi, Chebyshev)
  double* b = nullptr;              ///< rhs, iterate, residual, temporary: B n each
  double* x = nullptr;
  double* r = nullptr;
  double* t = nullptr;
  ProlongationView P;  ///< from the next coarser level to this one (unused on the coarsest)

  template <int B>
  LevelMatrix<B> matrix() const {
    return {n, rowStart, col, values};
  }

  /// The Gauss-Seidel copy's entries, of GsValue<B>.
  template <int B>
  GsValue<B>* gsCopy() const {
    if constexpr (B == 3)
      return gsValuesSingle;
    else
      return gsValues;
  }
};

struct CycleSettings {
  CycleSmoother smoother = CycleSmoother::kGaussSeidel;
  int preSweeps = 2, postSweeps = 2;              ///< level 0
  int coarsePreSweeps = 2, coarsePostSweeps = 2;  ///< the levels between it and the coarsest
  double chebyshevLow = 0.1;                      ///< Chebyshev targets [low, 1] x lambda_max
  int powerIterations = 12;                       ///< of estimateLambda
  double lambdaMargin = 1.1;  ///< put on its estimate (the Rayleigh quotient is below it)
};

/// What every smoother needs of a level's values: the diagonal blocks' inverses and, for
/// Gauss-Seidel, the matrix's copy in colour order.
template <int B, class Exec>
void setUpDiagonals(const Exec& exec, const CycleLevel& lv, bool gaussSeidel) {
  exec.run(lv.n, B == 3 ? 128 : 8,
           DiagonalSetupStage<B>{lv.values, lv.diagIndex, lv.invDiag,
                                 gaussSeidel ? lv.gsRowStart : nullptr, lv.gsBlock, lv.colourRows,
                                 lv.gsCopy<B>()});
}

/// The largest eigenvalue of D^-1 A (Jacobi and Chebyshev need a bound) by power iteration
/// with the Rayleigh quotient v.Av / v.Dv, which approaches it from below; lv.x, lv.r and lv.t
/// are the scratch. Returns `margin` times the estimate, or 2 when none was found.
template <int B, class Exec>
double estimateLambda(const Exec& exec, const CycleLevel& lv, int iterations, double margin) {
  const int32_t len = B * lv.n;
  double* v = lv.x;
  double* w = lv.r;
  double* t = lv.t;
  exec.run(len, 2048, PowerStartStage{v});
  double lambda = 0;
  for (int it = 0; it < iterations; ++it) {
    exec.run(lv.n, B == 3 ? 128 : 8, LevelProductStage<B>{lv.matrix<B>(), v, w});
    const double vav = exec.dot(v, w, len);
    exec.run(lv.n, B == 3 ? 128 : 8, BlockDiagonalApplyStage<B>{lv.values, lv.diagIndex, v, t});
    const double vdv = exec.dot(v, t, len);
    if (!(vdv > 0) || !std::isfinite(vav)) break;
    lambda = vav / vdv;
    // v = D^-1 A v, normalised.
    exec.run(lv.n, B == 3 ? 128 : 8, BlockDiagonalApplyStage<B>{lv.invDiag, nullptr, w, v});
    const double nv = std::sqrt(exec.dot(v, v, len));
    if (!(nv > 0) || !std::isfinite(nv)) break;
    exec.run(len, 2048, ScaleStage{1 / nv, v});
  }
  return lambda > 0 && std::isfinite(lambda) ? margin * lambda : 2.0;
}

/// Wall time per part of the cycles (on the device: of the launches, which run asynchronously
/// except where a reduction waits).
struct CycleTimes {
  double smoothMs = 0, transferMs = 0, coarseSolveMs = 0;
};

/// x = V b on level l (x overwritten; eq 6.1-6.3) over levels[0..L], read when a cycle runs
/// (the caller's prepare may rebuild them); `coarse(b, x)` solves the coarsest level exactly
/// (or sets x = 0 when it has no factor).
template <class Exec, class CoarseSolve>
class VCycle {
 public:
  VCycle(const Exec& exec, const std::vector<CycleLevel>& levels, const CycleSettings& s,
         const CoarseSolve& coarse, CycleTimes& times)
      : m_exec(exec), m_levels(levels), m_s(s), m_coarse(coarse), m_times(times) {}

  template <int B>
  void cycle(int l, const double* b, double* x) const {
    descend<B>(l, b, x);
    ascend<B>(l, b, x);
  }

  /// The part of cycle(l, b, x) before the coarsest solve: on level l and every level below
  /// it but the coarsest, x = 0, pre-smoothing, the residual restricted to the next level's b.
  /// Of the coarsest level it only writes b, so it may run while that level is factorised;
  /// ascend(l, b, x) then completes the cycle, the same bits as cycle().
  template <int B>
  void descend(int l, const double* b, double* x) const {
    const int L = int(m_levels.size()) - 1;
    const CycleLevel& lv = m_levels[size_t(l)];
    if (l == L && L > 0) return;
    m_exec.run(B * lv.n, kEntryGrain, FillStage{0.0, x});
    auto t0 = Clock::now();
    smooth<B>(lv, b, x, l == 0 ? m_s.preSweeps : m_s.coarsePreSweeps, true);
    m_times.smoothMs += msSince(t0);
    if (L == 0) return;
    const CycleLevel& next = m_levels[size_t(l) + 1];
    t0 = Clock::now();
    m_exec.run(lv.n, rowGrain<B>(), LevelResidualStage<B>{lv.matrix<B>(), b, x, lv.r});
    m_exec.run(next.n, kHandleGrain, RestrictStage{lv.P, lv.r, next.b});  // eq 6.1
    m_times.transferMs += msSince(t0);
    descend<12>(l + 1, next.b, next.x);
  }

  /// The rest of cycle(l, b, x) after descend(l, b, x): the coarsest solve, then on every
  /// level from the coarsest up to l the prolonged correction and post-smoothing.
  template <int B>
  void ascend(int l, const double* b, double* x) const {
    const int L = int(m_levels.size()) - 1;
    const CycleLevel& lv = m_levels[size_t(l)];
    const int post = l == 0 ? m_s.postSweeps : m_s.coarsePostSweeps;
    if (l == L && L > 0) {
      const auto t0 = Clock::now();
      m_coarse(b, x);
      m_times.coarseSolveMs += msSince(t0);
      return;
    }
    if (L > 0) {
      const CycleLevel& next = m_levels[size_t(l) + 1];
      ascend<12>(l + 1, next.b, next.x);
      const auto t0 = Clock::now();
      m_exec.run(lv.n, B == 3 ? 256 : kHandleGrain * 8,
                 ProlongAddStage{lv.P, next.x, x});  // eq 6.3
      m_times.transferMs += msSince(t0);
    }
    const auto t0 = Clock::now();
    smooth<B>(lv, b, x, post, false);
    m_times.smoothMs += msSince(t0);
  }

 private:
  static constexpr uint32_t kEntryGrain = 2048, kHandleGrain = 8;
  // Rows per parallel range: a few thousand flops each.
  template <int B>
  static constexpr uint32_t rowGrain() {
    return B == 3 ? 128 : 8;
  }

  // `sweeps` smoothing steps; forward selects the Gauss-Seidel colour order (pre-smoothing
  // forward, post-smoothing backward keeps the cycle symmetric).
  template <int B>
  void smooth(const CycleLevel& lv, const double* b, double* x, int sweeps, bool forward) const {
    if (sweeps <= 0) return;
    const uint32_t grain = rowGrain<B>();
    const int32_t len = B * lv.n;
    switch (m_s.smoother) {
      case CycleSmoother::kGaussSeidel: {
        GaussSeidelColourStage<B> sweep{
            lv.colourRows, lv.gsRowStart, lv.gsCol, lv.gsCopy<B>(), lv.invDiag, b, x, 0};
        for (int s = 0; s < sweeps; ++s)
          for (int32_t cc = 0; cc < lv.colours; ++cc) {
            const int32_t c = forward ? cc : lv.colours - 1 - cc;
            sweep.first = lv.colourStart[c];
            m_exec.run(lv.colourStart[c + 1] - sweep.first, grain, sweep);
          }
        break;
      }
      case CycleSmoother::kJacobi: {
        // Damping 4 / (3 lambda_max) of D^-1 A: 2/3 at the classic lambda_max = 2.
        const double omega = 4.0 / (3.0 * lv.lambdaMax);
        for (int s = 0; s < sweeps; ++s) {
          m_exec.run(lv.n, grain,
                     JacobiDirectionStage<B>{lv.matrix<B>(), lv.invDiag, b, x, lv.t, 0.0, 1.0});
          m_exec.run(len, kEntryGrain, AxpyStage{x, lv.t, omega, x});
        }
        break;
      }
      case CycleSmoother::kChebyshev: {
        // Chebyshev iteration (Saad, Alg. 12.1) on D^-1 A over [low, high]; degree = sweeps.
        const double high = lv.lambdaMax, low = m_s.chebyshevLow * lv.lambdaMax;
        const double theta = 0.5 * (high + low), delta = 0.5 * (high - low);
        const double sigma = theta / delta;
        double rho = 1 / sigma;
        double* d = lv.t;
        m_exec.run(lv.n, grain,
                   JacobiDirectionStage<B>{lv.matrix<B>(), lv.invDiag, b, x, d, 0.0, 1 / theta});
        for (int k = 1;; ++k) {
          m_exec.run(len, kEntryGrain, AxpyStage{x, d, 1.0, x});
          if (k == sweeps) break;
          const double rhoNew = 1 / (2 * sigma - rho);
          m_exec.run(lv.n, grain,
                     JacobiDirectionStage<B>{lv.matrix<B>(), lv.invDiag, b, x, d, rhoNew * rho,
                                             2 * rhoNew / delta});
          rho = rhoNew;
        }
        break;
      }
    }
  }

  const Exec& m_exec;
  const std::vector<CycleLevel>& m_levels;
  CycleSettings m_s;
  const CoarseSolve& m_coarse;
  CycleTimes& m_times;
};

/// How a multigrid solve runs and what it reports beyond SolveReport.
struct MultigridRun {
  bool preconditionCG = true;  ///< flexible CG with one V-cycle per iteration, else cycles alone
  int cycles = 1;              ///< V-cycles when cycling alone
  int vCycles = 0;             ///< out: V-cycles run
  /// out, cycling alone: relative true residual before the first and after every V-cycle.
  std::vector<double>* cycleResiduals = nullptr;
};

/// A prepared MultigridSolver's host views, for a solve on another executor (gpu::
/// DeviceMultigrid): its levels and coarse operators' inputs, and its coarsest level's
/// factorisation and solve on host arrays.
struct MultigridMirror {
  std::vector<CycleLevel> levels;           ///< MultigridSolver::cycleLevels(A); level 0 is A
  std::vector<GalerkinLevelView> galerkin;  ///< galerkinLevels()
  CycleSettings settings;
  std::function<void(const double* values)> factorCoarsest;  ///< from its blocks' values
  std::function<void(const double* b, double* x)> solveCoarsest;
  /// Factorise and solve the coarsest level on the device when it is small enough (then the
  /// two functions above are not called). Off by default until it has run on a device.
  bool denseCoarsestOnDevice = false;
  /// The levels' values are prepared (the host's, to copy). Otherwise the solve's executor
  /// prepares them from A as MultigridSolver::prepare does: the fine diagonal (and, cycling
  /// with Jacobi or Chebyshev, its spectral bound) every solve and, with `refresh`, the coarse
  /// operators, their diagonals and bounds and the coarsest factor; the values here are then
  /// only those of levels whose `version` it has not seen.
  bool valuesOnHost = true;
  bool refresh = false;
  uint64_t version = 0;  ///< changes with the levels' structure (a re-binding) or a restore
};

/// Solves A x = b (x: the initial guess) with the cycle on level 0 of `cycle`. `prepare()` runs
/// once, before the first V-cycle (not at all when x already meets the tolerance). The contract
/// of MultigridSolver::solve.
template <class Exec, class Cycle, class Prepare>
SolveReport multigridSolve(const Exec& exec, const BlockMatrixView& A, const double* b, double* x,
                           const CgBuffers& w, const Cycle& cycle, const Prepare& prepare,
                           int maxIterations, double relativeTolerance, MultigridRun& run) {
  constexpr uint32_t kRows = 128, kEntries = 2048;
  const int32_t n3 = 3 * A.n;
  SolveReport report;
  report.relativeResidual = std::numeric_limits<double>::infinity();
  if (run.preconditionCG) {
    // One V-cycle per iteration of flexible CG (the cycle is not a fixed linear map).
    struct VCyclePreconditioner {
      bool flexible;
      const Exec* exec;
      const Cycle* cycle;
      const Prepare* prepareLevels;
      int32_t n3;
      int* count;
      void prepare() const { (*prepareLevels)(); }
      double apply(const double* r, double* z) const {
        cycle->template cycle<3>(0, r, z);
        ++*count;
        return exec->dot(r, z, n3);
      }
    };
    report = conjugateGradients(
        exec, A, b, x, w, VCyclePreconditioner{true, &exec, &cycle, &prepare, n3, &run.vCycles},
        maxIterations, relativeTolerance);
  } else {
    auto trueResidual = [&]() {
      exec.run(A.n, kRows, SpmvStage{A, x, w.ap});
      return exec.template reduce<SumOp>(n3, ResidualTerm{b, w.ap, w.r});
    };
    const double bb = exec.dot(b, b, n3);
    if (!std::isfinite(bb)) return report;
    if (bb == 0) {
      exec.run(n3, kEntries, FillStage{0.0, x});
      report.converged = true;
      report.relativeResidual = 0;
      return report;
    }
    if (exec.template reduce<MaxOp>(n3, NonFiniteTerm{x}) > 0)
      exec.run(n3, kEntries, FillStage{0.0, x});
    const double bnorm = std::sqrt(bb);
    const double tol2 = relativeTolerance * relativeTolerance * bb;
    double rr = trueResidual();
    bool converged = std::isfinite(rr) && rr <= tol2;
    if (!converged) {
      prepare();
      if (run.cycleResiduals) run.cycleResiduals->push_back(std::sqrt(rr) / bnorm);
    }
    int it = 0;
    while (!converged && it < run.cycles) {
      cycle.template cycle<3>(0, w.r, w.z);  // the error equation A e = r
      ++it;
      ++run.vCycles;
      exec.run(n3, kEntries, AxpyStage{x, w.z, 1.0, x});
      rr = trueResidual();
      if (run.cycleResiduals) run.cycleResiduals->push_back(std::sqrt(rr) / bnorm);
      if (!std::isfinite(rr)) {
        exec.run(n3, kEntries, AxpyStage{x, w.z, -1.0, x});  // the last finite iterate
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
  if (const double bb = exec.dot(b, b, n3);
      !std::isfinite(report.relativeResidual) && std::isfinite(bb) && bb > 0) {
    // Nothing finite came out: the zero vector, whose residual is |b| (relative 1).
    exec.run(n3, kEntries, FillStage{0.0, x});
    report.converged = false;
    report.relativeResidual = 1;
  }
  return report;
}

}  // namespace gf::detail
