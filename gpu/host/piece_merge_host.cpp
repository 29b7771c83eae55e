// The host build of gpu/piece_merge.cu (see host/element_pass_host.cpp).
#include "gpu/piece_merge.cu"  // NOLINT(bugprone-suspicious-include)
