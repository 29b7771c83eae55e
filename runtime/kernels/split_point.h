// Where the render surface splits a broken edge (thesis sec 4.4.1, fig 4.10): the force-ratio
// point, and the clamp that keeps every split point off the edge's ends.
#pragma once

#include "kernels/gf_hd.h"
#include "kernels/math.h"

namespace gf {

/// Split ratios are kept in [kMinSplitRatio, 1 - kMinSplitRatio]. At a ratio t the corner
/// cell's boundary facet (a, e_ab, f_abc) has t / 0.5 of its midpoint area; on an equilateral
/// face its quality 4 sqrt(3) A / sum(l^2) falls from 0.75 at the midpoint to 0.17 at t = 0.1
/// and to 0 at t = 0 (a sliver a renderer shades with a garbage normal). 0.1 allows force
/// ratios up to 9 : 1 and keeps every facet at least about a quarter as good as the midpoint's.
constexpr double kMinSplitRatio = 0.1;

/// t clamped to [kMinSplitRatio, 1 - kMinSplitRatio]; a non-finite t gives the midpoint.
GF_HD double clampSplitRatio(double t) {
  if (!isFinite(t)) return 0.5;
  return t < kMinSplitRatio ? kMinSplitRatio : (t > 1 - kMinSplitRatio ? 1 - kMinSplitRatio : t);
}

/// The force-ratio split of edge (a, b) from the nodal forces f_a, f_b (fig 4.10: the sections
/// are in inverse proportion to the forces, |a s| / |s b| = |f_b| / |f_a|), as the parameter
/// t = |f_b| / (|f_a| + |f_b|) from a, clamped (clampSplitRatio). No force on either node: 0.5.
GF_HD double forceRatioSplit(const Vec3& fa, const Vec3& fb) {
  const double na = norm(fa), nb = norm(fb);
  const double sum = na + nb;
  if (!(sum > 0) || !isFinite(sum)) return 0.5;
  return clampSplitRatio(nb / sum);
}

}  // namespace gf
