// Collider contact at points inside a body's boundary faces (issue 15, item 3): the node penalty
// (kernels/contact.h) lets a collider feature smaller than a cell, or a box's edge or corner,
// press into a face between its nodes and pass into the body without any node touching it.
// Each boundary face near a box, sphere or capsule gets, per Newton linearisation, a half-space
// at the collider's point y that reaches deepest past it (faceContact) with the face's inward
// normal n and the barycentric weights w of y's projection, all held fixed until the next
// linearisation; the face point x_w = sum w_i x_i then has the one-sided penalty
// k m_w d^2 / 2, d = (y - x_w).n, m_w = sum w_i m_i (a face contact at a node is as stiff as
// the node's own), gradient -k m_w d w_i n and the PSD Hessian k m_w (w w^T) (x) n n^T, which
// is exact for the fixed half-space. Faces are 4-node elements (the face's three nodes, then
// the opposite node of its tet), so the Hessian is gathered into the blocks the tet already has.
#pragma once

#include <cstdint>

#include "fem/node_stage.h"
#include "kernels/contact.h"

namespace gf::detail {

/// Per boundary face: its collider (-1: none), half-space and stiffness.
struct FaceContacts {
  const int32_t* faces = nullptr;  ///< 4 per face: the face's nodes, then the tet's fourth node
  int32_t* collider = nullptr;
  Vec3* weight = nullptr;   ///< barycentric weights of the contact point
  Vec3* point = nullptr;    ///< the collider's deepest point y
  Vec3* normal = nullptr;   ///< into the body
  double* k = nullptr;      ///< stiffness times the weighted mass [N/m]
  uint8_t* seen = nullptr;  ///< in contact at the last linearisation
  /// Friction: the normal force at the linearisation times the mixed coefficient (0: none).
  double* muLambda = nullptr;

  GF_HD Vec3 facePoint(int32_t f, const double* x) const {
    const Vec3 w = weight[f];
    Vec3 p{0, 0, 0};
    for (int i = 0; i < 3; ++i) {
      const int64_t i3 = 3 * int64_t(faces[4 * int64_t(f) + i]);
      p += w[i] * Vec3{x[i3], x[i3 + 1], x[i3 + 2]};
    }
    return p;
  }
  /// Depth (> 0 in contact) of face f's contact point at x.
  GF_HD double depth(int32_t f, const double* x) const {
    return dot(point[f] - facePoint(f, x), normal[f]);
  }
  /// Face f's contact point's sliding over the step against collider c's surface where the
  /// point starts (as ColliderFriction::slide), in the contact plane.
  GF_HD Vec3 slide(int32_t f, const double* x, const double* xn, const ColliderData& c,
                   double dt) const {
    const Vec3 start = facePoint(f, xn);
    const Vec3 surface = c.velocity + cross(c.angularVelocity, start - c.point);
    const Vec3 s = facePoint(f, x) - start - dt * surface;
    return s - dot(s, normal[f]) * normal[f];
  }
};

/// Per free boundary face, the continuous check the node sweep (SweepStage) makes per node: a
/// box, sphere or capsule smaller than a cell can pass between a fast body's nodes, where no
/// node's path meets it and the face contact at the step's end (FacePlaneStage) finds it behind
/// the face. The face moves from x_n to x_n + dt v_n (its nodes straight, in the colliders'
/// end-of-step frame); where the collider's point reaching farthest into the body
/// (supportPoint) starts less than its thickness (or maxDepth) past the face's plane and would
/// end more than half of that past it, the face advances (conservatively: by the depth still to
/// go over the plane's speed) to the first time the collider's part over the triangle reaches
/// its plane (faceContact there). That point y and the face's inward normal there are the
/// entry (`collider`, `point`, `normal`; -1: none), `radius` the farthest of the face's nodes
/// from y then, and `crossed` 1 (a max-reduction input). FaceEntryNodeStage hands the entry to
/// the nodes. A face one of whose nodes meets the collider over the step leaves it to the
/// nodes.
struct FaceSweepStage {
  const int32_t* faces = nullptr;  ///< FaceContacts::faces
  const double* x = nullptr;       ///< x_n
  const double* v = nullptr;       ///< v_n
  const uint8_t* fixedNode = nullptr;
  double dt = 0;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;
  double maxDepth = 0;  ///< FacePlaneStage's
  double band = 0;      ///< faceContact's
  int32_t* collider = nullptr;
  Vec3* point = nullptr;
  Vec3* normal = nullptr;
  double* radius = nullptr;
  double* crossed = nullptr;

