// gpu/device.h on the CUDA runtime.
#include <cuda_runtime.h>

#include <atomic>

#include "gpu/device.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

namespace {
cudaError_t g_lastError = cudaSuccess;
std::atomic<uint64_t> g_toDevice{0}, g_toHost{0}, g_held{0}, g_peak{0};

bool check(cudaError_t e) {
  if (e != cudaSuccess) g_lastError = e;
  return e == cudaSuccess;
}
}  // namespace

bool deviceAvailable(std::string& why) {
  int count = 0;
  const cudaError_t e = cudaGetDeviceCount(&count);
  if (e != cudaSuccess) {
    why = std::string("no CUDA device: ") + cudaGetErrorString(e);
    return false;
  }
  if (count == 0) why = "no CUDA device";
  return count > 0;
}

void* deviceAlloc(size_t bytes) {
  void* p = nullptr;
  if (!check(cudaMalloc(&p, bytes))) return nullptr;
  const uint64_t held = g_held.fetch_add(bytes) + bytes;
  for (uint64_t peak = g_peak.load(); held > peak && !g_peak.compare_exchange_weak(peak, held);) {
  }
  return p;
}

void deviceFree(void* p, size_t bytes) {
  if (!p) return;
  g_held.fetch_sub(bytes);
  cudaFree(p);
}

bool copyToDevice(void* dst, const void* src, size_t bytes) {
  g_toDevice.fetch_add(bytes, std::memory_order_relaxed);
  return check(cudaMemcpy(dst, src, bytes, cudaMemcpyHostToDevice));
}

bool copyToHost(void* dst, const void* src, size_t bytes) {
  g_toHost.fetch_add(bytes, std::memory_order_relaxed);
  return check(cudaMemcpy(dst, src, bytes, cudaMemcpyDeviceToHost));
}

CopyTotals copyTotals() { return {g_toDevice.load(), g_toHost.load()}; }
MemoryTotals memoryTotals() { return {g_held.load(), g_peak.load()}; }

bool synchronize() { return check(cudaGetLastError()) && check(cudaDeviceSynchronize()); }

std::string lastError() { return cudaGetErrorString(g_lastError); }

std::string deviceName() {
  int device = 0;
  cudaDeviceProp prop{};
  if (!check(cudaGetDevice(&device)) || !check(cudaGetDeviceProperties(&prop, device)))
    return "no CUDA device (" + lastError() + ")";
  return prop.name;
}

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
