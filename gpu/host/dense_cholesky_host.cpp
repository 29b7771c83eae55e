// The host build of gpu/dense_cholesky.cu (see host/element_pass_host.cpp).
#include "gpu/dense_cholesky.cu"  // NOLINT(bugprone-suspicious-include)
