// The multigrid's coarsest level factorised and solved on the device: solver/dense_cholesky.h's
// stages, run by the device executor (gpu/executor.h) on device arrays, so the CPU and the
// device factorise from one source. Matrices above detail::kDenseCholeskyMaxSize scalars are
// refused (the caller keeps the sparse host factor). Built twice from one source like
// gpu/piece_merge.h.
#pragma once

#include <cstdint>

#include "gpu/device.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

/// detail::denseCholeskyFactorBlocks on the device: the 12x12 block matrix (device arrays,
/// block CSR) expanded into `dense` (12 rows squared doubles, device) and factorised, with the
/// host's diagonal-shift retries. False when it is too large, not positive definite after
/// every retry, or on a device error (lastError()).
bool factorDenseBlocks(int32_t rows, const int32_t* rowStart, const int32_t* col,
                       const double* values, double* dense);
/// x = A^-1 b with the factor of factorDenseBlocks (n = 12 rows; device arrays, b and x apart),
/// asynchronously on the default stream.
void solveDense(int32_t n, const double* factor, const double* b, double* x);

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
