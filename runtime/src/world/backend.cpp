#include "world/backend.h"

#if defined(GF_HAVE_CUDA)
#include <dlfcn.h>
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

}  // namespace

BackendChoice chooseBackend(Backend requested) {
  BackendChoice c;
  if (requested == Backend::Cpu) {
    c.description = "cpu: requested";
    return c;
  }
  const DeviceProbe& d = device();
  // The device runs the element and gather stages (gpu/) but not yet a whole step, so no
  // world steps on it; Auto says what it found.
  const std::string why = d.present ? "CUDA device " + d.text +
                                          " found, but the whole step does not run on the "
                                          "device in this version"
                                    : d.text;
  if (requested == Backend::Cuda) {
    c.error = "WorldDef.backend: Cuda cannot run: " + why + "; use Backend::Auto or Backend::Cpu";
    return c;
  }
  c.description = "cpu: " + why;
  return c;
}

}  // namespace gf::detail
