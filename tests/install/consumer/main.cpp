// The smallest engine: one free-falling box. Checks that the installed headers and library
// work together, and that one implicit step does the right physics: a free body at rest has
// no elastic force, so after one backward Euler step every node moves with v = g dt.
#include <graphfrac/mesh.h>
#include <graphfrac/world.h>

#include <cmath>
#include <cstdio>
#include <span>

int main() {
  constexpr double kDensity = 1000, kSx = 1.0, kSy = 0.2, kSz = 0.2;
  constexpr double kMass = kDensity * kSx * kSy * kSz;
  constexpr double kDt = 1.0 / 60;

  gf::WorldDef worldDef;  // gravity (0, -9.81, 0), no colliders
  gf::World world(worldDef);

  gf::BodyDef def;
  def.mesh = gf::gen::box(kSx, kSy, kSz, 10, 2, 2);
  def.material = gf::Material::stableNeoHookean(1e6, 0.3, kDensity);
  gf::Result<gf::BodyId> body = world.createBody(def);
  if (!body.ok()) {
    std::printf("createBody failed: %s\n", body.error().message.c_str());
    return 1;
  }

  gf::StepStatus status = world.step(kDt);
  if (!status.ok()) {
    std::printf("step failed (flags %u): %s\n", status.flags, status.message.c_str());
    return 1;
  }

  // The mean velocity from the momentum, and the worst node's deviation from (0, g dt, 0).
  const double expected = double(worldDef.gravity.y) * kDt;
  const gf::BodyStats stats = world.stats(body.value());
  const double meanVy = stats.linearMomentum.y / stats.mass;
  std::span<const double> v = world.velocities(body.value());
  double worst = 0;
  for (size_t i = 0; i + 2 < v.size(); i += 3) {
    worst =
        std::fmax(worst, std::fabs(v[i]) + std::fabs(v[i + 1] - expected) + std::fabs(v[i + 2]));
  }
  std::printf(
      "%zu nodes, %zu tets, mass %.9g kg (expected %.9g), mean vy %.9g m/s (g dt = %.9g), "
      "worst node error %.3g m/s\n",
      def.mesh.nodeCount(), def.mesh.tetCount(), stats.mass, kMass, meanVy, expected, worst);

  // PCG stops at a relative residual of 1e-6, so 1e-4 of g dt leaves ample margin.
  const double tol = 1e-4 * std::fabs(expected);
  const bool ok = def.mesh.tetCount() > 0 && v.size() == 3 * def.mesh.nodeCount() &&
                  std::fabs(stats.mass - kMass) < 1e-9 * kMass &&
                  std::fabs(meanVy - expected) < tol && worst < tol;
  if (!ok) {
    std::printf("wrong result after one step\n");
    return 1;
  }
  std::printf("graphfrac consumer: ok\n");
  return 0;
}
