// The host build of gpu/element_pass.cu: the same source compiled by the host compiler, with
// gpu/launch.h running each grid on the calling thread and host/device_host.cpp for memory.
#include "gpu/element_pass.cu"  // NOLINT(bugprone-suspicious-include)
