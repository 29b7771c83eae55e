// gpu/element_pass.h: the host code is buffer management; the stages and the reduction are
// the CPU executor's (fem/element_stage.h, step/reduce.h), launched through gpu/launch.h.
#include "gpu/element_pass.h"
#include "gpu/launch.h"
#include "step/reduce.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

bool DeviceElementPass::fail(const char* what) {
  m_error = std::string(what) + ": " + lastError();
  return false;
}

bool DeviceElementPass::upload(const detail::ElementStage& h, const detail::GatherStage& gather,
                               int32_t tetCount, int32_t nodeCount) {
  m_tetCount = -1;  // copies everything
  return prepare(h, gather, tetCount, nodeCount, true);
}

bool DeviceElementPass::prepare(const detail::ElementStage& h, const detail::GatherStage& gather,
                                int32_t tetCount, int32_t nodeCount, bool stateChanged) {
  const size_t nt = size_t(tetCount), nn = size_t(nodeCount);
  const detail::ElementStage& was = m_modelFrom;
  const bool model =
      tetCount != m_tetCount || nodeCount != m_nodeCount || h.tets != was.tets ||
      h.restVolume != was.restVolume || h.fibreDir != was.fibreDir ||
      h.edgeMatrix != was.edgeMatrix || h.edgeMatrixInverse != was.edgeMatrixInverse ||
      gather.nodeRefStart != m_gatherFrom.nodeRefStart || gather.nodeRef != m_gatherFrom.nodeRef;
  const bool state = model || stateChanged || h.restInverse != was.restInverse ||
                     h.tetMask != was.tetMask || h.chi != was.chi || h.rigidTet != was.rigidTet ||
                     h.tetLame != was.tetLame;
  m_tetCount = tetCount;
  m_nodeCount = nodeCount;
  m_host = h;
  if (model) {
    m_modelFrom = {};  // a failed copy is retried at the next call
    if (!m_tets.upload(h.tets, 4 * nt) || !m_restVolume.upload(h.restVolume, nt) ||
        !m_fibreDir.upload(h.fibreDir, nt) || !m_edgeMatrix.upload(h.edgeMatrix, nt) ||
        !m_edgeMatrixInverse.upload(h.edgeMatrixInverse, nt) ||
        !m_nodeRefStart.upload(gather.nodeRefStart, nn + 1) ||
        !m_nodeRef.upload(gather.nodeRef, 4 * nt) || !m_energy.resize(nt) ||
        !m_grad.resize(12 * nt) || !m_nodeGrad.resize(3 * nn) ||
        !m_partials.resize(size_t(detail::sumChunks(tetCount))) || !m_sum.resize(1))
      return fail("uploading the body");
    m_modelFrom = h;
    m_gatherFrom = gather;
  }
  if (state) {
    m_modelFrom.restInverse = nullptr;  // retried at the next call if a copy fails
    const bool damaged = h.tetMask != nullptr;
    if (!mirrorChanged(m_restInverse, m_restInverseCopy, h.restInverse, nt) ||
        !mirrorChanged(m_tetMask, m_tetMaskCopy, h.tetMask, nt) ||
        !mirrorChanged(m_chi, m_chiCopy, damaged ? h.chi : nullptr, nt) ||
        !mirrorChanged(m_rigidTet, m_rigidTetCopy, h.rigidTet, nt) ||
        !mirrorChanged(m_tetLame, m_tetLameCopy, h.tetLame, 2 * nt))
      return fail("uploading the body's state");
    m_modelFrom.restInverse = h.restInverse;
    m_modelFrom.tetMask = h.tetMask;
    m_modelFrom.chi = h.chi;
    m_modelFrom.rigidTet = h.rigidTet;
    m_modelFrom.tetLame = h.tetLame;
  }
  return uploadPositions(h.x);
}

bool DeviceElementPass::uploadPositions(const double* x) {
  return m_x.upload(x, 3 * size_t(m_nodeCount)) || fail("uploading positions");
}

bool DeviceElementPass::run(bool withHessian, bool withStress, bool withGradient,
                            bool withNodeGradient) {
  const size_t nt = size_t(m_tetCount);
  if ((withHessian && !m_hess.resize(kElementMatrixSize * nt)) ||
      (withStress && !m_stress.resize(6 * nt)))
    return fail("allocating the element outputs");
  detail::ElementStage s = m_host;
  s.tets = m_tets.data();
  s.x = m_x.data();
  s.restInverse = m_restInverse.data();
  s.restVolume = m_restVolume.data();
  s.fibreDir = m_fibreDir.data();
  s.tetMask = m_tetMask.data();
  s.edgeMatrix = m_edgeMatrix.data();
  s.edgeMatrixInverse = m_edgeMatrixInverse.data();
  s.chi = m_chi.data();
  s.rigidTet = m_rigidTet.data();
  s.tetLame = m_tetLame.data();
  s.energy = m_energy.data();
  s.grad = withGradient ? m_grad.data() : nullptr;
  s.hess = withGradient && withHessian ? m_hess.data() : nullptr;
  s.stress = withStress ? m_stress.data() : nullptr;
  s.svdCache = nullptr;  // m_host's would be a host pointer; the device pass keeps no cache
  launch(s, m_tetCount, nullptr);
  launch(detail::ChunkReduceStage<detail::SumOp>{{m_energy.data()}, m_tetCount, m_partials.data()},
         detail::sumChunks(m_tetCount), nullptr);
  launch(detail::ChunkTotalStage<detail::SumOp>{m_partials.data(), detail::sumChunks(m_tetCount),
                                                m_sum.data()},
         1, nullptr);
  if (withGradient && withNodeGradient)
    launch(detail::GatherStage{m_nodeRefStart.data(), m_nodeRef.data(), m_grad.data(),
                               m_nodeGrad.data()},
           m_nodeCount, nullptr);
  if (!synchronize()) return fail("running the element stages");
  return m_sum.download(&m_psi, 1) || fail("reading the energy");
}

bool DeviceElementPass::criterionStresses(const detail::CriterionStressStage& stage) {
  const size_t nt = size_t(m_tetCount);
  if (!m_stress.resize(6 * nt)) return fail("allocating the stresses");
  detail::CriterionStressStage s = stage;
  s.tets = m_tets.data();
  s.x = m_x.data();
  s.restInverse = m_restInverse.data();
  s.fibreDir = m_fibreDir.data();
  s.tetLame = m_tetLame.data();
  s.tetMask = m_tetMask.data();
  s.chi = m_chi.data();
  s.rigidTet = m_rigidTet.data();
  s.stress = m_stress.data();
  s.svdCache = nullptr;
  launch(s, m_tetCount, nullptr);
  return synchronize() || fail("running the stress stage");
}

bool DeviceElementPass::download(double* energy, double* grad, double* hess, double* stress,
                                 double* nodeGrad) const {
  const size_t nt = size_t(m_tetCount);
  return (!energy || m_energy.download(energy, nt)) && (!grad || m_grad.download(grad, 12 * nt)) &&
         (!hess || m_hess.download(hess, kElementMatrixSize * nt)) &&
         (!stress || m_stress.download(stress, 6 * nt)) &&
         (!nodeGrad || m_nodeGrad.download(nodeGrad, 3 * size_t(m_nodeCount)));
}

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
