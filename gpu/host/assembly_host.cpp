// The host build of gpu/assembly.cu (see host/element_pass_host.cpp).
#include "gpu/assembly.cu"  // NOLINT(bugprone-suspicious-include)
