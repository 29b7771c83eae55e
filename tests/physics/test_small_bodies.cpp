// The multigrid's size rule (MultigridSettings::directBelowNodes): a body with fewer free nodes
// than the threshold is solved by the sparse Cholesky. Checked against a body that asks for the
// direct solver itself (the same step to round-off, and no iterations), against the forced
// multigrid on the same body (CG iterations), and on both sides of the threshold counting only
// free nodes.
#include <graphfrac/jobs.h>
#include <gtest/gtest.h>

#include <cmath>

#include "common/sim_helpers.h"
#include "fem/fem_body.h"

namespace gf {
namespace {

struct DropRun {
  std::vector<double> x;
  int linearIterations = 0;
};

// A box of n^3 cells dropped onto the ground with a sideways push, 10 steps.
DropRun dropBox(int n, const SolverSettings& solver) {
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
  wd.colliders.push_back(Collider{Collider::Kind::Plane, glm::vec3(0, 0, 0)});
  World world(wd);
  BodyDef def;
  def.mesh = gen::box(0.1, 0.1, 0.1, n, n, n);
  for (size_t i = 0; i < def.mesh.nodeCount(); ++i) def.mesh.positions[3 * i + 1] += 0.01;
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.initialVelocity = glm::vec3(0.5f, -1.0f, 0.2f);
  def.solver = solver;
  const BodyId id = world.createBody(def).value();
  DropRun r;
  for (int s = 0; s < 10; ++s) r.linearIterations += world.step(1.0 / 60).linearIterations;
  const auto x = world.positions(id);
  r.x.assign(x.begin(), x.end());
  return r;
}

double maxDiff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0;
  for (size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

TEST(SmallBodies, DefaultSolverOfADebrisBoxIsTheDirectOne) {
  SolverSettings direct;
  direct.linearSolver = LinearSolverKind::Direct;
  SolverSettings forced;  // the multigrid at every size
  forced.multigrid.directBelowNodes = 0;
  for (int n : {2, 3}) {  // 27 and 64 nodes, 48 and 162 tets
    const DropRun byDefault = dropBox(n, SolverSettings{});
    const DropRun reference = dropBox(n, direct);
    const DropRun multigrid = dropBox(n, forced);
    ASSERT_EQ(byDefault.x.size(), reference.x.size());
    // The body moves about 0.17 m over the run; round-off is 1e-15 of that.
    EXPECT_LE(maxDiff(byDefault.x, reference.x), 1e-12) << n << "^3 cells";
    EXPECT_EQ(byDefault.linearIterations, 0) << "a factorisation takes no iterations";
    EXPECT_GT(multigrid.linearIterations, 0) << "directBelowNodes = 0 keeps the multigrid";
    // The multigrid solves to its tolerance (1e-6 relative), so it stays close but not equal.
    EXPECT_LE(maxDiff(multigrid.x, reference.x), 1e-4);
  }
  // 6^3 = 216 nodes, above the default threshold of 128: the multigrid iterates.
  EXPECT_GT(dropBox(5, SolverSettings{}).linearIterations, 0);
}

TEST(SmallBodies, RuleCountsFreeNodesOnly) {
  SolverSettings s;  // the default multigrid, threshold 128
  ASSERT_EQ(s.multigrid.directBelowNodes, 128);
  EXPECT_EQ(detail::effectiveLinearSolver(s, 127), LinearSolverKind::Direct);
  EXPECT_EQ(detail::effectiveLinearSolver(s, 128), LinearSolverKind::Multigrid);
  s.multigrid.directBelowNodes = 0;
  EXPECT_EQ(detail::effectiveLinearSolver(s, 1), LinearSolverKind::Multigrid);
  s.linearSolver = LinearSolverKind::PCG;  // only the multigrid is rerouted
  s.multigrid.directBelowNodes = 1000;
  EXPECT_EQ(detail::effectiveLinearSolver(s, 10), LinearSolverKind::PCG);

  // 216 nodes with 100 of them gripped: 116 free, so the body is solved directly.
  BodyDef def;
  def.mesh = gen::box(0.1, 0.1, 0.1, 5, 5, 5);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  Grip grip;
  for (int32_t i = 0; i < 100; ++i) grip.nodes.push_back(i);
  def.grips.push_back(grip);
  EXPECT_EQ(detail::buildFemModel(def).solver.linearSolver, LinearSolverKind::Direct);
  def.grips.clear();
  EXPECT_EQ(detail::buildFemModel(def).solver.linearSolver, LinearSolverKind::Multigrid);
}

TEST(SmallBodies, NegativeThresholdIsRejectedWithTheField) {
  World world(WorldDef{});
  BodyDef def;
  def.mesh = gen::box(0.1, 0.1, 0.1, 2, 2, 2);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.solver.multigrid.directBelowNodes = -1;
  const Result<BodyId> r = world.createBody(def);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("multigrid.directBelowNodes"), std::string::npos)
      << r.error().message;
}

}  // namespace
}  // namespace gf
