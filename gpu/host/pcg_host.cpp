// The host build of gpu/pcg.cu (see host/element_pass_host.cpp).
#include "gpu/pcg.cu"  // NOLINT(bugprone-suspicious-include)
