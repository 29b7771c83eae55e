// The CPU's PCG: solver/pcg_stages.h's algorithm on the CPU executor, with the work vectors
// kept between solves.
#include "solver/pcg.h"

#include "solver/pcg_stages.h"
#include "step/executor.h"

namespace gf::detail {

SolveReport PcgSolver::solve(const BlockSparseMatrix& A, const double* b, double* x,
                             int maxIterations, double relativeTolerance, JobSystem& jobs) {
  const size_t n3 = 3 * static_cast<size_t>(A.n);
  if (m_r.size() < n3) {
    m_r.resize(n3);
    m_z.resize(n3);
    m_p.resize(n3);
    m_ap.resize(n3);
    m_invDiag.resize(3 * n3);
  }
  const CpuExecutor exec(jobs, &m_partials);
  const CgBuffers work{m_r.data(), m_z.data(), m_p.data(), m_ap.data(), nullptr};
  return conjugateGradients(exec, A.view(), b, x, work,
                            BlockJacobi<CpuExecutor>{false, exec, A.view(), m_invDiag.data()},
                            maxIterations, relativeTolerance);
}

}  // namespace gf::detail
