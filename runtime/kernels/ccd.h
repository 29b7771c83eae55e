// Continuous collision of linearly moving points (thesis sec 7.2.3.1, fig 7.3): a vertex
// against a triangle and an edge against an edge. Both reduce to the signed volume of four
// points, f(t) = N(t) . (x(t) - y(t)), a cubic in t when every point moves linearly over the
// interval; contacts begin where it changes sign with the point inside the feature. The
// penalty impulses of eq 7.5-7.6 integrate the depth -f / |N| along N / |N| over the times
// the point is inside (its penetration intervals).
#pragma once

#include "contact.h"
#include "math.h"

namespace gf {

/// Four points moving linearly over t in [0, 1]: x0 -> x1 and so on.
struct MovingQuad {
  Vec3 p0, p1;  ///< the point (vertex), or the first edge's start
  Vec3 a0, a1;  ///< the triangle's first vertex, or the first edge's end
  Vec3 b0, b1;  ///< the triangle's second vertex, or the second edge's start
  Vec3 c0, c1;  ///< the triangle's third vertex, or the second edge's end
};

GF_HD Vec3 lerp3(Vec3 x0, Vec3 x1, double t) { return x0 + t * (x1 - x0); }

/// Vertex-face: N = (b - a) x (c - a) (outward for a counter-clockwise triangle), f = N . (p - a),
/// positive in front of the face. Edge-edge: N = (a - p) x (c - b), f = N . (p - b), whose sign
/// tells on which side of the other edge's line the first edge passes.
GF_HD Vec3 quadNormal(const MovingQuad& q, bool edgeEdge, double t) {
  const Vec3 p = lerp3(q.p0, q.p1, t), a = lerp3(q.a0, q.a1, t), b = lerp3(q.b0, q.b1, t),
             c = lerp3(q.c0, q.c1, t);
  return edgeEdge ? cross(a - p, c - b) : cross(b - a, c - a);
}
GF_HD double quadVolume(const MovingQuad& q, bool edgeEdge, double t) {
  const Vec3 p = lerp3(q.p0, q.p1, t), a = lerp3(q.a0, q.a1, t), b = lerp3(q.b0, q.b1, t);
  return dot(quadNormal(q, edgeEdge, t), p - (edgeEdge ? b : a));
}

/// Coefficients k[0] + k[1] t + k[2] t^2 + k[3] t^3 of quadVolume, from the product of the
/// normal's quadratic and the offset's line.
GF_HD void quadVolumeCubic(const MovingQuad& q, bool edgeEdge, double k[4]) {
  // N = U x V with U, V and the offset W linear in t.
  const Vec3 u0 = edgeEdge ? q.a0 - q.p0 : q.b0 - q.a0;
  const Vec3 u1 = edgeEdge ? q.a1 - q.p1 : q.b1 - q.a1;
  const Vec3 v0 = edgeEdge ? q.c0 - q.b0 : q.c0 - q.a0;
  const Vec3 v1 = edgeEdge ? q.c1 - q.b1 : q.c1 - q.a1;
  const Vec3 w0 = q.p0 - (edgeEdge ? q.b0 : q.a0);
  const Vec3 w1 = q.p1 - (edgeEdge ? q.b1 : q.a1);
  const Vec3 du = u1 - u0, dv = v1 - v0, dw = w1 - w0;
  const Vec3 n0 = cross(u0, v0), n1 = cross(u0, dv) + cross(du, v0), n2 = cross(du, dv);
  k[0] = dot(n0, w0);
  k[1] = dot(n0, dw) + dot(n1, w0);
  k[2] = dot(n1, dw) + dot(n2, w0);
  k[3] = dot(n2, dw);
}

/// The times in (0, 1) where quadVolume changes sign, increasing, at most 3; returns the count.
/// The cubic's critical points split [0, 1] into pieces on which it is monotone, and each
/// piece whose ends differ in sign holds one root, found by bisection on the directly
/// evaluated volume (not the expanded cubic, which cancels badly when points nearly meet), so
/// no root is lost to a double root or a vanishing leading coefficient.
GF_HD int quadVolumeSignChanges(const MovingQuad& q, bool edgeEdge, double roots[3]) {
  double k[4];
  quadVolumeCubic(q, edgeEdge, k);
  double cut[4] = {0, 1, 1, 1};
  int cuts = 1;
  // Critical points: 3 k3 t^2 + 2 k2 t + k1 = 0.
  const double A = 3 * k[3], B = 2 * k[2], C = k[1];
  const double scale = fabs(A) + fabs(B) + fabs(C);
  if (scale > 0) {
    if (fabs(A) <= 1e-14 * scale) {
      if (fabs(B) > 0) cut[cuts++] = -C / B;
    } else {
      const double disc = B * B - 4 * A * C;
      if (disc >= 0) {
        const double s = sqrt(disc);
        // The stable pair of quadratic roots.
        const double qq = -0.5 * (B + (B >= 0 ? s : -s));
        cut[cuts++] = qq / A;
        if (qq != 0) cut[cuts++] = C / qq;
      }
    }
  }
  // Keep the critical points inside (0, 1), sorted, then close with 1.
  double inner[2];
  int n = 0;
  for (int i = 1; i < cuts; ++i)
    if (cut[i] > 0 && cut[i] < 1) inner[n++] = cut[i];
  if (n == 2 && inner[0] > inner[1]) {
    const double s = inner[0];
    inner[0] = inner[1];
    inner[1] = s;
  }
  double ends[4] = {0, 0, 0, 0};
  int m = 0;
  ends[m++] = 0;
  for (int i = 0; i < n; ++i) ends[m++] = inner[i];
  ends[m++] = 1;
  int count = 0;
  for (int i = 0; i + 1 < m; ++i) {
    double lo = ends[i], hi = ends[i + 1];
    double flo = quadVolume(q, edgeEdge, lo), fhi = quadVolume(q, edgeEdge, hi);
    if (!((flo > 0 && fhi < 0) || (flo < 0 && fhi > 0))) continue;
    for (int it = 0; it < 60 && hi - lo > 1e-15; ++it) {
      const double mid = 0.5 * (lo + hi);
      const double fm = quadVolume(q, edgeEdge, mid);
      if ((fm > 0) == (flo > 0) && fm != 0) {
        lo = mid;
        flo = fm;
      } else {
        hi = mid;
      }
    }
    roots[count++] = 0.5 * (lo + hi);
  }
  return count;
}

/// Vertex-face: whether the point at time t lies over the triangle, its barycentric weights
/// within [-tol, 1 + tol] in the triangle's plane.
GF_HD bool pointOverTriangle(const MovingQuad& q, double t, double tol, Vec3& w) {
  const Vec3 p = lerp3(q.p0, q.p1, t), a = lerp3(q.a0, q.a1, t), b = lerp3(q.b0, q.b1, t),
             c = lerp3(q.c0, q.c1, t);
  const Vec3 n = cross(b - a, c - a);
  const double nn = dot(n, n);
  if (!(nn > 0)) return false;
  w.y = dot(cross(p - a, c - a), n) / nn;
  w.z = dot(cross(b - a, p - a), n) / nn;
  w.x = 1 - w.y - w.z;
  return w.x >= -tol && w.y >= -tol && w.z >= -tol;
}

/// Edge-edge: whether the two edges at time t pass within `tol` of their lengths of each other
/// with both closest points on the segments; s and u are those points' parameters.
GF_HD bool edgesMeet(const MovingQuad& q, double t, double tol, double& s, double& u) {
  const Vec3 p = lerp3(q.p0, q.p1, t), a = lerp3(q.a0, q.a1, t), b = lerp3(q.b0, q.b1, t),
             c = lerp3(q.c0, q.c1, t);
  if (!closestOnSegments(p, a, b, c, s, u)) return false;
  const double gap = norm(lerp3(p, a, s) - lerp3(b, c, u));
  return gap <= tol * (norm(a - p) + norm(c - b));
}

/// The penalty impulse direction integral of eq 7.5-7.6 over [t0, t1] for a contact whose
/// outside is the side where sign * f > 0: the integral of max(0, -sign f) / |N| * sign N / |N|
/// dt, i.e. depth times the unit normal pointing to the outside. The caller multiplies by the
/// stiffness and the step. Five-point Gauss-Legendre on each eighth of a penetration interval:
/// exact when the normal is constant (a depth linear in t); a turning normal makes the
/// integrand rational, and the eighths keep it accurate where |N| changes fast (5e-7 relative
/// on tests/unit/test_ccd.cpp's turning quads).
GF_HD Vec3 penetrationIntegral(const MovingQuad& q, bool edgeEdge, double sign, double t0,
                               double t1) {
  double roots[3];
  const int n = quadVolumeSignChanges(q, edgeEdge, roots);
  double ends[5];
  int m = 0;
  ends[m++] = t0;
  for (int i = 0; i < n; ++i)
    if (roots[i] > t0 && roots[i] < t1) ends[m++] = roots[i];
  ends[m++] = t1;
  const double x[5] = {-0.9061798459386640, -0.5384693101056831, 0.0, 0.5384693101056831,
                       0.9061798459386640};
  const double w[5] = {0.2369268850561891, 0.4786286704993665, 0.5688888888888889,
                       0.4786286704993665, 0.2369268850561891};
  Vec3 sum;
  for (int i = 0; i + 1 < m; ++i) {
    const double lo = ends[i], hi = ends[i + 1];
    if (!(hi > lo)) continue;
    // The sign is constant on a piece between roots: test it at the middle.
    if (sign * quadVolume(q, edgeEdge, 0.5 * (lo + hi)) >= 0) continue;
    const double eighth = 0.125 * (hi - lo);
    for (int piece = 0; piece < 8; ++piece) {
      const double half = 0.5 * eighth, mid = lo + (piece + 0.5) * eighth;
      for (int g = 0; g < 5; ++g) {
        const double t = mid + half * x[g];
        const Vec3 N = quadNormal(q, edgeEdge, t);
        const double nn = dot(N, N);
        if (!(nn > 0)) continue;
        // depth -sign f / |N| along sign N / |N|: -f N / |N|^2.
        sum += (-w[g] * half * quadVolume(q, edgeEdge, t) / nn) * N;
      }
    }
  }
  return sum;
}

}  // namespace gf
