// The host build of gpu/criterion.cu (see host/element_pass_host.cpp).
#include "gpu/criterion.cu"  // NOLINT(bugprone-suspicious-include)
