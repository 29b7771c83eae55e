// Blades for the Is-XFEM tests: planar rectangles meshed with jittered interior vertices, so
// a blade's triangles do not line up with the tets while the blade stays exactly planar.
#pragma once

#include <graphfrac/mesh.h>

#include <cmath>
#include <cstdint>
#include <random>

#include "fracture/cutting.h"
#include "xfem/cut_body.h"

namespace gf::test {

/// The plane x = a + b y + c z over y, z in [lo, hi]: n x n cells, two triangles each, with
/// jittered interior vertices, counter-clockwise in (y, z) so the normal points along
/// +x - b y - c z.
inline detail::Blade planarBlade(double a, double b, double c, double lo, double hi, int n,
                                 unsigned seed = 3) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  detail::Blade blade;
  const double h = (hi - lo) / n;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) {
      const bool interior = i > 0 && i < n && j > 0 && j < n;
      const double y = lo + h * (i + (interior ? jitter(rng) : 0));
      const double z = lo + h * (j + (interior ? jitter(rng) : 0));
      blade.vertices.insert(blade.vertices.end(), {a + b * y + c * z, y, z});
    }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const int32_t v00 = i * (n + 1) + j, v10 = v00 + n + 1, v01 = v00 + 1, v11 = v10 + 1;
      blade.triangles.insert(blade.triangles.end(), {v00, v10, v11, v00, v11, v01});
    }
  return blade;
}

/// x = a + b y + c z as a unit-normal cut plane (positive side: x above it).
inline CutPlane slantedPlane(double a, double b, double c) {
  const double len = std::sqrt(1 + b * b + c * c);
  return {{1 / len, -b / len, -c / len}, a / len};
}

/// The 2 x 1 x 1 m box of 6 x 3 x 3 cells (nodes every 1/3 m) the blade tests cut, dt = 1e-3.
inline detail::XfemBodyDef xfemBox(double youngs) {
  detail::XfemBodyDef def;
  def.mesh = gen::box(2, 1, 1, 6, 3, 3);
  def.material = {youngs, 0.3, 1000};
  def.dt = 1e-3;
  return def;
}

}  // namespace gf::test
