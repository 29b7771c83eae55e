// The totals gpu/device.h reports (copyTotals, memoryTotals), kept alike by both of its
// implementations (device_cuda.cu, host/device_host.cpp).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>

#include "gpu/device.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

class DeviceTotals {
 public:
  void allocated(size_t bytes) {
    const uint64_t held = m_held.fetch_add(bytes) + bytes;
    for (uint64_t peak = m_peak.load(); held > peak && !m_peak.compare_exchange_weak(peak, held);) {
    }
  }
  void freed(size_t bytes) { m_held.fetch_sub(bytes); }
  void copiedToDevice(size_t bytes) { m_toDevice.fetch_add(bytes, std::memory_order_relaxed); }
  void copiedToHost(size_t bytes) { m_toHost.fetch_add(bytes, std::memory_order_relaxed); }
  CopyTotals copies() const { return {m_toDevice.load(), m_toHost.load()}; }
  MemoryTotals memory() const { return {m_held.load(), m_peak.load()}; }

 private:
  std::atomic<uint64_t> m_toDevice{0}, m_toHost{0}, m_held{0}, m_peak{0};
};

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
