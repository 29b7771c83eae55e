// The per-node part of the incremental potential (header of fem/integrator.h), written once
// for both executors like fem/element_stage.h: inertia, mass damping, gravity and point forces,
// collider contact and friction. Each node writes its own terms; the integrator sums them in the
// fixed order of step/reduce.h.
#pragma once

#include <cstdint>

#include "fem/friction_stage.h"
#include "kernels/contact.h"
#include "solver/vector_stages.h"

namespace gf::detail {

/// A pull's springs for one step (FemState::tether, FemState::tetherTarget): node n is drawn
/// toward its target t by 1/2 m w |x - t|^2 in the h^2-scaled units of the incremental
/// potential, a spring of stiffness m w / h^2. Null weights: no pull.
struct Tether {
  const double* w = nullptr;       ///< per node, 0 where not pulled
  const double* target = nullptr;  ///< 3 per node

  GF_HD double weight(int32_t n) const { return w ? w[n] : 0.0; }
  /// x - t, or zero where not pulled.
  GF_HD Vec3 offset(int32_t n, Vec3 x) const {
    if (!w || w[n] == 0) return {0, 0, 0};
    const int64_t i3 = 3 * int64_t(n);
    return x - Vec3{target[i3], target[i3 + 1], target[i3 + 2]};
  }
};

/// The node's energy terms, one array of nodeCount values each, laid out one after another
/// in NodePotentialStage::terms.
enum NodeTerm : int { kNodeEnergy, kNodeContact, kNodeMagnitude, kNodeGradMagnitude, kNodeTerms };

/// E_n(x) = 1/2 m |x-y|^2 + dt/2 r1 m |x-x_n|^2 - dt^2 f^T x + dt^2 (Psi_c(x) + D_f(x)) per node
/// (eq 2.7, 3.13 with Rayleigh r1; D_f collider friction's dissipation potential), plus the
/// sculpting terms 1/2 m w |x-x_n|^2 (deform drag) and 1/2 m w_t |x-t|^2 (pull tether; see
/// FemState::drag, FemState::tether), and, when `grad` is non-null, its gradient plus dt^2 times
/// the elastic node gradient, the contact Hessian block and whether the node touches a collider.
/// The magnitude terms are the summed sizes of the parts that cancel in E and in dE/dx |x|
/// (round-off scale of the line search).
struct NodePotentialStage {
  const double* x = nullptr;   ///< 3 per node
  const double* xn = nullptr;  ///< start of the step
  const double* y = nullptr;   ///< inertia target
  const double* nodeMass = nullptr;
  const double* externalForce = nullptr;  ///< 3 per node
  Vec3 gravity;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;
  SweptContacts swept;
  HalfSpaceContacts bodies;  ///< body-body and self contact
  ColliderFriction friction;
  double dt = 0, massDamping = 0, lengthScale = 1;
  const double* drag = nullptr;  ///< FemState::drag, null: none
  Tether tether;
  int32_t nodeCount = 0;
  double* terms = nullptr;  ///< kNodeTerms * nodeCount
  // Gradient pass only (null otherwise).
  const double* elasticGrad = nullptr;  ///< dPsi/dx, 3 per node
  double* grad = nullptr;               ///< dE/dx without friction and stiffness damping
  Mat3* contactHess = nullptr;
  uint8_t* contactSeen = nullptr;

  GF_HD void operator()(int32_t n) const {
    const double m = nodeMass[n], dt2 = dt * dt, r1 = massDamping;
    const int64_t i3 = 3 * int64_t(n);
    const Vec3 xi{x[i3], x[i3 + 1], x[i3 + 2]}, xni{xn[i3], xn[i3 + 1], xn[i3 + 2]};
    const Vec3 yi{y[i3], y[i3 + 1], y[i3 + 2]};
    const Vec3 fext =
        Vec3{externalForce[i3], externalForce[i3 + 1], externalForce[i3 + 2]} + m * gravity;
    Vec3 cg;
    Mat3 ch;
    double contact = 0;
    for (int c = 0; c < colliderCount; ++c)
      contact += swept.contact(colliders[c], c, n, xi, m, cg, ch);
    contact += bodies.contact(n, xi, cg, ch) + bodies.friction(n, xi, xni, cg, ch);
    bodies.reactionTerms(n, cg, ch);
    const Vec3 dy = xi - yi, dn = xi - xni;
    const double w = drag ? drag[n] : 0.0;
    const Vec3 dp = tether.offset(n, xi);
    const double wt = tether.weight(n);
    const double inertia =
        0.5 * m * dot(dy, dy) + 0.5 * (dt * r1 + w) * m * dot(dn, dn) + 0.5 * wt * m * dot(dp, dp);
    const double work = dt2 * dot(fext, xi);
    terms[kNodeEnergy * int64_t(nodeCount) + n] = inertia - work;
    terms[kNodeContact * int64_t(nodeCount) + n] = contact;
    terms[kNodeMagnitude * int64_t(nodeCount) + n] = inertia + (work < 0 ? -work : work);
    double gradMagnitude = 0;
    if (grad) {
      const Vec3 g = m * dy + ((dt * r1 + w) * m) * dn + (wt * m) * dp + dt2 * (cg - fext);
      const Vec3 ge{elasticGrad[i3], elasticGrad[i3 + 1], elasticGrad[i3 + 2]};
      // Round-off of E from rounding x: |dE/dx| |x| eps, summed over the parts before they
      // cancel (inertia against gravity against elasticity).
      gradMagnitude = (norm(m * dy) + (dt * r1 + w) * m * norm(dn) + wt * m * norm(dp) +
                       dt2 * (norm(cg) + norm(fext)) + dt2 * norm(ge)) *
                      (norm(xi) + lengthScale);
      for (int i = 0; i < 3; ++i) grad[i3 + i] = g[i] + dt2 * ge[i];
      contactHess[n] = ch;
      contactSeen[n] = frobeniusDot(ch, ch) > 0;
    }
    terms[kNodeGradMagnitude * int64_t(nodeCount) + n] = gradMagnitude;
    if (friction.muLambda) addFriction(n, xi);
  }

