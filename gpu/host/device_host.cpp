// gpu/device.h in host memory: the host build of the device sources (gpu/host/), which CI
// runs against the CPU backend where there is no GPU.
#include <cstdlib>
#include <cstring>

#include "gpu/device.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

bool deviceAvailable(std::string&) { return true; }
void* deviceAlloc(size_t bytes) { return std::malloc(bytes); }
void deviceFree(void* p) { std::free(p); }

bool copyToDevice(void* dst, const void* src, size_t bytes) {
  std::memcpy(dst, src, bytes);
  return true;
}

bool copyToHost(void* dst, const void* src, size_t bytes) {
  std::memcpy(dst, src, bytes);
  return true;
}

bool synchronize() { return true; }
std::string lastError() { return "no error"; }
std::string deviceName() { return "host emulation"; }

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
