// Penalty contact of one node against a static collider: a one-sided quadratic energy
// k m d^2 / 2 on the penetration depth d, so contact enters the implicit step as an energy
// (consistent gradient and a PSD Hessian k m n n^T) and stays stable at large time steps.
// A moving collider is placed at its end-of-step pose, so the same energy pushes nodes along.
#pragma once

#include "math.h"

namespace gf {

enum ColliderKind : int {
  kColliderPlane = 0,
  kColliderBox = 1,
  kColliderSphere = 2,
  kColliderCapsule = 3
};

/// Collider in kernel form. `stiffness` is per unit node mass [1/s^2].
struct ColliderData {
  int kind = kColliderPlane;
  Vec3 point;                        ///< plane point, box, sphere or capsule centre
  Vec3 normal;                       ///< plane normal (unit)
  Vec3 halfExtents;                  ///< box
  Mat3 rotation = Mat3::identity();  ///< box, capsule: local-to-world axes (columns)
  double radius = 0;                 ///< sphere, capsule
  double halfLength = 0;             ///< capsule: its segment runs along local y, +-halfLength
  double stiffness = 0;
  Vec3 velocity;         ///< translation [m/s]: sliding is measured against it
  Vec3 angularVelocity;  ///< spin [rad/s] about `point`, for the surface's velocity
  double friction = 0;   ///< the collider's Coulomb coefficient (mixed with the body's)
};

/// A capsule's segment: its start and its axis times the segment's length (local y).
GF_HD void capsuleSegment(const ColliderData& c, Vec3& start, Vec3& along) {
  const Vec3 axis = column(c.rotation, 1);
  start = c.point - c.halfLength * axis;
  along = (2 * c.halfLength) * axis;
}

/// The parameter in [0, 1] of the point of segment a + s (b - a) nearest to p.
GF_HD double closestOnSegment(Vec3 p, Vec3 a, Vec3 along) {
  const double len2 = dot(along, along);
  if (!(len2 > 0)) return 0;
  const double s = dot(p - a, along) / len2;
  return s < 0 ? 0 : (s > 1 ? 1 : s);
}

/// Penetration depth (> 0 inside) and the outward direction that reduces it.
GF_HD double penetration(const ColliderData& c, Vec3 x, Vec3& n) {
  if (c.kind == kColliderPlane) {
    n = c.normal;
    return -dot(x - c.point, c.normal);
  }
  if (c.kind == kColliderCapsule) {
    // Measured from the segment's nearest point: the normal is radial and turns smoothly
    // across a rounded edge, where a box's jumps from one face to the next at its corner.
    Vec3 a, along;
    capsuleSegment(c, a, along);
    const Vec3 d = x - (a + closestOnSegment(x, a, along) * along);
    const double r = norm(d);
    // On the axis any radial direction is as near; the local x axis is one.
    n = r > 1e-12 * c.radius ? (1.0 / r) * d : column(c.rotation, 0);
    return c.radius - r;
  }
  if (c.kind == kColliderSphere) {
    const Vec3 d = x - c.point;
    const double r = norm(d);
    n = r > 1e-12 ? (1.0 / r) * d : Vec3{0, 1, 0};
    return c.radius - r;
  }
  // Box: push out through the face of least penetration, in the box's axes.
  const Vec3 d = transpose(c.rotation) * (x - c.point);
  double best = 1e300;
  n = Vec3{0, 1, 0};
  for (int i = 0; i < 3; ++i) {
    const double depthPos = c.halfExtents[i] - d[i];  // to the + face
    const double depthNeg = c.halfExtents[i] + d[i];  // to the - face
    if (depthPos < best) {
      best = depthPos;
      n = Vec3{};
      n[i] = 1;
    }
    if (depthNeg < best) {
      best = depthNeg;
      n = Vec3{};
      n[i] = -1;
    }
  }
  n = c.rotation * n;
  return best;
}

/// Adds the penalty energy k d^2 / 2 of a node at depth d > 0 along the outward direction n
/// (k = stiffness times the node's mass), its gradient and its Hessian block; returns the
/// energy (0 when not in contact). On a curved collider (sphere, capsule) the exact Hessian also
/// has -k d / r times the projector off n (and off a capsule's axis), r the distance to the
/// centre or axis; that part is negative, so it is left out to keep the block PSD.
GF_HD double penaltyContact(double k, double d, Vec3 n, Vec3& grad, Mat3& hess) {
  if (!(d > 0)) return 0;
  grad -= (k * d) * n;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) hess(i, j) += k * n[i] * n[j];
  return 0.5 * k * d * d;
}