  /// Unit normal of triangle p[0..2] towards p[3] (into the body); false when degenerate.
  GF_HD static bool inward(const Vec3 p[4], Vec3& n) {
    n = cross(p[1] - p[0], p[2] - p[0]);
    const double len = norm(n);
    if (!(len > 0)) return false;
    n = (dot(n, p[3] - p[0]) < 0 ? -1.0 / len : 1.0 / len) * n;
    return true;
  }

  GF_HD void operator()(int32_t f) const {
    collider[f] = -1;
    crossed[f] = 0;
    const int32_t* q = faces + 4 * int64_t(f);
    if (fixedNode[q[0]] || fixedNode[q[1]] || fixedNode[q[2]]) return;
    Vec3 a[4], b[4];
    for (int i = 0; i < 4; ++i) {
      const int64_t i3 = 3 * int64_t(q[i]);
      a[i] = Vec3{x[i3], x[i3 + 1], x[i3 + 2]};
      b[i] = a[i] + dt * Vec3{v[i3], v[i3 + 1], v[i3 + 2]};
    }
    const Vec3 end = (1.0 / 3) * (b[0] + b[1] + b[2]);
    double first = HUGE_VAL;
    for (int c = 0; c < colliderCount; ++c) {
      const ColliderData& col = colliders[c];
      if (col.kind == kColliderPlane) continue;
      // Relative to the collider at its end-of-step pose the face starts dt v_c further back.
      Vec3 s[4];
      for (int i = 0; i < 4; ++i) s[i] = a[i] + dt * col.velocity;
      const Vec3 start = (1.0 / 3) * (s[0] + s[1] + s[2]);
      double extent = 0;
      for (int i = 0; i < 3; ++i) extent = fmax(extent, fmax(norm(s[i] - start), norm(b[i] - end)));
      const double reach = col.kind == kColliderBox       ? norm(col.halfExtents)
                           : col.kind == kColliderCapsule ? col.radius + col.halfLength
                                                          : col.radius;
      const Vec3 path = end - start;
      const Vec3 nearest = start + closestOnSegment(col.point, start, path) * path;
      if (norm(col.point - nearest) > reach + extent + band) continue;
      Vec3 n0;
      if (!inward(s, n0)) continue;
      const Vec3 deepest = supportPoint(col, n0);
      const double d0 = dot(deepest - start, n0), d1 = dot(deepest - end, n0);
      const double limit = fmin(colliderThickness(col, n0), maxDepth);
      // A face already in contact is left to its face contact unless the collider would end
      // past maxDepth, where that contact no longer holds it (a body resting on a bar, its
      // faces ringing at 1 m/s, needs no clamp).
      if (!(d0 < limit) || !(d1 > (d0 < 0 ? 0.5 * limit : maxDepth))) continue;
      // Only a collider that passes between the face's nodes: one that a node starts in, ends
      // in or whose path enters it is the node contacts' (a glass bunny thrown at a box at 20
      // m/s, its faces clamped too, broke into 5018 fragments instead of 290).
      bool nodeMeets = false;
      for (int i = 0; i < 3; ++i) {
        Vec3 entry, outward;
        double thick = 0;
        nodeMeets |= penetration(col, s[i], outward) > 0 || penetration(col, b[i], outward) > 0 ||
                     sweptEntry(col, s[i], b[i], entry, outward, thick);
      }
      if (nodeMeets) continue;
      double t = d0 < 0 ? d0 / (d0 - d1) : 0.0;
      for (int it = 0; it < 4 && t <= 1 && t < first; ++it) {
        Vec3 p[4], n, y, w;
        for (int i = 0; i < 4; ++i) p[i] = s[i] + t * (b[i] - s[i]);
        if (!inward(p, n)) break;
        double share = 0;
        const double d = faceContact(col, p[0], p[1], p[2], n, band, y, w, share);
        if (d == -HUGE_VAL) break;  // the collider passes beside the triangle
        if (d < -0.1 * band) {
          t += -d / (d1 - d0);
          continue;
        }
        if (!(share > 0) || w.x >= 1 || w.y >= 1 || w.z >= 1) break;
        const double past = dot(y - (w.x * b[0] + w.y * b[1] + w.z * b[2]), n);
        if (!(past > 0.5 * fmin(colliderThickness(col, n), maxDepth))) break;
        first = t;
        collider[f] = c;
        point[f] = y;
        normal[f] = n;
        radius[f] = fmax(norm(p[0] - y), fmax(norm(p[1] - y), norm(p[2] - y)));
        break;
      }
    }
    crossed[f] = collider[f] >= 0 ? 1.0 : 0.0;
  }
};

/// A face's entry into a collider (FaceSweepStage), for FaceEntryNodeStage.
struct FaceEntry {
  int32_t collider = -1;
  Vec3 point;         ///< where the collider's part over the face reached its plane
  Vec3 normal;        ///< the face's, into the body: the collider's outward side there
  double radius = 0;  ///< the farthest of the face's nodes from point then
};

/// Per free node, the clamp that the node sweep gives a node crossing a plate, for the face
/// entries of the step: a collider met between the nodes must stop the body behind the face,
/// and a penalty at the face point alone has to dent the body around it by most of the step's
/// motion (a 10 cm box at 50 m/s onto a 1 cm ball inverted its tets and diverged). So each
/// node whose path crosses an entry's plane (through y, along the face's normal) within `spread`
/// times the entry's radius of y, having started on the body's side, gets that plane
/// as its swept contact (SweptContacts, the earliest crossing where several) with the crossing
/// node's stiffness (sweptStiffness), as if the collider were a wall there for this step. A node
/// that already keeps a swept contact keeps it. `crossed` and `bound` as SweepStage's.
struct FaceEntryNodeStage {
  const double* x = nullptr;  ///< x_n
  const double* v = nullptr;  ///< v_n
  const uint8_t* fixedNode = nullptr;
  double dt = 0;
  double cell = 0;
  double spread = 0;
  const ColliderData* colliders = nullptr;
  const FaceEntry* entries = nullptr;
  int32_t entryCount = 0;
  int32_t* collider = nullptr;
  Vec3* point = nullptr;
  Vec3* normal = nullptr;
  double* stiffness = nullptr;
  double* crossed = nullptr;
  double* bound = nullptr;

