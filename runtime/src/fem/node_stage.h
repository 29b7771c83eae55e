// The per-node part of the incremental potential (header of fem/integrator.h), written once
// for both executors like fem/element_stage.h: inertia, mass damping, gravity and point forces,
// collider contact. Each node writes its own terms; the integrator sums them in the fixed
// order of step/reduce.h.
#pragma once

#include <cstdint>

#include "kernels/contact.h"

namespace gf::detail {

/// The node's energy terms, one array of nodeCount values each, laid out one after another
/// in NodePotentialStage::terms.
enum NodeTerm : int { kNodeEnergy, kNodeContact, kNodeMagnitude, kNodeGradMagnitude, kNodeTerms };

/// E_n(x) = 1/2 m |x-y|^2 + dt/2 r1 m |x-x_n|^2 - dt^2 f^T x + dt^2 Psi_c(x) per node (eq 2.7,
/// 3.13 with Rayleigh r1), and, when `grad` is non-null, its gradient plus dt^2 times the
/// elastic node gradient, the contact Hessian block and whether the node touches a collider.
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
  double dt = 0, massDamping = 0, lengthScale = 1;
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
    for (int c = 0; c < colliderCount; ++c) contact += nodeContact(colliders[c], xi, m, cg, ch);
    const Vec3 dy = xi - yi, dn = xi - xni;
    const double inertia = 0.5 * m * dot(dy, dy) + 0.5 * dt * r1 * m * dot(dn, dn);
    const double work = dt2 * dot(fext, xi);
    terms[kNodeEnergy * int64_t(nodeCount) + n] = inertia - work;
    terms[kNodeContact * int64_t(nodeCount) + n] = contact;
    terms[kNodeMagnitude * int64_t(nodeCount) + n] = inertia + (work < 0 ? -work : work);
    double gradMagnitude = 0;
    if (grad) {
      const Vec3 g = m * dy + (dt * r1 * m) * dn + dt2 * (cg - fext);
      const Vec3 ge{elasticGrad[i3], elasticGrad[i3 + 1], elasticGrad[i3 + 2]};
      // Round-off of E from rounding x: |dE/dx| |x| eps, summed over the parts before they
      // cancel (inertia against gravity against elasticity).
      gradMagnitude =
          (norm(m * dy) + dt * r1 * m * norm(dn) + dt2 * (norm(cg) + norm(fext)) + dt2 * norm(ge)) *
          (norm(xi) + lengthScale);
      for (int i = 0; i < 3; ++i) grad[i3 + i] = g[i] + dt2 * ge[i];
      contactHess[n] = ch;
      contactSeen[n] = frobeniusDot(ch, ch) > 0;
    }
    terms[kNodeGradMagnitude * int64_t(nodeCount) + n] = gradMagnitude;
  }
};

/// out[i] = a[i] + alpha b[i] (out may be a): the step's vector updates (grips moved, Newton
/// and line-search trials, the constant-velocity prediction).
struct AxpyStage {
  const double* a = nullptr;
  const double* b = nullptr;
  double alpha = 1;
  double* out = nullptr;

  GF_HD void operator()(int32_t i) const { out[i] = a[i] + alpha * b[i]; }
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

/// The per-node blocks of the step's matrix, A_nn += m (1 + dt r1) I + dt^2 H_contact
/// (eq 2.7, 3.13 with Rayleigh r1): `values` are the block-sparse values (9 per block) and
/// diagonalBlock the block of each node's diagonal.
struct NodeBlockStage {
  double* values = nullptr;
  const int32_t* diagonalBlock = nullptr;
  const double* nodeMass = nullptr;
  const Mat3* contactHess = nullptr;
  double massScale = 1, dt2 = 0;

  GF_HD void operator()(int32_t n) const {
    double* blk = values + 9 * int64_t(diagonalBlock[n]);
    const double md = nodeMass[n] * massScale;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        blk[3 * i + j] += (i == j ? md : 0.0) + dt2 * contactHess[n](i, j);
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

  GF_HD double operator()(int32_t n) const {
    if (contactSeen[n] || fixedNode[n]) return 0.0;
    const Vec3 xi{x[3 * int64_t(n)], x[3 * int64_t(n) + 1], x[3 * int64_t(n) + 2]};
    for (int c = 0; c < colliderCount; ++c) {
      Vec3 normal;
      if (penetration(colliders[c], xi, normal) > 0) return 1.0;
    }
    return 0.0;
  }
};

}  // namespace gf::detail