/// Adds the contact energy of node x (mass m) and its gradient and Hessian block; returns
/// the energy (0 when not in contact).
GF_HD double nodeContact(const ColliderData& c, Vec3 x, double m, Vec3& grad, Mat3& hess) {
  Vec3 n;
  const double d = penetration(c, x, n);
  return penaltyContact(c.stiffness * m, d, n, grad, hess);
}

/// Extent of a box, sphere or capsule collider along direction n (unit).
GF_HD double colliderThickness(const ColliderData& c, Vec3 n) {
  if (c.kind == kColliderSphere) return 2 * c.radius;
  if (c.kind == kColliderCapsule)
    return 2 * c.radius + 2 * c.halfLength * fabs(dot(column(c.rotation, 1), n));
  const Vec3 l = transpose(c.rotation) * n;
  return 2 *
         (fabs(l.x) * c.halfExtents.x + fabs(l.y) * c.halfExtents.y + fabs(l.z) * c.halfExtents.z);
}

/// The point of a box, sphere or capsule collider that reaches farthest along direction n (unit).
GF_HD Vec3 supportPoint(const ColliderData& c, Vec3 n) {
  if (c.kind == kColliderSphere) return c.point + c.radius * n;
  if (c.kind == kColliderCapsule) {
    Vec3 a, along;
    capsuleSegment(c, a, along);
    return (dot(along, n) > 0 ? a + along : a) + c.radius * n;
  }
  const Vec3 l = transpose(c.rotation) * n;
  const Vec3 corner{l.x < 0 ? -c.halfExtents.x : c.halfExtents.x,
                    l.y < 0 ? -c.halfExtents.y : c.halfExtents.y,
                    l.z < 0 ? -c.halfExtents.z : c.halfExtents.z};
  return c.point + c.rotation * corner;
}

/// The first t in [0, 1] at which a + t d meets the sphere (centre, r), a outside it; or -1.
GF_HD double sphereEntry(Vec3 a, Vec3 d, Vec3 centre, double r) {
  const Vec3 f = a - centre;
  const double A = dot(d, d), B = dot(f, d), C = dot(f, f) - r * r;
  if (!(C > 0) || !(A > 0)) return -1;
  const double disc = B * B - A * C;
  if (!(disc >= 0)) return -1;
  const double t = (-B - sqrt(disc)) / A;
  return t >= 0 && t <= 1 ? t : -1;
}