  // Collider friction after the rest: the contact set that the impact test compares with
  // (contactSeen) is the penalty's.
  GF_HD void addFriction(int32_t n, Vec3 xi) const {
    const double dt2 = dt * dt;
    const int64_t i3 = 3 * int64_t(n);
    double energy = 0, magnitude = 0, gradMagnitude = 0;
    for (int c = 0; c < colliderCount; ++c) {
      if (!friction.touches(c, n)) continue;
      Vec3 g{0, 0, 0};
      Mat3 h;
      const double d = dt2 * friction.potential(colliders[c], c, n, xi, dt, g, h);
      energy += d;
      magnitude += d < 0 ? -d : d;
      if (!grad) continue;
      gradMagnitude += dt2 * norm(g) * (norm(xi) + lengthScale);
      for (int i = 0; i < 3; ++i) grad[i3 + i] += dt2 * g[i];
      contactHess[n] = contactHess[n] + h;
    }
    terms[kNodeEnergy * int64_t(nodeCount) + n] += energy;
    terms[kNodeMagnitude * int64_t(nodeCount) + n] += magnitude;
    terms[kNodeGradMagnitude * int64_t(nodeCount) + n] += gradMagnitude;
  }
};

/// out[i] = a[i] - b[i] (a null: 0) on the free nodes' entries and 0 on the prescribed ones,
/// whose rows the system holds as identity: the Newton right-hand side -dE/dx and the
/// constant-velocity start of the iterative solvers.
struct FreeDifferenceStage {
  const double* a = nullptr;
  const double* b = nullptr;
  const uint8_t* fixedNode = nullptr;
  double* out = nullptr;

  GF_HD void operator()(int32_t i) const {
    out[i] = fixedNode[i / 3] ? 0.0 : (a ? a[i] : 0.0) - b[i];
  }
};

/// The per-node blocks of the step's matrix, A_nn += m (1 + dt r1 + w + w_t) I + dt^2 H_contact
/// (eq 2.7, 3.13 with Rayleigh r1, a deform brush's drag w and a pull's tether w_t): `values` are
/// the block-sparse values (9 per block) and diagonalBlock the block of each node's diagonal;
/// contactHess null where no node can touch anything.
struct NodeBlockStage {
  double* values = nullptr;
  const int32_t* diagonalBlock = nullptr;
  const double* nodeMass = nullptr;
  const Mat3* contactHess = nullptr;
  double massScale = 1, dt2 = 0;
  const double* drag = nullptr;  ///< FemState::drag, null: none
  Tether tether;

  GF_HD void operator()(int32_t n) const {
    double* blk = values + 9 * int64_t(diagonalBlock[n]);
    const double md = nodeMass[n] * (massScale + (drag ? drag[n] : 0.0) + tether.weight(n));
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        blk[3 * i + j] += (i == j ? md : 0.0) + (contactHess ? dt2 * contactHess[n](i, j) : 0.0);
  }
};

/// 1 when free node n at x penetrates a collider that the last linearisation did not see
/// (contactSeen 0), else 0: a max-reduction term, so "any" is one fixed-order pass.
struct UnseenContactTerm {
  const double* x = nullptr;
  const uint8_t* contactSeen = nullptr;
  const uint8_t* fixedNode = nullptr;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;
  SweptContacts swept;
  HalfSpaceContacts bodies;

