// The CUDA executor's launch of a stage (runtime/src/step/executor.h): one thread per item
// through one generic __global__ wrapper. Compiled by a host compiler (gpu/host/) the same
// grid runs block by block on the calling thread, so CI runs the device path's sources
// without a GPU.
#pragma once

#include <cstdint>

#if defined(__CUDACC__)
#include <cuda_runtime.h>
#endif

namespace gf::gpu {

/// Threads per block of every stage launch.
constexpr int32_t kBlock = 128;

/// A cudaStream_t, or null for the default stream (ignored on the host).
using Stream = void*;

#if defined(__CUDACC__)
template <class Stage>
__global__ void stageKernel(Stage stage, int32_t count) {
  const int32_t i = int32_t(blockIdx.x) * int32_t(blockDim.x) + int32_t(threadIdx.x);
  if (i < count) stage(i);
}
#endif

/// stage(i) for every i in [0, count) on the device, asynchronously on `stream`.
template <class Stage>
void launch(const Stage& stage, int32_t count, Stream stream) {
  if (count <= 0) return;
  const int32_t blocks = (count + kBlock - 1) / kBlock;
#if defined(__CUDACC__)
  stageKernel<<<blocks, kBlock, 0, static_cast<cudaStream_t>(stream)>>>(stage, count);
#else
  (void)stream;
  for (int32_t b = 0; b < blocks; ++b)
    for (int32_t t = 0; t < kBlock; ++t)
      if (b * kBlock + t < count) stage(b * kBlock + t);
#endif
}

}  // namespace gf::gpu