/// Where the straight path a -> b first enters collider c when a lies outside it: the entry
/// point, the outward normal of the face (or sphere point) it enters through, and the
/// collider's thickness along that normal. False when a is inside, or the path misses. A plane is a
/// half-space and cannot be passed through, so it never has an entry. This is the continuous check
/// that keeps a fast node from crossing a thin box, a small sphere or a thin capsule within one
/// step, where the nearest-face depth of penetration() would point out of the far side.
GF_HD bool sweptEntry(const ColliderData& c, Vec3 a, Vec3 b, Vec3& point, Vec3& normal,
                      double& thickness) {
  if (c.kind == kColliderSphere) {
    // |a + t (b - a) - centre| = r, smallest root in [0, 1], with a outside.
    const double t = sphereEntry(a, b - a, c.point, c.radius);
    if (t < 0) return false;
    point = a + t * (b - a);
    const Vec3 r = point - c.point;
    const double len = norm(r);
    normal = len > 0 ? (1.0 / len) * r : Vec3{0, 1, 0};
    thickness = 2 * c.radius;
    return true;
  }
  if (c.kind == kColliderCapsule) {
    // The capsule is the union of its two end spheres and the side of its cylinder; with a
    // outside all three, the path enters it where it first enters one of them.
    Vec3 p0, along;
    capsuleSegment(c, p0, along);
    Vec3 n;
    if (penetration(c, a, n) >= 0) return false;
    const Vec3 d = b - a;
    double best = sphereEntry(a, d, p0, c.radius);
    const double t1 = sphereEntry(a, d, p0 + along, c.radius);
    if (t1 >= 0 && (best < 0 || t1 < best)) best = t1;
    const double len2 = dot(along, along);
    if (len2 > 0) {
      // The side: |radial part of (a + t d - p0)| = r, with the axial part on the segment.
      const Vec3 u = (1.0 / sqrt(len2)) * along, m = a - p0;
      const Vec3 dp = d - dot(d, u) * u, mp = m - dot(m, u) * u;
      const double A = dot(dp, dp), B = dot(mp, dp), C = dot(mp, mp) - c.radius * c.radius;
      const double disc = B * B - A * C;
      if (A > 0 && C > 0 && disc >= 0) {
        const double t = (-B - sqrt(disc)) / A;
        const double s = dot(m + t * d, u);
        if (t >= 0 && t <= 1 && s >= 0 && s * s <= len2 && (best < 0 || t < best)) best = t;
      }
    }
    if (best < 0) return false;
    point = a + best * d;
    const Vec3 r = point - (p0 + closestOnSegment(point, p0, along) * along);
    const double len = norm(r);
    normal = len > 0 ? (1.0 / len) * r : column(c.rotation, 0);
    thickness = colliderThickness(c, normal);
    return true;
  }
  if (c.kind != kColliderBox) return false;
  // Slabs in the box's axes: the path is inside every slab for t in [enter, leave].
  const Vec3 la = transpose(c.rotation) * (a - c.point), lb = transpose(c.rotation) * (b - c.point);
  double enter = 0, leave = 1;
  int axis = -1;
  double side = 0;
  for (int i = 0; i < 3; ++i) {
    const double h = c.halfExtents[i], d = lb[i] - la[i];
    if (d == 0) {
      if (la[i] < -h || la[i] > h) return false;
      continue;
    }
    double t0 = (-h - la[i]) / d, t1 = (h - la[i]) / d;
    double faceSide = -1;
    if (t0 > t1) {
      const double tmp = t0;
      t0 = t1;
      t1 = tmp;
      faceSide = 1;
    }
    if (t0 > enter) {
      enter = t0;
      axis = i;
      side = faceSide;
    }
    if (t1 < leave) leave = t1;
    if (enter > leave) return false;
  }
  if (axis < 0) return false;  // a is inside the box (or on its boundary)
  Vec3 ln{0, 0, 0};
  ln[axis] = side;
  normal = c.rotation * ln;
  point = a + enter * (b - a);
  thickness = 2 * c.halfExtents[axis];
  return true;
}

/// Penalty stiffness per unit mass for a node whose path over dt reaches `reach` past the face
/// it entered, on a collider `thickness` thick: a node meeting a penalty k stops about
/// reach / (1 + k dt^2) in (the implicit step's balance of inertia and penalty), so the
/// collider's own k, raised where needed to stop it within a hundredth of the thickness (the
/// body behind the node pushes harder than its own mass, so it ends deeper, but well inside).
GF_HD double sweptStiffness(double colliderStiffness, double reach, double thickness, double dt) {
  const double k = reach / (0.01 * thickness * dt * dt);
  return k > colliderStiffness ? k : colliderStiffness;
}

/// Swept contacts of one step: per node, the collider whose face its path entered (-1 none)
/// with the entry point, normal and penalty stiffness. For that collider the node's depth is
/// measured from the entry face's plane for the whole step, so the penalty pushes it back the
/// way it came even when it ends past the middle of a thin plate or beyond it.
struct SweptContacts {
  const int32_t* collider = nullptr;  ///< per node; null: no swept contact this step
  const Vec3* point = nullptr;
  const Vec3* normal = nullptr;
  const double* stiffness = nullptr;  ///< per node, per unit mass (sweptStiffness)
  /// Per node, the factor on a moving collider's own stiffness where the node has no swept
  /// face (the step's stiffening of deep contacts); null: 1.
  const double* scale = nullptr;

  /// Depth (> 0 inside) of node n at x against collider ci, and the outward direction.
  GF_HD double depth(const ColliderData& c, int ci, int32_t n, Vec3 x, Vec3& out) const {
    if (collider && collider[n] == ci) {
      out = normal[n];
      return dot(point[n] - x, normal[n]);
    }
    return penetration(c, x, out);
  }
  /// nodeContact against collider ci, with its swept face.
  GF_HD double contact(const ColliderData& c, int ci, int32_t n, Vec3 x, double m, Vec3& grad,
                       Mat3& hess) const {
    Vec3 dir;
    const double d = depth(c, ci, n, x, dir);
    const double k = collider && collider[n] == ci              ? stiffness[n]
                     : scale && dot(c.velocity, c.velocity) > 0 ? c.stiffness * scale[n]
                                                                : c.stiffness;
    return penaltyContact(k * m, d, dir, grad, hess);
  }
};

