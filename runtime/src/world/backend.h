// Which backend runs a world's bodies (WorldDef::backend, World::backend).
#pragma once

#include <string>

#include "fem/body_device.h"
#include "graphfrac/defs.h"

namespace gf::detail {

/// The backend a world gets for a request: Auto resolved, the reason in words, or an error
/// when the request cannot be met.
struct BackendChoice {
  Backend backend = Backend::Cpu;
  std::string description;             ///< e.g. "cpu: no CUDA device"
  std::string error;                   ///< empty when the request is met
  BodyDeviceFactory device = nullptr;  ///< Cuda: makes each body's device
};

/// Looks for a CUDA device once per process (through the driver library, so a machine
/// without the driver runs the CPU backend unchanged).
BackendChoice chooseBackend(Backend requested);

/// For tests: while set, `factory` is the device of Backend::Cuda (named `name`), whether or
/// not the build has CUDA; the `backend` tests give it the host build of the device sources
/// (gpu/host/). Null restores the real one. Worlds created before keep theirs.
void setTestDevice(BodyDeviceFactory factory, const char* name);

}  // namespace gf::detail