  GF_HD void operator()(int32_t n) const {
    if (fixedNode[n] || collider[n] >= 0) return;
    const int64_t i3 = 3 * int64_t(n);
    const Vec3 a{x[i3], x[i3 + 1], x[i3 + 2]};
    const Vec3 b = a + dt * Vec3{v[i3], v[i3 + 1], v[i3 + 2]};
    double first = HUGE_VAL;
    for (int32_t k = 0; k < entryCount; ++k) {
      const FaceEntry& e = entries[k];
      const ColliderData& col = colliders[e.collider];
      const Vec3 s = a + dt * col.velocity;
      const double ds = dot(s - e.point, e.normal), de = dot(b - e.point, e.normal);
      const double thickness = colliderThickness(col, e.normal);
      // On the body's side at the start (a face that starts a little in keeps it), past it at
      // the end.
      if (!(ds > -0.5 * thickness) || !(de < 0)) continue;
      const double t = ds > 0 ? ds / (ds - de) : 0.0;
      const Vec3 r = s + t * (b - s) - e.point;
      if (norm(r - dot(r, e.normal) * e.normal) > spread * e.radius || !(t < first)) continue;
      first = t;
      collider[n] = e.collider;
      point[n] = e.point;
      normal[n] = e.normal;
      stiffness[n] = sweptStiffness(col.stiffness, -de, thickness, dt);
      crossed[n] = 1.0;
      bound[n] = contactDepthBound(cell, thickness);
    }
  }
};

/// Squared speed of free node n: a max-reduction term (FaceSweepStage's gate).
struct NodeSpeedTerm {
  const double* v = nullptr;
  const uint8_t* fixedNode = nullptr;
  GF_HD double operator()(int32_t n) const {
    const int64_t i3 = 3 * int64_t(n);
    return fixedNode[n] ? 0.0 : v[i3] * v[i3] + v[i3 + 1] * v[i3 + 1] + v[i3 + 2] * v[i3 + 2];
  }
};

/// Per boundary face at x, the box, sphere or capsule collider reaching deepest past it within
/// `margin` (so the half-space is in place before the face gets there), unless a node of the
/// face is already in contact with that collider: then the node's penalty holds the face there,
/// and a face term as well would stiffen contacts that the node penalty alone has always held
/// (a ball resting on a block at its nodes keeps the result it had). A face with a prescribed
/// node, or whose projection is at a vertex (the node's contact), has none. `active` is 1 where
/// a face has a contact (a max-reduction term).
struct FacePlaneStage {
  const double* x = nullptr;
  const double* xn = nullptr;  ///< start of the step
  double dt = 0;
  const double* nodeMass = nullptr;
  const uint8_t* fixedNode = nullptr;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;
  SweptContacts swept;
  double margin = 0;
  double maxDepth = 0;  ///< deeper contacts are not the face's (see operator())
  double band = 0;      ///< faceContact's
  double bodyFriction = 0;
  const uint8_t* skip = nullptr;  ///< per collider, 1: none with it (Integrator::prepareFaces)
  FaceContacts fc;

