// Penalty contact of one node against a static collider: a one-sided quadratic energy
// k m d^2 / 2 on the penetration depth d, so contact enters the implicit step as an energy
// (consistent gradient and a PSD Hessian k m n n^T) and stays stable at large time steps.
// A moving collider is placed at its end-of-step pose, so the same energy pushes nodes along.
#pragma once

#include "math.h"

namespace gf {

enum ColliderKind : int { kColliderPlane = 0, kColliderBox = 1, kColliderSphere = 2 };

/// Collider in kernel form. `stiffness` is per unit node mass [1/s^2].
struct ColliderData {
  int kind = kColliderPlane;
  Vec3 point;                        ///< plane point, box or sphere centre
  Vec3 normal;                       ///< plane normal (unit)
  Vec3 halfExtents;                  ///< box
  Mat3 rotation = Mat3::identity();  ///< box: local-to-world axes (columns)
  double radius = 0;                 ///< sphere
  double stiffness = 0;
  Vec3 velocity;        ///< translation [m/s]: sliding is measured against it
  double friction = 0;  ///< the collider's Coulomb coefficient (mixed with the body's)
};

/// Penetration depth (> 0 inside) and the outward direction that reduces it.
GF_HD double penetration(const ColliderData& c, Vec3 x, Vec3& n) {
  if (c.kind == kColliderPlane) {
    n = c.normal;
    return -dot(x - c.point, c.normal);
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

/// Adds the contact energy of node x (mass m) and its gradient and Hessian block; returns
/// the energy (0 when not in contact).
GF_HD double nodeContact(const ColliderData& c, Vec3 x, double m, Vec3& grad, Mat3& hess) {
  Vec3 n;
  const double d = penetration(c, x, n);
  if (!(d > 0)) return 0;
  const double k = c.stiffness * m;
  grad -= (k * d) * n;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) hess(i, j) += k * n[i] * n[j];
  return 0.5 * k * d * d;
}

/// Smoothed Coulomb friction of a node sliding by u (tangential, over the step) under the
/// lagged normal force lambda: the dissipation potential mu lambda f0(|u|) with f0' = f1,
/// f1(y) = 2 y / eps - y^2 / eps^2 below eps and 1 above (Li et al. 2020, IPC, sec 5), eps =
/// the slip speed times dt. Adds its gradient and a PSD Hessian (mu lambda f1(y) / y on the
/// tangent plane; the curvature along u, negative below eps, dropped) and returns the
/// potential.
GF_HD double nodeFriction(double muLambda, Vec3 normal, Vec3 u, double eps, Vec3& grad,
                          Mat3& hess) {
  const double y = norm(u);
  double f0, f1OverY;
  if (y < eps) {
    f0 = y * y / eps - y * y * y / (3 * eps * eps) + eps / 3;
    f1OverY = 2 / eps - y / (eps * eps);
  } else {
    f0 = y;
    f1OverY = 1 / y;
  }
  grad += (muLambda * f1OverY) * u;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      hess(i, j) += muLambda * f1OverY * ((i == j ? 1.0 : 0.0) - normal[i] * normal[j]);
  return muLambda * f0;
}

}  // namespace gf
