// The rigid motion of a body's free pieces as stages (header of fem/integrator.h and
// docs/design.md, "Rigid motion in a turning frame"). A piece's totals (mass, momentum,
// angular momentum, second moment, friction) are per-node terms that each node writes into
// one array per component, summed per piece by step/segments.h's fixed-order segmented
// reduction over the nodes grouped by piece; a stage over the pieces turns the totals into
// the piece's motion, and a stage over the nodes applies it. Nothing depends on the thread
// count, and a body of one piece sums in exactly the order of the executor's other reductions.
#pragma once

#include <cstdint>

#include "fem/friction_stage.h"
#include "fem/node_stage.h"
#include "kernels/contact.h"
#include "kernels/eigen_sym.h"
#include "kernels/tet_inertia.h"

namespace gf::detail {

/// One free piece's rigid motion over the step.
struct RigidPiece {
  double mass = 0;
  Vec3 centre{0, 0, 0}, velocity{0, 0, 0}, spin{0, 0, 0}, newCentre{0, 0, 0}, newSpin{0, 0, 0},
      momentTarget{0, 0, 0};
  Mat3 inertia, rotation, newInertia;
  Mat3 fullRotation;  ///< the turn over the whole step when the solve covers theta of it
  /// Friction (PieceSlideStage): summed mu lambda n, summed mu lambda, and the Newton start's
  /// slide over the step.
  Vec3 contactNormal{0, 0, 0}, slide{0, 0, 0};
  double frictionForce = 0;
  bool fixed = false, rigid = false;
  /// Taken out of the turning frame for this step (PiecePressedStage).
  bool plainStep = false;
};

// A thin piece (a needle or a line of nodes: some axis has under kThinAxis of the largest
// inertia) has almost no inertia about its own axis, and its angular momentum about that axis
// is round-off and the small moments of linearised contact impulses: I^-1 L turned that noise
// into spins of thousands of rad/s (up to 21 E0 gained in the stability suite). Such a piece is
// stepped by plain backward Euler, which cannot gain energy; a piece that becomes thin within a
// step keeps its start spin. 1e-3 is a rod about 1/75 as thick as it is long.
inline constexpr double kThinAxis = 1e-3;

/// Node n's three values of a 3-per-node array.
GF_HD Vec3 nodeVec3(const double* p, int32_t n) {
  return {p[3 * int64_t(n)], p[3 * int64_t(n) + 1], p[3 * int64_t(n) + 2]};
}

/// Components of a second moment m r r^T as summed: 00 01 02 11 12 22.
constexpr int kMomentTerms = 6;
GF_HD void writeSecondMoment(double* out, int64_t stride, int32_t n, double m, Vec3 r) {
  int k = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) out[(k++) * stride + n] = m * r[i] * r[j];
}
GF_HD Mat3 readSecondMoment(const double* sums, int64_t stride, int32_t s) {
  Mat3 c;
  int k = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) c(i, j) = c(j, i) = sums[(k++) * stride + s];
  return c;
}
GF_HD Vec3 readVec3(const double* sums, int64_t stride, int32_t s) {
  return {sums[s], sums[stride + s], sums[2 * stride + s]};
}
GF_HD void writeVec3(double* out, int64_t stride, int32_t n, Vec3 v) {
  for (int k = 0; k < 3; ++k) out[k * stride + n] = v[k];
}

/// w = I^-1 L; false for a thin piece (kThinAxis), whose spin is not to be trusted.
GF_HD bool spinOf(const Mat3& inertia, Vec3 angularMomentum, Vec3& spin) {
  double lambda[3];  // descending
  Mat3 axes;
  symmetricEigen(inertia, lambda, axes);
  if (!(isFinite(lambda[0]) && lambda[0] > 0 && lambda[2] >= kThinAxis * lambda[0])) return false;
  spin = inverse(inertia) * angularMomentum;
  return true;
}

/// The turn exp(w dt) by Rodrigues: R = I + sin(a) K + (1 - cos(a)) K^2 about the unit axis k.
GF_HD Mat3 turnBy(Vec3 spin, double dt) {
  const double angle = norm(spin) * dt;
  if (!(angle > 0)) return Mat3::identity();
  const Vec3 k = (1.0 / norm(spin)) * spin;
  Mat3 K;
  K(0, 1) = -k.z;
  K(0, 2) = k.y;
  K(1, 0) = k.z;
  K(1, 2) = -k.x;
  K(2, 0) = -k.y;
  K(2, 1) = k.x;
  return Mat3::identity() + sin(angle) * K + (1 - cos(angle)) * (K * K);
}