/// The point of triangle abc nearest to p, as barycentric weights w (w[0] a + w[1] b + w[2] c)
/// (Ericson, Real-Time Collision Detection, sec 5.1.5: Voronoi regions of vertices, edges, face).
GF_HD Vec3 closestOnTriangle(Vec3 p, Vec3 a, Vec3 b, Vec3 c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Vec3 bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double t = d1 / (d1 - d3);
    return {1 - t, t, 0};
  }
  const Vec3 cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double t = d2 / (d2 - d6);
    return {1 - t, 0, t};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - t, t};
  }
  const double denom = 1 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {1 - v - w, v, w};
}

/// Closest points of segments p0-p1 and q0-q1 as parameters s, t in [0, 1] (p0 + s (p1 - p0),
/// q0 + t (q1 - q0)) (Ericson, Real-Time Collision Detection, sec 5.1.9). False when a segment
/// has no length or the two are parallel (no single pair of closest points).
GF_HD bool closestOnSegments(Vec3 p0, Vec3 p1, Vec3 q0, Vec3 q1, double& s, double& t) {
  const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = dot(d1, d1), e = dot(d2, d2), f = dot(d2, r), c = dot(d1, r), b = dot(d1, d2);
  const double denom = a * e - b * b;
  if (!(a > 0 && e > 0) || !(denom > 1e-12 * a * e)) return false;
  s = (b * f - c * e) / denom;
  s = s < 0 ? 0 : (s > 1 ? 1 : s);
  t = (b * s + f) / e;
  if (t < 0) {
    t = 0;
    s = -c / a;
  } else if (t > 1) {
    t = 1;
    s = (b - c) / a;
  }
  s = s < 0 ? 0 : (s > 1 ? 1 : s);
  return true;
}

/// The part of segment p0 -> p1 over triangle abc grown by `band` (inside the prism the grown
/// triangle sweeps along its normal nf): the parameters [t0, t1] in [0, 1], false when none of
/// it is.
GF_HD bool clipToPrism(Vec3 p0, Vec3 p1, Vec3 a, Vec3 b, Vec3 c, Vec3 nf, double band, double& t0,
                       double& t1) {
  t0 = 0;
  t1 = 1;
  const Vec3 v[3] = {a, b, c};
  for (int e = 0; e < 3; ++e) {
    const Vec3 s = v[e], t = v[(e + 1) % 3], o = v[(e + 2) % 3];
    Vec3 m = cross(nf, t - s);
    const double len = norm(m);
    if (!(len > 0)) return false;
    m = (dot(m, o - s) < 0 ? -1.0 / len : 1.0 / len) * m;  // unit, towards the triangle
    const double f0 = dot(p0 - s, m) + band, df = dot(p1 - p0, m);
    if (df == 0) {
      if (f0 < 0) return false;
      continue;
    }
    const double tc = -f0 / df;
    if (df > 0) {
      if (tc > t0) t0 = tc;
    } else if (tc < t1) {
      t1 = tc;
    }
    if (t0 > t1) return false;
  }
  return true;
}

/// Where the swept sphere (capsule) of radius r about segment p0 -> p1 reaches past the plane
/// of triangle abc along nIn (its unit normal into the body), over the part of the segment
/// above the triangle (or, where none is, above the triangle grown by `band`): that part's ends
/// s[0], s[1] and their depths d[0], d[1] (signed, > 0 past the plane; linear along it, so one
/// of the ends is the part's deepest point). False when no part is above it.
GF_HD bool chordUnderFace(Vec3 p0, Vec3 p1, double r, Vec3 a, Vec3 b, Vec3 c, Vec3 nIn, double band,
                          Vec3 s[2], double d[2]) {
  // The triangle's own prism first: a bar that crosses the face, slightly tilted, reaches
  // deepest at one end of the part over it, and over the grown triangle that end would lie in
  // the band, where the face's share fades to nothing. The band is for the thin wedge between
  // two faces that meet at a slight angle, a gap as wide as the depth times the angle: a part
  // found only there and deeper than the band is beyond another face's edge (a bar under a
  // block's bottom, seen from a side face).
  double t0, t1;
  const bool own = clipToPrism(p0, p1, a, b, c, nIn, 0, t0, t1);
  if (!own && !clipToPrism(p0, p1, a, b, c, nIn, band, t0, t1)) return false;
  s[0] = p0 + t0 * (p1 - p0);
  s[1] = p0 + t1 * (p1 - p0);
  for (int k = 0; k < 2; ++k) d[k] = dot(s[k] - a, nIn) + r;
  return own || (d[0] <= band && d[1] <= band);
}

