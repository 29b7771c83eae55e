// Reductions of the step (energy sums) in one fixed order for both executors: chunks of
// kSumChunk items summed in index order, then the chunk sums in chunk order. The CPU runs it
// serially, the CUDA executor one chunk per thread; both give the same bits for any thread
// count or launch shape.
#pragma once

#include <cstdint>

#include "kernels/gf_hd.h"

namespace gf::detail {

/// Items per partial sum of a reduction.
constexpr int32_t kSumChunk = 256;

/// Sum of chunk c of values[0..count), in index order.
GF_HD double chunkSum(const double* values, int32_t count, int32_t c) {
  const int32_t end = (c + 1) * kSumChunk < count ? (c + 1) * kSumChunk : count;
  double s = 0;
  for (int32_t i = c * kSumChunk; i < end; ++i) s += values[i];
  return s;
}

/// Number of chunks of a reduction over `count` items.
GF_HD int32_t sumChunks(int32_t count) { return (count + kSumChunk - 1) / kSumChunk; }

/// Partial sums of a reduction, one chunk per item: the parallel half of chunkedSum.
struct ChunkSumStage {
  const double* values = nullptr;
  int32_t count = 0;
  double* partials = nullptr;  ///< sumChunks(count)

  GF_HD void operator()(int32_t c) const { partials[c] = chunkSum(values, count, c); }
};

/// Sum of values[0..count): the chunk sums of ChunkSumStage added in chunk order.
GF_HD double chunkedSum(const double* values, int32_t count) {
  double total = 0;
  for (int32_t c = 0; c < sumChunks(count); ++c) total += chunkSum(values, count, c);
  return total;
}

}  // namespace gf::detail
