// gpu/body_device.h: the device stages' owners behind detail::BodyDevice; no algorithm here.
#include "fem/element_stage.h"
#include "gpu/assembly.h"
#include "gpu/body_device.h"
#include "gpu/criterion.h"
#include "gpu/element_pass.h"
#include "gpu/multigrid.h"
#include "gpu/pcg.h"
#include "solver/block_sparse.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

namespace {

class DeviceBody final : public detail::BodyDevice {
 public:
  bool elementPass(const detail::ElementStage& stage, const detail::GatherStage& gather,
                   int32_t tetCount, int32_t nodeCount, bool stateChanged, double& psi,
                   double* nodeGrad) override {
    const bool withGradient = stage.grad != nullptr;
    if (!m_elements.prepare(stage, gather, tetCount, nodeCount, stateChanged) ||
        !m_elements.run(stage.hess != nullptr, stage.stress != nullptr, withGradient,
                        withGradient) ||
        !m_elements.download(nullptr, nullptr, nullptr, nullptr, withGradient ? nodeGrad : nullptr))
      return fail(m_elements.error());
    psi = m_elements.energy();
    return true;
  }

  bool criterionStresses(const detail::ElementStage& body, const detail::GatherStage& gather,
                         int32_t tetCount, int32_t nodeCount, bool stateChanged,
                         const detail::CriterionStressStage& criterion) override {
    if (!m_elements.prepare(body, gather, tetCount, nodeCount, stateChanged) ||
        !m_elements.criterionStresses(criterion))
      return fail(m_elements.error());
    return true;
  }

  int32_t criterionCandidates(const detail::CriterionView& host, double weakest) override {
    const int32_t count = m_criterion.find(host, m_elements.stresses(), weakest);
    if (count < 0) fail(m_criterion.error());
    return count;
  }

  bool readCriterionStresses(double* stress) override {
    return m_elements.download(nullptr, nullptr, nullptr, stress, nullptr) ||
           fail("reading the stresses");
  }

  bool downloadHessians(double* hess) override {
    return m_elements.download(nullptr, nullptr, hess, nullptr, nullptr) ||
           fail("reading the element Hessians");
  }

  bool assemble(const detail::DeviceAssembly& assembly) override {
    if (!m_elements.hessians()) return fail("assembling: no element Hessians on the device");
    return m_assembly.assemble(assembly, m_elements.hessians()) || fail(m_assembly.error());
  }

  bool downloadMatrix(double* values) override {
    return m_assembly.downloadValues(values) || fail(m_assembly.error());
  }

  bool multiply(const double* x, double* y) override {
    return m_assembly.multiply(x, y) || fail(m_assembly.error());
  }

  bool pcgSolve(const detail::BlockSparseMatrix& A, bool assembled, const double* b, double* x,
                int maxIterations, double tolerance, detail::SolveReport& report) override {
    if (!(assembled ? m_pcg.use(m_assembly.matrix()) : m_pcg.upload(A)) ||
        !m_pcg.solve(b, x, maxIterations, tolerance, report))
      return fail(m_pcg.error());
    return true;
  }

  bool multigridSolve(const detail::BlockSparseMatrix& A, bool assembled,
                      const detail::CycleSettings& settings,
                      const std::function<const detail::MultigridMirror*()>& prepare,
                      const double* b, double* x, int maxIterations, double tolerance,
                      detail::MultigridRun& run, detail::SolveReport& report) override {
    if (!(assembled ? m_multigrid.useMatrix(m_assembly.matrix(), settings)
                    : m_multigrid.uploadMatrix(A, settings)) ||
        !m_multigrid.solve(b, x, maxIterations, tolerance, run, report, prepare))
      return fail(m_multigrid.error());
    return true;
  }

  bool readLevel(uint64_t version, int level, double* values, size_t count) override {
    return m_multigrid.downloadLevel(version, level, values, count) || fail(m_multigrid.error());
  }

  const std::string& error() const override { return m_error; }

 private:
  bool fail(const std::string& why) {
    m_error = why;
    return false;
  }

  DeviceElementPass m_elements;
  DeviceCriterion m_criterion;
  DeviceAssembly m_assembly;
  DevicePcg m_pcg;
  DeviceMultigrid m_multigrid;
  std::string m_error;
};

}  // namespace

std::unique_ptr<detail::BodyDevice> makeBodyDevice() {
  std::string why;
  if (!deviceAvailable(why)) return nullptr;
  return std::make_unique<DeviceBody>();
}

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
