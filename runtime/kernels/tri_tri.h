// Triangle-triangle and point/segment-tetrahedron tests for a blade's path through a tet mesh
// (Is-XFEM, thesis sec 3.1: "Moeller's triangle-triangle tests").
//
// Design: Moeller's interval test (T. Moeller, "A Fast Triangle-Triangle Intersection Test",
// JGT 2(2), 1997): each triangle's vertices are classified against the other's plane; if both
// straddle, the two triangles cut the planes' common line in two intervals, which overlap exactly
// when the triangles meet. Signed distances below a tolerance relative to the triangles' size
// count as zero, so touching triangles (a blade through a tet's vertex or along an edge) are
// reported as intersecting; coplanar triangles fall back to 2D edge-edge and containment tests.
// Touching is resolved later by the caller (a tet the blade only touches is left uncut).
#pragma once

#include "math.h"

namespace gf {

namespace detail {

// The interval where a triangle (projections vp, signed distances d to the other plane) meets
// the planes' common line; false when the triangle lies in the other plane.
GF_HD bool triangleInterval(const double vp[3], const double d[3], double& a, double& b) {
  int alone, o1, o2;
  if (d[0] * d[1] > 0) {
    alone = 2, o1 = 0, o2 = 1;
  } else if (d[0] * d[2] > 0) {
    alone = 1, o1 = 0, o2 = 2;
  } else if (d[1] * d[2] > 0 || d[0] != 0) {
    alone = 0, o1 = 1, o2 = 2;
  } else if (d[1] != 0) {
    alone = 1, o1 = 0, o2 = 2;
  } else if (d[2] != 0) {
    alone = 2, o1 = 0, o2 = 1;
  } else {
    return false;
  }
  // The lone vertex is strictly off the plane and the other two are on it or beyond, so neither
  // denominator vanishes.
  a = vp[alone] + (vp[o1] - vp[alone]) * d[alone] / (d[alone] - d[o1]);
  b = vp[alone] + (vp[o2] - vp[alone]) * d[alone] / (d[alone] - d[o2]);
  if (a > b) {
    const double t = a;
    a = b;
    b = t;
  }
  return true;
}

GF_HD double orient2(const double p[2], const double q[2], const double r[2]) {
  return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
}

// Closed 2D segments pq and rs meet (collinear overlaps included).
GF_HD bool segments2Intersect(const double p[2], const double q[2], const double r[2],
                              const double s[2]) {
  const double d1 = orient2(r, s, p), d2 = orient2(r, s, q);
  const double d3 = orient2(p, q, r), d4 = orient2(p, q, s);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0)))
    return true;
  const auto onSegment = [](const double a[2], const double b[2], const double c[2]) {
    return c[0] >= fmin(a[0], b[0]) && c[0] <= fmax(a[0], b[0]) && c[1] >= fmin(a[1], b[1]) &&
           c[1] <= fmax(a[1], b[1]);
  };
  return (d1 == 0 && onSegment(r, s, p)) || (d2 == 0 && onSegment(r, s, q)) ||
         (d3 == 0 && onSegment(p, q, r)) || (d4 == 0 && onSegment(p, q, s));
}

// Closed 2D triangle t contains point p (either orientation).
GF_HD bool triangle2Contains(const double t[3][2], const double p[2]) {
  const double a = orient2(t[0], t[1], p), b = orient2(t[1], t[2], p), c = orient2(t[2], t[0], p);
  return (a >= 0 && b >= 0 && c >= 0) || (a <= 0 && b <= 0 && c <= 0);
}