/// What the outside gives node n over dt when it ends at x: point forces, mass-damping,
/// deform-brush drag, a pull's tether and contact (penalty, body contact, friction) as the last
/// Newton step linearised it at xLin. No gravity: it has no moment about the centre.
struct ExternalImpulse {
  const double* externalForce = nullptr;
  const double* nodeMass = nullptr;
  const double* xStart = nullptr;
  const double* xLin = nullptr;  ///< read only with colliders or body contact
  double massDamping = 0, dt = 0;
  const double* drag = nullptr;  ///< FemState::drag, null: none
  Tether tether;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;
  SweptContacts swept;
  HalfSpaceContacts bodies;
  ColliderFriction friction;
  /// Per node, what the face contacts gave it over the step (FaceImpulseStage); null: none.
  const double* faceImpulse = nullptr;

  GF_HD Vec3 operator()(int32_t n, Vec3 x) const {
    const double m = nodeMass[n];
    const Vec3 xs = nodeVec3(xStart, n);
    const double damping = massDamping + (drag ? drag[n] / dt : 0.0);
    Vec3 impulse = dt * nodeVec3(externalForce, n) - (damping * m) * (x - xs) -
                   (tether.weight(n) * m / dt) * tether.offset(n, x);
    if (colliderCount > 0) {
      const Vec3 xl = nodeVec3(xLin, n);
      for (int c = 0; c < colliderCount; ++c) {
        Vec3 g;
        Mat3 h;
        if (swept.contact(colliders[c], c, n, xl, m, g, h) != 0) impulse -= dt * (g + h * (x - xl));
      }
    }
    if (bodies.start) {
      Vec3 g;
      Mat3 h;
      const Vec3 xl = nodeVec3(xLin, n);
      const HalfSpaceContacts b = bodies.at(xLin);
      const bool reacts = b.reactionTerms(n, g, h);
      if (b.contact(n, xl, g, h) + b.friction(n, xl, xs, g, h) != 0 || reacts)
        impulse -= dt * (g + h * (x - xl));
    }
    if (faceImpulse) impulse += nodeVec3(faceImpulse, n);
    if (friction.muLambda) {
      const Vec3 xl = nodeVec3(xLin, n);
      for (int c = 0; c < colliderCount; ++c)
        if (friction.touches(c, n)) impulse += friction.impulse(colliders[c], c, n, x, xl, dt);
    }
    return impulse;
  }
};

/// Per node, its share of its piece's totals at the step's start: m, m x (3), m v (3) and 1
/// when prescribed, into out[k nodeCount + n].
constexpr int kPieceMassTerms = 8;
struct PieceMassTerms {
  const double* x = nullptr;
  const double* v = nullptr;
  const double* nodeMass = nullptr;
  const uint8_t* fixedNode = nullptr;
  int32_t nodeCount = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t n) const {
    const double m = nodeMass[n];
    out[n] = m;
    writeVec3(out + nodeCount, nodeCount, n, m * nodeVec3(x, n));
    writeVec3(out + 4 * int64_t(nodeCount), nodeCount, n, m * nodeVec3(v, n));
    out[7 * int64_t(nodeCount) + n] = fixedNode[n] ? 1.0 : 0.0;
  }
};

/// A fresh piece s from PieceMassTerms' totals: mass, centre, velocity, whether it holds a
/// prescribed node.
struct PieceMassStage {
  const double* sums = nullptr;
  int32_t pieceCount = 0;
  RigidPiece* pieces = nullptr;

  GF_HD void operator()(int32_t s) const {
    RigidPiece p;
    p.mass = sums[s];
    p.centre = readVec3(sums + pieceCount, pieceCount, s);
    p.velocity = readVec3(sums + 4 * int64_t(pieceCount), pieceCount, s);
    p.fixed = sums[7 * int64_t(pieceCount) + s] > 0;
    if (p.mass > 0) {
      p.centre = (1.0 / p.mass) * p.centre;
      p.velocity = (1.0 / p.mass) * p.velocity;
    }
    pieces[s] = p;
  }
};

