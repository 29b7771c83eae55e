// gpu/pcg.h: buffer management around the one conjugate-gradient source.
#include "gpu/pcg.h"
#include "solver/pcg_stages.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

bool DevicePcg::fail(const char* what) {
  m_error = std::string(what) + ": " + lastError();
  return false;
}

bool DevicePcg::allocate(int32_t n) {
  const size_t n3 = 3 * size_t(n);
  return (m_b.resize(n3) && m_x.resize(n3) && m_r.resize(n3) && m_z.resize(n3) && m_p.resize(n3) &&
          m_ap.resize(n3) && m_invDiag.resize(3 * n3)) ||
         fail("allocating the solve's vectors");
}

bool DevicePcg::upload(const detail::BlockSparseMatrix& A) {
  m_A = {};
  if (!m_rowStart.upload(A.rowStart.data(), A.rowStart.size()) ||
      !m_col.upload(A.col.data(), A.col.size()) ||
      !m_values.upload(A.values.data(), A.values.size()))
    return fail("uploading the matrix");
  m_A = {A.n, m_rowStart.data(), m_col.data(), m_values.data()};
  return allocate(A.n);
}

bool DevicePcg::use(const detail::BlockMatrixView& A) {
  m_A = A;
  return allocate(A.n);
}

bool DevicePcg::solve(const double* b, double* x, int maxIterations, double relativeTolerance,
                      detail::SolveReport& report) {
  const size_t n3 = 3 * size_t(m_A.n);
  if (!m_b.upload(b, n3) || !m_x.upload(x, n3)) return fail("uploading the right-hand side");
  const detail::BlockMatrixView& A = m_A;
  const detail::CgBuffers work{m_r.data(), m_z.data(), m_p.data(), m_ap.data(), nullptr};
  report =
      detail::conjugateGradients(m_exec, A, m_b.data(), m_x.data(), work,
                                 detail::BlockJacobi<Executor>{false, m_exec, A, m_invDiag.data()},
                                 maxIterations, relativeTolerance);
  if (m_exec.takeFailure() || !synchronize()) return fail("solving");
  return m_x.download(x, n3) || fail("reading the solution");
}

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
