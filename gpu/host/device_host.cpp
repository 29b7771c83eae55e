// gpu/device.h in host memory: the host build of the device sources (gpu/host/), which CI
// runs against the CPU backend where there is no GPU.
#include <cstdlib>
#include <cstring>

#include "gpu/device.h"
#include "gpu/device_totals.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

namespace {
DeviceTotals g_totals;
}  // namespace

bool deviceAvailable(std::string&) { return true; }

void* deviceAlloc(size_t bytes) {
  void* p = std::malloc(bytes);
  if (p) g_totals.allocated(bytes);
  return p;
}

void deviceFree(void* p, size_t bytes) {
  if (!p) return;
  g_totals.freed(bytes);
  std::free(p);
}

bool copyToDevice(void* dst, const void* src, size_t bytes) {
  g_totals.copiedToDevice(bytes);
  std::memcpy(dst, src, bytes);
  return true;
}

bool copyToHost(void* dst, const void* src, size_t bytes) {
  g_totals.copiedToHost(bytes);
  std::memcpy(dst, src, bytes);
  return true;
}

CopyTotals copyTotals() { return g_totals.copies(); }
MemoryTotals memoryTotals() { return g_totals.memory(); }
bool synchronize() { return true; }
std::string lastError() { return "no error"; }
std::string deviceName() { return "host emulation"; }

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