/// Per node of a piece without a prescribed node: its angular momentum m r x (v - v_c) about
/// the centre and its second moment m r r^T, 3 + kMomentTerms values.
constexpr int kPieceSpinTerms = 3 + kMomentTerms;
struct PieceSpinTerms {
  const double* x = nullptr;
  const double* v = nullptr;
  const double* nodeMass = nullptr;
  const RigidPiece* pieces = nullptr;
  const int32_t* pieceOfNode = nullptr;
  int32_t nodeCount = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t n) const {
    const RigidPiece& p = pieces[pieceOfNode[n]];
    const double m = p.fixed ? 0.0 : nodeMass[n];
    const Vec3 r = nodeVec3(x, n) - p.centre;
    writeVec3(out, nodeCount, n, m * cross(r, nodeVec3(v, n) - p.velocity));
    writeSecondMoment(out + 3 * int64_t(nodeCount), nodeCount, n, m, r);
  }
};

/// Piece s's spin w = I^-1 L from PieceSpinTerms' totals and its turn over the step (and over
/// the whole step, fullDt, when the solve covers theta of it). A thin piece is not turned.
struct PieceSpinStage {
  const double* sums = nullptr;
  int32_t pieceCount = 0;
  double dt = 0, fullDt = 0;
  RigidPiece* pieces = nullptr;

  GF_HD void operator()(int32_t s) const {
    RigidPiece& p = pieces[s];
    p.rigid = !p.fixed && p.mass > 0;
    if (!p.rigid) return;
    p.inertia =
        inertiaFromSecondMoment(readSecondMoment(sums + 3 * int64_t(pieceCount), pieceCount, s));
    if (!spinOf(p.inertia, readVec3(sums, pieceCount, s), p.spin)) {
      p.rigid = false;
      return;
    }
    p.rotation = turnBy(p.spin, dt);
    p.fullRotation = fullDt == dt ? p.rotation : turnBy(p.spin, fullDt);
  }
};

/// Per node, its share of its piece's friction: summed mu lambda n, mu lambda and mu lambda
/// times the surface velocity over its contacts, and the gravity and point force on it, 10
/// values.
constexpr int kPieceFrictionTerms = 10;
struct PieceFrictionTerms {
  const double* externalForce = nullptr;
  const double* nodeMass = nullptr;
  Vec3 gravity;
  const ColliderData* colliders = nullptr;
  ColliderFriction friction;
  int colliderCount = 0;
  int32_t nodeCount = 0;
  double* out = nullptr;
  /// Friction against other bodies' faces counts too: without it a block set sliding over a
  /// slab started at no slide and stopped within one step, as if welded. Their faces are taken
  /// at rest: with each face's lagged predicted motion as the surface's, a block resting on a
  /// slab on a frictional floor (mu 1) was thrown while it settled.
  HalfSpaceContacts bodies;

  GF_HD void operator()(int32_t n) const {
    Vec3 normal{0, 0, 0}, surface{0, 0, 0};
    double force = 0;
    for (int c = 0; friction.muLambda && c < colliderCount; ++c) {
      const int64_t s = friction.slot(c, n);
      if (!(friction.muLambda[s] > 0)) continue;
      normal += friction.muLambda[s] * friction.normal[s];
      force += friction.muLambda[s];
      surface += friction.muLambda[s] * friction.surfaceVelocity(colliders[c], n);
    }
    if (bodies.start && bodies.muLambda)
      for (int32_t k = bodies.start[n]; k < bodies.start[n + 1]; ++k)
        if (bodies.muLambda[k] > 0 && !bodies.moving(k)) {
          normal += bodies.muLambda[k] * bodies.normal[k];
          force += bodies.muLambda[k];
        }
    writeVec3(out, nodeCount, n, normal);
    out[3 * int64_t(nodeCount) + n] = force;
    writeVec3(out + 4 * int64_t(nodeCount), nodeCount, n,
              nodeVec3(externalForce, n) + nodeMass[n] * gravity);
    writeVec3(out + 7 * int64_t(nodeCount), nodeCount, n, surface);
  }
};

