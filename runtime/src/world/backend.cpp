#include "world/backend.h"

#include <atomic>

#if defined(GF_HAVE_CUDA)
#include <dlfcn.h>

#include "gpu/body_device.h"
#endif

namespace gf::detail {

namespace {

// Whether a CUDA device is usable, and its name or why not. The driver API is loaded at run
// time, so the library needs neither the toolkit nor the driver to load.
struct DeviceProbe {
  bool present = false;
  std::string text;  // the device's name, or why there is none
};

DeviceProbe probeDevice() {
#if defined(GF_HAVE_CUDA)
  void* lib = dlopen("libcuda.so.1", RTLD_NOW | RTLD_LOCAL);
  if (!lib) return {false, "no CUDA driver (libcuda.so.1 not found)"};
  using Init = int (*)(unsigned);
  using Count = int (*)(int*);
  using Get = int (*)(int*, int);
  using Name = int (*)(char*, int, int);
  auto init = reinterpret_cast<Init>(dlsym(lib, "cuInit"));
  auto count = reinterpret_cast<Count>(dlsym(lib, "cuDeviceGetCount"));
  auto get = reinterpret_cast<Get>(dlsym(lib, "cuDeviceGet"));
  auto name = reinterpret_cast<Name>(dlsym(lib, "cuDeviceGetName"));
  DeviceProbe p{false, "the CUDA driver has no cuInit"};
  int devices = 0, device = 0;
  char buffer[256] = {};
  if (init && count && get && name) {
    if (const int e = init(0); e != 0)
      p.text = "no CUDA device (cuInit error " + std::to_string(e) + ")";
    else if (count(&devices) != 0 || devices == 0)
      p.text = "no CUDA device";
    else if (get(&device, 0) == 0 && name(buffer, int(sizeof buffer), device) == 0)
      p = {true, buffer};
    else
      p = {true, "CUDA device 0"};
  }
  // The driver stays loaded: unloading it under a live context is not supported.
  return p;
#else
  return {false, "this build has no CUDA backend"};
#endif
}

const DeviceProbe& device() {
  static const DeviceProbe probe = probeDevice();
  return probe;
}

std::atomic<BodyDeviceFactory> g_testDevice{nullptr};
std::atomic<const char*> g_testDeviceName{""};

}  // namespace

void setTestDevice(BodyDeviceFactory factory, const char* name) {
  g_testDeviceName.store(name ? name : "");
  g_testDevice.store(factory);
}

BackendChoice chooseBackend(Backend requested) {
  BackendChoice c;
  if (requested == Backend::Cpu) {
    c.description = "cpu: requested";
    return c;
  }
  BodyDeviceFactory factory = g_testDevice.load();
  std::string name = g_testDeviceName.load();
  if (!factory) {
    const DeviceProbe& d = device();
    name = d.text;
#if defined(GF_HAVE_CUDA)
    if (d.present) factory = &gpu::makeBodyDevice;
#endif
  }
  if (requested == Backend::Cuda) {
    if (!factory) {
      c.error =
          "WorldDef.backend: Cuda cannot run: " + name + "; use Backend::Auto or Backend::Cpu";
      return c;
    }
    c.backend = Backend::Cuda;
    c.device = factory;
    c.description = "cuda: " + name +
                    ": the element pass, the Newton matrix and the PCG and multigrid solves on "
                    "the device, the rest of the step on the CPU";
    return c;
  }
  // The device runs part of the step, with copies each Newton iteration, which has not been
  // measured faster than the CPU: Auto keeps the CPU until it has.
  c.description = factory ? "cpu: CUDA device " + name +
                                " found; Auto keeps the CPU until the whole step runs on the "
                                "device (Backend::Cuda runs part of it there)"
                          : "cpu: " + name;
  return c;
}

}  // namespace gf::detail
