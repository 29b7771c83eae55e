// Engine-facing commands, re-entrancy, save/restore, determinism, surfaces and grip forces,
// checked against conservation laws and exact replays rather than "it runs".
#include <graphfrac/jobs.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "common/sim_helpers.h"

namespace gf {
namespace {

// A free cube in zero gravity: momentum changes come only from the commands.
BodyDef freeCube() {
  BodyDef def;
  def.mesh = gen::box(0.2, 0.2, 0.2, 4, 4, 4);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  return def;
}

// Bar pulled apart by grips at both ends: the nominal stress grows by 1e5 Pa/s, so the default
// strength breaks it after about 25 steps of 1/100 s.
BodyDef fracturingBar(double strength = 2.5e4) {
  BodyDef def;
  def.mesh = gen::box(1.0, 0.1, 0.1, 24, 3, 3);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.material.massDamping = 2;
  def.fracture.enabled = true;
  def.fracture.strength = strength;
  Grip left, right;
  left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x > 1 - 1e-9; });
  left.velocity = glm::vec3(-0.05f, 0, 0);
  right.velocity = glm::vec3(0.05f, 0, 0);
  def.grips = {left, right};
  return def;
}

std::vector<double> copy(std::span<const double> s) { return {s.begin(), s.end()}; }

bool sameBits(const std::vector<double>& a, std::span<const double> b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

TEST(WorldApi, ImpulseChangesMomentumByJAndAngularMomentumByPointCrossJ) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(freeCube()).value();
  const BodyStats before = world.stats(id);
  const glm::vec3 p(0.13f, 0.07f, 0.05f), J(0.3f, -1.2f, 0.7f);
  ASSERT_TRUE(world.applyImpulse(id, p, J).ok());
  const BodyStats after = world.stats(id);
  const glm::dvec3 dP = after.linearMomentum - before.linearMomentum;
  const glm::dvec3 dL = after.angularMomentum - before.angularMomentum;
  const glm::dvec3 expectL = glm::cross(glm::dvec3(p), glm::dvec3(J));
  std::printf("impulse: |dP - J| = %.2e, |dL - p x J| = %.2e (|J| = %.2f)\n",
              glm::length(dP - glm::dvec3(J)), glm::length(dL - expectL),
              glm::length(glm::dvec3(J)));
  EXPECT_LT(glm::length(dP - glm::dvec3(J)), 1e-12 * glm::length(glm::dvec3(J)));
  EXPECT_LT(glm::length(dL - expectL), 1e-12 * glm::length(expectL) + 1e-14);

  // Outside the body: still exactly J of momentum, applied at a point of the nearest tet.
  const BodyStats b2 = world.stats(id);
  ASSERT_TRUE(world.applyImpulse(id, glm::vec3(0.5f, 0.1f, 0.1f), J).ok());
  EXPECT_LT(glm::length(world.stats(id).linearMomentum - b2.linearMomentum - glm::dvec3(J)), 1e-12);
}

