// Set-up shared by the tests that drive detail::EmbeddedSurface outside the World: the rest
// inverses D_m^-1 of a mesh's tets that EmbeddedSurface::init takes.
#pragma once

#include <vector>

#include "common/render_mesh_checks.h"
#include "surface/embedded_mesh.h"

namespace gf::test {

inline std::vector<Mat3> tetRestInverses(const TetMesh& mesh) {
  std::vector<Mat3> restInverse(mesh.tetCount());
  for (size_t t = 0; t < mesh.tetCount(); ++t) {
    Vec3 P[4];
    for (int k = 0; k < 4; ++k) {
      const glm::dvec3 p = at(mesh.positions, size_t(mesh.tets[4 * t + size_t(k)]));
      P[k] = {p.x, p.y, p.z};
    }
    restInverse[t] = inverse(fromColumns(P[1] - P[0], P[2] - P[0], P[3] - P[0]));
  }
  return restInverse;
}

}  // namespace gf::test
