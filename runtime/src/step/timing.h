// Wall-clock timing of the step's stages (StepTimings, the multigrid's statistics).
#pragma once

#include <chrono>

namespace gf::detail {

using Clock = std::chrono::steady_clock;

/// Milliseconds since t0.
inline double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace gf::detail
