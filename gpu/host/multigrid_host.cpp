// The host build of gpu/multigrid.cu (see host/element_pass_host.cpp).
#include "gpu/multigrid.cu"  // NOLINT(bugprone-suspicious-include)