  GF_HD double operator()(int32_t n) const {
    if (contactSeen[n] || fixedNode[n]) return 0.0;
    const Vec3 xi{x[3 * int64_t(n)], x[3 * int64_t(n) + 1], x[3 * int64_t(n) + 2]};
    if (bodies.inside(n, xi)) return 1.0;
    for (int c = 0; c < colliderCount; ++c) {
      Vec3 normal;
      if (swept.depth(colliders[c], c, n, xi, normal) > 0) return 1.0;
    }
    return 0.0;
  }
};

/// 1 when free node n was behind one of its self-contact half-spaces at the last linearisation's
/// point xLin and ends in front of it at x, else 0: a max-reduction term. The penalty is linear in
/// x where it acts, so that step solved it as a two-sided spring and pulled the node back towards
/// the plane. A plane set at the other side's predicted face lies ahead of x_n when both move
/// together, and that pull dragged the pieces of a falling cut body apart.
struct ReleasedContactTerm {
  const double* x = nullptr;
  const double* xLin = nullptr;
  const uint8_t* fixedNode = nullptr;
  HalfSpaceContacts bodies;

  GF_HD double operator()(int32_t n) const {
    if (fixedNode[n] || bodies.start[n] == bodies.start[n + 1]) return 0.0;
    const Vec3 xi{x[3 * int64_t(n)], x[3 * int64_t(n) + 1], x[3 * int64_t(n) + 2]};
    const Vec3 xl{xLin[3 * int64_t(n)], xLin[3 * int64_t(n) + 1], xLin[3 * int64_t(n) + 2]};
    const HalfSpaceContacts atLin = bodies.at(xLin), atX = bodies.at(x);
    for (int32_t k = bodies.start[n]; k < bodies.start[n + 1]; ++k) {
      const double dl = atLin.depth(k, xl), dx = atX.depth(k, xi);
      if (bodies.self(k) && dl > 0 && dx < 0) return 1.0;
      // A pair solved with its face is piecewise quadratic in the body's unknowns: where it acts
      // (or did), the step goes on to convergence.
      if (atX.moving(k) && (dl > 0 || dx > 0)) return 1.0;
    }
    return 0.0;
  }
};

/// 1 when free node n has friction against another body's face (a half-space with a lagged
/// normal force whose face is not its own body's).
struct BodyFrictionTerm {
  const uint8_t* fixedNode = nullptr;
  HalfSpaceContacts bodies;

  GF_HD double operator()(int32_t n) const {
    if (fixedNode[n] || !bodies.muLambda) return 0.0;
    for (int32_t k = bodies.start[n]; k < bodies.start[n + 1]; ++k)
      if (bodies.muLambda[k] > 0 && !bodies.moving(k)) return 1.0;
    return 0.0;
  }
};

/// The cross terms of the moving self pairs (contact/body_contact.h) that the block pattern
/// lacks. Pair k's Gauss-Newton Hessian is k g g^T, g = (-n, w_1 n, w_2 n, w_3 n) over (vertex,
/// face nodes) the gradient of its depth at the linearisation (HalfSpaceContacts::pair); its
/// diagonal blocks are in the matrix (contact and reactionTerms), the rest is applied here,
/// matrix-free. First per half-space (SelfPairActiveStage) a_k = dt^2 k when the pair acts at
/// the linearisation else 0, with its n and w there; then (SelfPairProjectStage) s_k = a_k g_k . p;
/// then per node (SelfPairCouplingStage) its rows of sum_k a_k g_k g_k^T p less the diagonal
/// blocks, summed in half-space order. Prescribed nodes take no part (their rows and columns are
/// the identity's).
/// A pair's moving friction (HalfSpaceContacts::slide) adds c c^T (x) B, c = (1, -w_1, -w_2,
/// -w_3) with the pair's held weights, B = f_k (I - n n^T) its node Hessian (nodeFriction) with
/// f_k = dt^2 mu lambda f1(y) / y at the linearisation; its cross blocks go the same way
/// (SelfPairProjectStage's t_k = B (p_v - sum_i w_i p_i)).
struct SelfPairActiveStage {
  HalfSpaceContacts bodies;  ///< at the linearisation point
  double dt2 = 0;
  double* active = nullptr;  ///< per half-space
  Vec3* normal = nullptr;    ///< per half-space, n and w at the linearisation point
  Vec3* weight = nullptr;
  double* friction = nullptr;  ///< per half-space, f_k (0: no moving friction)

  GF_HD void operator()(int32_t k) const {
    Vec3 n{0, 0, 0}, w{0, 0, 0};
    const double d = bodies.moving(k) ? bodies.pair(k, bodies.nodeAt(bodies.owner[k]), n, w) : 0.0;
    active[k] = d > 0 ? dt2 * bodies.stiffness[k] : 0.0;
    normal[k] = n;
    weight[k] = w;
    friction[k] = 0;
    if (bodies.movingFriction(k)) {
      const int32_t v = bodies.owner[k];
      const Vec3 u = bodies.slide(k, bodies.nodeAt(v), bodies.startAt(v));
      friction[k] = dt2 * bodies.muLambda[k] * frictionF1OverY(norm(u), bodies.slipEps);
    }
  }
};

struct SelfPairProjectStage {
  HalfSpaceContacts bodies;
  const uint8_t* fixedNode = nullptr;
  const double* active = nullptr;
  const Vec3* normal = nullptr;  ///< SelfPairActiveStage's
  const Vec3* weight = nullptr;
  const double* friction = nullptr;
  const double* p = nullptr;
  double* s = nullptr;  ///< per half-space
  Vec3* t = nullptr;    ///< per half-space