TEST(WorldApi, ForceActsDuringOneStepOnly) {
  // Backward Euler sums internal forces to zero, so the momentum gains exactly dt F.
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  BodyDef def = freeCube();
  def.solver.linearSolver = LinearSolverKind::Direct;
  const BodyId id = world.createBody(def).value();
  const glm::vec3 p(0.1f, 0.1f, 0.1f), F(2.0f, 0.5f, -1.0f);
  const double dt = 1.0 / 100;
  ASSERT_TRUE(world.applyForce(id, p, F).ok());
  (void)world.step(dt);
  const glm::dvec3 P1 = world.stats(id).linearMomentum;
  EXPECT_LT(glm::length(P1 - dt * glm::dvec3(F)), 1e-9 * dt * glm::length(glm::dvec3(F)));
  (void)world.step(dt);
  EXPECT_LT(glm::length(world.stats(id).linearMomentum - P1), 1e-9 * glm::length(P1));
  // Its torque: the angular momentum about the centre of mass c = (0.1, 0.1, 0.1) (exact for
  // lumped masses of a uniform box) gains dt (q - c) x F, up to the O(dt^2) rotation of the
  // internal forces during the step.
  World w2(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id2 = w2.createBody(def).value();
  const glm::vec3 q(0.15f, 0.05f, 0.12f);
  ASSERT_TRUE(w2.applyForce(id2, q, F).ok());
  (void)w2.step(dt);
  const BodyStats s2 = w2.stats(id2);
  const glm::dvec3 torque = glm::cross(glm::dvec3(q) - glm::dvec3(0.1), glm::dvec3(F));
  const glm::dvec3 Lspin = s2.angularMomentum - glm::cross(glm::dvec3(0.1), s2.linearMomentum);
  std::printf("force: spin dL = (%.4e %.4e %.4e), dt (q - c) x F = (%.4e %.4e %.4e)\n", Lspin.x,
              Lspin.y, Lspin.z, dt * torque.x, dt * torque.y, dt * torque.z);
  EXPECT_LT(glm::length(Lspin - dt * torque), 0.02 * dt * glm::length(torque));
}

TEST(WorldApi, GripVelocityMovesGripExactly) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  BodyDef def = fracturingBar();
  const std::vector<int32_t> right = def.grips[1].nodes;
  const BodyId id = world.createBody(def).value();
  const glm::vec3 v(0.0f, 0.25f, -0.5f);
  ASSERT_TRUE(world.setGripVelocity(id, 1, v).ok());
  const std::vector<double> x0 = copy(world.positions(id));
  const double dt = 0.01;
  (void)world.step(dt);
  const auto x1 = world.positions(id);
  for (int32_t n : right)
    for (int i = 0; i < 3; ++i) ASSERT_EQ(x1[3 * n + i], x0[3 * n + i] + dt * double(v[i]));
  EXPECT_FALSE(world.setGripVelocity(id, 2, v).ok());
  EXPECT_FALSE(world.setGripVelocity(id, -1, v).ok());
  EXPECT_FALSE(world.setGripVelocity(id, 0, glm::vec3(NAN, 0, 0)).ok());
}

TEST(WorldApi, EdgeStrengthsAndMaterialTakeEffect) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  BodyDef def = fracturingBar();
  def.fracture.strength = 1e9;  // unbreakable until the strengths are lowered
  const BodyId id = world.createBody(def).value();
  for (int s = 0; s < 5; ++s) (void)world.step(0.01);
  ASSERT_EQ(world.fractureStats(id).brokenEdges, 0);
  const double weak = 100;  // Pa, far below the ~5e3 Pa the stretch has built up
  std::vector<double> strengths(size_t(world.fractureStats(id).edgeCount), weak);
  ASSERT_TRUE(world.setEdgeStrengths(id, strengths).ok());
  (void)world.step(0.01);
  ASSERT_FALSE(world.fractureEvents().empty());
  for (const FractureEvent& e : world.fractureEvents())
    if (e.cause == FractureEvent::Cause::Stress) {
      EXPECT_GE(e.stress, weak);
    }
  strengths[3] = NAN;
  EXPECT_FALSE(world.setEdgeStrengths(id, strengths).ok());
  strengths[3] = -1;
  EXPECT_FALSE(world.setEdgeStrengths(id, strengths).ok());
  strengths.pop_back();
  EXPECT_FALSE(world.setEdgeStrengths(id, strengths).ok());
  const BodyId plain = world.createBody(freeCube()).value();
  EXPECT_FALSE(world.setEdgeStrengths(plain, std::vector<double>(10, 1e6)).ok());

  // Energy of a fixed deformation is linear in E at fixed nu; masses are linear in density.
  std::vector<double> x = copy(world.positions(plain));
  for (size_t i = 0; i < x.size(); i += 3) x[i] *= 1.1;  // 10 % stretch along x
  ASSERT_TRUE(world.setPositions(plain, x).ok());
  const BodyStats s1 = world.stats(plain);
  Material m = freeCube().material;
  m.youngsModulus *= 3;
  m.density *= 2;
  ASSERT_TRUE(world.setMaterial(plain, m).ok());
  const BodyStats s3 = world.stats(plain);
  EXPECT_NEAR(s3.elasticEnergy / s1.elasticEnergy, 3.0, 1e-12);
  EXPECT_NEAR(s3.mass / s1.mass, 2.0, 1e-12);
  Material bad = m;
  bad.poissonRatio = 0.5;
  EXPECT_FALSE(world.setMaterial(plain, bad).ok());
  bad = m;
  bad.model = MaterialModel::StVK;
  EXPECT_FALSE(world.setMaterial(plain, bad).ok());
  EXPECT_NEAR(world.stats(plain).elasticEnergy, s3.elasticEnergy, 0);  // unchanged by errors
}

