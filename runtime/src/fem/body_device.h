// What a device runs of a body's step on the CUDA backend (WorldDef::backend): the element pass
// and the linear solves, by the stages and solve templates the CPU runs (fem/element_stage.h,
// solver/pcg_stages.h, solver/multigrid_cycle.h), on device copies of the body's buffers. The
// integrator keeps the rest of the step, and its order, on the host. Implemented by the device
// sources (gpu/body_device.cu; their host build, gpu/host/, for the `backend` tests), so the
// runtime names no CUDA type.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace gf::detail {

struct ElementStage;
struct GatherStage;
struct BlockSparseMatrix;
struct SolveReport;
struct MultigridRun;
struct MultigridMirror;
struct CycleSettings;

class BodyDevice {
 public:
  virtual ~BodyDevice() = default;
  /// The element stage over every tet, its energies, gradients, Hessians and stresses written
  /// to the stage's host outputs (those that are non-null), and their sum into psi (the CPU's
  /// order, step/reduce.h). The body's model arrays (topology, rest data, the gather) are
  /// copied when their host addresses change; its state arrays (rest inverses, damage, rigid
  /// tets, wet Lamé values) when `stateChanged`; x every call.
  virtual bool elementPass(const ElementStage& stage, const GatherStage& gather, int32_t tetCount,
                           int32_t nodeCount, bool stateChanged, double& psi) = 0;
  /// A x = b by block-Jacobi PCG, as detail::PcgSolver::solve (x: the start on entry).
  virtual bool pcgSolve(const BlockSparseMatrix& A, const double* b, double* x, int maxIterations,
                        double tolerance, SolveReport& report) = 0;
  /// A x = b by the multigrid of MultigridSolver::solveWith, cycling with `settings`:
  /// `prepare` gives the levels to mirror, called where the solve reaches its first cycle
  /// (null: they cannot be had).
  virtual bool multigridSolve(const BlockSparseMatrix& A, const CycleSettings& settings,
                              const std::function<const MultigridMirror*()>& prepare,
                              const double* b, double* x, int maxIterations, double tolerance,
                              MultigridRun& run, SolveReport& report) = 0;
  /// Why the last call failed.
  virtual const std::string& error() const = 0;
};

/// Makes a body's device; null when none can be made.
using BodyDeviceFactory = std::unique_ptr<BodyDevice> (*)();

}  // namespace gf::detail
