// A body's device on the CUDA backend (runtime/src/fem/body_device.h): the device element pass
// (gpu/element_pass.h), assembly (gpu/assembly.h) and linear solves (gpu/pcg.h,
// gpu/multigrid.h) behind the interface the integrator calls. Built twice from one source like
// them.
#pragma once

#include <memory>

#include "fem/body_device.h"
#include "gpu/device.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

/// A body's device, or null when no device can run it (deviceAvailable()).
std::unique_ptr<detail::BodyDevice> makeBodyDevice();

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
