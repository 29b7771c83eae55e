// Exact mass properties of uniform-density tetrahedra, for handing fragments to rigid-body
// physics (World::detachFragment). A fragment owns the corner cells of its nodes (the cells
// whose masses are the lumped node masses, eq 2.10 row-summed), so its mass equals the FEM's
// and its inertia is that of the actual material, not of point masses at the nodes.
#pragma once

#include "math.h"

namespace gf {

/// Mass-weighted second moment int rho x x^T dV of a uniform tet of mass m with corners x
/// (any origin): m/20 (sum_i x_i x_i^T + s s^T), s = sum_i x_i. Covariance form of the exact
/// tet inertia of Tonon 2005 ("Explicit exact formulas for the 3-D tetrahedron inertia tensor
/// in terms of its vertex coordinates", J. Math. Stat. 1(1), eq. 2-7).
GF_HD Mat3 tetSecondMoment(double mass, const Vec3 x[4]) {
  const Vec3 s = x[0] + x[1] + x[2] + x[3];
  Mat3 c;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double sum = s[i] * s[j];
      for (int a = 0; a < 4; ++a) sum += x[a][i] * x[a][j];
      c(i, j) = mass / 20.0 * sum;
    }
  return c;
}

/// Inertia tensor about the origin of a body with second moment C about the origin.
GF_HD Mat3 inertiaFromSecondMoment(const Mat3& c) { return trace(c) * Mat3::identity() - c; }

/// The 6 tets of the corner cell of corner `a` in the barycentric subdivision of tet x (the
/// cell of CrackSurface's default split: edge midpoints, face and tet centroids). Each has a
/// twenty-fourth of the tet's volume, the cell a quarter, and an affine map of the tet maps
/// them along, so a deformed tet's cell keeps its share of the mass.
GF_HD void cornerCellTets(const Vec3 x[4], int a, Vec3 out[6][4]) {
  const Vec3 g = 0.25 * (x[0] + x[1] + x[2] + x[3]);
  int others[3], k = 0;
  for (int b = 0; b < 4; ++b)
    if (b != a) others[k++] = b;
  int t = 0;
  for (int f = 0; f < 3; ++f) {
    // Face (a, e0, e1): the two sub-tets on the edges a-e0 and a-e1.
    const int e0 = others[f], e1 = others[(f + 1) % 3];
    const Vec3 face = (1.0 / 3.0) * (x[a] + x[e0] + x[e1]);
    for (int side = 0; side < 2; ++side) {
      const int e = side == 0 ? e0 : e1;
      out[t][0] = x[a];
      out[t][1] = 0.5 * (x[a] + x[e]);
      out[t][2] = face;
      out[t][3] = g;
      ++t;
    }
  }
}

}  // namespace gf
