// A tetrahedron clipped by cut planes (Is-XFEM, thesis sec 3.2): the convex cells an element is
// split into, their exact polynomial moments, and the Grundmann-Moeller simplex rules the moments
// are computed with.
//
// Design: a cell is kept as its boundary, a list of outward-oriented convex polygons, each
// labelled with where it came from (a tet face or a cut plane), so the cut faces are available
// for the surface rule and for rendering without a second intersection pass. Clipping is
// Sutherland-Hodgman per face plus one cap polygon per plane. A point ON a plane belongs to both
// sides (kept by either half-space), so a plane through a vertex or an edge gives one empty side
// and never a sliver of rounding noise. Every plane-edge intersection is computed from the edge's
// endpoints in lexicographic order, so the two faces sharing an edge produce the bitwise same
// point and the cap polygon's vertices can be deduplicated exactly.
// Moments are exact: the cell is split into cones from its vertex average over fan triangles of
// each face, and each cone tet is integrated by a Grundmann-Moeller rule of degree
// 2s + 1 >= the moment degree (exact for polynomials up to that degree).
#pragma once

#include "math.h"

namespace gf {

/// A plane n.x = offset; planeDistance is the signed distance when n is a unit vector.
struct CutPlane {
  Vec3 normal;
  double offset = 0;
};

GF_HD double planeDistance(const CutPlane& p, Vec3 x) { return dot(p.normal, x) - p.offset; }

/// Cut planes one element can carry (several cuts per element, issue 21).
constexpr int kMaxCutPlanes = 4;
/// A cell of a tet cut by planes has at most 4 + kMaxCutPlanes faces, and a face of a convex
/// polytope with F faces at most F - 1 edges; the margin absorbs vertices that round onto a plane.
constexpr int kCutPolytopeMaxFaces = 4 + kMaxCutPlanes;
constexpr int kCutPolygonMaxVertices = 2 * kCutPolytopeMaxFaces;
/// Label of a cell face that lies on cut plane j: kCutFaceLabel + j (tet faces are 0..3,
/// the face opposite node a).
constexpr int kCutFaceLabel = 4;

/// A planar convex polygon, counter-clockwise seen from outside its cell.
struct CutPolygon {
  Vec3 v[kCutPolygonMaxVertices];
  /// Per vertex, bit l set when it lies on the plane labelled l (tet faces 0..3, cuts
  /// kCutFaceLabel + j): which mesh node, edge or face and which cuts a vertex is made of, so a
  /// surface can weld vertices by what they are rather than by where they round to.
  unsigned on[kCutPolygonMaxVertices] = {};
  int count = 0;
  int label = 0;  ///< 0..3: tet face opposite that node; kCutFaceLabel + j: cut plane j.
};

/// A convex cell as its outward-oriented boundary polygons; faceCount == 0 is the empty cell.
struct CutPolytope {
  CutPolygon faces[kCutPolytopeMaxFaces];
  int faceCount = 0;
};

/// The tet X[0..3] (positively oriented) as a polytope.
GF_HD CutPolytope tetPolytope(const Vec3 X[4]) {
  // Faces opposite node 0..3, counter-clockwise from outside for det[X1-X0, X2-X0, X3-X0] > 0.
  const int f[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  CutPolytope p;
  for (int a = 0; a < 4; ++a) {
    CutPolygon& g = p.faces[a];
    for (int k = 0; k < 3; ++k) {
      g.v[k] = X[f[a][k]];
      g.on[k] = 0xFu & ~(1u << f[a][k]);  // node n lies on every face but the one opposite it
    }
    g.count = 3;
    g.label = a;
  }
  p.faceCount = 4;
  return p;
}

namespace detail {

GF_HD bool lexLess(Vec3 a, Vec3 b) {
  if (a.x != b.x) return a.x < b.x;
  if (a.y != b.y) return a.y < b.y;
  return a.z < b.z;
}

GF_HD bool sameBits(Vec3 a, Vec3 b) { return a.x == b.x && a.y == b.y && a.z == b.z; }

// The crossing of segment (a, b) with the plane, from the lexicographically smaller endpoint so
// both faces of an edge get the same bits.
GF_HD Vec3 planeCrossing(const CutPlane& plane, Vec3 a, Vec3 b) {
  if (lexLess(b, a)) {
    const Vec3 t = a;
    a = b;
    b = t;
  }
  const double da = planeDistance(plane, a), db = planeDistance(plane, b);
  return a + (da / (da - db)) * (b - a);
}

}  // namespace detail

/// Keeps the part of `p` where planeDistance(plane, x) * side >= 0 (side = +1 or -1) and closes
/// it with a cap polygon labelled `capLabel`. A vertex within `onPlane` of the plane counts as on
/// it (0: exactly on it only); a cut through a node to rounding then leaves no sliver cell of
/// rounding noise either. Returns false (and leaves `p` unusable) when a capacity would be
/// exceeded, which cannot happen for a tet and at most kMaxCutPlanes planes.
GF_HD bool clipPolytope(CutPolytope& p, const CutPlane& plane, double side, int capLabel,
                        double onPlane = 0) {
  const CutPlane h{side * plane.normal, side * plane.offset};
  CutPolytope out;
  Vec3 cap[2 * kCutPolygonMaxVertices * kCutPolytopeMaxFaces];
  unsigned capOn[2 * kCutPolygonMaxVertices * kCutPolytopeMaxFaces];
  const unsigned capBit = 1u << capLabel;
  int capCount = 0;
  bool capInFace = false;
  for (int f = 0; f < p.faceCount; ++f) {
    const CutPolygon& in = p.faces[f];
    CutPolygon g;
    g.label = in.label;
    // A face lying in the plane already is the cap (same outward normal): relabel it.
    bool inPlane = true;
    for (int i = 0; i < in.count && inPlane; ++i)
      inPlane = fabs(planeDistance(h, in.v[i])) <= onPlane;
    if (inPlane) {
      g = in;
      g.label = capLabel;
      for (int i = 0; i < g.count; ++i) g.on[i] |= capBit;
      out.faces[out.faceCount++] = g;
      capInFace = true;
      continue;
    }
    for (int i = 0; i < in.count; ++i) {
      const Vec3 a = in.v[i], b = in.v[(i + 1) % in.count];
      double da = planeDistance(h, a), db = planeDistance(h, b);
      if (fabs(da) <= onPlane) da = 0;
      if (fabs(db) <= onPlane) db = 0;
      if (da >= 0) {
        if (g.count == kCutPolygonMaxVertices) return false;
        g.on[g.count] = in.on[i] | (da == 0 ? capBit : 0u);
        g.v[g.count++] = a;
        if (da == 0) {
          capOn[capCount] = in.on[i] | capBit;
          cap[capCount++] = a;
        }
      }
      // Strictly opposite sides only: a vertex on the plane is its own crossing.
      if ((da > 0 && db < 0) || (da < 0 && db > 0)) {
        if (g.count == kCutPolygonMaxVertices) return false;
        const Vec3 x = detail::planeCrossing(h, a, b);
        // On the planes both ends share (the edge's line) and on this one.
        const unsigned on = (in.on[i] & in.on[(i + 1) % in.count]) | capBit;
        g.on[g.count] = on;
        g.v[g.count++] = x;
        capOn[capCount] = on;
        cap[capCount++] = x;
      }
    }
    if (g.count >= 3) out.faces[out.faceCount++] = g;
  }
  // Each cap point was found once per face through it: keep one copy.
  int unique = 0;
  for (int i = 0; i < capCount; ++i) {
    int seen = -1;
    for (int j = 0; j < unique && seen < 0; ++j)
      if (detail::sameBits(cap[i], cap[j])) seen = j;
    if (seen >= 0) {
      capOn[seen] |= capOn[i];
    } else {
      capOn[unique] = capOn[i];
      cap[unique++] = cap[i];
    }
  }
  if (out.faceCount > 0 && unique >= 3 && !capInFace) {
    if (out.faceCount == kCutPolytopeMaxFaces || unique > kCutPolygonMaxVertices) return false;
    // The cap is convex and its outward normal is -h.normal: order by angle around its centre.
    Vec3 c;
    for (int i = 0; i < unique; ++i) c += cap[i];
    c = (1.0 / unique) * c;
    const Vec3 n = -h.normal;
    Vec3 u = cap[0] - c;
    for (int i = 1; i < unique && dot(u, u) == 0; ++i) u = cap[i] - c;
    const Vec3 w = cross(n, u);
    double angle[kCutPolygonMaxVertices];
    for (int i = 0; i < unique; ++i) angle[i] = atan2(dot(cap[i] - c, w), dot(cap[i] - c, u));
    for (int i = 1; i < unique; ++i)
      for (int j = i; j > 0 && angle[j] < angle[j - 1]; --j) {
        const double ta = angle[j];
        angle[j] = angle[j - 1];
        angle[j - 1] = ta;
        const Vec3 tv = cap[j];
        cap[j] = cap[j - 1];
        cap[j - 1] = tv;
        const unsigned to = capOn[j];
        capOn[j] = capOn[j - 1];
        capOn[j - 1] = to;
      }
    CutPolygon& g = out.faces[out.faceCount++];
    for (int i = 0; i < unique; ++i) {
      g.v[i] = cap[i];
      g.on[i] = capOn[i];
    }
    g.count = unique;
    g.label = capLabel;
  }
  // A cell that only touches the plane (fewer than four faces left) has no volume.
  if (out.faceCount < 4) out.faceCount = 0;
  p = out;
  return true;
}

/// The cell of tet X on the sides of `planes` given by `sideMask` (bit j set: planeDistance >= 0
/// for plane j; clear: <= 0), `onPlane` as in clipPolytope. Empty (faceCount 0) when that cell
/// has no volume or planeCount is outside [0, kMaxCutPlanes].
GF_HD CutPolytope clipTet(const Vec3 X[4], const CutPlane* planes, int planeCount,
                          unsigned sideMask, double onPlane = 0) {
  CutPolytope p = tetPolytope(X);
  if (planeCount < 0 || planeCount > kMaxCutPlanes) {
    p.faceCount = 0;
    return p;
  }
  for (int j = 0; j < planeCount && p.faceCount > 0; ++j)
    if (!clipPolytope(p, planes[j], (sideMask >> j) & 1u ? 1.0 : -1.0, kCutFaceLabel + j, onPlane))
      p.faceCount = 0;
  return p;
}

/// Number of monomials of total degree <= d in n variables: C(d + n, n).
GF_HD constexpr int monomialCount(int n, int d) {
  return n == 2 ? (d + 1) * (d + 2) / 2 : (d + 1) * (d + 2) * (d + 3) / 6;
}

/// All monomials of degree <= D in (x, y, z) at p, in the order: total degree, then the power of
/// x descending, then of y descending (1, x, y, z, x^2, xy, xz, y^2, ...).
template <int D>
GF_HD void monomials3(Vec3 p, double out[monomialCount(3, D)]) {
  double px[D + 1], py[D + 1], pz[D + 1];
  px[0] = py[0] = pz[0] = 1;
  for (int k = 1; k <= D; ++k) {
    px[k] = px[k - 1] * p.x;
    py[k] = py[k - 1] * p.y;
    pz[k] = pz[k - 1] * p.z;
  }
  int m = 0;
  for (int t = 0; t <= D; ++t)
    for (int a = t; a >= 0; --a)
      for (int b = t - a; b >= 0; --b) out[m++] = px[a] * py[b] * pz[t - a - b];
}

/// All monomials of degree <= D in (u, v), ordered as monomials3.
template <int D>
GF_HD void monomials2(double u, double v, double out[monomialCount(2, D)]) {
  double pu[D + 1], pv[D + 1];
  pu[0] = pv[0] = 1;
  for (int k = 1; k <= D; ++k) {
    pu[k] = pu[k - 1] * u;
    pv[k] = pv[k - 1] * v;
  }
  int m = 0;
  for (int t = 0; t <= D; ++t)
    for (int a = t; a >= 0; --a) out[m++] = pu[a] * pv[t - a];
}

namespace detail {

GF_HD double factorial(int n) {
  double f = 1;
  for (int k = 2; k <= n; ++k) f *= k;
  return f;
}

// Grundmann-Moeller weight of layer i for an n-simplex and degree d = 2s + 1, normalised so the
// weights of a rule sum to 1 (Grundmann and Moeller 1978, Theorem 4).
GF_HD double gmWeight(int n, int s, int i) {
  const int d = 2 * s + 1;
  double w = (i % 2 == 0 ? 1.0 : -1.0) * ldexp(1.0, -2 * s) * pow(double(d + n - 2 * i), d);
  return w / (factorial(i) * factorial(d + n - i)) * factorial(n);
}

}  // namespace detail

/// Calls fn(weight, barycentric[4]) for every point of the Grundmann-Moeller rule of degree
/// 2s + 1 on a tetrahedron; weights sum to 1 (multiply by the volume).
template <typename Fn>
GF_HD void grundmannMoellerTet(int s, Fn&& fn) {
  const int d = 2 * s + 1;
  for (int i = 0; i <= s; ++i) {
    const double w = detail::gmWeight(3, s, i);
    const int m = s - i;
    const double den = double(d + 3 - 2 * i);
    for (int b0 = m; b0 >= 0; --b0)
      for (int b1 = m - b0; b1 >= 0; --b1)
        for (int b2 = m - b0 - b1; b2 >= 0; --b2) {
          const int b3 = m - b0 - b1 - b2;
          const double l[4] = {(2 * b0 + 1) / den, (2 * b1 + 1) / den, (2 * b2 + 1) / den,
                               (2 * b3 + 1) / den};
          fn(w, l);
        }
  }
}

/// As grundmannMoellerTet on a triangle: fn(weight, barycentric[3]); weights sum to 1.
template <typename Fn>
GF_HD void grundmannMoellerTriangle(int s, Fn&& fn) {
  const int d = 2 * s + 1;
  for (int i = 0; i <= s; ++i) {
    const double w = detail::gmWeight(2, s, i);
    const int m = s - i;
    const double den = double(d + 2 - 2 * i);
    for (int b0 = m; b0 >= 0; --b0)
      for (int b1 = m - b0; b1 >= 0; --b1) {
        const int b2 = m - b0 - b1;
        const double l[3] = {(2 * b0 + 1) / den, (2 * b1 + 1) / den, (2 * b2 + 1) / den};
        fn(w, l);
      }
  }
}

/// Exact moments of a cell: out[k] = integral over the cell of monomial k (monomials3 order) of
/// xi = W (x - origin). Adds nothing for an empty cell (out is zeroed first).
template <int D>
GF_HD void polytopeMoments(const CutPolytope& p, Vec3 origin, const Mat3& W,
                           double out[monomialCount(3, D)]) {
  constexpr int M = monomialCount(3, D);
  for (int k = 0; k < M; ++k) out[k] = 0;
  if (p.faceCount == 0) return;
  // Apex of the cones: the vertex average lies in the (convex) cell.
  Vec3 apex;
  int n = 0;
  for (int f = 0; f < p.faceCount; ++f)
    for (int i = 0; i < p.faces[f].count; ++i, ++n) apex += W * (p.faces[f].v[i] - origin);
  apex = (1.0 / n) * apex;
  for (int f = 0; f < p.faceCount; ++f) {
    const CutPolygon& g = p.faces[f];
    const Vec3 a = W * (g.v[0] - origin);
    for (int i = 1; i + 1 < g.count; ++i) {
      const Vec3 b = W * (g.v[i] - origin), c = W * (g.v[i + 1] - origin);
      // Signed: outward faces give positive cones, and a face through the apex gives zero.
      const double volume = det(fromColumns(a - apex, b - apex, c - apex)) / 6.0;
      if (volume == 0) continue;
      grundmannMoellerTet(D / 2, [&](double w, const double l[4]) {
        double mono[M];
        monomials3<D>(l[0] * apex + l[1] * a + l[2] * b + l[3] * c, mono);
        for (int k = 0; k < M; ++k) out[k] += volume * w * mono[k];
      });
    }
  }
}

/// Volume of a cell (zero when empty).
GF_HD double polytopeVolume(const CutPolytope& p) {
  double m[1];
  polytopeMoments<0>(p, Vec3{}, Mat3::identity(), m);
  return m[0];
}

/// Area of a planar polygon.
GF_HD double polygonArea(const CutPolygon& g) {
  Vec3 n;
  for (int i = 1; i + 1 < g.count; ++i) n += cross(g.v[i] - g.v[0], g.v[i + 1] - g.v[0]);
  return 0.5 * norm(n);
}

}  // namespace gf
