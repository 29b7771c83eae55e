// A glass body thrown spinning stays whole in flight and breaks when it hits something (issue
// acceptance; scenes/glass_bunny.json with a spin). The flight itself is tested at 60 Hz for a
// whole second in Fracture.SpinningGlassStaysWholeInFlight; here the impact. An implicit step
// sees the impact stress only when it is short against the time the elastic wave needs to
// cross the body (0.3 m / 6 km/s = 50 us here): in 0.25 ms steps this bunny shatters on the
// ball; in 1 ms steps it stays whole (scenes/glass_bunny.json, not spinning and landing
// differently, breaks into 91 fragments at 1 ms). docs/validation.md has the figures.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "common/sim_helpers.h"

namespace gf {
namespace {

struct Impact {
  int contactStep = -1, brokenBeforeContact = 0;
  FractureStats end;
};

// The bunny thrown at the ball for `duration` seconds in steps of dt.
Impact throwBunny(double dt, double duration) {
  Impact out;
  Result<TetMesh> loaded = TetMesh::fromFile(GF_SOURCE_DIR "/scenes/meshes/bunny_small.msh");
  EXPECT_TRUE(loaded.ok()) << loaded.error().message;
  if (!loaded.ok()) return out;
  BodyDef def;
  def.mesh = std::move(loaded.value());
  // As scenes/glass_bunny.json: scale 0.03, thesis Table 4.1 solid glass, brittle, 8 regions.
  double lowX = 1e300;
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    for (int a = 0; a < 3; ++a) def.mesh.positions[3 * n + a] *= 0.03;
    lowX = std::min(lowX, def.mesh.positions[3 * n]);
  }
  const glm::dvec3 ball(-0.26, 0.12, 0);
  const double radius = 0.08;
  // 2 cm of flight before the ball's leftmost reach: contact comes within a few steps.
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
    def.mesh.positions[3 * n] += (ball.x + radius + 0.02) - lowX;
  test::makeTableGlass(def);

  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
  Collider sphere;
  sphere.kind = Collider::Kind::Sphere;
  sphere.point = glm::vec3(ball);
  sphere.radius = float(radius);
  wd.colliders.push_back(sphere);
  World world(wd);
  const Result<BodyId> created = world.createBody(def);
  EXPECT_TRUE(created.ok()) << created.error().message;
  if (!created.ok()) return out;
  const BodyId id = created.value();

  // Thrown at 20 m/s along -x, spinning at 10 rad/s about z through its centre of mass.
  glm::dvec3 centre(0);
  double volume = 0;
  for (size_t t = 0; t < def.mesh.tetCount(); ++t) {
    glm::dvec3 p[4];
    for (int k = 0; k < 4; ++k) {
      const double* x = &def.mesh.positions[3 * size_t(def.mesh.tets[4 * t + k])];
      p[k] = {x[0], x[1], x[2]};
    }
    const double v = std::abs(glm::dot(p[1] - p[0], glm::cross(p[2] - p[0], p[3] - p[0]))) / 6;
    centre += v * 0.25 * (p[0] + p[1] + p[2] + p[3]);
    volume += v;
  }
  centre /= volume;
  std::vector<double> velocity(def.mesh.positions.size());
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    const glm::dvec3 r = glm::dvec3(def.mesh.positions[3 * n], def.mesh.positions[3 * n + 1],
                                    def.mesh.positions[3 * n + 2]) -
                         centre;
    const glm::dvec3 v = glm::dvec3(-20, 0, 0) + glm::cross(glm::dvec3(0, 0, 10), r);
    for (int a = 0; a < 3; ++a) velocity[3 * n + a] = v[a];
  }
  EXPECT_TRUE(world.setVelocities(id, velocity).ok());

  const int steps = int(std::lround(duration / dt));
  for (int s = 0; s < steps; ++s) {
    EXPECT_TRUE(world.step(dt).ok());
    const bool touching = glm::length(world.colliderImpulses()[0]) > 0;
    if (out.contactStep < 0 && touching)
      out.contactStep = s;
    else if (out.contactStep < 0)
      out.brokenBeforeContact = world.fractureStats(id).brokenEdges;
  }
  out.end = world.fractureStats(id);
  std::printf(
      "glass bunny, 20 m/s and 10 rad/s, dt %.2g s: first contact at step %d, %d edges "
      "broken before it; %d broken and %d fragments %g ms later\n",
      dt, out.contactStep, out.brokenBeforeContact, out.end.brokenEdges, out.end.fragments,
      1e3 * (steps - out.contactStep) * dt);
  return out;
}

TEST(GlassImpact, SpinningBunnyBreaksOnlyWhenItHitsTheBall) {
  const Impact fine = throwBunny(2.5e-4, 0.015);
  ASSERT_GE(fine.contactStep, 1);
  EXPECT_EQ(fine.brokenBeforeContact, 0);
  EXPECT_GT(fine.end.brokenEdges, 100);
  EXPECT_GE(fine.end.fragments, 3);
  // For the record: the same throw in 1 ms steps (not asserted; see the comment at the top).
  throwBunny(1e-3, 0.015);
}

}  // namespace
}  // namespace gf