  GF_HD double operator()(int32_t f) const {
    fc.collider[f] = -1;
    fc.k[f] = 0;
    fc.muLambda[f] = 0;
    fc.weight[f] = Vec3{0, 0, 0};
    const int32_t* q = fc.faces + 4 * int64_t(f);
    Vec3 p[4];
    for (int i = 0; i < 4; ++i) {
      const int64_t i3 = 3 * int64_t(q[i]);
      p[i] = Vec3{x[i3], x[i3 + 1], x[i3 + 2]};
    }
    if (fixedNode[q[0]] || fixedNode[q[1]] || fixedNode[q[2]]) return 0.0;
    Vec3 nIn = cross(p[1] - p[0], p[2] - p[0]);
    const double len = norm(nIn);
    if (!(len > 0)) return 0.0;
    nIn = (dot(nIn, p[3] - p[0]) < 0 ? -1.0 / len : 1.0 / len) * nIn;
    double best = -margin;
    // Bounding spheres first: most faces are far from every collider, and the exact test clips
    // up to 12 segments.
    const Vec3 centre = (1.0 / 3) * (p[0] + p[1] + p[2]);
    const double faceRadius =
        fmax(norm(p[0] - centre), fmax(norm(p[1] - centre), norm(p[2] - centre)));
    for (int c = 0; c < colliderCount; ++c) {
      const ColliderData& col = colliders[c];
      if (col.kind == kColliderPlane || skip[c]) continue;
      const double reach = col.kind == kColliderBox       ? norm(col.halfExtents)
                           : col.kind == kColliderCapsule ? col.radius + col.halfLength
                                                          : col.radius;
      if (norm(col.point - centre) > reach + faceRadius + margin) continue;
      Vec3 y, w;
      double share = 0;
      const double d = faceContact(col, p[0], p[1], p[2], nIn, band, y, w, share);
      // Only a collider that reaches past the face from outside, and not deeper than
      // maxDepth: one that lies behind the plane (under the opposite face), or whose far part
      // lies in the face's prism while it passes beside the face (a long bar under a block
      // reaches far past its side faces' planes, near their bottom edges), is not this face's.
      if (!(d > best) || !(d < colliderThickness(col, nIn) + margin) || !(d < maxDepth)) continue;
      if (!(share > 0) || w.x >= 1 || w.y >= 1 || w.z >= 1) continue;
      // Nor one the face came to from behind: where Newton linearises, a body that moves a
      // cell or more in a step (100 m/s onto a rod) has faces that were on the far side of
      // the collider at the step's start, whose contact would push the body on through it.
      Vec3 start{0, 0, 0};
      for (int i = 0; i < 3; ++i) {
        const int64_t i3 = 3 * int64_t(q[i]);
        start += w[i] * Vec3{xn[i3], xn[i3 + 1], xn[i3 + 2]};
      }
      if (dot(y - dt * col.velocity - start, nIn) > maxDepth) continue;
      bool nodeHolds = false;
      for (int i = 0; i < 3; ++i) {
        Vec3 out;
        nodeHolds |= swept.depth(col, c, q[i], p[i], out) > 0;
      }
      if (nodeHolds) continue;
      best = d;
      fc.collider[f] = c;
      fc.weight[f] = w;
      fc.point[f] = y;
      fc.normal[f] = nIn;
      fc.k[f] = share * col.stiffness *
                (w.x * nodeMass[q[0]] + w.y * nodeMass[q[1]] + w.z * nodeMass[q[2]]);
      // IPC's lagged normal force, as FrictionContactStage's, here at the linearisation.
      fc.muLambda[f] =
          col.friction > 0 && d > 0 ? sqrt(bodyFriction * col.friction) * fc.k[f] * d : 0.0;
    }
    return fc.collider[f] >= 0 ? 1.0 : 0.0;
  }
};

/// Face f's penalty energy at x into energy[f] (with friction, muLambda, also the smoothed
/// Coulomb friction of its contact point sliding over the step, nodeFriction, whose gradient
/// and Hessian on the point spread over the nodes as w_i and w_i w_j like the penalty's); with
/// grad, its 12-gradient (the fourth node's part zero) and, with hess, its 12x12 Hessian
/// (row-major, node-major as the element matrices), and whether it is in contact (seen).
struct FaceEnergyStage {
  const double* x = nullptr;
  const double* xn = nullptr;  ///< start of the step (friction's sliding)
  const ColliderData* colliders = nullptr;
  double dt = 0;
  FaceContacts fc;
  double* energy = nullptr;
  double* grad = nullptr;
  double* hess = nullptr;