/// The Newton start of free piece s on frictional contacts. Linearised at no slide, smoothed
/// friction is a stiff viscous drag, so one Newton step from there holds a sliding body still
/// (a block on a 26 degree slope with mu = 0.2 stopped where it should accelerate at
/// 2.6 m/s^2), and one from its old slide keeps a stopping body creeping. So the piece starts
/// where Coulomb's law takes its centre: it sticks when the friction available, mu N, holds
/// the tangential external force and stops the tangential velocity within the step; else it
/// slides at the velocity that force and mu N leave, along the mean contact plane (no deeper
/// into the collider). Both relative to the contacts' mean surface velocity: a start that
/// ignored a conveyor's or turntable's motion was linearised at a slide up to 2 mu g dt too
/// fast, and the step's friction force fell short of mu N by that ratio (0.82 mu N on a
/// 2 m/s conveyor).
struct PieceSlideStage {
  const double* sums = nullptr;  ///< PieceFrictionTerms' totals
  int32_t pieceCount = 0;
  double dt = 0;
  RigidPiece* pieces = nullptr;

  GF_HD void operator()(int32_t s) const {
    RigidPiece& p = pieces[s];
    if (!p.rigid) return;
    p.contactNormal = readVec3(sums, pieceCount, s);
    p.frictionForce = sums[3 * int64_t(pieceCount) + s];
    const Vec3 force = readVec3(sums + 4 * int64_t(pieceCount), pieceCount, s);
    const double len = norm(p.contactNormal);
    if (!(len > 0)) return;
    const Vec3 n = (1.0 / len) * p.contactNormal;
    Vec3 surface =
        (1.0 / p.frictionForce) * readVec3(sums + 7 * int64_t(pieceCount), pieceCount, s);
    surface = surface - dot(surface, n) * n;
    const Vec3 vt = p.velocity - dot(p.velocity, n) * n - surface;
    const Vec3 ft = force - dot(force, n) * n;
    // Tangential velocity at the end if nothing held it, then friction's most against it.
    const Vec3 free = vt + (dt / p.mass) * ft;
    const double speed = norm(free), cut = dt * p.frictionForce / p.mass;
    p.slide = dt * surface;
    if (speed > cut) p.slide += dt * ((1 - cut / speed) * free);  // else it sticks
  }
};

/// In the frame that turns with a free piece, backward Euler on the deformation: y is the
/// rigid motion of x_n (c + dt v_c + R r) plus the deformation's own velocity, turned, and the
/// centrifugal and Coriolis accelerations of the turning frame; Newton starts from x_n turned
/// (c + R r, which has the stresses of x_n: a spin stretches nothing) plus the piece's slide.
/// The rigid motion itself is carried exactly. Nodes of other pieces are left as they are.
struct RigidStartStage {
  const double* xn = nullptr;
  const double* vn = nullptr;
  const RigidPiece* pieces = nullptr;
  const int32_t* pieceOfNode = nullptr;
  double dt = 0, fullDt = 0;
  double* x = nullptr;        ///< Newton's start
  double* y = nullptr;        ///< inertia target
  double* dampRef = nullptr;  ///< null without stiffness damping

  GF_HD void operator()(int32_t n) const {
    const RigidPiece& p = pieces[pieceOfNode[n]];
    if (!p.rigid) return;
    const Vec3 r = nodeVec3(xn, n) - p.centre;
    const Vec3 turned = p.rotation * r;
    // Newton starts from the turn alone: the translation is linear in x and solved exactly,
    // and a start moved along the velocity could begin inside a collider.
    const Vec3 start = p.centre + turned;
    const Vec3 vDefStart = nodeVec3(vn, n) - p.velocity - cross(p.spin, r);
    Vec3 vDef = p.rotation * vDefStart;
    Vec3 fictitious = -1.0 * cross(p.spin, cross(p.spin, turned));
    if (fullDt == dt) {
      fictitious -= 2.0 * cross(p.spin, vDef);
    } else {
      // The theta method below 1 leaves the stiff modes undamped, and an explicit Coriolis
      // term pumps energy into them (a tumbling block gained 12 % in 2 s). So Coriolis is split
      // off (Strang): over half a step on either side of the solve it turns the deformation
      // velocity by exp(-2 w dt/2), the transpose of the whole step's turn, which keeps its
      // size (ThetaSpinTerms applies the second half).
      vDef = p.rotation * (transpose(p.fullRotation) * vDefStart);
    }
    const Vec3 target = start + dt * (p.velocity + vDef) + (dt * dt) * fictitious;
    const int64_t i3 = 3 * int64_t(n);
    // Stiffness damping acts on the deformation: measured from the rigid motion, not x_n.
    for (int i = 0; i < 3; ++i) {
      x[i3 + i] = start[i] + p.slide[i];
      y[i3 + i] = target[i];
      if (dampRef) dampRef[i3 + i] = start[i];
    }
  }
};