// Coplanar triangles (normal n) meet: projected on the axis plane where n is largest.
GF_HD bool coplanarTrianglesIntersect(Vec3 n, const Vec3 v[3], const Vec3 u[3]) {
  const double ax = fabs(n.x), ay = fabs(n.y), az = fabs(n.z);
  const int drop = ax >= ay && ax >= az ? 0 : (ay >= az ? 1 : 2);
  const int i0 = drop == 0 ? 1 : 0, i1 = drop == 2 ? 1 : 2;
  double p[3][2], q[3][2];
  for (int k = 0; k < 3; ++k) {
    p[k][0] = v[k][i0], p[k][1] = v[k][i1];
    q[k][0] = u[k][i0], q[k][1] = u[k][i1];
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (segments2Intersect(p[i], p[(i + 1) % 3], q[j], q[(j + 1) % 3])) return true;
  return triangle2Contains(p, q[0]) || triangle2Contains(q, p[0]);
}

}  // namespace detail

/// Closed triangles v and u meet (Moeller 1997); touching counts. `relTol` scales the distance
/// below which a vertex counts as on the other triangle's plane, relative to the triangles' size.
GF_HD bool trianglesIntersect(const Vec3 v[3], const Vec3 u[3], double relTol = 1e-12) {
  double size = 0;
  for (int k = 0; k < 3; ++k) {
    size = fmax(size, norm(v[(k + 1) % 3] - v[k]));
    size = fmax(size, norm(u[(k + 1) % 3] - u[k]));
  }
  const double tol = relTol * size;
  // Distances of u's vertices to v's plane, and the other way round, zeroed within tolerance.
  Vec3 n1 = cross(v[1] - v[0], v[2] - v[0]);
  Vec3 n2 = cross(u[1] - u[0], u[2] - u[0]);
  const double l1 = norm(n1), l2 = norm(n2);
  if (l1 == 0 || l2 == 0) return false;  // degenerate triangles cover nothing
  n1 = (1.0 / l1) * n1;
  n2 = (1.0 / l2) * n2;
  double du[3], dv[3];
  for (int k = 0; k < 3; ++k) {
    du[k] = dot(n1, u[k] - v[0]);
    dv[k] = dot(n2, v[k] - u[0]);
    if (fabs(du[k]) <= tol) du[k] = 0;
    if (fabs(dv[k]) <= tol) dv[k] = 0;
  }
  if ((du[0] > 0 && du[1] > 0 && du[2] > 0) || (du[0] < 0 && du[1] < 0 && du[2] < 0)) return false;
  if ((dv[0] > 0 && dv[1] > 0 && dv[2] > 0) || (dv[0] < 0 && dv[1] < 0 && dv[2] < 0)) return false;
  if (du[0] == 0 && du[1] == 0 && du[2] == 0) return detail::coplanarTrianglesIntersect(n1, v, u);
  // Both straddle: project onto the common line's largest axis and compare the intervals.
  const Vec3 d = cross(n1, n2);
  const double ax = fabs(d.x), ay = fabs(d.y), az = fabs(d.z);
  const int axis = ax >= ay && ax >= az ? 0 : (ay >= az ? 1 : 2);
  const double vp[3] = {v[0][axis], v[1][axis], v[2][axis]};
  const double up[3] = {u[0][axis], u[1][axis], u[2][axis]};
  double a0, a1, b0, b1;
  if (!detail::triangleInterval(vp, dv, a0, a1) || !detail::triangleInterval(up, du, b0, b1))
    return detail::coplanarTrianglesIntersect(n1, v, u);
  return a0 <= b1 + tol && b0 <= a1 + tol;
}

/// Barycentric coordinates of p in the tet X (positively oriented); all >= 0 inside.
GF_HD void tetBarycentric(const Vec3 X[4], Vec3 p, double l[4]) {
  const double v = det(fromColumns(X[1] - X[0], X[2] - X[0], X[3] - X[0]));
  l[1] = det(fromColumns(p - X[0], X[2] - X[0], X[3] - X[0])) / v;
  l[2] = det(fromColumns(X[1] - X[0], p - X[0], X[3] - X[0])) / v;
  l[3] = det(fromColumns(X[1] - X[0], X[2] - X[0], p - X[0])) / v;
  l[0] = 1 - l[1] - l[2] - l[3];
}

