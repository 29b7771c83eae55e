// gpu/device.h on the CUDA runtime.
#include <cuda_runtime.h>

#include "gpu/device.h"
#include "gpu/device_totals.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

namespace {
cudaError_t g_lastError = cudaSuccess;
DeviceTotals g_totals;

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
  g_totals.allocated(bytes);
  return p;
}

void deviceFree(void* p, size_t bytes) {
  if (!p) return;
  g_totals.freed(bytes);
  cudaFree(p);
}

bool copyToDevice(void* dst, const void* src, size_t bytes) {
  g_totals.copiedToDevice(bytes);
  return check(cudaMemcpy(dst, src, bytes, cudaMemcpyHostToDevice));
}

bool copyToHost(void* dst, const void* src, size_t bytes) {
  g_totals.copiedToHost(bytes);
  return check(cudaMemcpy(dst, src, bytes, cudaMemcpyDeviceToHost));
}

CopyTotals copyTotals() { return g_totals.copies(); }
MemoryTotals memoryTotals() { return g_totals.memory(); }

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