  GF_HD Vec3 at(int32_t n) const {
    if (fixedNode[n]) return {0, 0, 0};
    return {p[3 * int64_t(n)], p[3 * int64_t(n) + 1], p[3 * int64_t(n) + 2]};
  }
  GF_HD void operator()(int32_t k) const {
    s[k] = 0;
    t[k] = Vec3{0, 0, 0};
    if (active[k] != 0) {
      Vec3 q = -1.0 * at(bodies.owner[k]);
      for (int i = 0; i < 3; ++i) q += weight[k][i] * at(bodies.faceNode[3 * int64_t(k) + i]);
      s[k] = active[k] * dot(normal[k], q);
    }
    if (friction[k] != 0) {
      Vec3 q = at(bodies.owner[k]);
      for (int i = 0; i < 3; ++i)
        q -= bodies.weight[k][i] * at(bodies.faceNode[3 * int64_t(k) + i]);
      t[k] = friction[k] * bodies.tangential(k, q);
    }
  }
};

struct SelfPairCouplingStage {
  HalfSpaceContacts bodies;
  const uint8_t* fixedNode = nullptr;
  const double* active = nullptr;
  const Vec3* normal = nullptr;  ///< SelfPairActiveStage's
  const Vec3* weight = nullptr;
  const double* friction = nullptr;
  const double* s = nullptr;  ///< SelfPairProjectStage's
  const Vec3* t = nullptr;
  const double* p = nullptr;
  double* y = nullptr;  ///< added to

  GF_HD void operator()(int32_t n) const {
    if (fixedNode[n]) return;
    const int64_t i3 = 3 * int64_t(n);
    const Vec3 pn{p[i3], p[i3 + 1], p[i3 + 2]};
    Vec3 acc{0, 0, 0};
    for (int32_t k = bodies.start[n]; k < bodies.start[n + 1]; ++k) {
      if (active[k] != 0) acc += -(s[k] + active[k] * dot(normal[k], pn)) * normal[k];
      if (friction[k] != 0) acc += t[k] - friction[k] * bodies.tangential(k, pn);
    }
    for (int32_t e = bodies.reactionStart[n]; e < bodies.reactionStart[n + 1]; ++e) {
      const int32_t k = bodies.reaction[e] / 3;
      if (friction[k] != 0) {
        const double w = bodies.weight[k][bodies.reaction[e] % 3];
        acc += -w * t[k] - (w * w * friction[k]) * bodies.tangential(k, pn);
      }
      if (active[k] == 0) continue;
      const double w = weight[k][bodies.reaction[e] % 3];
      acc += (w * (s[k] - active[k] * w * dot(normal[k], pn))) * normal[k];
    }
    y[i3] += acc.x;
    y[i3 + 1] += acc.y;
    y[i3 + 2] += acc.z;
  }
};

/// The end of a backward-Euler step: x = the solved positions, v = (x - x_n) / dt on free
/// nodes and exactly the grip velocity on prescribed ones; one entry per item.
struct EndOfStepStage {
  const double* solved = nullptr;
  const double* xn = nullptr;
  const double* gripVelocity = nullptr;
  const uint8_t* fixedNode = nullptr;
  double dt = 0;
  double* x = nullptr;
  double* v = nullptr;

  GF_HD void operator()(int32_t i) const {
    v[i] = fixedNode[i / 3] ? gripVelocity[i] : (solved[i] - xn[i]) / dt;
    x[i] = solved[i];
  }
};

/// 1 when free node n at x, or at x + dt v (v non-null), is inside a collider, else 0: a
/// max-reduction term.
struct InsideColliderTerm {
  const double* x = nullptr;
  const double* v = nullptr;
  double dt = 0;
  const uint8_t* fixedNode = nullptr;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;

  GF_HD double operator()(int32_t n) const {
    if (fixedNode[n]) return 0.0;
    const int64_t i3 = 3 * int64_t(n);
    const Vec3 xi{x[i3], x[i3 + 1], x[i3 + 2]};
    const Vec3 ahead = v ? xi + dt * Vec3{v[i3], v[i3 + 1], v[i3 + 2]} : xi;
    for (int c = 0; c < colliderCount; ++c) {
      Vec3 normal;
      if (penetration(colliders[c], xi, normal) > 0 ||
          (v && penetration(colliders[c], ahead, normal) > 0))
        return 1.0;
    }
    return 0.0;
  }
};

/// Free node n's penalty energy against the colliders at x: a sum-reduction term.
struct ColliderEnergyTerm {
  const double* x = nullptr;
  const double* nodeMass = nullptr;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;

