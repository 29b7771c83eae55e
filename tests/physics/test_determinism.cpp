// Determinism, the runtime's promise to engines: the same scene gives bit-identical states for any
// number of worker threads, because every parallel loop writes disjoint outputs and every reduction
// sums in a fixed order.
#include <graphfrac/jobs.h>
#include <gtest/gtest.h>

#include <cstring>

#include "common/sim_helpers.h"

namespace gf {
namespace {

std::vector<double> simulate(JobSystem* jobs, LinearSolverKind solver) {
  BodyDef def;
  def.mesh = gen::box(0.6, 0.1, 0.1, 24, 4, 4);
  def.material = Material::stableNeoHookean(5e5, 0.4, 1000);
  def.material.stiffnessDamping = 0.01;
  def.solver.linearSolver = solver;
  Grip clamp;
  clamp.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  def.grips.push_back(clamp);
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, jobs, 1, {}};
  wd.colliders.push_back(Collider{Collider::Kind::Plane, glm::vec3(0, -0.05f, 0)});
  World world(wd);
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok());
  for (int s = 0; s < 30; ++s) (void)world.step(1.0 / 60);
  const auto x = world.positions(id.value());
  return {x.begin(), x.end()};
}

TEST(Determinism, IdenticalBitsForOneAndTwoThreads) {
  ThreadPoolJobSystem pool2(2), pool4(4);
  for (LinearSolverKind solver : {LinearSolverKind::PCG, LinearSolverKind::Direct}) {
    const std::vector<double> serial = simulate(nullptr, solver);
    const std::vector<double> two = simulate(&pool2, solver);
    const std::vector<double> four = simulate(&pool4, solver);
    ASSERT_EQ(serial.size(), two.size());
    EXPECT_EQ(0, std::memcmp(serial.data(), two.data(), serial.size() * sizeof(double)));
    EXPECT_EQ(0, std::memcmp(serial.data(), four.data(), serial.size() * sizeof(double)));
    EXPECT_EQ(simulate(&pool2, solver), two);  // and across runs
  }
}

}  // namespace
}  // namespace gf