/// Contact of a box, sphere or capsule collider with a point of boundary triangle abc of a body
/// (nIn: the triangle's unit normal into the body): the collider's point y that reaches
/// deepest past the triangle's plane above the triangle, its depth (> 0 past the plane; the
/// returned value, -HUGE_VAL when no part of the collider is above the triangle), the
/// barycentric weights w of y's projection on the triangle, and the face's share `share` of the
/// contact. Planes have no such contact (a flat face's deepest point in a half-space is a
/// vertex, the node's). A sphere or capsule is its segment swept by its radius; a box, whose
/// deepest point over the triangle is a vertex of the box cut by the triangle's prism, is its 12
/// edges (corners included): a box face parallel to the triangle and covering it reaches
/// deepest at the triangle's vertices, which are nodes.
/// The prisms of two faces that meet at an angle leave a wedge between them that neither
/// covers, where a ball's centre under a bent surface found no face and dropped through; so each
/// triangle is grown by `band`, and a contact within band of an edge is shared by the faces on
/// both sides: share = min over the edges of (s + band) / (2 band) clamped to [0, 1], s the
/// projection's distance inside the edge, which sums to 1 across an edge between coplanar faces.
/// w is clamped to the triangle there.
GF_HD double faceContact(const ColliderData& c, Vec3 a, Vec3 b, Vec3 cc, Vec3 nIn, double band,
                         Vec3& y, Vec3& w, double& share) {
  // The collider as segments swept by a radius: a sphere's point, a capsule's segment, or a
  // box's 12 edges.
  Vec3 p0[12], p1[12];
  int count = 0;
  double r = 0;
  if (c.kind == kColliderSphere) {
    p0[0] = p1[0] = c.point;
    r = c.radius;
    count = 1;
  } else if (c.kind == kColliderCapsule) {
    Vec3 along;
    capsuleSegment(c, p0[0], along);
    p1[0] = p0[0] + along;
    r = c.radius;
    count = 1;
  } else if (c.kind == kColliderBox) {
    for (int axis = 0; axis < 3; ++axis) {
      const int i = (axis + 1) % 3, j = (axis + 2) % 3;
      for (int k = 0; k < 4; ++k, ++count) {
        Vec3 l0, l1;
        l0[axis] = -c.halfExtents[axis];
        l1[axis] = c.halfExtents[axis];
        l0[i] = l1[i] = (k & 1) ? c.halfExtents[i] : -c.halfExtents[i];
        l0[j] = l1[j] = (k & 2) ? c.halfExtents[j] : -c.halfExtents[j];
        p0[count] = c.point + c.rotation * l0;
        p1[count] = c.point + c.rotation * l1;
      }
    }
  }
  double depth = -HUGE_VAL;
  for (int k = 0; k < count; ++k) {
    Vec3 s[2];
    double d[2];
    if (!chordUnderFace(p0[k], p1[k], r, a, b, cc, nIn, band, s, d)) continue;
    depth = fmax(depth, fmax(d[0], d[1]));
  }
  if (depth == -HUGE_VAL) return depth;
  // The contact point: the middle of the parts that reach within a tenth of the band of the
  // deepest, at the deepest depth. A bar lying flat on the face (or a box's face) reaches as
  // deep along a line or over an area, and the deepest end or corner alone jumped from one to
  // another as the face tilted by a hair, rocking the body off a short bar.
  const double tol = 0.1 * band;
  Vec3 sum{0, 0, 0};
  int n = 0;
  for (int k = 0; k < count; ++k) {
    Vec3 s[2];
    double d[2];
    if (!chordUnderFace(p0[k], p1[k], r, a, b, cc, nIn, band, s, d)) continue;
    for (int e = 0; e < 2; ++e)
      if (d[e] >= depth - tol) {
        sum += s[e];
        ++n;
      }
  }
  const Vec3 mid = (1.0 / n) * sum;
  y = mid + (depth - dot(mid - a, nIn)) * nIn;
  share = 1;
  const Vec3 v[3] = {a, b, cc};
  for (int e = 0; e < 3; ++e) {
    const Vec3 s = v[e], t = v[(e + 1) % 3], o = v[(e + 2) % 3];
    Vec3 m = cross(nIn, t - s);
    m = (dot(m, o - s) < 0 ? -1.0 / norm(m) : 1.0 / norm(m)) * m;
    const double f = band > 0 ? (dot(y - s, m) + band) / (2 * band) : 1.0;
    if (f < share) share = f < 0 ? 0 : f;
  }
  // Barycentric weights of y's projection (Ericson, Real-Time Collision Detection, sec 3.4).
  const Vec3 v0 = b - a, v1 = cc - a, v2 = y - a;
  const double d00 = dot(v0, v0), d01 = dot(v0, v1), d11 = dot(v1, v1);
  const double d20 = dot(v2, v0), d21 = dot(v2, v1), den = d00 * d11 - d01 * d01;
  if (!(den > 0)) return -HUGE_VAL;
  double wb = (d11 * d20 - d01 * d21) / den, wc = (d00 * d21 - d01 * d20) / den;
  double wa = 1 - wb - wc;
  wa = wa > 0 ? wa : 0;
  wb = wb > 0 ? wb : 0;
  wc = wc > 0 ? wc : 0;
  const double total = wa + wb + wc;
  w = (1.0 / total) * Vec3{wa, wb, wc};
  return depth;
}