/// p lies in the closed tet X, up to relTol in barycentric coordinates.
GF_HD bool pointInTet(const Vec3 X[4], Vec3 p, double relTol = 1e-12) {
  double l[4];
  tetBarycentric(X, p, l);
  return l[0] >= -relTol && l[1] >= -relTol && l[2] >= -relTol && l[3] >= -relTol;
}

/// Segment (a, b) meets the closed tet X (positively oriented): the segment clipped against the
/// four faces' half-spaces (Cyrus-Beck) is not empty; relTol as in pointInTet.
GF_HD bool segmentMeetsTet(const Vec3 X[4], Vec3 a, Vec3 b, double relTol = 1e-12) {
  double la[4], lb[4];
  tetBarycentric(X, a, la);
  tetBarycentric(X, b, lb);
  // Barycentrics are affine along the segment: keep t where every l(t) >= -relTol.
  double t0 = 0, t1 = 1;
  for (int k = 0; k < 4; ++k) {
    const double fa = la[k] + relTol, fb = lb[k] + relTol;
    if (fa < 0 && fb < 0) return false;
    if (fa < 0) t0 = fmax(t0, fa / (fa - fb));
    if (fb < 0) t1 = fmin(t1, fa / (fa - fb));
  }
  return t0 <= t1;
}

/// Closed segment (a, b) crosses triangle (p0, p1, p2): its endpoints lie strictly on opposite
/// sides of the triangle's plane and the crossing is inside the triangle up to relTol of its
/// barycentric coordinates. On a hit, s is the crossing's parameter from a.
GF_HD bool segmentCrossesTriangle(Vec3 a, Vec3 b, Vec3 p0, Vec3 p1, Vec3 p2, double& s,
                                  double relTol = 1e-12) {
  const Vec3 n = cross(p1 - p0, p2 - p0);
  const double nn = dot(n, n);
  const double da = dot(n, a - p0), db = dot(n, b - p0);
  if (nn == 0 || !((da > 0 && db < 0) || (da < 0 && db > 0))) return false;
  s = da / (da - db);
  const Vec3 x = a + s * (b - a);
  const double w1 = dot(cross(x - p0, p2 - p0), n) / nn;  // barycentric of p1
  const double w2 = dot(cross(p1 - p0, x - p0), n) / nn;  // of p2
  return w1 >= -relTol && w2 >= -relTol && w1 + w2 <= 1 + relTol;
}

/// As segmentCrossesTriangle, for the sides of tet nodes against a blade: an endpoint within
/// snapA (snapB) of the triangle's plane counts as on it, and a point on the plane counts as the
/// positive side (normal (p1 - p0) x (p2 - p0)), as xfemHeaviside does. An endpoint on the plane
/// is its own crossing (s exactly 0 or 1). So a blade through a node (to rounding) crosses
/// exactly that node's edges towards the negative side, the same way in every tet around the
/// node, instead of crossing each edge or not by the sign of rounding noise.
GF_HD bool segmentCrossesTriangleSnapped(Vec3 a, Vec3 b, double snapA, double snapB, Vec3 p0,
                                         Vec3 p1, Vec3 p2, double& s, double relTol = 1e-12) {
  const Vec3 n = cross(p1 - p0, p2 - p0);
  const double nn = dot(n, n);
  if (nn == 0) return false;
  const double len = sqrt(nn);
  const double da = dot(n, a - p0) / len, db = dot(n, b - p0) / len;
  const bool onA = fabs(da) <= snapA, onB = fabs(db) <= snapB;
  if ((onA || da > 0) == (onB || db > 0)) return false;
  s = onA ? 0.0 : (onB ? 1.0 : da / (da - db));
  const Vec3 x = onA ? a : (onB ? b : a + s * (b - a));
  const double w1 = dot(cross(x - p0, p2 - p0), n) / nn;  // barycentric of p1
  const double w2 = dot(cross(p1 - p0, x - p0), n) / nn;  // of p2
  return w1 >= -relTol && w2 >= -relTol && w1 + w2 <= 1 + relTol;
}

}  // namespace gf
