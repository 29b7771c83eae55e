// gpu/body_device.h: the device stages' owners behind detail::BodyDevice; no algorithm here.
#include "fem/element_stage.h"
#include "gpu/body_device.h"
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
                   int32_t tetCount, int32_t nodeCount, bool stateChanged, double& psi) override {
    if (!m_elements.prepare(stage, gather, tetCount, nodeCount, stateChanged) ||
        !m_elements.run(stage.hess != nullptr, stage.stress != nullptr, stage.grad != nullptr,
                        false) ||
        !m_elements.download(stage.energy, stage.grad, stage.hess, stage.stress, nullptr))
      return fail(m_elements.error());
    psi = m_elements.energy();
    return true;
  }

  bool pcgSolve(const detail::BlockSparseMatrix& A, const double* b, double* x, int maxIterations,
                double tolerance, detail::SolveReport& report) override {
    if (!m_pcg.upload(A) || !m_pcg.solve(b, x, maxIterations, tolerance, report))
      return fail(m_pcg.error());
    return true;
  }

  bool multigridSolve(const detail::BlockSparseMatrix& A, const detail::CycleSettings& settings,
                      const std::function<const detail::MultigridMirror*()>& prepare,
                      const double* b, double* x, int maxIterations, double tolerance,
                      detail::MultigridRun& run, detail::SolveReport& report) override {
    if (!m_multigrid.uploadMatrix(A, settings) ||
        !m_multigrid.solve(b, x, maxIterations, tolerance, run, report, prepare))
      return fail(m_multigrid.error());
    return true;
  }

  const std::string& error() const override { return m_error; }

 private:
  bool fail(const std::string& why) {
    m_error = why;
    return false;
  }

  DeviceElementPass m_elements;
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
