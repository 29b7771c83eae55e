// Queries on a triangle soup that need no clean input: the generalised winding number (Jacobson,
// Kavan and Sorkine-Hornung 2013), an inside/outside test that stays meaningful for open,
// multi-part and self-intersecting surfaces, and the closest point on the soup. Both run over one
// bounding-volume hierarchy; far clusters enter the winding number as dipoles (the first-order
// term of Barill et al. 2018, "Fast winding numbers for soups and clouds"), near ones by the
// exact van Oosterom-Strackee solid angle of each triangle.
#pragma once

#include <cstdint>
#include <vector>

#include "kernels/math.h"

namespace gf::meshing {

/// A triangle soup with a BVH over it. Triangle orientation matters for the winding number
/// (outward counter-clockwise); nothing else about the input is assumed.
class TriangleSoup {
 public:
  /// positions: 3 per vertex; triangles: 3 vertex indices each, in range. Degenerate
  /// triangles are kept (their solid angle and area are zero).
  TriangleSoup(const std::vector<double>& positions, const std::vector<int32_t>& triangles);

  /// Generalised winding number at q: (1 / 4 pi) times the sum of the triangles' signed solid
  /// angles; 1 inside a closed outward surface, 0 outside, 1/2 on a face. beta is how far (in
  /// cluster radii) a cluster must be to enter as a dipole; 0 sums every triangle exactly.
  double winding(Vec3 q, double beta = 3.0) const;
  /// The closest point on the soup to q among those within maxDistance; false if none.
  bool closestPoint(Vec3 q, double maxDistance, Vec3& closest) const;

  /// Bounding box of the triangles' vertices.
  Vec3 lo() const { return m_lo; }
  Vec3 hi() const { return m_hi; }
  size_t triangleCount() const { return m_tris.size(); }
  /// Divergence-theorem volume (sum of signed tets to the origin): the enclosed volume of a
  /// closed, outward-oriented surface; for overlapping parts it counts the overlap twice.
  double signedVolume() const;

 private:
  struct Tri {
    Vec3 a, b, c;
  };
  struct Node {
    Vec3 lo, hi;        // bounding box
    Vec3 centre;        // area-weighted centroid (the dipole's position)
    Vec3 areaNormal;    // sum of area * unit normal (the dipole's moment)
    double radius = 0;  // of the ball about centre holding the node's triangles
    int32_t first = 0;  // leaf: first triangle in m_tris; inner: left child (right = left+1)
    int32_t count = 0;  // leaf: triangle count; inner: 0
  };
  void build();  // fills m_nodes over m_tris (reordering them)

  std::vector<Tri> m_tris;
  std::vector<Node> m_nodes;
  Vec3 m_lo, m_hi;
};

/// Signed solid angle of triangle (a, b, c) seen from q (van Oosterom and Strackee 1983):
/// positive when q lies behind it (opposite its counter-clockwise normal), so the angles of a
/// closed outward surface sum to 4 pi from inside.
double solidAngle(Vec3 q, Vec3 a, Vec3 b, Vec3 c);

}  // namespace gf::meshing
