// Shared beam set-ups for the physics and slow tests (statics through the implicit step with a
// time step so long that inertia is negligible: rho L^2 / (E dt^2) < 1e-9).
#pragma once

#include <cmath>

#include "common/sim_helpers.h"

namespace gf::test {

/// Full Newton to 1e-10 with the direct solver: the static equilibrium.
inline SolverSettings staticSolver() {
  SolverSettings s;
  s.newtonIterations = 50;
  s.newtonTolerance = 1e-10;
  s.linearSolver = LinearSolverKind::Direct;
  return s;
}

/// A 1 x 0.1 x 0.1 m beam of nx x nh x nh cells, clamped (held still) at x = 0.
inline BodyDef clampedBeam(const Material& m, int nx, int nh) {
  BodyDef def;
  def.mesh = gen::box(1.0, 0.1, 0.1, nx, nh, nh);
  def.material = m;
  Grip clamp;
  clamp.nodes = selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  def.grips.push_back(clamp);
  return def;
}

struct BeamResult {
  double tip = 0, analytic = 0;
};

// Cantilever of length L, square section h, clamped at x = 0, sagging under gravity.
inline BeamResult cantilever(int nx, int nh) {
  const double L = 1.0, h = 0.05, E = 1e9, nu = 0.3, rho = 1000, g = 9.81;
  BodyDef def;
  def.mesh = gen::box(L, h, h, nx, nh, nh);
  def.material = Material::corotated(E, nu, rho);
  def.solver = staticSolver();
  Grip clamp;
  clamp.nodes = selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  def.grips.push_back(clamp);
  const TetMesh rest = def.mesh;
  World world(WorldDef{glm::vec3(0, -g, 0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok());
  // One step from rest: with this dt the step is the static solve (inertia weight < 1e-9).
  const StepStatus st = world.step(1e3);
  EXPECT_TRUE(st.ok()) << st.flags << " " << st.message;
  const auto tipNodes = selectNodes(rest, [&](double x, double, double) { return x > L - 1e-9; });
  BeamResult r;
  r.tip = -meanDisplacement(world, id.value(), rest, tipNodes, 1);
  // Euler-Bernoulli q L^4 / (8 E I) plus Timoshenko's shear term q L^2 / (2 kappa G A).
  const double A = h * h, I = h * h * h * h / 12, q = rho * g * A, G = E / (2 * (1 + nu));
  r.analytic = q * std::pow(L, 4) / (8 * E * I) + q * L * L / (2 * (5.0 / 6.0) * G * A);
  return r;
}

}  // namespace gf::test
