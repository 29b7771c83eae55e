// What only the device backend does: memory, copies and synchronisation. Two implementations
// with one interface: device_cuda.cu (the CUDA runtime) and host/device_host.cpp (host
// memory, for the host build of the device sources that CI tests). Each lives in its own
// inline namespace (a host-compiled user of graphfrac_cuda sees GF_GPU_CUDA from it), so the
// two builds never mix.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#if defined(__CUDACC__) || defined(GF_GPU_CUDA)
#define GF_GPU_ABI cuda
#else
#define GF_GPU_ABI host
#endif

namespace gf::gpu {
inline namespace GF_GPU_ABI {

/// Whether a device can run the calls below; when not, `why` says why.
bool deviceAvailable(std::string& why);
/// Device memory of `bytes`, or null when it cannot be had (lastError() says why).
void* deviceAlloc(size_t bytes);
/// Frees what deviceAlloc(bytes) gave.
void deviceFree(void* p, size_t bytes);
/// Copies between host and device memory; false on an error (lastError()).
bool copyToDevice(void* dst, const void* src, size_t bytes);
bool copyToHost(void* dst, const void* src, size_t bytes);
/// Waits for the device's work; false when a launch failed.
bool synchronize();
/// Bytes the copies above moved each way since the process started (all threads).
struct CopyTotals {
  uint64_t toDevice = 0, toHost = 0;
};
CopyTotals copyTotals();
/// Device memory held through deviceAlloc now, and at most since the process started.
struct MemoryTotals {
  uint64_t current = 0, peak = 0;
};
MemoryTotals memoryTotals();
/// The last error of the calls above, as text.
std::string lastError();
/// The device the calls above use ("host emulation" in the host build).
std::string deviceName();

/// An array of T in device memory, sized on upload.
template <class T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  ~DeviceBuffer() { deviceFree(m_data, m_capacity * sizeof(T)); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;

  /// Makes room for n items (contents undefined after a growth); false when out of memory.
  bool resize(size_t n) {
    if (n <= m_capacity) {
      m_size = n;
      return true;
    }
    deviceFree(m_data, m_capacity * sizeof(T));
    m_data = static_cast<T*>(deviceAlloc(n * sizeof(T)));
    m_capacity = m_data ? n : 0;
    m_size = m_capacity;
    return m_data != nullptr;
  }
  /// Copies n items from the host; a null host pointer (an absent optional input) leaves the
  /// buffer empty, so data() is null on the device too.
  bool upload(const T* host, size_t n) {
    if (!host || n == 0) {
      m_size = 0;
      return true;
    }
    return resize(n) && copyToDevice(m_data, host, n * sizeof(T));
  }
  bool download(T* host, size_t n) const {
    return n <= m_size && copyToHost(host, m_data, n * sizeof(T));
  }
  T* data() const { return m_size ? m_data : nullptr; }
  size_t size() const { return m_size; }

 private:
  T* m_data = nullptr;
  size_t m_size = 0, m_capacity = 0;
};

/// `device` holds host's n items after it: copied only where they differ from `copy`, the host
/// copy of what the last call copied (null or empty: `device` empty). For state arrays that
/// most steps leave as they were: comparing costs far less than a copy over the link.
template <class T>
bool mirrorChanged(DeviceBuffer<T>& device, std::vector<T>& copy, const T* host, size_t n) {
  if (!host || n == 0) {
    copy.clear();
    return device.upload(nullptr, 0);
  }
  if (device.size() == n && copy.size() == n && std::memcmp(copy.data(), host, n * sizeof(T)) == 0)
    return true;
  copy.clear();  // a failed copy is retried at the next call
  if (!device.upload(host, n)) return false;
  copy.assign(host, host + n);
  return true;
}

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
