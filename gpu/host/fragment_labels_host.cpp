// The host build of gpu/fragment_labels.cu (see host/element_pass_host.cpp).
#include "gpu/fragment_labels.cu"  // NOLINT(bugprone-suspicious-include)