/// Per node of a free piece: how much deeper in the colliders Newton's start (the turned x_n
/// plus the slide), or the start carried on by the piece's velocity over the step, lies than
/// x_n, the largest over the colliders (0 if nowhere deeper).
struct PiecePressTerms {
  const double* xn = nullptr;
  const double* x = nullptr;  ///< Newton's start
  const RigidPiece* pieces = nullptr;
  const int32_t* pieceOfNode = nullptr;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;
  SweptContacts swept;
  double dt = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t n) const {
    double deeper = 0;
    const RigidPiece& p = pieces[pieceOfNode[n]];
    if (p.rigid) {
      const Vec3 xi = nodeVec3(x, n), xni = nodeVec3(xn, n);
      // A piece that reaches a collider within the step meets it as surely as one its turn
      // presses in: the contact impulses then set its end spin (a one-tet chip thrown at a
      // ball spun up to 3e5 rad/s and was flung at 4.5 km/s when it broke).
      const Vec3 ahead = xi + dt * p.velocity;
      for (int c = 0; c < colliderCount; ++c) {
        Vec3 normal;
        const double depth = swept.depth(colliders[c], c, n, xi, normal);
        const double reached = swept.depth(colliders[c], c, n, ahead, normal);
        const double before = swept.depth(colliders[c], c, n, xni, normal);
        const double excess = (depth > reached ? depth : reached) - (before > 0 ? before : 0.0);
        if (excess > deeper) deeper = excess;
      }
    }
    out[n] = deeper;
  }
};

/// Piece s is stepped by plain backward Euler when its turned start lies deeper in a collider
/// than x_n anywhere (sums: PiecePressTerms' per-piece maxima).
struct PiecePressedStage {
  const double* sums = nullptr;
  RigidPiece* pieces = nullptr;
  double* pressed = nullptr;  ///< per piece, 1 when so stepped

  GF_HD void operator()(int32_t s) const {
    RigidPiece& p = pieces[s];
    p.plainStep = p.rigid && sums[s] > 0;
    if (p.plainStep) p.rigid = false;
    pressed[s] = p.plainStep ? 1.0 : 0.0;
  }
};

/// The plain backward-Euler step's start x_n, inertia target x_n + dt v_n and stiffness
/// damping reference x_n on the nodes of the pieces PiecePressedStage took out of the frame.
struct PlainStepStage {
  const double* xn = nullptr;
  const double* vn = nullptr;
  const RigidPiece* pieces = nullptr;
  const int32_t* pieceOfNode = nullptr;
  double dt = 0;
  double* x = nullptr;
  double* y = nullptr;
  double* dampRef = nullptr;  ///< null without stiffness damping

  GF_HD void operator()(int32_t n) const {
    if (!pieces[pieceOfNode[n]].plainStep) return;
    for (int64_t i = 3 * int64_t(n); i < 3 * int64_t(n) + 3; ++i) {
      x[i] = xn[i];
      y[i] = xn[i] + dt * vn[i];
      if (dampRef) dampRef[i] = xn[i];
    }
  }
};

/// The residual's share of a free piece's spin in the first Newton step: |m dt w x r|^2 per
/// node, a sum term (the iterative solvers' tolerance scale).
struct SpinShareTerm {
  const double* xStart = nullptr;
  const double* nodeMass = nullptr;
  const RigidPiece* pieces = nullptr;
  const int32_t* pieceOfNode = nullptr;
  double dt = 0;

  GF_HD double operator()(int32_t n) const {
    const RigidPiece& p = pieces[pieceOfNode[n]];
    if (!p.rigid) return 0.0;
    const Vec3 u = (nodeMass[n] * dt) * cross(p.spin, nodeVec3(xStart, n) - p.centre);
    return dot(u, u);
  }
};

/// Per node of a free piece, its share m x of the piece's centre at x, 3 values.
struct EndCentreTerms {
  const double* x = nullptr;
  const double* nodeMass = nullptr;
  const RigidPiece* pieces = nullptr;
  const int32_t* pieceOfNode = nullptr;
  int32_t nodeCount = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t n) const {
    const bool rigid = pieces[pieceOfNode[n]].rigid;
    writeVec3(out, nodeCount, n, rigid ? nodeMass[n] * nodeVec3(x, n) : Vec3{0, 0, 0});
  }
};