  GF_HD double operator()(int32_t n) const {
    const Vec3 xi{x[3 * int64_t(n)], x[3 * int64_t(n) + 1], x[3 * int64_t(n) + 2]};
    double e = 0;
    for (int c = 0; c < colliderCount; ++c) {
      Vec3 g;
      Mat3 h;
      e += nodeContact(colliders[c], xi, nodeMass[n], g, h);
    }
    return e;
  }
};

/// Free node n's mass (axis < 0) or momentum along one axis: a sum-reduction term.
struct NodeMomentumTerm {
  const double* v = nullptr;
  const double* nodeMass = nullptr;
  const uint8_t* fixedNode = nullptr;
  int axis = -1;
  GF_HD double operator()(int32_t n) const {
    if (fixedNode[n]) return 0.0;
    return axis < 0 ? nodeMass[n] : nodeMass[n] * v[3 * int64_t(n) + axis];
  }
};

/// 1 when node n's swept contact holds a collider (SweepStage), else 0: a max-reduction term.
struct SweptAnyTerm {
  const int32_t* collider = nullptr;
  GF_HD double operator()(int32_t n) const { return collider[n] >= 0 ? 1.0 : 0.0; }
};

/// Node n's share of a body's momentum balance over the last step (Integrator::
/// bodyContactImpulses), kBalanceTerms arrays of nodeCount: the impulses its body-contact
/// half-spaces gave it as the last Newton step linearised them at xLin (each also written to
/// `impulse`, 3 per half-space), its momentum change beyond gravity, point forces, mass damping,
/// drag and tether, and 1 when it is prescribed.
constexpr int kBalanceTerms = 7;
struct BodyContactBalanceStage {
  const double* x = nullptr;
  const double* xLin = nullptr;
  const double* xStart = nullptr;
  const double* v = nullptr;
  const double* vStart = nullptr;
  const double* nodeMass = nullptr;
  const double* externalForce = nullptr;
  const uint8_t* fixedNode = nullptr;
  const double* drag = nullptr;  ///< FemState::drag, null: none
  Tether tether;
  HalfSpaceContacts hs;
  Vec3 gravity;
  double dt = 0, massDamping = 0;
  int32_t nodeCount = 0;
  double* impulse = nullptr;
  double* terms = nullptr;

  GF_HD void operator()(int32_t n) const {
    const int64_t i3 = 3 * int64_t(n);
    const Vec3 xi{x[i3], x[i3 + 1], x[i3 + 2]}, x0{xStart[i3], xStart[i3 + 1], xStart[i3 + 2]};
    Vec3 linearised{0, 0, 0};
    if (!fixedNode[n]) {
      const Vec3 xl{xLin[i3], xLin[i3 + 1], xLin[i3 + 2]};
      const HalfSpaceContacts atLin = hs.at(xLin);
      for (int32_t c = hs.start[n]; c < hs.start[n + 1]; ++c) {
        Vec3 g;
        Mat3 h;
        // A moving-face pair (penalty and friction) is an exact action-reaction inside the
        // body.
        double e = 0;
        if (!hs.moving(c)) {
          e = penaltyContact(hs.stiffness[c], atLin.depth(c, xl), hs.normal[c], g, h);
          if (hs.muLambda && hs.muLambda[c] > 0)
            e += nodeFriction(hs.muLambda[c], hs.normal[c], hs.slide(c, xl, x0), hs.slipEps, g, h);
        }
        const Vec3 j = e == 0 ? Vec3{0, 0, 0} : -dt * (g + h * (xi - xl));
        linearised += j;
        for (int i = 0; i < 3; ++i) impulse[3 * int64_t(c) + i] = j[i];
      }
    } else {
      for (int32_t c = hs.start[n]; c < hs.start[n + 1]; ++c)
        for (int i = 0; i < 3; ++i) impulse[3 * int64_t(c) + i] = 0;
    }
    const double m = nodeMass[n];
    const Vec3 vi{v[i3], v[i3 + 1], v[i3 + 2]}, v0{vStart[i3], vStart[i3 + 1], vStart[i3 + 2]};
    const Vec3 f{externalForce[i3], externalForce[i3 + 1], externalForce[i3 + 2]};
    Vec3 change = m * (vi - v0) - dt * (f + m * gravity);
    change += ((massDamping + (drag ? drag[n] / dt : 0.0)) * m) * (xi - x0);
    change += (tether.weight(n) * m / dt) * tether.offset(n, xi);
    for (int k = 0; k < 3; ++k) {
      terms[k * int64_t(nodeCount) + n] = linearised[k];
      terms[(3 + k) * int64_t(nodeCount) + n] = change[k];
    }
    terms[6 * int64_t(nodeCount) + n] = fixedNode[n] ? 1.0 : 0.0;
  }
};

/// The force on a prescribed node, its gradient of the incremental potential times `scale`
/// (1 / dt^2), and zero on free nodes; one entry per item.
struct PrescribedGradientStage {
  const double* grad = nullptr;
  const uint8_t* fixedNode = nullptr;
  double scale = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t i) const { out[i] = fixedNode[i / 3] ? grad[i] * scale : 0.0; }
};

