// gpu/assembly.h: buffer management around the host's assembly stages.
#include "gpu/assembly.h"
#include "solver/sparse_stages.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

bool DeviceAssembly::fail(const char* what) {
  m_error = std::string(what) + ": " + lastError();
  return false;
}

bool DeviceAssembly::assemble(const detail::DeviceAssembly& in, const double* elementMatrices) {
  const detail::BlockSparseMatrix& A = *in.pattern;
  const size_t nn = size_t(A.n), blocks = A.col.size();
  if (&A != m_patternFrom || in.gather != m_gatherFrom || in.diagonalBlock != m_diagonalFrom ||
      A.n != m_n) {
    m_patternFrom = nullptr;  // a failed copy is retried at the next call
    if (!m_rowStart.upload(A.rowStart.data(), nn + 1) || !m_col.upload(A.col.data(), blocks) ||
        !m_values.resize(9 * blocks) ||
        !m_gatherStart.upload(in.gather->start.data(), in.gather->start.size()) ||
        !m_gatherEntry.upload(in.gather->entry.data(), in.gather->entry.size()) ||
        !m_diagonalBlock.upload(in.diagonalBlock, nn))
      return fail("uploading the matrix pattern");
    m_n = A.n;
    m_patternFrom = &A;
    m_gatherFrom = in.gather;
    m_diagonalFrom = in.diagonalBlock;
  }
  const detail::NodeBlockStage& h = in.nodes;
  const bool tether = h.tether.w != nullptr;
  if (!m_nodeMass.upload(h.nodeMass, nn) || !m_contactHess.upload(h.contactHess, nn) ||
      !m_drag.upload(h.drag, nn) || !m_tetherW.upload(tether ? h.tether.w : nullptr, nn) ||
      !m_tetherTarget.upload(tether ? h.tether.target : nullptr, 3 * nn) ||
      !m_fixedNode.upload(in.fixedNode, nn) || (in.sum && !m_sum.resize(9 * blocks)) ||
      (!in.sum && in.addSum && !m_sum.upload(in.addSum, 9 * blocks)))
    return fail("uploading the node blocks");
  if (in.addScale != 0 && m_sum.size() != 9 * blocks) {
    m_error = "assembling: no damping matrix on the device";
    return false;
  }
  detail::AssembleStage elements{m_gatherStart.data(), m_gatherEntry.data(), elementMatrices,
                                 in.scale, m_values.data()};
  elements.accumulate = false;
  if (in.sum) elements.sum = m_sum.data();
  if (in.addScale != 0) {
    elements.addAfter = m_sum.data();
    elements.addScale = in.addScale;
  }
  m_exec.run(int32_t(blocks), 512, elements);
  detail::NodeBlockStage nodes = h;
  nodes.values = m_values.data();
  nodes.diagonalBlock = m_diagonalBlock.data();
  nodes.nodeMass = m_nodeMass.data();
  nodes.contactHess = m_contactHess.data();
  nodes.drag = m_drag.data();
  nodes.tether = {m_tetherW.data(), m_tetherTarget.data()};
  m_exec.run(m_n, 256, nodes);
  m_exec.run(
      m_n, 128,
      detail::DirichletStage{m_rowStart.data(), m_col.data(), m_fixedNode.data(), m_values.data()});
  if (!synchronize()) return fail("assembling the matrix");
  if (in.sum && !m_sum.download(in.sum, 9 * blocks)) return fail("reading the damping matrix");
  return true;
}

bool DeviceAssembly::downloadValues(double* values) {
  return m_values.download(values, 9 * m_col.size()) || fail("reading the matrix");
}

bool DeviceAssembly::multiply(const double* x, double* y) {
  const size_t n3 = 3 * size_t(m_n);
  if (!m_x.upload(x, n3) || !m_y.resize(n3)) return fail("uploading the vector");
  m_exec.run(m_n, 128, detail::SpmvStage{matrix(), m_x.data(), m_y.data()});
  if (!synchronize()) return fail("multiplying");
  return m_y.download(y, n3) || fail("reading the product");
}

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
