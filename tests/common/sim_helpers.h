// Small helpers shared by the physics tests: node selection, displacements, energy totals.
#pragma once

#include <graphfrac/world.h>

#include <cmath>
#include <functional>
#include <vector>

#include "kernels/element.h"

namespace gf::test {

/// Nodes of `mesh` whose rest position satisfies `pred(x, y, z)`.
inline std::vector<int32_t> selectNodes(const TetMesh& mesh,
                                        const std::function<bool(double, double, double)>& pred) {
  std::vector<int32_t> out;
  for (size_t i = 0; i < mesh.nodeCount(); ++i) {
    const double* p = &mesh.positions[3 * i];
    if (pred(p[0], p[1], p[2])) out.push_back(int32_t(i));
  }
  return out;
}

/// Thesis Table 4.1's solid glass (the glass bunny of fig 4.14 and scenes/glass_bunny.json):
/// StVK, E = 1e10 Pa, nu = 0.45, rho = 1e3, sigma_th = 5e7 Pa, brittle with 8 crack regions,
/// direct solver.
inline void makeTableGlass(BodyDef& def) {
  def.material = Material::stvk(1e10, 0.45, 1000);
  def.fracture.enabled = true;
  def.fracture.strength = 5e7;
  def.fracture.brittle = true;
  def.fracture.regions = 8;
  def.solver.linearSolver = LinearSolverKind::Direct;
}

/// Mean displacement component `axis` of `nodes`.
inline double meanDisplacement(const World& world, BodyId id, const TetMesh& rest,
                               const std::vector<int32_t>& nodes, int axis) {
  const auto x = world.positions(id);
  double s = 0;
  for (int32_t n : nodes) s += x[3 * n + axis] - rest.positions[3 * n + axis];
  return nodes.empty() ? 0.0 : s / double(nodes.size());
}

/// Total mechanical energy (kinetic + elastic + gravity + contact).
inline double totalEnergy(const BodyStats& s) {
  return s.kineticEnergy + s.elasticEnergy + s.gravityEnergy + s.contactEnergy;
}

/// True when every position and velocity is finite.
inline bool stateFinite(const World& world, BodyId id) {
  for (double v : world.positions(id))
    if (!std::isfinite(v)) return false;
  for (double v : world.velocities(id))
    if (!std::isfinite(v)) return false;
  return true;
}

/// Deformation gradient of tet e at current positions x (3 per node) against the rest mesh.
inline Mat3 tetDeformationGradient(const TetMesh& rest, std::span<const double> x, size_t e) {
  Vec3 X[4], xe[4];
  for (int a = 0; a < 4; ++a) {
    const int32_t n = rest.tets[4 * e + a];
    X[a] = {rest.positions[3 * n], rest.positions[3 * n + 1], rest.positions[3 * n + 2]};
    xe[a] = {x[3 * n], x[3 * n + 1], x[3 * n + 2]};
  }
  double vol = 0;
  return deformationGradient(xe, restShapeInverse(X, vol));
}

}  // namespace gf::test
