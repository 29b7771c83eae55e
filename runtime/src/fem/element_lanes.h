// The CPU's element pass over a range of tets: the undamaged tets of a body without a fibre
// term several at a time, one a SIMD lane (the kernels instantiated on a batch, kernels/
// lanes.h), the others one by one through ElementStage. A lane's results depend on its tet
// alone, never on the tets beside it, so they do not depend on how the tets are split between
// threads; they are the scalar kernels' to round-off.
#pragma once

#include <cstdint>

#include "fem/element_stage.h"

namespace gf::detail {

/// What stage(t) does for every t in [begin, end).
void evaluateElementRange(const ElementStage& stage, int32_t begin, int32_t end);

/// Tets evaluated at once: 1 where the library was built without SIMD batches (no xsimd).
int elementLaneWidth();

}  // namespace gf::detail
