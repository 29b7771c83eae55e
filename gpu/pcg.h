// The body's linear solve on the device: solver/pcg_stages.h's conjugate gradients with the
// block-Jacobi preconditioner, run by the device executor (gpu/executor.h) on device copies of
// the matrix and the vectors. Built twice from one source like gpu/element_pass.h.
#pragma once

#include <string>

#include "gpu/device.h"
#include "gpu/executor.h"
#include "solver/block_sparse.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

class DevicePcg {
 public:
  /// Copies the matrix (pattern and values); false when device memory runs out (error()).
  bool upload(const detail::BlockSparseMatrix& A);
  /// Solves with a matrix already in device memory (gpu/assembly.h's) instead; it must stay
  /// there until the next upload() or use().
  bool use(const detail::BlockMatrixView& A);
  /// Solves the uploaded A x = b as detail::PcgSolver::solve does (same arguments, same
  /// report); b and x are host arrays of 3 n, x the initial guess on entry. False on a device
  /// error (error()), x then unchanged.
  bool solve(const double* b, double* x, int maxIterations, double relativeTolerance,
             detail::SolveReport& report);
  const std::string& error() const { return m_error; }

 private:
  bool fail(const char* what);
  bool allocate(int32_t n);

  detail::BlockMatrixView m_A;
  DeviceBuffer<int32_t> m_rowStart, m_col;
  DeviceBuffer<double> m_values, m_b, m_x, m_r, m_z, m_p, m_ap, m_invDiag;
  Executor m_exec;
  std::string m_error;
};

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