TEST(WorldApi, InvalidCommandsChangeNothing) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(freeCube()).value();
  const uint64_t h = world.stateHash();
  EXPECT_FALSE(world.applyForce(id, glm::vec3(NAN, 0, 0), glm::vec3(1)).ok());
  EXPECT_FALSE(world.applyForce(id, glm::vec3(0), glm::vec3(INFINITY, 0, 0)).ok());
  EXPECT_FALSE(world.applyImpulse(id, glm::vec3(0), glm::vec3(0, NAN, 0)).ok());
  const BodyId stale = world.createBody(freeCube()).value();
  ASSERT_TRUE(world.destroyBody(stale).ok());
  const auto r = world.applyImpulse(stale, glm::vec3(0), glm::vec3(1));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("stale"), std::string::npos);
  EXPECT_FALSE(world.applyForce(BodyId{}, glm::vec3(0), glm::vec3(1)).ok());
  EXPECT_EQ(h, world.stateHash());
  (void)world.step(0.01);
  EXPECT_LT(glm::length(world.stats(id).linearMomentum), 1e-15);  // no stray force
}

// Calls back into the world from inside a parallelFor, as an engine job might.
class ReentrantJobs final : public JobSystem {
 public:
  World* world = nullptr;
  BodyId body;
  int calls = 0;
  std::vector<bool> accepted;
  void parallelFor(uint32_t count, uint32_t,
                   const std::function<void(uint32_t, uint32_t)>& fn) override {
    if (world && calls++ == 0) {
      accepted.push_back(world->createBody(freeCube()).ok());
      accepted.push_back(world->destroyBody(body).ok());
      accepted.push_back(world->applyImpulse(body, glm::vec3(0.1f), glm::vec3(1)).ok());
      accepted.push_back(world->applyForce(body, glm::vec3(0.1f), glm::vec3(1)).ok());
      accepted.push_back(world->setVelocity(body, glm::dvec3(1)).ok());
      accepted.push_back(world->restore(world->snapshot()).ok());
      accepted.push_back(world->step(0.01).ok());
      accepted.push_back(!world->surface(body).positions.empty());
      // Read-only diagnostics answer nothing rather than race the step's buffers.
      accepted.push_back(world->stats(body).mass > 0);
      accepted.push_back(!world->gripForces(body).empty());
    }
    if (count > 0) fn(0, count);
  }
  int threadCount() const override { return 1; }
};

