// gpu/dense_cholesky.h: the device executor around the one dense Cholesky source.
#include "gpu/dense_cholesky.h"
#include "gpu/executor.h"
#include "solver/dense_cholesky.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

bool factorDenseBlocks(int32_t rows, const int32_t* rowStart, const int32_t* col,
                       const double* values, double* dense) {
  if (rows < 0 || 12 * int64_t(rows) > detail::kDenseCholeskyMaxSize) return false;
  Executor exec;
  const bool ok = detail::denseCholeskyFactorBlocks(exec, rows, rowStart, col, values, dense);
  return ok && !exec.takeFailure() && synchronize();
}

void solveDense(int32_t n, const double* factor, const double* b, double* x) {
  detail::denseCholeskySolve(Executor(), n, factor, b, x);
}

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
