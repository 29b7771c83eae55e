// gpu/device.h in host memory: the host build of the device sources (gpu/host/), which CI
// runs against the CPU backend where there is no GPU.
#include <atomic>
#include <cstdlib>
#include <cstring>

#include "gpu/device.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

namespace {
std::atomic<uint64_t> g_toDevice{0}, g_toHost{0}, g_held{0}, g_peak{0};
}  // namespace

bool deviceAvailable(std::string&) { return true; }

void* deviceAlloc(size_t bytes) {
  void* p = std::malloc(bytes);
  if (p) {
    const uint64_t held = g_held.fetch_add(bytes) + bytes;
    for (uint64_t peak = g_peak.load(); held > peak && !g_peak.compare_exchange_weak(peak, held);) {
    }
  }
  return p;
}

void deviceFree(void* p, size_t bytes) {
  if (!p) return;
  g_held.fetch_sub(bytes);
  std::free(p);
}

bool copyToDevice(void* dst, const void* src, size_t bytes) {
  g_toDevice.fetch_add(bytes, std::memory_order_relaxed);
  std::memcpy(dst, src, bytes);
  return true;
}

bool copyToHost(void* dst, const void* src, size_t bytes) {
  g_toHost.fetch_add(bytes, std::memory_order_relaxed);
  std::memcpy(dst, src, bytes);
  return true;
}

CopyTotals copyTotals() { return {g_toDevice.load(), g_toHost.load()}; }
MemoryTotals memoryTotals() { return {g_held.load(), g_peak.load()}; }
bool synchronize() { return true; }
std::string lastError() { return "no error"; }
std::string deviceName() { return "host emulation"; }

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