/// What each collider's penalty gave free node n over the step, as the last Newton step
/// linearised it at xLin: j = scale (g + H (x - xLin)) with scale = -dt (over theta below 1)
/// and its moment about the collider's point, 6 values per collider into
/// out[(6 c + k) nodeCount + n], so each total is one fixed-order sum over the nodes.
struct ColliderImpulseStage {
  const double* x = nullptr;
  const double* xLin = nullptr;
  const uint8_t* fixedNode = nullptr;
  const double* nodeMass = nullptr;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;
  SweptContacts swept;
  double scale = 0;
  int32_t nodeCount = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t n) const {
    const int64_t i3 = 3 * int64_t(n);
    const Vec3 xi{x[i3], x[i3 + 1], x[i3 + 2]}, xl{xLin[i3], xLin[i3 + 1], xLin[i3 + 2]};
    for (int c = 0; c < colliderCount; ++c) {
      Vec3 j, moment, g;
      Mat3 h;
      // Prescribed nodes take no part in the balance.
      if (!fixedNode[n] && swept.contact(colliders[c], c, n, xl, nodeMass[n], g, h) != 0) {
        j = scale * (g + h * (xi - xl));
        moment = cross(xi - colliders[c].point, j);
      }
      for (int k = 0; k < 3; ++k) {
        out[(6 * int64_t(c) + k) * nodeCount + n] = j[k];
        out[(6 * int64_t(c) + 3 + k) * nodeCount + n] = moment[k];
      }
    }
  }
};

/// The depth a kept (swept) face may hold a node at: kContactDepthCells of the body's cell and
/// kContactDepthThickness of the collider's thickness, whichever is less.
constexpr double kContactDepthCells = 0.1;
constexpr double kContactDepthThickness = 0.05;
GF_HD double contactDepthBound(double cell, double thickness) {
  const double a = kContactDepthCells * cell, b = kContactDepthThickness * thickness;
  return a < b ? a : b;
}
/// Per-step stiffening of a kept face at most this much per Newton iteration, and to at most
/// kMaxContactStiffnessDt2 / dt^2 per unit mass (the matrix's spread stays within what the
/// linear solvers resolve).
constexpr double kMaxContactStiffening = 100;
constexpr double kMaxContactStiffnessDt2 = 1e8;
/// A contact counts as a push (DeepContactTerm::deepened) where the node went deeper within the
/// step by more than this share of its bound; a resting contact's depth stays put (a Bullet ball
/// resting on a block). A quarter also caught a 3 cm ball at 1 m/s and 240 Hz slowly pushing a
/// soft block with k dt^2 10 (0.24 cell deep with 1), but stiffened the porcelain column's
/// contact with its 6 m/s ball (1.2 mm a step against a 1.9 mm bound), which needed none.
constexpr double kDeepenedShare = 1;

/// Per free node, the box, sphere or capsule collider that it is in at the step's start (its
/// nearest face), or else the first one that its path over the step (x_n to x_n + dt v_n, in the
/// colliders' end-of-step frame) enters, with the face's point and normal (SweptContacts),
/// kept only where the path would pass the collider (`crossed` 1: it ends more than half the
/// collider's thickness below the face, where the nearest-face depth would push it out of the
/// far side), with a penalty stiffened to stop the node inside (sweptStiffness), or where a
/// moving collider has swept over x_n (keepFace); and whether a collider presses into the node
/// over the step or has swept over x_n (classify).
struct SweepStage {
  const double* x = nullptr;
  const double* v = nullptr;
  const uint8_t* fixedNode = nullptr;
  double dt = 0;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;
  int32_t* collider = nullptr;
  Vec3* point = nullptr;
  Vec3* normal = nullptr;
  double* stiffness = nullptr;
  double* crossed = nullptr;
  double cell = 0;            ///< the body's cell size (kContactDepthCells)
  double* bound = nullptr;    ///< per node, the depth a kept face may hold it at (DeepContactTerm)
  double* scale = nullptr;    ///< per node, SweptContacts::scale, reset to 1
  double* pressed = nullptr;  ///< per node, 1 where a collider presses into it (classify)
  double* over = nullptr;     ///< per node, 1 where a moving collider swept over x_n (classify)
  Vec3 body;                  ///< the body's mean velocity (NodeMomentumTerm), for classify

