// The host build of gpu/body_device.cu (see host/element_pass_host.cpp).
#include "gpu/body_device.cu"  // NOLINT(bugprone-suspicious-include)
