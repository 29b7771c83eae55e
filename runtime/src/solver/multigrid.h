// Galerkin multigrid solver of the implicit step (SPEC §5, thesis sec 6.2, Xian et al. 2019):
// V-cycles over the hierarchy of multigrid_hierarchy.h, alone or preconditioning CG.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "graphfrac/defs.h"
#include "graphfrac/jobs.h"
#include "graphfrac/status.h"
#include "solver/block_sparse.h"
#include "solver/multigrid_cycle.h"
#include "solver/multigrid_hierarchy.h"

namespace gf::detail {

/// Costs and sizes of the multigrid, for reports and benchmarks. Stage times are those of the
/// last solve; setup and rebind times those of the last call.
struct MultigridStats {
  double refreshMs = 0;          ///< coarse operators, smoother set-up, coarsest factorisation
  double galerkinMs = 0;         ///< of refreshMs: the coarse operators P^T A P (and smoothing P)
  double factorMs = 0;           ///< of refreshMs: the coarsest factorisation
  double smoothMs = 0;           ///< smoothing sweeps on every level
  double coarseSolveMs = 0;      ///< coarsest-level solves
  double transferMs = 0;         ///< residuals, restriction and prolongation between levels
  double totalMs = 0;            ///< the whole solve
  double setupMs = 0;            ///< last setup()
  double rebindMs = 0;           ///< last re-binding applied (deferred ones: by a solve)
  std::vector<int32_t> handles;  ///< per coarse level, coarsest first (as MultigridSettings)
  int iterations = 0;            ///< CG iterations of the last solve (0 when cycling alone)
  int cycles = 0;                ///< V-cycles of the last solve
  bool refreshed = false;        ///< the last solve recomputed the coarse operators
  bool coarseFactorOk = true;    ///< the coarsest factorisation succeeded (else no correction)
};

/// What a solve reads beyond the matrix, its right-hand side and the settings: the re-bindings
/// applied and pending, the refresh schedule (coarseRefreshInterval) and what the last refresh
/// left that the next solve keeps. Given back to a solver set up alike (restore()), the solves
/// that follow are the same bits as the original solver's (World snapshots).
struct MultigridState {
  std::vector<int32_t> rebinds;  ///< broken-edge count at each re-binding applied, in order
  int32_t pendingRebind = -1;    ///< broken-edge count of a deferred re-binding; -1: none
  bool needRefresh = true;
  int solvesSinceRefresh = 0, refreshIterations = -1, lastIterations = 0;
  /// Empty when the next solve recomputes everything anyway.
  std::vector<CoarseLevelValues> levels;
};

/// Galerkin multigrid for the SPD block systems of the implicit step. Deterministic: the same
/// bits for any thread count. Allocates nothing in solve() after the first one following a
/// setup or rebind.
class MultigridSolver {
 public:
  MultigridSolver();
  ~MultigridSolver();
  MultigridSolver(MultigridSolver&&) noexcept;
  MultigridSolver& operator=(MultigridSolver&&) noexcept;

