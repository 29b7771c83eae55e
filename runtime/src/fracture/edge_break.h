// What breaking an edge records, written by the fracture stages on either executor.
#pragma once

#include <cstdint>

#include "kernels/math.h"

namespace gf::detail {

/// One edge broken by the criterion, a brittle crack plane or a cut.
struct EdgeBreak {
  int32_t edge = -1;  ///< Edge id in the EdgeGraph.
  int32_t tet = -1;   ///< Tet that reported it (criterion, brittle seed); -1 for a cut.
  double stress = 0;  ///< Normal stress that broke it [Pa]; brittle: seed's principal; cut: 0.
  /// Where the edge splits, as the parameter from edgeNodes[2e] (0) to edgeNodes[2e+1] (1):
  /// 0.5 for the criterion, the plane or blade crossing for brittle planes and cuts.
  double split = 0.5;
  /// The split point in the positions the call was given: current positions when passed;
  /// otherwise rest positions (brittle) or (0, 0, 0) (criterion, which sees no mesh).
  Vec3 position;
};

}  // namespace gf::detail
