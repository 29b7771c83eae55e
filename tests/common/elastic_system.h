// The linear system of a first implicit step from rest, assembled outside the integrator for
// solver tests: A = M + dt^2 K (lumped mass, the element Hessians of kernels/element.h) with
// Dirichlet rows, and the gravity right-hand side dt^2 M g.
#pragma once

#include <graphfrac/mesh.h>

#include <cstdint>
#include <functional>
#include <vector>

#include "kernels/element.h"
#include "solver/block_sparse.h"

namespace gf::test {

struct ElasticSystem {
  TetMesh mesh;
  detail::BlockSparseMatrix A;
  std::vector<double> b;         ///< 3 per node, zero at fixed nodes
  std::vector<uint8_t> fixed;    ///< Dirichlet nodes
  std::vector<double> nodeMass;  ///< lumped
};

/// Assembles the step matrix of `mesh` at rest. `fixedPred(x, y, z)` picks the Dirichlet nodes;
/// `skipTet(e)`, when set, leaves a tet's stiffness out (its mass stays), as a fully broken
/// element would.
inline ElasticSystem assembleElasticSystem(
    TetMesh mesh, double E, double nu, double rho, double dt,
    const std::function<bool(double, double, double)>& fixedPred, JobSystem& jobs,
    const std::function<bool(size_t)>& skipTet = {}) {
  ElasticSystem s;
  s.mesh = std::move(mesh);
  const size_t n = s.mesh.nodeCount(), tets = s.mesh.tetCount();
  s.A = detail::BlockSparseMatrix::fromTets(s.mesh.tets.data(), tets, n);
  const detail::ElementGather gather = detail::ElementGather::build(s.mesh.tets.data(), tets, s.A);
  const MaterialCoeffs c = makeMaterialCoeffs(kStableNeoHookean, E, nu, 0, Vec3{1, 0, 0});
  std::vector<double> ke(kElementMatrixSize * tets, 0.0);
  s.nodeMass.assign(n, 0.0);
  for (size_t e = 0; e < tets; ++e) {
    Vec3 X[4];
    for (int a = 0; a < 4; ++a) {
      const double* p = &s.mesh.positions[3 * s.mesh.tets[4 * e + a]];
      X[a] = {p[0], p[1], p[2]};
    }
    double vol = 0;
    const Mat3 dmInv = restShapeInverse(X, vol);
    for (int a = 0; a < 4; ++a) s.nodeMass[s.mesh.tets[4 * e + a]] += 0.25 * rho * vol;
    if (skipTet && skipTet(e)) continue;
    double grad[12];
    Mat12 H;
    elementForces(c, X, dmInv, vol, grad, &H, true);
    storeUpperBlocks(H.m, &ke[kElementMatrixSize * e]);
  }
  detail::gatherElementBlocks(gather, ke.data(), dt * dt, s.A, jobs);
  s.fixed.assign(n, 0);
  s.b.assign(3 * n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    double* blk = s.A.block(s.A.diagonal(static_cast<int32_t>(i)));
    for (int k = 0; k < 3; ++k) blk[4 * k] += s.nodeMass[i];
    const double* p = &s.mesh.positions[3 * i];
    s.fixed[i] = fixedPred && fixedPred(p[0], p[1], p[2]) ? 1 : 0;
    if (!s.fixed[i]) s.b[3 * i + 1] = -dt * dt * 9.81 * s.nodeMass[i];
  }
  detail::applyDirichlet(s.A, s.fixed.data());
  return s;
}

}  // namespace gf::test
