// Issue 5 acceptance with Bullet: a glass bunny hit by a Bullet ball shatters and its fragments
// come to rest on the Bullet floor without falling through it; and a soak test that breaks and
// hands off fragments for 5000 steps with resident memory flat after warm-up and no NaN.
#include <BulletCollision/CollisionShapes/btConvexHullShape.h>
#include <LinearMath/btConvexHullComputer.h>
#include <btBulletDynamicsCommon.h>
#include <graphfrac/bullet/bridge.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <span>
#include <vector>

#include "common/bullet_world.h"
#include "common/sim_helpers.h"

namespace gf {
namespace {

// Floor tolerance: Bullet's default collision margin (CONVEX_DISTANCE_MARGIN, 4 cm). The bridge's
// hulls carry at most 2 cm of margin outside the nodes, and Bullet lets resting contacts overlap
// by millimetres; a fragment through the floor ends up metres below it.
constexpr double kTolerance = 0.04;

double seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Resident set size [bytes] from /proc/self/statm (second field, in pages).
double residentBytes() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return -1;
  long size = 0, resident = 0;
  const int got = std::fscanf(f, "%ld %ld", &size, &resident);
  std::fclose(f);
  return got == 2 ? double(resident) * double(sysconf(_SC_PAGESIZE)) : -1;
}

// Thesis fig 4.14 / scenes/glass_bunny.json: the solid glass bunny (Table 4.1), here standing on
// a Bullet floor and hit by a Bullet ball at 20 m/s instead of being thrown at a fixed ball.
TEST(BulletAcceptance, GlassBunnyShattersAndFragmentsRestOnBulletFloor) {
  Result<TetMesh> mesh = TetMesh::fromFile(GF_SOURCE_DIR "/scenes/meshes/bunny_small.msh");
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  BodyDef def;
  def.mesh = std::move(mesh.value());
  // Scaled by 0.03 (0.3 m tall, as in the scene), centred over the origin, resting on y = 0.
  glm::dvec3 lo(1e300), hi(-1e300);
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
    for (int i = 0; i < 3; ++i) {
      double& p = def.mesh.positions[3 * n + i];
      p *= 0.03;
      lo[i] = std::min(lo[i], p);
      hi[i] = std::max(hi[i], p);
    }
  const glm::dvec3 shift(-(lo.x + hi.x) / 2, -lo.y + 1e-3, -(lo.z + hi.z) / 2);
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
    for (int i = 0; i < 3; ++i) def.mesh.positions[3 * n + i] += shift[i];
  const glm::dvec3 size = hi - lo;
  test::makeTableGlass(def);

  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(def).value();
  const double bunnyMass = world.stats(id).mass;
  test::BulletWorld dyn(btVector3(0, -9.81f, 0));
  // Shards leave at up to the ball's 20 m/s; a rough floor (friction 2 x Bullet's default 0.5
  // of the hulls: 1 combined) stops them within the 3 s instead of letting them skate away.
  dyn.floor->setFriction(2);
  dyn.floor->setRollingFriction(0.1f);
  // A 5 kg ball of radius 8 cm (the scene's) at the bunny's mid-height, 20 m/s along -x.
  const float radius = 0.08f, ballMass = 5;
  btSphereShape ballShape(radius);
  btVector3 ballInertia;
  ballShape.calculateLocalInertia(ballMass, ballInertia);
  btRigidBody::btRigidBodyConstructionInfo ci(ballMass, nullptr, &ballShape, ballInertia);
  ci.m_startWorldTransform.setOrigin(
      btVector3(btScalar(size.x / 2 + radius + 0.01), btScalar(0.4 * size.y), 0));
  btRigidBody ball(ci);
  ball.setLinearVelocity(btVector3(-20, 0, 0));
  dyn.world.addRigidBody(&ball);
  std::printf("[ info ] bunny %zu nodes, %zu tets, %.3f x %.3f x %.3f m, %.3f kg\n",
              def.mesh.nodeCount(), def.mesh.tetCount(), size.x, size.y, size.z, bunnyMass);
  {
    bullet::Bridge bridge(world, dyn.world);
    ASSERT_TRUE(bridge.addCollider(dyn.floor.get()).ok());
    ASSERT_TRUE(bridge.addCollider(&ball).ok());
    ASSERT_TRUE(bridge.setPolicy(id, bullet::HandoffPolicy::EveryFragment).ok());
    // 1 ms steps through the impact: contact acts on FEM nodes, so the 20 m/s ball must move
    // well under the node spacing per step (2 cm) or it would pass between them. Once every
    // fragment is in Bullet no FEM node is left to collide, and the fragments settle at 60 Hz
    // (the world still pays its full per-step cost then). The pieces leave spinning at up to
    // ~50 rad/s, as a hit above the centre spins them; 6 s lets Bullet's friction stop them.
    const double impact = 0.1, duration = 6;
    const auto t0 = std::chrono::steady_clock::now();
    uint32_t flags = 0;
    size_t handoffs = 0;
    int steps = 0;
    double handedMass = 0, firstBreak = -1, ballSpeed = 0;
    while (world.time() < duration - 1e-9) {
      const double dt = world.time() < impact - 1e-9 ? 1e-3 : 1.0 / 60;
      const StepStatus st = bridge.step(dt);
      flags |= st.flags;
      handoffs += world.handoffEvents().size();
      for (const HandoffEvent& e : world.handoffEvents()) handedMass += e.mass;
      if (firstBreak < 0 && !world.fractureEvents().empty()) firstBreak = world.time();
      if (std::abs(world.time() - impact) < 1e-9) ballSpeed = ball.getLinearVelocity().length();
      ++steps;
    }
    const double wall = seconds(t0);
    EXPECT_EQ(flags & (kStepNanContained | kStepInvalidInput), 0u);
    EXPECT_TRUE(test::stateFinite(world, id));
    const int32_t fragments = world.fractureStats(id).fragments;
    EXPECT_GE(fragments, 2);  // it shattered
    EXPECT_GE(bridge.fragments().size(), 2u);
    EXPECT_EQ(handoffs, bridge.fragments().size());

    // Lowest node of every fragment (handed off or still FEM) against the floor.
    const std::span<const int32_t> fragmentOf = world.nodeFragments(id);
    const std::span<const double> x = world.positions(id);
    std::vector<double> lowest(size_t(fragments), 1e300);
    for (size_t n = 0; n < fragmentOf.size(); ++n)
      lowest[size_t(fragmentOf[n])] = std::min(lowest[size_t(fragmentOf[n])], x[3 * n + 1]);
    double worst = 1e300, maxSpeed = 0, maxMargin = 0;
    for (const bullet::RigidFragment& f : bridge.fragments()) {
      maxSpeed = std::max(maxSpeed, double(f.rigidBody->getLinearVelocity().length()));
      const btCollisionShape* shape = f.rigidBody->getCollisionShape();
      if (shape->isCompound()) shape = static_cast<const btCompoundShape*>(shape)->getChildShape(0);
      maxMargin = std::max(maxMargin, double(shape->getMargin()));
    }
    for (double l : lowest) worst = std::min(worst, l);
    std::printf(
        "[ info ] first edge broke at t = %.3f s; ball speed after the impact %.2f m/s\n"
        "[ info ] %d steps, %d fragments (%zu in Bullet, %.4f of %.4f kg), lowest node y %.4f m "
        "(tolerance %.2f), largest hull margin %.4f m, fastest fragment %.3f m/s, step flags "
        "%u, wall %.1f s\n",
        firstBreak, ballSpeed, steps, fragments, bridge.fragments().size(), handedMass, bunnyMass,
        worst, kTolerance, maxMargin, maxSpeed, flags, wall);
    // Does the collision shape fit the piece (compound hulls would be needed if it does not)?
    // Volume of the fragment's hull (of its nodes) against the fragment's own volume
    // (that of its corner cells, which reach past the nodes to edge midpoints and centroids):
    // above 1 means a concave piece rests on points that are not there, below 1 a thin shard
    // whose hull is slimmer than the piece drawn. Printed, not asserted (docs/validation.md).
    auto convexVolume = [](const btConvexHullShape* hull) {
      btConvexHullComputer computer;
      computer.compute(&hull->getUnscaledPoints()->getX(), sizeof(btVector3), hull->getNumPoints(),
                       0, 0);
      double volume = 0;  // sum of tets from the first vertex over the faces' fans
      const btVector3 o = computer.vertices[0];
      for (int fi = 0; fi < computer.faces.size(); ++fi) {
        const btConvexHullComputer::Edge* e0 = &computer.edges[computer.faces[fi]];
        const btVector3 a = computer.vertices[e0->getSourceVertex()];
        for (const btConvexHullComputer::Edge* e = e0->getNextEdgeOfFace();
             e->getTargetVertex() != e0->getSourceVertex(); e = e->getNextEdgeOfFace()) {
          const btVector3 b = computer.vertices[e->getSourceVertex()];
          const btVector3 c = computer.vertices[e->getTargetVertex()];
          volume += double((a - o).dot((b - o).cross(c - o))) / 6;
        }
      }
      return std::abs(volume);
    };
    double worstRatio = 0, meanRatio = 0;
    int hulls = 0;
    for (const bullet::RigidFragment& f : bridge.fragments()) {
      const btCollisionShape* shape = f.rigidBody->getCollisionShape();
      double volume = 0;
      if (shape->isCompound()) {
        const auto* compound = static_cast<const btCompoundShape*>(shape);
        for (int c = 0; c < compound->getNumChildShapes(); ++c, ++hulls)
          volume += convexVolume(static_cast<const btConvexHullShape*>(compound->getChildShape(c)));
      } else {
        volume = convexVolume(static_cast<const btConvexHullShape*>(shape));
        ++hulls;
      }
      const double ratio = volume / world.fragmentInfo(id, f.fragment).value().volume;
      worstRatio = std::max(worstRatio, ratio);
      meanRatio += ratio / double(bridge.fragments().size());
    }
    std::printf(
        "[ info ] %d convex hulls for %zu fragments; hull volume / fragment volume: mean %.2f, "
        "worst %.2f\n",
        hulls, bridge.fragments().size(), meanRatio, worstRatio);
    EXPECT_LT(ballSpeed, 19);  // the ball hit the bunny (without it the bunny does not break)
    // Every piece went, none twice; loose nodes (one-node chips) stay FEM particles.
    double looseMass = 0;
    std::vector<int> nodes(size_t(world.fractureStats(id).fragments), 0);
    for (int32_t f : fragmentOf) ++nodes[size_t(f)];
    for (size_t f = 0; f < nodes.size(); ++f)
      if (nodes[f] == 1 && !bridge.rigidBody(id, int32_t(f)))
        looseMass += world.fragmentInfo(id, int32_t(f)).value().mass;
    std::printf("[ info ] loose nodes left in the FEM body: %.4g kg\n", looseMass);
    EXPECT_NEAR(handedMass + looseMass, bunnyMass, 1e-9 * bunnyMass);
    // Loose nodes: the brittle planes give a node they leave with no whole tet to a piece
    // (brittle.cpp, keepNodesInPieces; 11.4 % of the mass was such dust before, issue 16); what
    // is left is 1.2 %: nodes where three pieces meet and the criterion's later breaks. Far
    // more would mean pieces crumbling into nodes.
    EXPECT_LT(looseMass, 0.03 * bunnyMass);
    EXPECT_LT(maxSpeed, 0.3);  // settled (a few cm/s of creep)
    for (size_t f = 0; f < lowest.size(); ++f) {
      SCOPED_TRACE(f);
      EXPECT_GT(lowest[f], -kTolerance);
    }
  }
  dyn.world.removeRigidBody(&ball);
}

// A finite static blade: the plane x = x0 over y in [y0, y1] (z across everything), so it cuts
// the bar and misses the slices already lying on the floor.
Blade sliceBlade(float x0, float y0, float y1) {
  Blade b;
  b.vertices = {{x0, y0, -1}, {x0, y1, -1}, {x0, y1, 1}, {x0, y0, 1}};
  b.triangles = {0, 1, 2, 0, 2, 3};
  return b;
}

// A bar gripped at x = 0 has a 2 cm slice cut off its free end every 30 steps; each slice goes to
// Bullet and falls onto the floor. When 12 slices are gone the body is destroyed (its rigid
// bodies leave Bullet) and a new bar is spawned: the steady state a game with breakables and
// debris lives in. After warm-up (one full cycle) the resident memory must not grow.
TEST(BulletAcceptance, SoakCuttingAndHandoffKeepsMemoryFlat) {
  constexpr int kSteps = 5000, kWarmup = 500, kCutEvery = 30, kSlices = 12;
  constexpr double dt = 1.0 / 120, cell = 0.02, side = 0.04, y0 = 0.3, rho = 1000;
  const double length = cell * (kSlices + 1);
  BodyDef def;
  def.mesh = gen::box(length, side, side, kSlices + 1, 2, 2);
  for (size_t i = 1; i < def.mesh.positions.size(); i += 3) def.mesh.positions[i] += y0;
  def.material = Material::stableNeoHookean(1e7, 0.3, rho);
  def.material.massDamping = 2;
  def.fracture.enabled = true;
  def.fracture.strength = 1e12;  // only the blade breaks it
  def.solver.linearSolver = LinearSolverKind::Direct;
  def.grips = {Grip{test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; }),
                    glm::vec3(0)}};
  const double barMass = rho * length * side * side;

  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  test::BulletWorld dyn(btVector3(0, -9.81f, 0));
  bullet::Bridge bridge(world, dyn.world);
  ASSERT_TRUE(bridge.addCollider(dyn.floor.get()).ok());
  BodyId bar{};
  int cuts = 0, bars = 0;
  size_t handoffs = 0, peakRigid = 0;
  double handedMass = 0, worstMassError = 0, rssWarm = 0, rssMid = 0, rssPeak = 0;
  uint32_t flags = 0;
  bool finite = true;
  const auto t0 = std::chrono::steady_clock::now();
  for (int s = 0; s < kSteps; ++s) {
    const int phase = s % (kCutEvery * (kSlices + 1));
    if (phase == 0) {
      if (bars > 0) {
        // Everything but the gripped column went to Bullet: the masses add up to the bar's.
        const double rest = world.fragmentInfo(bar, world.nodeFragments(bar)[0]).value().mass;
        worstMassError = std::max(worstMassError, std::abs(handedMass + rest - barMass) / barMass);
        ASSERT_TRUE(world.destroyBody(bar).ok());
      }
      Result<BodyId> created = world.createBody(def);
      ASSERT_TRUE(created.ok()) << created.error().message;
      bar = created.value();
      ASSERT_TRUE(bridge.setPolicy(bar, bullet::HandoffPolicy::EveryFragment).ok());
      handedMass = 0;
      ++bars;
    } else if (phase % kCutEvery == 0) {
      const int k = phase / kCutEvery;  // 1..kSlices, from the free end inwards
      const float x0 = float(length - (k - 0.5) * cell);
      ASSERT_TRUE(world.cut(bar, sliceBlade(x0, float(y0 - 0.1), float(y0 + side + 0.1))).ok());
      ++cuts;
    }
    const StepStatus st = bridge.step(dt);
    flags |= st.flags;
    for (const HandoffEvent& e : world.handoffEvents()) handedMass += e.mass;
    handoffs += world.handoffEvents().size();
    peakRigid = std::max(peakRigid, bridge.fragments().size());
    finite = finite && test::stateFinite(world, bar);
    if (s + 1 == kWarmup) rssWarm = residentBytes();
    if (s + 1 == (kWarmup + kSteps) / 2) rssMid = residentBytes();
    if (s + 1 >= kWarmup) rssPeak = std::max(rssPeak, residentBytes());
  }
  const double rssEnd = residentBytes();
  const double wall = seconds(t0);
  // The slices of the last bar lie on the floor, not under it.
  double lowest = 1e300;
  const std::span<const int32_t> fragmentOf = world.nodeFragments(bar);
  const std::span<const double> x = world.positions(bar);
  for (size_t n = 0; n < fragmentOf.size(); ++n)
    if (fragmentOf[n] != fragmentOf[0]) lowest = std::min(lowest, x[3 * n + 1]);
  const double MB = 1024.0 * 1024.0;
  std::printf(
      "[ info ] %d steps: %d bars, %d cuts, %zu hand-offs, at most %zu fragments in Bullet, "
      "lowest slice node y %.4f m; worst mass error %.2e\n[ info ] RSS after warm-up (step %d) "
      "%.2f MB, mid %.2f MB, end %.2f MB, peak %.2f MB (growth %+.3f MB); flags %u, wall %.1f s\n",
      kSteps, bars, cuts, handoffs, peakRigid, lowest, worstMassError, kWarmup, rssWarm / MB,
      rssMid / MB, rssEnd / MB, rssPeak / MB, (rssEnd - rssWarm) / MB, flags, wall);
  EXPECT_TRUE(finite);
  EXPECT_EQ(flags & (kStepNanContained | kStepInvalidInput), 0u);
  EXPECT_EQ(handoffs, size_t(cuts));  // every cut freed exactly one slice
  EXPECT_LT(worstMassError, 1e-9);
  EXPECT_GT(lowest, -kTolerance);
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "resident memory is not flat under ASan (its quarantine keeps freed blocks)";
#endif
  // Measured: +0.06 to +0.09 MB from warm-up to the end, none of it in the second half. A leak of
  // 60 bytes per step, or of one fragment's rigid body and hull (~2 KB) per hand-off, would add
  // more than 128 KB over the second half (2250 steps, ~70 hand-offs).
  ASSERT_GT(rssWarm, 0);
  EXPECT_LT(rssEnd - rssMid, 128.0 * 1024);
  EXPECT_LT(rssEnd - rssWarm, 512.0 * 1024);
}

}  // namespace
}  // namespace gf