/// Body-body and self contacts of one body for one step (contact/body_contact.h): per node a
/// run of half-spaces, each a point and an outward unit normal that the node must stay in
/// front of, with the one-sided penalty of a collider (energy k d^2 / 2, gradient, PSD Hessian
/// k n n^T; k per half-space, contact/body_contact.h). A self pair's plane moves with its face's
/// nodes (faceNode below), whose cross blocks the sparse pattern lacks.
struct HalfSpaceContacts {
  const int32_t* start = nullptr;  ///< nodeCount + 1 offsets; null: no half-space this step
  const Vec3* point = nullptr;
  const Vec3* normal = nullptr;
  const double* stiffness = nullptr;  ///< per half-space [N/m]
  /// Per half-space, friction's lagged normal force times the pair's coefficient (null: none),
  /// and the motion over the step of the face point it slides on.
  const double* muLambda = nullptr;
  const Vec3* faceMotion = nullptr;
  double slipEps = 0;  ///< nodeFriction's smoothing length (slip speed times dt)
  /// Per half-space the group on the other side (null: none known), and the body's own groups
  /// [ownFirst, ownEnd): a self pair's half-space that let go of its node within the step has the
  /// step go on (Integrator::releasedBodyContact).
  const int32_t* partner = nullptr;
  int32_t ownFirst = 0, ownEnd = 0;
  GF_HD bool self(int32_t k) const {
    return partner && partner[k] >= ownFirst && partner[k] < ownEnd;
  }
  /// Self pairs solved with their face inside the body's step (contact/body_contact.h): per
  /// half-space the face's three nodes (-1: a fixed plane; an edge-edge pair: the other edge's
  /// two, the second repeated) and, for an edge-edge pair, its point's weights w (the plane then
  /// passes through point + sum_i w_i X_i), the face nodes read at X. reaction lists, per node
  /// (reactionStart, nodeCount + 1; null: no such pair), the entries 3 k + i of the half-spaces k
  /// whose face has it as node i, in half-space order; owner is each half-space's vertex node.
  const int32_t* faceNode = nullptr;
  const Vec3* weight = nullptr;
  const int32_t* owner = nullptr;
  const int32_t* reactionStart = nullptr;
  const int32_t* reaction = nullptr;
  const double* X = nullptr;
  /// The step's start x_n (null: not known): a moving pair's friction then slides against its
  /// face nodes' motion from there, an action and reaction inside the body (slide()).
  const double* Xn = nullptr;
  double selfSkin = 0;  ///< [m] a self vertex-face pair's plane lies this far in front of its face
  /// Per half-space, its own skin in place of selfSkin (null: selfSkin for all).
  const double* skin = nullptr;
  /// Coupled contact (WorldDef::coupledContact): node indices (owner, faceNode, reaction) are
  /// the joint ones of all coupled bodies, X and Xn their joint positions, which at() keeps.
  bool joint = false;
  /// A copy whose moving faces are read at positions x (unless joint).
  GF_HD HalfSpaceContacts at(const double* x) const {
    HalfSpaceContacts h = *this;
    if (!joint) h.X = x;
    return h;
  }
  GF_HD bool moving(int32_t k) const { return faceNode && faceNode[3 * int64_t(k)] >= 0; }
  GF_HD Vec3 nodeAt(int32_t i) const {
    return {X[3 * int64_t(i)], X[3 * int64_t(i) + 1], X[3 * int64_t(i) + 2]};
  }
  /// Whether half-space k's friction is the moving kind: a self pair's, with x_n known.
  GF_HD bool movingFriction(int32_t k) const {
    return Xn && moving(k) && muLambda && muLambda[k] > 0;
  }
  /// The slide over the step of a node that starts at xn and ends at x, against half-space k's
  /// face, in its plane (the lagged normal). A self pair's face point (the pair's weights w of
  /// the prediction, held over the step) moves with its nodes' iterate at X, so the friction
  /// acts on both sides and is a function of the body's unknowns; with the face's predicted
  /// motion instead, the pieces of one body slid on each other as if on ice (each dragged
  /// towards the other's last velocity) and a stack of them crept apart.
  GF_HD Vec3 slide(int32_t k, Vec3 x, Vec3 xn) const {
    Vec3 u = x - xn;
    if (movingFriction(k)) {
      const int32_t* f = faceNode + 3 * int64_t(k);
      for (int i = 0; i < 3; ++i) u -= weight[k][i] * (nodeAt(f[i]) - startAt(f[i]));
    } else {
      u -= faceMotion[k];
    }
    return tangential(k, u);
  }
  GF_HD Vec3 startAt(int32_t i) const {
    return {Xn[3 * int64_t(i)], Xn[3 * int64_t(i) + 1], Xn[3 * int64_t(i) + 2]};
  }
  /// q in the plane of half-space k (its lagged normal).
  GF_HD Vec3 tangential(int32_t k, Vec3 q) const { return q - dot(q, normal[k]) * normal[k]; }
  /// Half-space k for a node at x, its faces read at X: the depth d (> 0 behind the plane), its
  /// normal n and the weights w with which the face nodes carry it: d's gradient is g = (-n,
  /// w_1 n, w_2 n, w_3 n) over (node, face nodes). A self vertex-face pair is re-linearised at X:
  /// the plane of its face as the face now is (its unit normal, the nodes' winding's), d =
  /// n . (x_1 - x) + selfSkin, and w the barycentric weights of x's projection onto that plane, not
  /// clamped to the triangle: the plane's tilt and shift under the face nodes' motion, exactly
  /// (a clamped nearest point lies in the same plane, so it gives the same d, but its weights
  /// are not d's gradient outside the face). A pair that kept the normal and the point of the
  /// face's prediction let a vertex sliding over a turning face in (docs/validation.md).
  GF_HD double pair(int32_t k, Vec3 x, Vec3& n, Vec3& w) const {
    n = normal[k];
    w = Vec3{0, 0, 0};
    if (!moving(k)) return dot(point[k] - x, n);
    const int32_t* f = faceNode + 3 * int64_t(k);
    if (f[1] != f[2]) {
      const Vec3 x1 = nodeAt(f[0]), e1 = nodeAt(f[1]) - x1, e2 = nodeAt(f[2]) - x1;
      const Vec3 a = cross(e1, e2);
      const double a2 = dot(a, a);
      if (a2 > 0) {
        const Vec3 r = x - x1;
        const double b1 = dot(cross(r, e2), a) / a2, b2 = dot(cross(e1, r), a) / a2;
        n = (1.0 / sqrt(a2)) * a;
        w = Vec3{1 - b1 - b2, b1, b2};
        return dot(x1 - x, n) + (skin ? skin[k] : selfSkin);
      }
    }
    w = weight[k];
    Vec3 p = point[k];
    for (int i = 0; i < 3; ++i) p += w[i] * nodeAt(f[i]);
    return dot(p - x, n);
  }

