// Collider friction of one body step as stages (header of fem/integrator.h): IPC's smoothed
// Coulomb friction with the normal force lagged at the step's start. The contacts are kept
// dense, one slot per collider and node, rather than compacted into a list: colliders are
// few, every stage then reads a node's contacts at fixed places, and a node's contacts are
// visited in collider order, the order the compacted list had.
#pragma once

#include <cstdint>

#include "kernels/contact.h"

namespace gf::detail {

/// The step's friction contacts: slot c nodeCount + n holds node n's contact with collider c,
/// its lagged normal force times the mixed coefficient (0: no contact) and the normal.
struct ColliderFriction {
  const double* muLambda = nullptr;  ///< null: no contact this step
  const Vec3* normal = nullptr;
  const double* xStart = nullptr;  ///< x_n, 3 per node
  int32_t nodeCount = 0;

  GF_HD int64_t slot(int c, int32_t n) const { return int64_t(c) * nodeCount + n; }
  GF_HD bool touches(int c, int32_t n) const { return muLambda[slot(c, n)] > 0; }
  /// The collider surface's velocity where node n starts the step.
  GF_HD Vec3 surfaceVelocity(const ColliderData& col, int32_t n) const {
    const int64_t i3 = 3 * int64_t(n);
    const Vec3 start{xStart[i3], xStart[i3 + 1], xStart[i3 + 2]};
    return col.velocity + cross(col.angularVelocity, start - col.point);
  }
  /// The node's sliding against the collider over dt when it ends at x, in the contact plane:
  /// against the surface's velocity where the node starts (a spinning collider's differs from
  /// point to point; held over the step, so the potential stays a function of x alone).
  GF_HD Vec3 slide(const ColliderData& col, int c, int32_t n, Vec3 x, double dt) const {
    const int64_t i3 = 3 * int64_t(n);
    const Vec3 start{xStart[i3], xStart[i3 + 1], xStart[i3 + 2]};
    const Vec3 s = x - start - dt * surfaceVelocity(col, n);
    const Vec3 nrm = normal[slot(c, n)];
    return s - dot(s, nrm) * nrm;
  }
  /// The contact's dissipation potential at x (nodeFriction), its gradient and Hessian added
  /// to grad and hess.
  GF_HD double potential(const ColliderData& col, int c, int32_t n, Vec3 x, double dt, Vec3& grad,
                         Mat3& hess) const {
    return nodeFriction(muLambda[slot(c, n)], normal[slot(c, n)], slide(col, c, n, x, dt),
                        kFrictionSlipSpeed * dt, grad, hess);
  }
  /// The impulse the contact gives over dt when the node ends at x, as the last Newton step
  /// linearised it at xLin: the momentum bookkeeping must use the force that step balanced
  /// (the exact one, smaller where the smoothing is concave, left a block on a slope with a
  /// spin it did not have).
  GF_HD Vec3 impulse(const ColliderData& col, int c, int32_t n, Vec3 x, Vec3 xLin,
                     double dt) const {
    Vec3 g{0, 0, 0};
    Mat3 h;
    (void)potential(col, c, n, xLin, dt, g, h);
    return -dt * (g + h * (x - xLin));
  }
};

/// Per free node, its friction contacts at the step's start x_n: every collider with friction
/// that it penetrates, with the penalty's normal force k m d there lagged over the step (IPC's
/// lambda) times sqrt(mu_body mu_collider); touching[n] 1 when it has one (a max-reduction).
struct FrictionContactStage {
  const double* xStart = nullptr;
  const uint8_t* fixedNode = nullptr;
  const double* nodeMass = nullptr;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;
  double bodyFriction = 0;
  int32_t nodeCount = 0;
  double* muLambda = nullptr;  ///< colliderCount * nodeCount
  Vec3* normal = nullptr;
  double* touching = nullptr;

  GF_HD void operator()(int32_t n) const {
    touching[n] = 0;
    const int64_t i3 = 3 * int64_t(n);
    const Vec3 x{xStart[i3], xStart[i3 + 1], xStart[i3 + 2]};
    for (int c = 0; c < colliderCount; ++c) {
      const int64_t s = int64_t(c) * nodeCount + n;
      muLambda[s] = 0;
      const ColliderData& col = colliders[c];
      if (fixedNode[n] || !(col.friction > 0)) continue;
      Vec3 nrm;
      const double depth = penetration(col, x, nrm);
      if (!(depth > 0)) continue;
      muLambda[s] = sqrt(bodyFriction * col.friction) * (col.stiffness * nodeMass[n] * depth);
      normal[s] = nrm;
      touching[n] = 1;
    }
  }
};

/// What each collider's friction gave node n over the step, linearised at xLin and scaled by
/// `scale` (1 / theta below theta 1), and its moment about the collider's point: the layout of
/// ColliderImpulseStage, so each total is one fixed-order sum over the nodes.
struct FrictionImpulseStage {
  const double* x = nullptr;
  const double* xLin = nullptr;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;
  ColliderFriction friction;
  double dt = 0, scale = 1;
  int32_t nodeCount = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t n) const {
    const int64_t i3 = 3 * int64_t(n);
    const Vec3 xi{x[i3], x[i3 + 1], x[i3 + 2]}, xl{xLin[i3], xLin[i3 + 1], xLin[i3 + 2]};
    for (int c = 0; c < colliderCount; ++c) {
      Vec3 j, moment;
      if (friction.touches(c, n)) {
        j = scale * friction.impulse(colliders[c], c, n, xi, xl, dt);
        moment = cross(xi - colliders[c].point, j);
      }
      for (int k = 0; k < 3; ++k) {
        out[(6 * int64_t(c) + k) * nodeCount + n] = j[k];
        out[(6 * int64_t(c) + 3 + k) * nodeCount + n] = moment[k];
      }
    }
  }
};

}  // namespace gf::detail
