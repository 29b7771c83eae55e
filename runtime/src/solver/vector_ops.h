// Vector kernels over raw double arrays, parallel through a JobSystem.
//
// Reductions are deterministic for any thread count: the array is cut into chunks of a fixed
// size (independent of the threads), each chunk is summed in a fixed order into its own partial,
// and the partials are added in chunk order on the calling thread. Element-wise operations write
// disjoint entries, so they are deterministic anyway.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "graphfrac/jobs.h"

namespace gf::detail {

/// jobs.parallelFor(count, grain, f) through a one-reference wrapper: a std::function stores
/// that inline, whereas a lambda capturing several references would be heap-allocated on every
/// call, and a step must allocate nothing after warm-up.
template <class F>
void forRanges(JobSystem& jobs, uint32_t count, uint32_t grain, const F& f) {
  jobs.parallelFor(count, grain, [&f](uint32_t begin, uint32_t end) { f(begin, end); });
}

/// Entries per reduction chunk. A multiple of 3 so a chunk holds whole nodes (fused per-node
/// operations such as the block-Jacobi preconditioner can reduce in the same pass).
inline constexpr size_t kReduceChunk = 3 * 1024;

/// Number of reduction chunks for n entries.
inline uint32_t reduceChunkCount(size_t n) {
  return static_cast<uint32_t>((n + kReduceChunk - 1) / kReduceChunk);
}

/// Runs f(begin, end) -> double over fixed chunks of [0, n) in parallel, stores each result in
/// partials[chunk] and returns their sum in chunk order. partials only grows, so a caller that
/// keeps it allocates nothing after warm-up.
template <class F>
double chunkedReduce(size_t n, std::vector<double>& partials, JobSystem& jobs, const F& f) {
  const uint32_t chunks = reduceChunkCount(n);
  if (partials.size() < chunks) partials.resize(chunks);
  double* out = partials.data();
  forRanges(jobs, chunks, 1, [&](uint32_t begin, uint32_t end) {
    for (uint32_t c = begin; c < end; ++c) {
      const size_t b = c * kReduceChunk;
      const size_t e = b + kReduceChunk < n ? b + kReduceChunk : n;
      out[c] = f(b, e);
    }
  });
  double s = 0;
  for (uint32_t c = 0; c < chunks; ++c) s += out[c];
  return s;
}

/// Runs f(begin, end) over fixed chunks of [0, n) in parallel (element-wise work).
template <class F>
void chunkedFor(size_t n, JobSystem& jobs, const F& f) {
  const uint32_t chunks = reduceChunkCount(n);
  forRanges(jobs, chunks, 1, [&](uint32_t begin, uint32_t end) {
    const size_t b = begin * kReduceChunk;
    const size_t e = end * kReduceChunk < n ? end * kReduceChunk : n;
    f(b, e);
  });
}

/// Sum of a[i] * b[i] over [begin, end) with four interleaved accumulators in a fixed order.
inline double dotRange(const double* a, const double* b, size_t begin, size_t end) {
  double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
  size_t i = begin;
  for (; i + 4 <= end; i += 4) {
    s0 += a[i] * b[i];
    s1 += a[i + 1] * b[i + 1];
    s2 += a[i + 2] * b[i + 2];
    s3 += a[i + 3] * b[i + 3];
  }
  for (; i < end; ++i) s0 += a[i] * b[i];
  return (s0 + s1) + (s2 + s3);
}

/// a . b over n entries; deterministic for any thread count.
inline double dot(const double* a, const double* b, size_t n, std::vector<double>& partials,
                  JobSystem& jobs) {
  return chunkedReduce(n, partials, jobs,
                       [&](size_t begin, size_t end) { return dotRange(a, b, begin, end); });
}

/// Euclidean norm of a over n entries; deterministic for any thread count.
inline double norm2(const double* a, size_t n, std::vector<double>& partials, JobSystem& jobs) {
  return std::sqrt(dot(a, a, n, partials, jobs));
}

/// y += alpha x.
inline void axpy(double alpha, const double* x, double* y, size_t n, JobSystem& jobs) {
  chunkedFor(n, jobs, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) y[i] += alpha * x[i];
  });
}

/// y = value.
inline void fill(double value, double* y, size_t n, JobSystem& jobs) {
  chunkedFor(n, jobs, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) y[i] = value;
  });
}

/// True when every entry is finite.
inline bool allFinite(const double* a, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(a[i])) return false;
  return true;
}

}  // namespace gf::detail