  GF_HD void operator()(int32_t n) const {
    collider[n] = -1;
    crossed[n] = 0;
    scale[n] = 1;
    pressed[n] = 0;
    over[n] = 0;
    if (fixedNode[n]) return;
    const int64_t i3 = 3 * int64_t(n);
    const Vec3 a{x[i3], x[i3 + 1], x[i3 + 2]}, vn{v[i3], v[i3 + 1], v[i3 + 2]};
    const Vec3 b = a + dt * vn;
    double nearest = HUGE_VAL, thickness = 0;
    for (int c = 0; c < colliderCount; ++c) {
      const ColliderData& col = colliders[c];
      if (col.kind == kColliderPlane) continue;  // a half-space cannot be passed through
      // The collider moved by dt * velocity over the step: relative to it, the node starts
      // that much further back.
      const Vec3 start = a + dt * col.velocity;
      Vec3 p, nrm;
      double t = 0;
      // A node that starts inside keeps the face it is nearest to for the whole step (it came
      // in through it), so that it cannot be pushed on through the far side either.
      const double inside = penetration(col, start, nrm);
      if (inside > 0) {
        p = start + inside * nrm;
        t = colliderThickness(col, nrm);
      } else if (!sweptEntry(col, start, b, p, nrm, t) &&
                 !(dot(col.velocity, col.velocity) > 0 && sweptEntry(col, start, a, p, nrm, t))) {
        // A moving collider, placed at its end-of-step pose, has swept over x_n, where Newton
        // starts, when the node moved with it: that path enters it too (keepFace).
        continue;
      }
      const double along = dot(p - start, p - start);
      if (along < nearest) {
        nearest = along;
        thickness = t;
        collider[n] = c;
        point[n] = p;
        normal[n] = nrm;
      }
    }
    if (collider[n] >= 0) keepFace(n, a, b, thickness);
    classify(n, a, b, vn);
  }

  // The path would pass the collider when it ends deeper below the face than half the
  // collider's thickness: from there the nearest face is the far one, which would push the node
  // on through. Such nodes keep the face, with a penalty stiff enough to stop them inside.
  // Newton linearises first at x_n, not at the prediction b: against a moving collider, placed
  // at its end-of-step pose, x_n lies dt v_c.n deeper than the node was, and a paddle or a ball
  // that moves more than half its thickness in a step had the nodes it pushed at the far face's
  // side, or off a ball's axis where its radial normal points sideways or back, when linearised
  // there, and pushed them on through (a 2 cm box at 1 m/s and 60 Hz left behind the block it
  // pushed, a 3 cm ball at 6 m/s and 240 Hz went through it). So a node whose x_n such a
  // collider has swept over keeps the face it met, at the collider's own stiffness. Only where
  // the collider moved more than the node's depth bound along the face: closer than that x_n is
  // as good a place to linearise as any (a ball resting on a body, mirrored from Bullet with
  // its residual velocity, keeps the nearest-face contact it had). Every other contact stays the
  // nearest-face one.
  GF_HD void keepFace(int32_t n, Vec3 a, Vec3 b, double thickness) const {
    const ColliderData& kept = colliders[collider[n]];
    bound[n] = contactDepthBound(cell, thickness);
    const double reach = dot(point[n] - b, normal[n]);
    if (reach > 0.5 * thickness) {
      crossed[n] = 1.0;
      stiffness[n] = sweptStiffness(kept.stiffness, reach, thickness, dt);
      return;
    }
    if (dt * dot(kept.velocity, normal[n]) > bound[n] && dot(point[n] - a, normal[n]) > 0) {
      stiffness[n] = kept.stiffness;
      return;
    }
    collider[n] = -1;
  }

  // Where a collider closes in on the node, or on the body as a whole (the touching nodes of a
  // soft body can move with the collider while they push the rest of it), over the step along
  // its face's normal by more than the depth the node may be held at (contactDepthBound):
  // `pressed`. The colliders are
  // the node's kept face and the moving ones that x_n or the prediction b is inside. Only such
  // a push carries the body's inertia on the touching nodes (DeepContactTerm); a node resting
  // on a collider, or leaving it, is held by a static load that the collider's own penalty
  // balances (a Bullet ball resting on a block: stiffening it there threw the ball up).
  // Where such a collider moved by more than that bound over x_n, and x_n is inside it:
  // `over`, Newton's first linearisation sees contacts that are not where the step ends (a
  // plane that moves a block's length in a step, linearised with the whole block inside it,
  // pulled the block back into itself by 1.5 cells), so the step iterates to convergence.
  GF_HD void classify(int32_t n, Vec3 a, Vec3 b, Vec3 vn) const {
    for (int c = 0; c < colliderCount; ++c) {
      const ColliderData& col = colliders[c];
      // A static collider's crossed face already has sweptStiffness, sized for the node's path.
      if (!(dot(col.velocity, col.velocity) > 0)) continue;
      Vec3 nrm, atStart;
      double limit = 0;
      bool inAtStart = false;
      if (c == collider[n]) {
        nrm = normal[n];
        limit = bound[n];
        inAtStart = dot(point[n] - a, nrm) > 0;  // behind the kept face
      } else {
        inAtStart = penetration(col, a, atStart) > 0;
        if (!(penetration(col, b, nrm) > 0)) {
          if (!inAtStart) continue;
          nrm = atStart;
        }
        limit = contactDepthBound(
            cell, col.kind == kColliderPlane ? HUGE_VAL : colliderThickness(col, nrm));
      }
      const double closing = dt * fmax(dot(col.velocity - vn, nrm), dot(col.velocity - body, nrm));
      if (closing > limit) pressed[n] = 1;
      if (inAtStart && dt * dot(col.velocity, nrm) > limit) over[n] = 1;
    }
  }
};

