// Host-side helpers of the loops that are not stages yet (the multigrid's set-up, the world's
// body batches): a parallel range loop through a JobSystem, and a finiteness check. Vector
// passes and reductions are stages (solver/vector_stages.h, step/reduce.h).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "graphfrac/jobs.h"

namespace gf::detail {

/// jobs.parallelFor(count, grain, f) through a one-reference wrapper: a std::function stores
/// that inline, whereas a lambda capturing several references would be heap-allocated on every
/// call, and a step must allocate nothing after warm-up.
template <class F>
void forRanges(JobSystem& jobs, uint32_t count, uint32_t grain, const F& f) {
  jobs.parallelFor(count, grain, [&f](uint32_t begin, uint32_t end) { f(begin, end); });
}

/// True when every entry is finite.
inline bool allFinite(const double* a, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(a[i])) return false;
  return true;
}

}  // namespace gf::detail