/// Free piece s's centre at the end from EndCentreTerms' totals.
struct PieceEndCentreStage {
  const double* sums = nullptr;
  int32_t pieceCount = 0;
  RigidPiece* pieces = nullptr;

  GF_HD void operator()(int32_t s) const {
    RigidPiece& p = pieces[s];
    p.newCentre = p.rigid ? (1.0 / p.mass) * readVec3(sums, pieceCount, s) : Vec3{0, 0, 0};
  }
};

/// Per node of a free piece at the end of a backward-Euler step: its share of the angular
/// momentum the piece must end with beyond the start's (the moment of the external impulse,
/// less what the deformation carries) and of its second moment about the new centre. The
/// external impulses are taken from the forces, not from m (x' - y), which would count an
/// unconverged Newton step's residual as a torque; internal forces of a rotation-invariant
/// energy have no moment, and uniform gravity none about the centre.
struct EndSpinTerms {
  const double* x = nullptr;
  const double* xStart = nullptr;
  const double* nodeMass = nullptr;
  const RigidPiece* pieces = nullptr;
  const int32_t* pieceOfNode = nullptr;
  ExternalImpulse external;
  double dt = 0;
  int32_t nodeCount = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t n) const {
    const RigidPiece& p = pieces[pieceOfNode[n]];
    Vec3 moment;
    Vec3 r;
    double m = 0;
    if (p.rigid) {
      m = nodeMass[n];
      const Vec3 xi = nodeVec3(x, n);
      r = xi - p.newCentre;
      const Vec3 turned = p.rotation * (nodeVec3(xStart, n) - p.centre);
      moment = cross(r, external(n, xi)) - (m / dt) * cross(r, r - turned);
    }
    writeVec3(out, nodeCount, n, moment);
    writeSecondMoment(out + 3 * int64_t(nodeCount), nodeCount, n, m, r);
  }
};

/// Free piece s's end spin w' from its end inertia and target angular momentum (the start's
/// plus EndSpinTerms' or ThetaSpinTerms' totals); a piece without inertia about some axis
/// keeps its spin.
struct PieceEndSpinStage {
  const double* sums = nullptr;
  int32_t pieceCount = 0;
  RigidPiece* pieces = nullptr;

  GF_HD void operator()(int32_t s) const {
    RigidPiece& p = pieces[s];
    if (!p.rigid) return;
    p.momentTarget = p.inertia * p.spin + readVec3(sums, pieceCount, s);
    p.newInertia =
        inertiaFromSecondMoment(readSecondMoment(sums + 3 * int64_t(pieceCount), pieceCount, s));
    if (!spinOf(p.newInertia, p.momentTarget, p.newSpin)) p.newSpin = p.spin;
  }
};

/// v = (c' - c) / dt + w' x r' + (r' - R r) / dt with r' = x' - c' on the nodes of free pieces:
/// the rigid spin carried over, the deformation's change over the step, and the centre's motion
/// exactly as backward Euler gives it (so momentum changes only by the external impulses).
struct RigidEndVelocityStage {
  const double* x = nullptr;
  const double* xStart = nullptr;
  const RigidPiece* pieces = nullptr;
  const int32_t* pieceOfNode = nullptr;
  double dt = 0;
  double* v = nullptr;

  GF_HD void operator()(int32_t n) const {
    const RigidPiece& p = pieces[pieceOfNode[n]];
    if (!p.rigid) return;
    const Vec3 rNew = nodeVec3(x, n) - p.newCentre;
    const Vec3 turned = p.rotation * (nodeVec3(xStart, n) - p.centre);
    const Vec3 vel = (1.0 / dt) * (p.newCentre - p.centre) + cross(p.newSpin, rNew) +
                     (1.0 / dt) * (rNew - turned);
    for (int i = 0; i < 3; ++i) v[3 * int64_t(n) + i] = vel[i];
  }
};

/// Theta method, one-leg form (Hairer, Lubich & Wanner, Geometric Numerical Integration,
/// sec. VI.3): z is backward Euler over h = theta dt; x' = x + (z - x) / theta and
/// v' = v + (v_z - v) / theta with v_z = (z - x) / h. Prescribed nodes move exactly. One entry
/// per item.
struct ThetaEndStage {
  const double* z = nullptr;
  const double* xStart = nullptr;
  const double* vStart = nullptr;
  const double* gripVelocity = nullptr;
  const uint8_t* fixedNode = nullptr;
  double dt = 0, h = 0, theta = 1;
  double* x = nullptr;
  double* v = nullptr;