  /// Half-space k of a node at x: its depth (> 0 behind the plane).
  GF_HD double depth(int32_t k, Vec3 x) const {
    Vec3 n, w;
    return pair(k, x, n, w);
  }
  /// The reaction on node n of the moving-face half-spaces it is a face node of: gradient
  /// k d w_i n and the diagonal block k w_i^2 n n^T of the pair's Gauss-Newton Hessian k g g^T
  /// (PSD; the cross blocks are applied matrix-free, fem/node_stage.h SelfPairCouplingStage),
  /// and of their moving friction (slide()): -w_i times the vertex's friction gradient and
  /// w_i^2 times its Hessian block. No energy: the vertex counts it. Returns whether any acts.
  GF_HD bool reactionTerms(int32_t n, Vec3& grad, Mat3& hess) const;
  /// The penalty of node n at x over its half-spaces, added to grad and hess.
  GF_HD double contact(int32_t n, Vec3 x, Vec3& grad, Mat3& hess) const {
    if (!start) return 0;
    double e = 0;
    for (int32_t k = start[n]; k < start[n + 1]; ++k) {
      Vec3 nk, wk;
      const double d = pair(k, x, nk, wk);
      e += penaltyContact(stiffness[k], d, nk, grad, hess);
    }
    return e;
  }
  /// The friction of node n sliding from xn to x over its half-spaces' faces (nodeFriction,
  /// defined below), added to grad and hess.
  GF_HD double friction(int32_t n, Vec3 x, Vec3 xn, Vec3& grad, Mat3& hess) const;
  /// True when node n at x is behind any of its half-spaces.
  GF_HD bool inside(int32_t n, Vec3 x) const {
    if (!start) return false;
    for (int32_t k = start[n]; k < start[n + 1]; ++k)
      if (depth(k, x) > 0) return true;
    return false;
  }
};

