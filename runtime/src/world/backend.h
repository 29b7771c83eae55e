// Which backend runs a world's bodies (WorldDef::backend, World::backend).
#pragma once

#include <string>

#include "graphfrac/defs.h"

namespace gf::detail {

/// The backend a world gets for a request: Auto resolved, the reason in words, or an error
/// when the request cannot be met.
struct BackendChoice {
  Backend backend = Backend::Cpu;
  std::string description;  ///< e.g. "cpu: no CUDA device"
  std::string error;        ///< empty when the request is met
};

/// Looks for a CUDA device once per process (through the driver library, so a machine
/// without the driver runs the CPU backend unchanged).
BackendChoice chooseBackend(Backend requested);

}  // namespace gf::detail
