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
    double* he = hess + 144 * int64_t(f);
    for (int a = 0; a < 4; ++a)
      for (int i = 0; i < 3; ++i)
        for (int b = 0; b < 4; ++b)
          for (int j = 0; j < 3; ++j) he[12 * (3 * a + i) + 3 * b + j] = wa[a] * wa[b] * h(i, j);
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