/// A node that a collider presses into (SweepStage::pressed) or that went deeper within the step
/// (deepened), held by its kept face or a moving collider's nearest face deeper than its bound:
/// its penalty per unit mass is
/// raised by (depth / bound)^2, and 1 is returned (a max-reduction term, so "any" is one
/// fixed-order pass). The penalty is sized for the node's own inertia (k dt^2 = 100 stops a
/// node within 1 % of its reach), but a collider that pushes a body carries the body's mass on
/// the few nodes it touches and stops them about (M / m_touching) / (k dt^2) of the way in: a
/// 3 cm ball at 6 m/s and 60 Hz ended 2.5 cm deep in the 1 kg block it hit. The depth falls as
/// 1 / k when the push is steady and as 1 / sqrt(k) in an impact, hence the square.
struct DeepContactTerm {
  const double* x = nullptr;
  const uint8_t* fixedNode = nullptr;
  const ColliderData* colliders = nullptr;
  SweptContacts swept;
  const double* bound = nullptr;
  double* stiffness = nullptr;      ///< SweptContacts::stiffness, raised in place
  double* scale = nullptr;          ///< SweptContacts::scale, raised in place
  const double* pressed = nullptr;  ///< SweepStage::pressed: stiffened wherever deep
  const double* xn = nullptr;       ///< start of the step: others where they deepened within it
  const uint8_t* contactSeen = nullptr;  ///< the last linearisation's
  int colliderCount = 0;
  double cell = 0, maxStiffness = 0, dt = 0;

  GF_HD double operator()(int32_t n) const {
    if (fixedNode[n]) return 0.0;
    const int32_t c = swept.collider[n];
    // A node without a kept face and out of contact in the last linearisation is left to the
    // next (UnseenContactTerm): most nodes cost one read.
    if (c < 0 && !contactSeen[n]) return 0.0;
    const int64_t i3 = 3 * int64_t(n);
    const Vec3 xi{x[i3], x[i3 + 1], x[i3 + 2]}, x0{xn[i3], xn[i3 + 1], xn[i3 + 2]};
    const bool isPressed = pressed[n] > 0;
    Vec3 nrm;
    if (c >= 0) {
      const ColliderData& col = colliders[c];
      // Only a moving collider's (SweepStage::classify).
      if (!(dot(col.velocity, col.velocity) > 0)) return 0.0;
      const double d = swept.depth(col, c, n, xi, nrm);
      if (!isPressed && !deepened(d, swept.depth(col, c, n, start(c, x0), nrm), bound[n]))
        return 0.0;
      return raise(d, bound[n], stiffness[n], maxStiffness);
    }
    // Without a kept face, the nearest-face contacts of the moving colliders (a pushing plane,
    // or a node that a ball's deforming target wrapped around it), with one factor per node.
    double deepest = 0, k = 0;
    for (int j = 0; j < colliderCount; ++j) {
      const ColliderData& col = colliders[j];
      if (!(dot(col.velocity, col.velocity) > 0)) continue;
      const double d = penetration(col, xi, nrm);
      const double t = col.kind == kColliderPlane ? HUGE_VAL : colliderThickness(col, nrm);
      const double b = contactDepthBound(cell, t);
      if (!isPressed && !deepened(d, penetration(col, start(j, x0), nrm), b)) continue;
      if (d / b > deepest) {
        deepest = d / b;
        k = col.stiffness;
      }
    }
    if (!(k > 0) || !scale) return 0.0;
    double s = k * scale[n];
    const double raised = raise(deepest, 1.0, s, maxStiffness);
    scale[n] = s / k;
    return raised;
  }
  // Where the node started the step relative to collider c, in its end-of-step frame.
  GF_HD Vec3 start(int c, Vec3 x0) const { return x0 + dt * colliders[c].velocity; }
  // Whether the node went deeper within the step, from depth d0 at its start to d, by more than
  // kDeepenedShare of its bound b: a push (a soft body's front rebounding into the ball that pushes
  // it, with no closing velocity at the step's start), not a resting contact, whose depth stays
  // put.
  GF_HD static bool deepened(double d, double d0, double b) {
    return d - (d0 > 0 ? d0 : 0.0) > kDeepenedShare * b;
  }
  // Raises k by (d / b)^2, within the caps; 1 when it did.
  GF_HD static double raise(double d, double b, double& k, double maxK) {
    if (!(d > b) || !(k < maxK)) return 0.0;
    double r = (d / b) * (d / b);
    if (r > kMaxContactStiffening) r = kMaxContactStiffening;
    k = k * r < maxK ? k * r : maxK;
    return 1.0;
  }
};

}  // namespace gf::detail
