// The multigrid on the device: solver/multigrid_cycle.h's flexible CG and V-cycle and
// galerkin_stages.h's coarse operators, run by the device executor on device copies of a
// detail::MultigridSolver's levels. The hierarchy (aggregates, prolongators, patterns) is built
// on the host and mirrored once per re-binding; a new matrix of the same pattern is refreshed
// on the device. The coarsest level is factorised and solved on the device too (a dense
// Cholesky, gpu/dense_cholesky.h) when HostMultigrid::denseCoarsestOnDevice asks for it and it
// has at most detail::kDenseCholeskyMaxSize scalars; otherwise its sparse Cholesky factor stays
// on the host (its values go there once per refresh, and 12 doubles per coarsest handle each
// way per V-cycle). Built twice from one source like gpu/pcg.h.
#pragma once

#include <deque>
#include <functional>
#include <string>
#include <vector>

#include "gpu/device.h"
#include "gpu/executor.h"
#include "solver/block_sparse.h"
#include "solver/multigrid_cycle.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

/// What DeviceMultigrid mirrors (detail::MultigridMirror).
using HostMultigrid = detail::MultigridMirror;

class DeviceMultigrid {
 public:
  /// Copies A and the levels to the device. False when device memory runs out (error()).
  bool upload(const detail::BlockSparseMatrix& A, const HostMultigrid& host);
  /// A new matrix of the uploaded pattern (host array of its values): the fine diagonal, the
  /// coarse operators P^T A P with their diagonals and spectral bounds on the device, the
  /// coarsest factor on the host; what MultigridSolver::prepare does on a refresh, with the
  /// prolongators of the upload. False on a device error (error()).
  bool refresh(const double* values);
  /// Solves the uploaded A x = b as MultigridSolver::solve does (same arguments and report);
  /// b and x are host arrays of 3 n, x the initial guess on entry. `run` says how (CG or
  /// cycles alone) and receives the cycle count. False on a device error (error()), x then
  /// unchanged.
  bool solve(const double* b, double* x, int maxIterations, double relativeTolerance,
             detail::MultigridRun& run, detail::SolveReport& report);
  /// For a solve that prepares its levels only where it reaches its first cycle, as
  /// MultigridSolver::solve does (the body step's, detail::BodyDevice): A and the cycle's
  /// settings, then solve() with `prepare`, which gives the levels (null fails the solve):
  /// mirrored when their values are the host's or their version is new, their values
  /// otherwise prepared here (HostMultigrid::valuesOnHost). A is level 0's matrix there.
  bool uploadMatrix(const detail::BlockSparseMatrix& A, const detail::CycleSettings& settings);
  /// As uploadMatrix() with a matrix already in device memory (gpu/assembly.h's), which must
  /// stay there until the next upload.
  bool useMatrix(const detail::BlockMatrixView& A, const detail::CycleSettings& settings);
  bool solve(const double* b, double* x, int maxIterations, double relativeTolerance,
             detail::MultigridRun& run, detail::SolveReport& report,
             const std::function<const HostMultigrid*()>& prepare);
  /// Coarse level `level`'s operator (count doubles) to the host, where the mirrored levels
  /// are of HostMultigrid::version `version` and the level has that size.
  bool downloadLevel(uint64_t version, int level, double* values, size_t count);
  const std::string& error() const { return m_error; }
  /// Whether the uploaded coarsest level is factorised and solved on the device (asked for and
  /// small enough), rather than on the host.
  bool coarsestOnDevice() const { return m_denseCoarse; }

 private:
  bool uploadLevels(const HostMultigrid& host);
  bool allocateVectors();
  // What MultigridSolver::prepare computes from A's values, on the device: the fine diagonal
  // (and its spectral bound when not refreshing) and, refreshing, the coarse operators, their
  // diagonals and bounds and the coarsest factor.
  bool prepareValues(bool refreshCoarse);
  bool factorCoarsestOnDevice();
  bool fail(const char* what);
  // A device copy of n items of host (null stays null); false when it cannot be made.
  template <class T, class Out>
  bool mirror(const T* host, size_t n, Out*& out);
  bool scratch(size_t n, double*& out);

  int32_t m_n = 0;
  size_t m_fineBlocks = 0;
  detail::BlockMatrixView m_A;
  std::vector<detail::CycleLevel> m_levels;  // device pointers; colourStart on the host
  std::vector<detail::GalerkinLevelView> m_galerkin;
  std::vector<std::vector<int32_t>> m_colourStart;
  HostMultigrid m_host;
  uint64_t m_version = ~uint64_t(0);         // HostMultigrid::version of the mirrored levels
  std::vector<double> m_coarsestValues;      // host copy for the factorisation
  std::vector<double> m_coarseB, m_coarseX;  // host staging of the coarsest solve
  std::deque<DeviceBuffer<int32_t>> m_ints;
  std::deque<DeviceBuffer<float>> m_floats;  // level 0's Gauss-Seidel copy
  std::deque<DeviceBuffer<double>> m_doubles;
  DeviceBuffer<double> m_b, m_x, m_r, m_z, m_p, m_ap, m_rOld;
  // uploadMatrix's copy of A, or useMatrix's A: level 0's matrix while fineReady.
  DeviceBuffer<int32_t> m_fineRowStart, m_fineCol;
  DeviceBuffer<double> m_fineValues;
  detail::BlockMatrixView m_fine;
  bool m_fineReady = false;
  DeviceBuffer<double> m_coarseDense;  // the coarsest level's dense factor (12 handles)^2
  bool m_denseCoarse = false, m_denseOk = false;
  Executor m_exec;
  bool m_coarseFailed = false;
  std::string m_error;
};

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