  GF_HD void operator()(int32_t i) const {
    const double x0 = xStart[i], v0 = vStart[i];
    if (fixedNode[i / 3]) {
      x[i] = x0 + dt * gripVelocity[i];
      v[i] = gripVelocity[i];
    } else {
      x[i] = x0 + (z[i] - x0) / theta;
      v[i] = v0 + ((z[i] - x0) / h - v0) / theta;
    }
  }
};

/// Per node of a free piece below theta 1: extrapolating a turn linearly would stretch the
/// body, so only the centre (a translation) and the deformation seen in the turning frame are
/// extrapolated and the piece turns by its spin over the whole step. Writes the node's end
/// position and its deformation velocity (PieceEndSpinStage's spin is added by
/// ThetaVelocityStage), and its share of the end angular momentum and second moment as
/// EndSpinTerms does; newCentre is the centre of z here.
struct ThetaSpinTerms {
  const double* z = nullptr;
  const double* xStart = nullptr;
  const double* vStart = nullptr;
  const double* nodeMass = nullptr;
  const RigidPiece* pieces = nullptr;
  const int32_t* pieceOfNode = nullptr;
  ExternalImpulse external;  ///< over h
  double h = 0, theta = 1;
  int32_t nodeCount = 0;
  double* x = nullptr;
  double* v = nullptr;
  double* out = nullptr;

  GF_HD void operator()(int32_t n) const {
    const RigidPiece& p = pieces[pieceOfNode[n]];
    Vec3 moment, r;
    double m = 0;
    if (p.rigid) {
      m = nodeMass[n];
      const Vec3 zi = nodeVec3(z, n), x0 = nodeVec3(xStart, n);
      // The external impulses of the solved step act at z over the whole step: 1 / theta of
      // them.
      moment = (1.0 / theta) * cross(zi - p.newCentre, external(n, zi));
      // The deformation over the solved step in the frame at the step's start, extrapolated
      // and turned over the whole step; its velocity likewise, between the two Coriolis
      // half-turns (RigidStartStage), whose second one undoes the frame's turn.
      const Vec3 r0 = x0 - p.centre;
      const Vec3 deformation = transpose(p.rotation) * (zi - p.newCentre) - r0;
      const Vec3 vDefStart =
          transpose(p.fullRotation) * (nodeVec3(vStart, n) - p.velocity - cross(p.spin, r0));
      r = p.fullRotation * (r0 + (1.0 / theta) * deformation);
      const Vec3 vDef = (1 - 1.0 / theta) * vDefStart + (1.0 / (theta * h)) * deformation;
      const Vec3 centre = p.centre + (1.0 / theta) * (p.newCentre - p.centre);
      for (int i = 0; i < 3; ++i) {
        x[3 * int64_t(n) + i] = centre[i] + r[i];
        v[3 * int64_t(n) + i] = vDef[i];
      }
      moment -= m * cross(r, vDef);  // what the deformation carries
    }
    writeVec3(out, nodeCount, n, moment);
    writeSecondMoment(out + 3 * int64_t(nodeCount), nodeCount, n, m, r);
  }
};

/// The end velocity of a free piece's node below theta 1: the extrapolated centre's velocity
/// plus the end spin about the extrapolated centre plus the deformation velocity in v.
struct ThetaVelocityStage {
  const double* x = nullptr;
  const RigidPiece* pieces = nullptr;
  const int32_t* pieceOfNode = nullptr;
  double h = 0, theta = 1;
  double* v = nullptr;

  GF_HD void operator()(int32_t n) const {
    const RigidPiece& p = pieces[pieceOfNode[n]];
    if (!p.rigid) return;
    const Vec3 centre = p.centre + (1.0 / theta) * (p.newCentre - p.centre);
    const Vec3 centreVelocity =
        p.velocity + (1.0 / theta) * ((1.0 / h) * (p.newCentre - p.centre) - p.velocity);
    const Vec3 vel = centreVelocity + cross(p.newSpin, nodeVec3(x, n) - centre) + nodeVec3(v, n);
    for (int i = 0; i < 3; ++i) v[3 * int64_t(n) + i] = vel[i];
  }
};

}  // namespace gf::detail