  /// Builds the hierarchy for the pattern of A (values are not read). restPositions: 3 per
  /// node; fixedNode: Dirichlet nodes, which A must hold as identity rows (applyDirichlet).
  Result<void> setup(const MultigridSettings& settings, const double* restPositions,
                     const uint8_t* fixedNode, const BlockSparseMatrix& A);
  /// Crack re-binding after edges broke (edgeNodes: 2 per edge; broken: 1/0 per edge, the
  /// full current state). No-op when settings.crackRebinding is false. With
  /// a refresh interval above 1 (the default with MG-CG) it is applied at the next refresh (the
  /// arrays are copied).
  void rebind(const int32_t* edgeNodes, const uint8_t* broken, int32_t edgeCount,
              JobSystem& jobs = serialJobs());
  /// Where solveWith's device prepared the levels, `read` copies each coarse level's operator
  /// (levels 1.., `count` doubles into `values`, of the levels of `version`) to the host, so
  /// that state() holds it; where it cannot (false), a solver restored from state() refreshes
  /// the operators at its first solve.
  void takeValues(
      const std::function<bool(uint64_t version, int level, double* values, size_t count)>& read);
  /// The state between solves (see MultigridState).
  MultigridState state() const;
  /// Whether restore() can take `state`: this solver applied a prefix of its re-bindings.
  bool canRestore(const MultigridState& state) const;
  /// Puts back state() of a solver set up with the same settings and A's pattern, when
  /// canRestore() (always right after setup()). breakOrder: the edges in the order they broke
  /// (the first k are the broken ones after k breaks); edgeNodes: 2 per edge. Fails when the
  /// state does not fit this solver.
  Result<void> restore(const MultigridState& state, const BlockSparseMatrix& A,
                       const int32_t* edgeNodes, int32_t edgeCount, const int32_t* breakOrder,
                       int32_t breakCount, JobSystem& jobs = serialJobs());
  /// Solves A x = b (A with the pattern given to setup). x holds the initial guess. With
  /// preconditionCG, flexible CG with one V-cycle per iteration up to maxIterations; else up to
  /// settings.cycles V-cycles (each x += V(b - A x)). Both stop early at relativeTolerance.
  /// iterations = CG iterations or V-cycles; relativeResidual is the true |b - A x| / |b|;
  /// converged = that residual <= relativeTolerance. Never leaves NaN in x.
  SolveReport solve(const BlockSparseMatrix& A, const double* b, double* x, int maxIterations,
                    double relativeTolerance, JobSystem& jobs);

  /// What solveWith() runs in place of the host's solve: A x = b by the cycle of `settings`,
  /// calling `prepare` where it reaches its first cycle (the levels to cycle on; null when they
  /// cannot be had), its report into `report`, `run` as multigridSolve's; false on a failure.
  using ExternalSolve = std::function<bool(const CycleSettings& settings,
                                           const std::function<const MultigridMirror*()>& prepare,
                                           MultigridRun& run, SolveReport& report)>;
  /// solve() run by `external` (a device's, detail::BodyDevice::multigridSolve) with the same
  /// schedule of refreshes and re-bindings and the same statistics; ok false when it failed
  /// (x is then as external left it). The levels' values are external's to prepare
  /// (MultigridMirror::valuesOnHost), but where only the host can: then `hostValues` is
  /// called first, to make A's values readable on the host (false fails the solve). A host
  /// solve after external ones refreshes the levels first.
  SolveReport solveWith(const BlockSparseMatrix& A, double* x, JobSystem& jobs,
                        const ExternalSolve& external, bool& ok,
                        const std::function<bool()>& hostValues = {});

  /// For a solve on another executor (gpu::DeviceMultigrid): whether the solver is set up for
  /// A's pattern; prepare() sets up what a V-cycle needs of A's values (what solve() does
  /// before its first cycle); cycleLevels() and galerkinLevels() (coarse level 1 first) are
  /// then the host buffers to mirror, valid until the next prepare() after a crack re-binding;
  /// the coarsest level's factorisation from a copy of its values and its solve on host arrays.
  bool ready(const BlockSparseMatrix& A) const;
  void prepare(const BlockSparseMatrix& A, JobSystem& jobs);
  std::vector<CycleLevel> cycleLevels(const BlockSparseMatrix& A);
  std::vector<GalerkinLevelView> galerkinLevels();
  CycleSettings cycleSettings() const;
  void factorCoarsest(const double* values);
  void solveCoarsest(const double* b, double* x, JobSystem& jobs);

  const MultigridStats& stats() const;
  const MultigridHierarchy& hierarchy() const;
  /// Relative true residual before the first and after every V-cycle of the last solve when
  /// cycling alone (the per-cycle reduction factors follow from it).
  const std::vector<double>& cycleResiduals() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

}  // namespace gf::detail
