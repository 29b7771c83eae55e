// The plane tags of clipped cells (cut_polytope.h, CutPolygon::on): every vertex of every cell of
// random tets cut by 1-4 random planes is tagged with at least three planes, and lies on each
// plane it is tagged with (tet faces by their barycentric coordinate, cuts by their distance),
// which is what lets the render surface weld vertices by name (cut_surface.h).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "kernels/cut_polytope.h"
#include "kernels/math.h"

namespace gf {
namespace {

TEST(XfemClipTags, EveryVertexLiesOnTheThreePlanesOrMoreItIsTaggedWith) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  int vertices = 0;
  double worst = 0;
  for (int trial = 0; trial < 300; ++trial) {
    Vec3 X[4];
    for (Vec3& x : X) x = {u(rng), u(rng), u(rng)};
    if (det(fromColumns(X[1] - X[0], X[2] - X[0], X[3] - X[0])) < 0) std::swap(X[1], X[2]);
    if (std::abs(det(fromColumns(X[1] - X[0], X[2] - X[0], X[3] - X[0]))) < 1e-3) continue;
    const int count = 1 + trial % kMaxCutPlanes;
    CutPlane planes[kMaxCutPlanes];
    const Vec3 centre = 0.25 * (X[0] + X[1] + X[2] + X[3]);
    for (int j = 0; j < count; ++j) {
      Vec3 n{u(rng), u(rng), u(rng)};
      n = (1.0 / norm(n)) * n;
      planes[j] = {n, dot(n, centre + 0.2 * Vec3{u(rng), u(rng), u(rng)})};
    }
    // Face a's plane: through the three other nodes.
    const int faces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    CutPlane face[4];
    for (int a = 0; a < 4; ++a) {
      Vec3 n = cross(X[faces[a][1]] - X[faces[a][0]], X[faces[a][2]] - X[faces[a][0]]);
      n = (1.0 / norm(n)) * n;
      face[a] = {n, dot(n, X[faces[a][0]])};
    }
    for (unsigned mask = 0; mask < (1u << count); ++mask) {
      const CutPolytope cell = clipTet(X, planes, count, mask);
      for (int f = 0; f < cell.faceCount; ++f) {
        const CutPolygon& g = cell.faces[f];
        for (int i = 0; i < g.count; ++i, ++vertices) {
          EXPECT_GE(__builtin_popcount(g.on[i]), 3) << trial;
          EXPECT_TRUE((g.on[i] >> g.label) & 1u) << "a face's vertex lies on the face";
          for (int l = 0; l < kCutFaceLabel + count; ++l)
            if ((g.on[i] >> l) & 1u) {
              const CutPlane& p = l < kCutFaceLabel ? face[l] : planes[l - kCutFaceLabel];
              worst = std::max(worst, std::abs(planeDistance(p, g.v[i])));
            }
        }
      }
    }
  }
  std::printf("%d cell vertices: farthest from a plane they are tagged with %.1e\n", vertices,
              worst);
  EXPECT_GT(vertices, 1000);
  EXPECT_LE(worst, 1e-14);
}

}  // namespace
}  // namespace gf