/// Sliding speed [m/s] below which friction is smoothed (IPC's eps_v): static friction becomes a
/// stiff viscous drag, so a body held by friction creeps at most at about this speed times
/// tan(angle) / (2 mu), and the potential stays differentiable for Newton.
constexpr double kFrictionSlipSpeed = 1e-3;

/// Smoothed Coulomb friction of a node sliding by u (tangential, over the step) under the
/// lagged normal force lambda: the dissipation potential mu lambda f0(|u|) with f0' = f1,
/// f1(y) = 2 y / eps - y^2 / eps^2 below eps and 1 above (Li et al. 2020, IPC, sec 5), eps =
/// the slip speed times dt. Adds its gradient and a PSD Hessian (mu lambda f1(y) / y on the
/// tangent plane; the curvature along u, negative below eps, dropped) and returns the
/// potential.
GF_HD double frictionF1OverY(double y, double eps);
GF_HD double nodeFriction(double muLambda, Vec3 normal, Vec3 u, double eps, Vec3& grad,
                          Mat3& hess) {
  const double y = norm(u);
  const double f0 = y < eps ? y * y / eps - y * y * y / (3 * eps * eps) + eps / 3 : y;
  const double f1OverY = frictionF1OverY(y, eps);
  grad += (muLambda * f1OverY) * u;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      hess(i, j) += muLambda * f1OverY * ((i == j ? 1.0 : 0.0) - normal[i] * normal[j]);
  return muLambda * f0;
}

/// f1(y) / y of nodeFriction: its Hessian's scale on the tangent plane per unit mu lambda.
GF_HD double frictionF1OverY(double y, double eps) {
  return y < eps ? 2 / eps - y / (eps * eps) : 1 / y;
}

GF_HD double HalfSpaceContacts::friction(int32_t n, Vec3 x, Vec3 xn, Vec3& grad, Mat3& hess) const {
  if (!start || !muLambda) return 0;
  double e = 0;
  for (int32_t k = start[n]; k < start[n + 1]; ++k)
    if (muLambda[k] > 0)
      e += nodeFriction(muLambda[k], normal[k], slide(k, x, xn), slipEps, grad, hess);
  return e;
}

GF_HD bool HalfSpaceContacts::reactionTerms(int32_t n, Vec3& grad, Mat3& hess) const {
  if (!reactionStart) return false;
  bool any = false;
  for (int32_t e = reactionStart[n]; e < reactionStart[n + 1]; ++e) {
    const int32_t k = reaction[e] / 3, i = reaction[e] % 3;
    const Vec3 xv = nodeAt(owner[k]);
    if (movingFriction(k)) {
      const double w = weight[k][i];
      Vec3 g{0, 0, 0};
      Mat3 h;
      (void)nodeFriction(muLambda[k], normal[k], slide(k, xv, startAt(owner[k])), slipEps, g, h);
      grad += -w * g;
      hess = hess + (w * w) * h;
      any = true;
    }
    Vec3 nk, wk;
    const double d = pair(k, xv, nk, wk);
    if (!(d > 0)) continue;
    const double w = wk[i];
    grad += (stiffness[k] * d * w) * nk;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) hess(a, b) += stiffness[k] * w * w * nk[a] * nk[b];
    any = true;
  }
  return any;
}

}  // namespace gf
