// What a device runs of a body's step on the CUDA backend (WorldDef::backend): the element pass,
// the Newton matrix's assembly, the fracture criterion and the linear solves, by the stages and
// solve templates the CPU runs (fem/element_stage.h, fem/node_stage.h, solver/sparse_stages.h,
// fracture/fracture_stages.h, solver/pcg_stages.h, solver/multigrid_cycle.h), on device copies
// of the body's buffers. The element Hessians, the assembled matrix and the criterion's stresses
// stay on the device; the host asks for them only where it needs them. The integrator keeps the
// rest of the step, and its order, on the host. Implemented by the device
// sources (gpu/body_device.cu; their host build, gpu/host/, for the `backend` tests), so the
// runtime names no CUDA type.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "fem/node_stage.h"

namespace gf::detail {

struct ElementStage;
struct GatherStage;
struct CriterionStressStage;
struct CriterionView;
struct BlockSparseMatrix;
struct ElementGather;
struct SolveReport;
struct MultigridRun;
struct MultigridMirror;
struct CycleSettings;

/// The Newton matrix as the host assembles it (Integrator::linearise), for assemble(): the
/// element blocks gathered with `scale` (AssembleStage, replacing A's values), the per-node
/// blocks (NodeBlockStage) and the Dirichlet rows (DirichletStage). Host arrays.
struct DeviceAssembly {
  const BlockSparseMatrix* pattern = nullptr;  ///< A's pattern (values not read)
  const ElementGather* gather = nullptr;
  const int32_t* diagonalBlock = nullptr;  ///< per node, its diagonal block in A
  double scale = 1;
  /// Also keep the element blocks' sum alone (K for Rayleigh damping), and copy it to `sum`.
  double* sum = nullptr;
  /// A += addScale * the kept sum, last (0: not added): this call's, else `addSum` (host, 9
  /// per block) where given, else the one an earlier call kept.
  double addScale = 0;
  const double* addSum = nullptr;
  NodeBlockStage nodes;  ///< its values and diagonalBlock are the device's
  const uint8_t* fixedNode = nullptr;
};

class BodyDevice {
 public:
  virtual ~BodyDevice() = default;
  /// The element stage over every tet and its energies' sum into psi (the CPU's order,
  /// step/reduce.h): the stage's non-null outputs say what is computed. Gradients are gathered
  /// per node (GatherStage, `gather`'s lists) into nodeGrad, 3 per node; Hessians and criterion
  /// stresses stay on the device (downloadHessians, assemble; criterionStresses). The body's model
  /// arrays (topology, rest data, the gather) are copied when their host addresses change; its
  /// state arrays (rest inverses, damage, rigid tets, wet Lamé values) with `stateChanged`, where
  /// their contents changed; x every call.
  virtual bool elementPass(const ElementStage& stage, const GatherStage& gather, int32_t tetCount,
                           int32_t nodeCount, bool stateChanged, double& psi, double* nodeGrad) = 0;
  /// The fracture criterion's stresses (`criterion`'s flags, the body's arrays as `body`
  /// names them and copies them as elementPass() does, at body.x), kept on the device; those
  /// of undamaged tets only with criterion.undamagedToo (else the last pass's serve).
  virtual bool criterionStresses(const ElementStage& body, const GatherStage& gather,
                                 int32_t tetCount, int32_t nodeCount, bool stateChanged,
                                 const CriterionStressStage& criterion) = 0;
  /// findCandidateEdges on those stresses, against `host`'s arrays (copied as
  /// gpu::DeviceCriterion::find says), the candidates into host's; -1 when it failed.
  virtual int32_t criterionCandidates(const CriterionView& host, double weakest) = 0;
  /// Those stresses to the host, 6 per tet.
  virtual bool readCriterionStresses(double* stress) = 0;
  /// The last pass's element Hessians to the host (kElementMatrixSize per tet).
  virtual bool downloadHessians(double* hess) = 0;
  /// The Newton matrix from the last pass's Hessians, on the device (see DeviceAssembly).
  virtual bool assemble(const DeviceAssembly& assembly) = 0;
  /// The assembled matrix's values to the host (9 per block).
  virtual bool downloadMatrix(double* values) = 0;
  /// y = A x with the assembled matrix (host arrays of 3 n).
  virtual bool multiply(const double* x, double* y) = 0;
  /// A x = b by block-Jacobi PCG, as detail::PcgSolver::solve (x: the start on entry); A's
  /// values are the last assemble()'s when `assembled`, else copied from A.
  virtual bool pcgSolve(const BlockSparseMatrix& A, bool assembled, const double* b, double* x,
                        int maxIterations, double tolerance, SolveReport& report) = 0;
  /// A x = b by the multigrid of MultigridSolver::solveWith, cycling with `settings` (A as for
  /// pcgSolve): `prepare` gives the levels to mirror, called where the solve reaches its first
  /// cycle (null: they cannot be had).
  virtual bool multigridSolve(const BlockSparseMatrix& A, bool assembled,
                              const CycleSettings& settings,
                              const std::function<const MultigridMirror*()>& prepare,
                              const double* b, double* x, int maxIterations, double tolerance,
                              MultigridRun& run, SolveReport& report) = 0;
  /// Coarse level `level`'s operator as the last multigrid solve prepared it, `count` doubles
  /// into `values`; false unless the mirrored levels are of `version` and that size
  /// (MultigridSolver::takeValues).
  virtual bool readLevel(uint64_t version, int level, double* values, size_t count) = 0;
  /// Why the last call failed.
  virtual const std::string& error() const = 0;
};

/// Makes a body's device; null when none can be made.
using BodyDeviceFactory = std::unique_ptr<BodyDevice> (*)();

}  // namespace gf::detail
