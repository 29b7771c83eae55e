// Separate tets (4 own nodes each) with their rest inverses and volumes, laid out as the
// element and criterion stages read them: for kernel tests that put many deformations into one
// pass.
#pragma once

#include <cstdint>
#include <vector>

#include "kernels/element.h"

namespace gf::test {

struct TetSet {
  std::vector<int32_t> tets;
  std::vector<double> x;
  std::vector<Mat3> restInverse;
  std::vector<double> restVolume;
  int32_t count = 0;

  /// A tet of rest shape X with its nodes at xd.
  void add(const Vec3 X[4], const Vec3 xd[4]) {
    double vol = 0;
    restInverse.push_back(restShapeInverse(X, vol));
    restVolume.push_back(vol);
    for (int a = 0; a < 4; ++a) {
      tets.push_back(int32_t(x.size() / 3));
      x.insert(x.end(), {xd[a].x, xd[a].y, xd[a].z});
    }
    ++count;
  }
};

}  // namespace gf::test
