// Is-XFEM enrichment of a cut tet (thesis eqs 3.1-3.4, 3.7; Wu and Li 2015): the signed
// distance to a cut, the stable enrichment psi and the enriched shape functions psi N with
// their gradients.
//
// Shape functions of an element with m cuts are numbered A = a (standard N_a, a = 0..3) and
// A = 4 + 4j + a (psi_a^j N_a, the enriched function of node a for cut j), 4 (1 + m) in all.
// Inside one cell of the cut element, H(Phi^j) is the cell's side of plane j, a constant, so
// every psi is linear there and every enriched function quadratic: a cell's quadrature is
// evaluated with the cell's sides, never with H of the point, because moment-fitted points
// may lie outside their cell.
#pragma once

#include "contact.h"
#include "cut_polytope.h"

namespace gf {

/// Heaviside of eq 3.2: a point on the cut counts as the positive side, as in graph cutting.
GF_HD double xfemHeaviside(double phi) { return phi >= 0 ? 1.0 : 0.0; }

/// Signed distance (eq 3.1) to the triangle (a, b, c): the distance to its closest point, with
/// the sign of the side of its plane (normal (b - a) x (c - a)). Exact for a point whose closest
/// point is inside the triangle; for the blade's interior that is every point near the cut.
GF_HD double signedDistanceToTriangle(Vec3 p, Vec3 a, Vec3 b, Vec3 c) {
  const double side = dot(cross(b - a, c - a), p - a) >= 0 ? 1.0 : -1.0;
  const Vec3 w = closestOnTriangle(p, a, b, c);
  return side * norm(p - (w.x * a + w.y * b + w.z * c));  // eq 3.1
}

/// Stable enrichment value (eq 3.2) in a cell on side hCell of the cut, for a node on side
/// hNode, with gamma the interpolated node sides at the point (eq 3.3). k = 0 is classic XFEM.
GF_HD double stableEnrichment(double k, double hCell, double gamma, double hNode) {
  return hCell - (k * gamma + (1.0 - k) * hNode);  // eq 3.2
}

/// The node sides of one element for its cuts: side[j][a] = H(Phi^j(X_a)).
struct CutElementSides {
  double side[kMaxCutPlanes][4] = {};
  int cutCount = 0;
};

/// Values and rest-space gradients of the 4 (1 + cutCount) shape functions of a cut element
/// (eqs 3.4, 3.7) at x, in the cell on the sides `cellMask` (bit j: positive side of cut j).
/// X0 is node 0 and B the shape gradients (element.h shapeGradients).
GF_HD void enrichedShapeFunctions(Vec3 X0, const Mat<4, 3>& B, const CutElementSides& sides,
                                  unsigned cellMask, double k, Vec3 x, double* value,
                                  Vec3* gradient) {
  double N[4];
  Vec3 dN[4];
  const Vec3 r = x - X0;
  for (int a = 0; a < 4; ++a) {
    dN[a] = {B(a, 0), B(a, 1), B(a, 2)};
    N[a] = (a == 0 ? 1.0 : 0.0) + dot(dN[a], r);
    value[a] = N[a];
    gradient[a] = dN[a];
  }
  for (int j = 0; j < sides.cutCount; ++j) {
    const double hCell = (cellMask >> j) & 1u ? 1.0 : 0.0;
    double gamma = 0;  // eq 3.3
    Vec3 dGamma;
    for (int l = 0; l < 4; ++l) {
      gamma += N[l] * sides.side[j][l];
      dGamma += sides.side[j][l] * dN[l];
    }
    for (int a = 0; a < 4; ++a) {
      const double psi = stableEnrichment(k, hCell, gamma, sides.side[j][a]);
      const int A = 4 + 4 * j + a;
      value[A] = psi * N[a];                             // eq 3.7
      gradient[A] = psi * dN[a] + (-k * N[a]) * dGamma;  // grad psi = -k grad gamma
    }
  }
}

}  // namespace gf
