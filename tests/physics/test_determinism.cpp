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

// Debris: small boxes of 48 and 162 tets (stepped side by side over the JobSystem, each serial
// inside) falling onto the ground next to one body large enough to spread its own loops over
// the threads. Some small bodies force the multigrid, so CHOLMOD factorises on several threads
// at once, and some break on impact. Returns every position, velocity and collider impulse.
std::vector<double> simulateDebris(JobSystem* jobs) {
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, jobs, 1, {}};
  wd.colliders.push_back(Collider{Collider::Kind::Plane, glm::vec3(0, 0, 0)});
  World world(wd);
  std::vector<BodyId> ids;
  for (int b = 0; b < 24; ++b) {
    BodyDef def;
    const int cells = 2 + b % 2;
    def.mesh = gen::box(0.1, 0.1, 0.1, cells, cells, cells);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
      def.mesh.positions[3 * n] += 0.2 * (b % 6);
      def.mesh.positions[3 * n + 1] += 0.01 + 0.005 * (b % 5);
      def.mesh.positions[3 * n + 2] += 0.2 * (b / 6);
    }
    def.material = Material::stableNeoHookean(2e5, 0.3, 1000);
    def.initialVelocity = glm::vec3(0.1f * float(b % 3), -1.0f, 0);
    if (b % 5 == 0) def.solver.multigrid.directBelowNodes = 0;
    if (b % 7 == 3) {
      def.fracture.enabled = true;
      def.fracture.strength = 200;
    }
    ids.push_back(world.createBody(def).value());
  }
  BodyDef big;
  big.mesh = gen::box(0.8, 0.1, 0.6, 8, 6, 8);  // 2304 tets: stepped alone, its loops split
  for (size_t n = 0; n < big.mesh.nodeCount(); ++n) big.mesh.positions[3 * n + 2] += 1.0;
  big.material = Material::stableNeoHookean(2e5, 0.3, 1000);
  ids.push_back(world.createBody(big).value());
  std::vector<double> out;
  size_t breaks = 0;
  for (int s = 0; s < 15; ++s) {
    const StepStatus st = world.step(1.0 / 60);
    EXPECT_FALSE(st.has(kStepNanContained)) << st.message;
    for (const glm::dvec3& j : world.colliderImpulses()) out.insert(out.end(), {j.x, j.y, j.z});
    for (const FractureEvent& e : world.fractureEvents())
      out.insert(out.end(), {double(e.body.index), double(e.edge)});
    breaks += world.fractureEvents().size();
  }
  EXPECT_GT(breaks, 0u) << "the scene exercises the events' order";
  EXPECT_GT(world.colliderImpulses()[0].y, 0) << "and the impulses' sum over bodies";
  for (BodyId id : ids) {
    const auto x = world.positions(id);
    const auto v = world.velocities(id);
    out.insert(out.end(), x.begin(), x.end());
    out.insert(out.end(), v.begin(), v.end());
  }
  return out;
}

TEST(Determinism, ManySmallBodiesIdenticalBitsForOneAndTwoThreads) {
  ThreadPoolJobSystem pool2(2), pool4(4);
  const std::vector<double> serial = simulateDebris(nullptr);
  const std::vector<double> two = simulateDebris(&pool2);
  const std::vector<double> four = simulateDebris(&pool4);
  ASSERT_EQ(serial.size(), two.size());
  ASSERT_EQ(serial.size(), four.size());
  EXPECT_EQ(0, std::memcmp(serial.data(), two.data(), serial.size() * sizeof(double)));
  EXPECT_EQ(0, std::memcmp(serial.data(), four.data(), serial.size() * sizeof(double)));
}

// A cracking body under MG-CG (the doormat tear of scenes/doormat_rd0.json; large enough that
// its loops spread over the threads): edges break on frames 2-7 (246 of them), each such frame
// re-binds the aggregates and refreshes the coarse levels, and every solve's first V-cycle
// descends while the coarsest level is factorised. Returns positions, velocities, broken edges and
// fragments of every frame.
std::vector<double> tearWithMultigrid(JobSystem* jobs) {
  BodyDef def;
  def.mesh = gen::slab(0.6, 0.3, 0.015, 40, 20);
  EXPECT_GE(def.mesh.tetCount(), 2048u);  // not stepped serially in a batch of small bodies
  def.material = Material::stableNeoHookean(1e8, 0.45, 1000);
  def.material.stiffnessDamping = 0.001;
  def.solver.linearSolver = LinearSolverKind::Multigrid;
  def.solver.multigrid.levels = {64, 512};
  def.fracture.enabled = true;
  def.fracture.strength = 2.5e6;
  def.fracture.radius = 0;
  def.fracture.model = DamageModel::Degradation;
  Grip pin, pull;
  pin.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  pull.nodes = test::selectNodes(
      def.mesh, [](double x, double, double z) { return x > 0.6 - 1e-9 && z > 0.15 - 1e-9; });
  pull.velocity = glm::vec3(0.3f, 0, 0);
  def.grips = {pin, pull};
  World world(WorldDef{glm::vec3(0), Backend::Cpu, jobs, 1, {}});
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok());
  std::vector<double> out;
  for (int s = 0; s < 8; ++s) {
    (void)world.step(0.005);
    const auto x = world.positions(id.value());
    const auto v = world.velocities(id.value());
    const FractureStats fs = world.fractureStats(id.value());
    out.insert(out.end(), x.begin(), x.end());
    out.insert(out.end(), v.begin(), v.end());
    out.push_back(fs.brokenEdges);
    out.push_back(fs.fragments);
  }
  const FractureStats fs = world.fractureStats(id.value());
  EXPECT_GT(fs.brokenEdges, 100);  // the coarse levels were re-bound on many frames
  return out;
}

TEST(Determinism, CrackingMultigridBodyIdenticalBitsOnOneTwoAndFourThreads) {
  ThreadPoolJobSystem pool2(2), pool4(4);
  const std::vector<double> serial = tearWithMultigrid(nullptr);
  const std::vector<double> two = tearWithMultigrid(&pool2);
  const std::vector<double> four = tearWithMultigrid(&pool4);
  ASSERT_EQ(serial.size(), two.size());
  ASSERT_EQ(serial.size(), four.size());
  EXPECT_EQ(0, std::memcmp(serial.data(), two.data(), serial.size() * sizeof(double)));
  EXPECT_EQ(0, std::memcmp(serial.data(), four.data(), serial.size() * sizeof(double)));
}

}  // namespace
}  // namespace gf