  GF_HD void operator()(int32_t f) const {
    const int32_t c = fc.collider[f];
    const double d = c >= 0 ? fc.depth(f, x) : 0.0;
    const Vec3 n = c >= 0 ? fc.normal[f] : Vec3{};
    Vec3 g{0, 0, 0};
    Mat3 h;
    double e = penaltyContact(c >= 0 ? fc.k[f] : 0.0, d, n, g, h);
    if (c >= 0 && fc.muLambda[f] > 0)
      e += nodeFriction(fc.muLambda[f], n, fc.slide(f, x, xn, colliders[c], dt),
                        kFrictionSlipSpeed * dt, g, h);
    energy[f] = e;
    if (!grad) return;
    fc.seen[f] = d > 0;
    const Vec3 w = fc.weight[f];
    const double wa[4] = {w.x, w.y, w.z, 0.0};
    double* ge = grad + 12 * int64_t(f);
    for (int a = 0; a < 4; ++a)
      for (int i = 0; i < 3; ++i) ge[3 * a + i] = wa[a] * g[i];
    if (!hess) return;
    // The upper node blocks (kElementMatrixSize, kernels/math.h) of w w^T (x) h, from h's
    // upper triangle: k n_i n_j is symmetric only to round-off, the stored blocks exactly.
    double* he = hess + kElementMatrixSize * int64_t(f);
    for (int a = 0; a < 4; ++a)
      for (int b = a; b < 4; ++b)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) *he++ = wa[a] * wa[b] * (i <= j ? h(i, j) : h(j, i));
  }
};

/// 1 when face f's contact point is past its half-space at x but was not at the last
/// linearisation (UnseenContactTerm's face part): a max-reduction term.
struct FaceUnseenTerm {
  const double* x = nullptr;
  FaceContacts fc;
  GF_HD double operator()(int32_t f) const {
    return fc.collider[f] >= 0 && !fc.seen[f] && fc.depth(f, x) > 0 ? 1.0 : 0.0;
  }
};

/// What face f's penalty gave its nodes over the step as the last Newton step linearised it
/// at xLin, j = -dt (g + H (x - xLin)) (ColliderImpulseStage): 12 per face into nodeImpulse
/// (the fourth node's part zero, for the per-node gather), and the total with its moment about
/// the collider's point, 6 per face into total.
struct FaceImpulseStage {
  const double* x = nullptr;
  const double* xLin = nullptr;
  const double* xn = nullptr;
  const ColliderData* colliders = nullptr;
  FaceContacts fc;
  double dt = 0;
  double* nodeImpulse = nullptr;
  double* total = nullptr;

  GF_HD void operator()(int32_t f) const {
    const int32_t c = fc.collider[f];
    // Linear in x while in contact at xLin: the linearised force is the one at x.
    const double d = c >= 0 && fc.depth(f, xLin) > 0 ? fc.depth(f, x) : 0.0;
    Vec3 j = (dt * fc.k[f] * d) * fc.normal[f];
    if (c >= 0 && fc.muLambda[f] > 0) {
      Vec3 g{0, 0, 0};
      Mat3 h;
      const Vec3 ul = fc.slide(f, xLin, xn, colliders[c], dt);
      nodeFriction(fc.muLambda[f], fc.normal[f], ul, kFrictionSlipSpeed * dt, g, h);
      j -= dt * (g + h * (fc.slide(f, x, xn, colliders[c], dt) - ul));
    }
    const Vec3 w = fc.weight[f];
    const double wa[4] = {w.x, w.y, w.z, 0.0};
    for (int a = 0; a < 4; ++a)
      for (int i = 0; i < 3; ++i) nodeImpulse[12 * int64_t(f) + 3 * a + i] = wa[a] * j[i];
    const Vec3 moment = c >= 0 ? cross(fc.facePoint(f, x) - colliders[c].point, j) : Vec3{};
    for (int i = 0; i < 3; ++i) {
      total[6 * int64_t(f) + i] = j[i];
      total[6 * int64_t(f) + 3 + i] = moment[i];
    }
  }
};

/// Component k of face f's FaceImpulseStage total when its collider is c: a sum-reduction term.
struct FaceColliderImpulseTerm {
  const int32_t* collider = nullptr;
  const double* total = nullptr;
  int c = 0, k = 0;
  GF_HD double operator()(int32_t f) const {
    return collider[f] == c ? total[6 * int64_t(f) + k] : 0.0;
  }
};

}  // namespace gf::detail
