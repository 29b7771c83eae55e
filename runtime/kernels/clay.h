// The clay-like response of a deform brush (thesis sec 7.2.3.4): node velocities are scaled by
// a kernel of the distance to the proxy, so the body yields near the tool and barely moves away
// from it.
#pragma once

#include "gf_hd.h"

namespace gf {

/// G_d of eq 7.7 at distance r [m] from the proxy: 1 / (1 + k1 r) inside the influence radius
/// rD, 1 / (1 + k1 r + exp(k2 r)) beyond it (k1, k2 in 1/m). As written in the thesis it drops
/// by the exp term at rD, so the region beyond the radius is held much more firmly.
GF_HD double clayDamping(double r, double rD, double k1, double k2) {
  return r < rD ? 1 / (1 + k1 * r) : 1 / (1 + k1 * r + exp(k2 * r));
}

}  // namespace gf