TEST(WorldApi, CallsDuringStepAreRefused) {
  ReentrantJobs jobs;
  World world(WorldDef{glm::vec3(0), Backend::Cpu, &jobs, 1, {}});
  const BodyId id = world.createBody(freeCube()).value();
  World reference(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId rid = reference.createBody(freeCube()).value();
  jobs.world = &world;
  jobs.body = id;
  jobs.calls = 0;
  (void)world.step(0.01);
  (void)reference.step(0.01);
  ASSERT_EQ(jobs.accepted.size(), 10u);
  for (size_t i = 0; i < jobs.accepted.size(); ++i) EXPECT_FALSE(jobs.accepted[i]) << "call " << i;
  EXPECT_TRUE(world.isValid(id));
  EXPECT_TRUE(sameBits(copy(reference.positions(rid)), world.positions(id)));
  EXPECT_TRUE(sameBits(copy(reference.velocities(rid)), world.velocities(id)));
  jobs.world = nullptr;
  EXPECT_TRUE(world.applyImpulse(id, glm::vec3(0.1f), glm::vec3(1)).ok());  // usable after
}

TEST(WorldApi, RestoreReplaysFractureBitForBit) {
  // Two bars: the weak one breaks before the snapshot, the strong one after it.
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  const BodyId weak = world.createBody(fracturingBar()).value();
  const BodyId id = world.createBody(fracturingBar(7e4)).value();
  (void)world.surface(id);  // a rendered body: its surface must follow the restore
  const double dt = 0.01;
  for (int s = 0; s < 50; ++s) (void)world.step(dt);
  ASSERT_GT(world.fractureStats(weak).brokenEdges, 0);
  const int brokenAt50 = world.fractureStats(id).brokenEdges;
  const WorldSnapshot snap = world.snapshot();
  const uint64_t hash50 = world.stateHash();
  for (int s = 0; s < 50; ++s) (void)world.step(dt);
  const std::vector<double> x100 = copy(world.positions(id));
  const std::vector<double> v100 = copy(world.velocities(id));
  const std::vector<double> xWeak100 = copy(world.positions(weak));
  const FractureStats f100 = world.fractureStats(id);
  const uint64_t hash100 = world.stateHash();
  const std::vector<float> surf100(world.surface(id).positions.begin(),
                                   world.surface(id).positions.end());
  std::printf("restore: broken edges %d at step 50, %d at step 100, fragments %d\n", brokenAt50,
              f100.brokenEdges, f100.fragments);
  ASSERT_GT(f100.brokenEdges, brokenAt50);  // fracture goes on after the snapshot

  ASSERT_TRUE(world.restore(snap).ok());
  EXPECT_EQ(world.stateHash(), hash50);
  EXPECT_EQ(world.fractureStats(id).brokenEdges, brokenAt50);
  for (int s = 0; s < 50; ++s) (void)world.step(dt);
  EXPECT_TRUE(sameBits(x100, world.positions(id)));
  EXPECT_TRUE(sameBits(v100, world.velocities(id)));
  EXPECT_TRUE(sameBits(xWeak100, world.positions(weak)));
  EXPECT_EQ(world.fractureStats(id).brokenEdges, f100.brokenEdges);
  EXPECT_EQ(world.fractureStats(id).fragments, f100.fragments);
  EXPECT_EQ(world.stateHash(), hash100);  // includes the broken-edge flags
  const SurfaceView sv = world.surface(id);
  ASSERT_EQ(sv.positions.size(), surf100.size());
  EXPECT_EQ(0, std::memcmp(sv.positions.data(), surf100.data(), surf100.size() * sizeof(float)));

  // Onto a world with other bodies: an error, and nothing changes.
  const BodyId extra = world.createBody(freeCube()).value();
  const uint64_t h = world.stateHash();
  EXPECT_FALSE(world.restore(snap).ok());
  EXPECT_EQ(world.stateHash(), h);
  ASSERT_TRUE(world.destroyBody(extra).ok());
  EXPECT_TRUE(world.restore(snap).ok());
  EXPECT_FALSE(world.restore(WorldSnapshot{}).ok());
}

// The multigrid refreshes its coarse levels every coarseRefreshInterval solves (earlier when
// CG drifts) and defers crack re-binding to the refresh, so a solve reads coarse operators
// built from an earlier matrix and a binding of earlier cracks. A snapshot taken anywhere in
// that schedule (right after a refresh, between refreshes, with a re-binding pending) must
// replay bit for bit, for both prolongations.
TEST(WorldApi, RestoreReplaysTheMultigridsRefreshScheduleBitForBit) {
  for (const int interval : {1, 3, 10})
    for (const bool smoothed : {false, true}) {
      BodyDef def = fracturingBar(5e4);
      def.solver.linearSolver = LinearSolverKind::Multigrid;
      def.solver.multigrid.coarseRefreshInterval = interval;
      def.solver.multigrid.smoothedProlongation = smoothed;
      World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
      const BodyId id = world.createBody(def).value();
      const int steps = 60;
      const std::vector<int> at = {7, 20, 33, 46};
      std::vector<WorldSnapshot> snaps;
      std::vector<int> brokenAt;
      for (int s = 0; s < steps; ++s) {
        if (std::find(at.begin(), at.end(), s) != at.end()) {
          snaps.push_back(world.snapshot());
          brokenAt.push_back(world.fractureStats(id).brokenEdges);
        }
        (void)world.step(0.01);
      }
      const uint64_t end = world.stateHash();
      const int broken = world.fractureStats(id).brokenEdges;
      // Edges break between the snapshots, so the replays re-bind.
      ASSERT_GT(broken, brokenAt.back()) << "interval " << interval;
      ASSERT_LT(brokenAt.front(), brokenAt.back()) << "interval " << interval;
      for (size_t k = 0; k < snaps.size(); ++k) {
        ASSERT_TRUE(world.restore(snaps[k]).ok());
        for (int s = at[k]; s < steps; ++s) (void)world.step(0.01);
        EXPECT_EQ(world.stateHash(), end)
            << "interval " << interval << (smoothed ? ", smoothed" : "") << ", snapshot at step "
            << at[k] << " (" << brokenAt[k] << " of " << broken << " edges broken)";
      }
    }
}

// surface() updates lazily: asked for every 5th step only, the surface of a fracturing bar
// must be the one a renderer asking every step sees (same triangles, same vertex positions),
// and its dirty range must cover every vertex that moved since the previous call.
TEST(WorldApi, SurfaceAskedForRarelyMatchesSurfaceAskedForEveryStep) {
  World every(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  World rarely(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  const BodyId a = every.createBody(fracturingBar()).value();
  const BodyId b = rarely.createBody(fracturingBar()).value();
  (void)every.surface(a);
  std::vector<float> last(rarely.surface(b).positions.begin(), rarely.surface(b).positions.end());
  int checks = 0;
  for (int s = 1; s <= 60; ++s) {
    (void)every.step(0.01);
    (void)rarely.step(0.01);
    const SurfaceView va = every.surface(a);
    if (s % 5 != 0) continue;
    const SurfaceView vb = rarely.surface(b);
    ASSERT_EQ(va.indices.size(), vb.indices.size()) << "step " << s;
    EXPECT_TRUE(std::equal(va.indices.begin(), va.indices.end(), vb.indices.begin()));
    EXPECT_TRUE(std::equal(va.crackMask.begin(), va.crackMask.end(), vb.crackMask.begin()));
    ASSERT_EQ(va.positions.size(), vb.positions.size());
    EXPECT_EQ(0, std::memcmp(va.positions.data(), vb.positions.data(),
                             va.positions.size() * sizeof(float)));
    // Every vertex outside the dirty range is where the previous call left it.
    if (last.size() == vb.positions.size())
      for (size_t i = 0; i < last.size(); ++i) {
        if (i / 3 < vb.dirtyBegin || i / 3 >= vb.dirtyEnd) {
          EXPECT_EQ(last[i], vb.positions[i]);
        }
      }
    last.assign(vb.positions.begin(), vb.positions.end());
    ++checks;
  }
  EXPECT_EQ(checks, 12);
  EXPECT_GT(rarely.fractureStats(b).brokenEdges, 0);  // topology changed on the way
}

// The dirty range is exact: empty when nothing moved, and every vertex outside it is where the
// previous call left it when only part of the body moved.
TEST(WorldApi, SurfaceDirtyRangeCoversExactlyWhatMoved) {
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  BodyDef def = fracturingBar();
  // Every node held still, so nothing moves, not even by round-off (a free body at rest
  // moves its nodes by ~1e-17 m per step, which the float surface does show).
  def.grips.resize(1);
  def.grips[0].velocity = glm::vec3(0);
  for (int32_t n = 0; n < int32_t(def.mesh.nodeCount()); ++n) def.grips[0].nodes.push_back(n);
  const BodyId id = world.createBody(def).value();
  const SurfaceView first = world.surface(id);
  EXPECT_EQ(first.dirtyBegin, 0u);
  EXPECT_EQ(first.dirtyEnd, uint32_t(first.positions.size() / 3));  // a new surface: all
  (void)world.step(0.01);
  const SurfaceView still = world.surface(id);
  EXPECT_EQ(still.dirtyBegin, still.dirtyEnd) << "nothing moved, yet vertices are dirty";

  // Move one boundary node: only its vertices (and the normals around it) change.
  const std::vector<float> before(still.positions.begin(), still.positions.end());
  std::vector<double> x = copy(world.positions(id));
  const int32_t node = int32_t(x.size() / 3 / 2);
  x[3 * size_t(node) + 1] += 1e-3;
  ASSERT_TRUE(world.setPositions(id, x).ok());
  const SurfaceView moved = world.surface(id);
  const uint32_t nv = uint32_t(moved.positions.size() / 3);
  ASSERT_LT(moved.dirtyBegin, moved.dirtyEnd);
  EXPECT_LT(moved.dirtyEnd - moved.dirtyBegin, nv);  // not the whole surface
  int changed = 0;
  for (uint32_t v = 0; v < nv; ++v) {
    const bool same = std::memcmp(&before[3 * v], &moved.positions[3 * v], 3 * sizeof(float)) == 0;
    changed += same ? 0 : 1;
    if (!same) {
      EXPECT_GE(v, moved.dirtyBegin);
      EXPECT_LT(v, moved.dirtyEnd);
    }
    if (moved.vertexNode[v] == node) {
      EXPECT_FALSE(same) << "vertex " << v << " of the moved node";
    }
  }
  EXPECT_GT(changed, 0);
  const SurfaceView again = world.surface(id);  // asked twice: nothing new
  EXPECT_EQ(again.dirtyBegin, again.dirtyEnd);
}

// World::edges names the nodes of the edge ids that events and setEdgeStrengths use: weakening
// the edges that cross the plane x = 0.52 (inside the 13th of 24 cells) makes the bar break
// there and nowhere else.
TEST(WorldApi, EdgesLetTheGameChooseWhereABodyBreaks) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(fracturingBar(1e9)).value();
  const std::span<const int32_t> edges = world.edges(id);
  const std::span<const double> x = world.positions(id);
  ASSERT_EQ(edges.size(), 2 * size_t(world.fractureStats(id).edgeCount));
  std::vector<double> strength(edges.size() / 2, 1e9);
  auto crosses = [&](size_t e) {
    const double xa = x[3 * size_t(edges[2 * e])], xb = x[3 * size_t(edges[2 * e + 1])];
    return (xa - 0.52) * (xb - 0.52) < 0;
  };
  int weakened = 0;
  for (size_t e = 0; e < strength.size(); ++e)
    if (crosses(e)) strength[e] = 1e3, ++weakened;
  ASSERT_GT(weakened, 0);
  ASSERT_TRUE(world.setEdgeStrengths(id, strength).ok());
  int events = 0;
  for (int s = 0; s < 40; ++s) {
    (void)world.step(0.01);
    for (const FractureEvent& ev : world.fractureEvents()) {
      ++events;
      EXPECT_TRUE(crosses(size_t(ev.edge))) << "edge " << ev.edge;
      EXPECT_EQ(ev.nodeA, edges[2 * size_t(ev.edge)]);
      EXPECT_EQ(ev.nodeB, edges[2 * size_t(ev.edge) + 1]);
    }
  }
  EXPECT_GT(events, 0);
  EXPECT_EQ(world.fractureStats(id).fragments, 2);
  const std::span<const uint8_t> broken = world.brokenEdges(id);
  ASSERT_EQ(broken.size(), strength.size());
  for (size_t e = 0; e < broken.size(); ++e)
    if (broken[e]) {
      EXPECT_TRUE(crosses(e)) << "edge " << e;
    }
  EXPECT_TRUE(world.edges(BodyId{}).empty());
  const BodyId plain = world.createBody(freeCube()).value();
  EXPECT_TRUE(world.edges(plain).empty());  // no fracture graph
}

// A bar hanging from a pinned top face: once settled, the grip holds exactly its weight.
TEST(WorldApi, GripForcesBalanceTheWeight) {
  const glm::vec3 g(0, -9.81f, 0);
  World world(WorldDef{g, Backend::Cpu, nullptr, 1, {}});
  BodyDef def;
  def.mesh = gen::box(0.1, 0.5, 0.1, 2, 10, 2);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.material.massDamping = 20;  // settles in a second
  def.solver.linearSolver = LinearSolverKind::Direct;
  Grip top;
  top.nodes = test::selectNodes(def.mesh, [](double, double y, double) { return y > 0.5 - 1e-9; });
  def.grips = {top};
  const BodyId id = world.createBody(def).value();
  EXPECT_EQ(world.gripForces(id)[0], glm::dvec3(0));  // before the first step
  for (int s = 0; s < 240; ++s) (void)world.step(1.0 / 120);
  const double weight = world.stats(id).mass * 9.81;
  const glm::dvec3 f = world.gripForces(id)[0];
  std::printf("grip: force (%.4f, %.4f, %.4f) N, weight %.4f N\n", f.x, f.y, f.z, weight);
  EXPECT_NEAR(f.y, weight, 1e-3 * weight);
  EXPECT_NEAR(f.x, 0, 1e-6 * weight);
  EXPECT_NEAR(f.z, 0, 1e-6 * weight);
  EXPECT_TRUE(world.gripForces(BodyId{}).empty());
}

// The strain colour map's field: a box stretched uniformly by (1.1, 0.95, 1) has the Green
// strain (1.1^2 - 1) / 2 = 0.105 as its largest principal value at every node; rotated
// rigidly as well, still 0.105; and surface vertices carry their node's value.
TEST(WorldApi, NodeStrainIsTheLargestPrincipalGreenStrain) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  BodyDef def = freeCube();
  const BodyId id = world.createBody(def).value();
  const double c = std::cos(0.7), s = std::sin(0.7);
  std::vector<double> x(def.mesh.positions.size());
  for (size_t n = 0; n < x.size() / 3; ++n) {
    const double X = 1.1 * def.mesh.positions[3 * n], Y = 0.95 * def.mesh.positions[3 * n + 1];
    x[3 * n] = c * X - s * Y + 0.3;  // stretch, then turn about z and move
    x[3 * n + 1] = s * X + c * Y;
    x[3 * n + 2] = def.mesh.positions[3 * n + 2];
  }
  ASSERT_TRUE(world.setPositions(id, x).ok());
  const std::span<const double> e = world.nodeStrain(id);
  ASSERT_EQ(e.size(), def.mesh.nodeCount());
  for (double v : e) EXPECT_NEAR(v, 0.5 * (1.1 * 1.1 - 1), 1e-12);
  const SurfaceView sv = world.surface(id);
  ASSERT_EQ(sv.vertexNode.size(), sv.positions.size() / 3);
  for (size_t v = 0; v < sv.vertexNode.size(); ++v) {
    const int32_t n = sv.vertexNode[v];
    ASSERT_TRUE(n >= 0 && size_t(n) < def.mesh.nodeCount());
    // The vertex lies in one of its node's tets (cells 0.05 m, stretched by at most 1.1).
    const glm::dvec3 d(sv.positions[3 * v] - x[3 * size_t(n)],
                       sv.positions[3 * v + 1] - x[3 * size_t(n) + 1],
                       sv.positions[3 * v + 2] - x[3 * size_t(n) + 2]);
    EXPECT_LE(glm::length(d), 0.05 * 1.1 * std::sqrt(3.0) + 1e-5);
  }
  EXPECT_TRUE(world.nodeStrain(BodyId{}).empty());
}

TEST(WorldApi, RestoreCarriesCommandsAndPendingForces) {
  // Commands issued before a snapshot (strengths, material, grip velocity, a pending force)
  // are part of the state: a replay from it matches the original run bit for bit.
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(fracturingBar()).value();
  for (int s = 0; s < 10; ++s) (void)world.step(0.01);
  std::vector<double> strengths(size_t(world.fractureStats(id).edgeCount), 2e4);
  strengths[7] = 1e3;
  ASSERT_TRUE(world.setEdgeStrengths(id, strengths).ok());
  Material m = fracturingBar().material;
  m.youngsModulus = 2e6;
  ASSERT_TRUE(world.setMaterial(id, m).ok());
  ASSERT_TRUE(world.setGripVelocity(id, 0, glm::vec3(-0.08f, 0.01f, 0)).ok());
  ASSERT_TRUE(world.applyForce(id, glm::vec3(0.5f, 0.05f, 0.05f), glm::vec3(0, 50, 0)).ok());
  const WorldSnapshot snap = world.snapshot();
  for (int s = 0; s < 30; ++s) (void)world.step(0.01);
  const uint64_t h = world.stateHash();
  // Undo every command, then restore: the snapshot must bring them back.
  ASSERT_TRUE(world.setEdgeStrengths(id, std::vector<double>(strengths.size(), 1e9)).ok());
  ASSERT_TRUE(world.setMaterial(id, fracturingBar().material).ok());
  ASSERT_TRUE(world.setGripVelocity(id, 0, glm::vec3(0)).ok());
  ASSERT_TRUE(world.restore(snap).ok());
  for (int s = 0; s < 30; ++s) (void)world.step(0.01);
  EXPECT_EQ(world.stateHash(), h);
}

uint64_t fracturingRunHash(JobSystem* jobs, int* broken) {
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, jobs, 1, {}});
  const BodyId id = world.createBody(fracturingBar()).value();
  for (int s = 0; s < 200; ++s) (void)world.step(0.01);
  *broken = world.fractureStats(id).brokenEdges;
  return world.stateHash();
}

TEST(WorldApi, SameHashForOneAndTwoThreadsAndAcrossRuns) {
  ThreadPoolJobSystem one(1), two(2);
  int b1 = 0, b2 = 0, b3 = 0;
  const uint64_t h1 = fracturingRunHash(&one, &b1);
  const uint64_t h2 = fracturingRunHash(&two, &b2);
  const uint64_t h3 = fracturingRunHash(&two, &b3);
  std::printf("determinism: 200 steps, %d broken edges, hash %016llx\n", b1,
              static_cast<unsigned long long>(h1));
  EXPECT_GT(b1, 0);
  EXPECT_EQ(h1, h2);
  EXPECT_EQ(h2, h3);
  EXPECT_EQ(b1, b2);
}

}  // namespace
}  // namespace gf
