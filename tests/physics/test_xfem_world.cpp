// Is-XFEM bodies in the World (issue 21 item 4: BodyDef::cutMode = Xfem, World::cut through the
// tets), checked against independent truths: a plane blade splits a box into pieces whose
// volumes are the plane's exact split (analytic); the cut faces of the render surface lie on the
// blade's plane (to the float surface's rounding) and every piece's surface is closed and encloses
// its volume; a cut keeps the momentum, angular momentum and energy of the state (the new enriched
// DOFs start at zero); a piece cut off a held body falls as implicit Euler's free fall, for
// several time steps, substeps and stiffnesses; a body falling on the floor never ends a step
// below it and comes to rest on it; and a setting an Is-XFEM body cannot honour is refused with
// the field named and the world unchanged.
#include <graphfrac/world.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <utility>
#include <vector>

#include "common/xfem_cut_box.h"

namespace gf {
namespace {

constexpr double kG = 9.81;

using SlantedBlade = test::SlantedCut;

// A 2 x 1 x 1 m box of 6 x 3 x 3 cells, lifted to y in [1, 2], in CutMode::Xfem.
BodyDef xfemBox(double youngs, bool holdLeftEnd) {
  BodyDef def;
  def.mesh = gen::box(2, 1, 1, 6, 3, 3);
  for (size_t i = 0; i < def.mesh.nodeCount(); ++i) def.mesh.positions[3 * i + 1] += 1.0;
  def.material = Material::stableNeoHookean(youngs, 0.3, 1000);
  def.cutMode = CutMode::Xfem;
  if (holdLeftEnd) {
    Grip g;
    for (int32_t n = 0; n < int32_t(def.mesh.nodeCount()); ++n)
      if (def.mesh.positions[3 * size_t(n)] == 0) g.nodes.push_back(n);
    def.grips.push_back(g);
  }
  return def;
}

// Per fragment of a surface: its enclosed volume and centroid (divergence theorem, in double
// from the float positions), and the number of edges not shared by exactly two of its triangles.
struct FragmentShape {
  double volume = 0;
  glm::dvec3 moment{0};
  int openEdges = 0;
  glm::dvec3 centroid() const { return moment / volume; }
};
std::map<int32_t, FragmentShape> fragmentShapes(const SurfaceView& v) {
  std::map<int32_t, FragmentShape> out;
  std::map<int32_t, std::map<std::pair<uint32_t, uint32_t>, int>> edges;
  const auto p = [&](uint32_t i) {
    return glm::dvec3(v.positions[3 * i], v.positions[3 * i + 1], v.positions[3 * i + 2]);
  };
  for (size_t t = 0; 3 * t < v.indices.size(); ++t) {
    const uint32_t i0 = v.indices[3 * t], i1 = v.indices[3 * t + 1], i2 = v.indices[3 * t + 2];
    const int32_t f = v.vertexFragment[i0];
    const glm::dvec3 a = p(i0), b = p(i1), c = p(i2);
    const double six = glm::dot(a, glm::cross(b, c));  // 6 x signed volume to the origin
    out[f].volume += six / 6;
    out[f].moment += (six / 24) * (a + b + c);
    for (auto [x, y] : {std::pair{i0, i1}, {i1, i2}, {i2, i0}})
      ++edges[f][{std::min(x, y), std::max(x, y)}];
  }
  for (auto& [f, list] : edges)
    for (auto& [e, n] : list) out[f].openEdges += n != 2;
  return out;
}

TEST(XfemWorld, PlaneBladeGivesTheExactSplitAndCutFacesOnThePlane) {
  const SlantedBlade cut;
  World world{WorldDef{}};
  auto id = world.createBody(xfemBox(1e7, false));
  ASSERT_TRUE(id.ok()) << id.error().message;
  ASSERT_TRUE(world.cut(id.value(), cut.blade()).ok());
  EXPECT_EQ(world.fractureStats(id.value()).fragments, 2);

  // The cut faces at rest: on the plane to the float surface's rounding (half an ulp of each
  // coordinate), the pieces closed and enclosing the exact split.
  const SurfaceView v = world.surface(id.value());
  const glm::dvec3 n = cut.normal();
  double offPlane = 0, bound = 0;
  int cutVertices = 0;
  for (size_t t = 0; t < v.crackMask.size(); ++t) {
    if (!v.crackMask[t]) continue;
    for (int k = 0; k < 3; ++k) {
      const uint32_t i = v.indices[3 * t + size_t(k)];
      const glm::dvec3 x(v.positions[3 * i], v.positions[3 * i + 1], v.positions[3 * i + 2]);
      const double round =
          (std::abs(n.x * x.x) + std::abs(n.y * x.y) + std::abs(n.z * x.z)) * std::ldexp(1.0, -24);
      offPlane = std::max(offPlane, std::abs(glm::dot(n, x) - cut.offset()) - round);
      bound = std::max(bound, round);
      ++cutVertices;
    }
  }
  const auto shapes = fragmentShapes(v);
  ASSERT_EQ(shapes.size(), 2u);
  std::printf(
      "cut-face vertices (%d) off the plane beyond float rounding: %.2e (rounding bound %.2e)\n",
      cutVertices, offPlane, bound);
  EXPECT_GT(cutVertices, 0);
  EXPECT_LE(offPlane, 1e-12);
  std::vector<double> enclosed;
  for (const auto& [f, s] : shapes) {
    EXPECT_EQ(s.openEdges, 0) << "fragment " << f;
    enclosed.push_back(s.volume);
  }
  std::sort(enclosed.begin(), enclosed.end());
  const double left = cut.leftVolume(), right = 2 - left;
  std::printf("surface-enclosed volumes %.9f, %.9f (exact %.9f, %.9f)\n", enclosed[0], enclosed[1],
              left, right);
  EXPECT_NEAR(enclosed[0], left, 1e-6 * left);
  EXPECT_NEAR(enclosed[1], right, 1e-6 * right);

  // The next step reports the cut: one event per cut tet, one new fragment with the exact
  // volume of its piece (double).
  ASSERT_FALSE(world.step(1.0 / 60).has(kStepNanContained));
  int cutEvents = 0;
  for (const FractureEvent& e : world.fractureEvents()) {
    EXPECT_EQ(e.cause, FractureEvent::Cause::Cut);
    EXPECT_EQ(e.edge, -1);
    EXPECT_GE(e.tet, 0);
    ++cutEvents;
  }
  ASSERT_EQ(world.fragmentEvents().size(), 1u);
  const FragmentEvent& split = world.fragmentEvents()[0];
  EXPECT_EQ(split.fragment, 1);
  EXPECT_EQ(split.parent, 0);
  const double exact =
      std::abs(split.volume - left) < std::abs(split.volume - right) ? left : right;
  const double err = std::abs(split.volume - exact) / exact;
  std::printf("%d cut events; new fragment volume %.15f, exact %.15f, rel. error %.2e\n", cutEvents,
              split.volume, exact, err);
  EXPECT_GT(cutEvents, 0);
  EXPECT_LE(err, 1e-10);
  EXPECT_NEAR(split.mass, 1000 * split.volume, 1e-9);
  // Events are the next step's only.
  ASSERT_FALSE(world.step(1.0 / 60).has(kStepNanContained));
  EXPECT_TRUE(world.fractureEvents().empty());
  EXPECT_TRUE(world.fragmentEvents().empty());
}

// A cut during the run keeps the state: the new enriched DOFs start at zero, so the field, its
// momentum, angular momentum and energies are those before the cut, to round-off.
TEST(XfemWorld, CutDuringTheRunKeepsMomentumAndEnergy) {
  const SlantedBlade cut;
  World world{WorldDef{}};
  auto id = world.createBody(xfemBox(1e6, true));
  ASSERT_TRUE(id.ok()) << id.error().message;
  for (int s = 0; s < 20; ++s) ASSERT_FALSE(world.step(1.0 / 60).has(kStepNanContained));
  const BodyStats before = world.stats(id.value());
  const std::vector<double> x0(world.positions(id.value()).begin(),
                               world.positions(id.value()).end());
  ASSERT_TRUE(world.cut(id.value(), cut.blade()).ok());
  const BodyStats after = world.stats(id.value());
  const double p = glm::length(before.linearMomentum - after.linearMomentum) /
                   glm::length(before.linearMomentum);
  const double L = glm::length(before.angularMomentum - after.angularMomentum) /
                   glm::length(before.angularMomentum);
  const double kinetic =
      std::abs(after.kineticEnergy - before.kineticEnergy) / before.kineticEnergy;
  const double elastic =
      std::abs(after.elasticEnergy - before.elasticEnergy) / before.elasticEnergy;
  double moved = 0;
  for (size_t i = 0; i < x0.size(); ++i)
    moved = std::max(moved, std::abs(world.positions(id.value())[i] - x0[i]));
  std::printf(
      "cut after 20 steps (|p| = %.4f kg m/s): rel. change of p %.2e, L %.2e, kinetic %.2e, "
      "elastic %.2e; nodes moved %.1e m\n",
      glm::length(before.linearMomentum), p, L, kinetic, elastic, moved);
  EXPECT_GT(glm::length(before.linearMomentum), 1e-3);
  EXPECT_LE(p, 1e-12);
  EXPECT_LE(L, 1e-12);
  EXPECT_LE(kinetic, 1e-12);
  EXPECT_LE(elastic, 1e-12);
  EXPECT_EQ(moved, 0.0);
  EXPECT_NEAR(after.mass, 2000, 1e-9);
}

// A blade comes in world coordinates and is carried to the rest frame by the motion of the piece
// it meets: a second cut of the held part of a body whose first piece has fallen 0.5 m away cuts
// the held part where the blade is (x = 0.4 at rest: the new piece is the slab between x = 0.4
// and the first plane, 0.828125 - 0.4 m^3), not where one motion of the whole body would put it.
TEST(XfemWorld, SecondCutFollowsThePieceItMeets) {
  const SlantedBlade first;
  World world{WorldDef{}};
  auto id = world.createBody(xfemBox(1e7, true));
  ASSERT_TRUE(id.ok()) << id.error().message;
  ASSERT_TRUE(world.cut(id.value(), first.blade()).ok());
  for (int s = 0; s < 20; ++s) ASSERT_FALSE(world.step(1.0 / 60).has(kStepNanContained));
  Blade second;  // the plane x = 0.4 over y in [0.9, 2.1], z in [-0.1, 1.1]
  for (float y : {0.9f, 2.1f})
    for (float z : {-0.1f, 1.1f}) second.vertices.push_back({0.4f, y, z});
  second.triangles = {0, 2, 3, 0, 3, 1};
  ASSERT_TRUE(world.cut(id.value(), second).ok());
  EXPECT_EQ(world.fractureStats(id.value()).fragments, 3);
  ASSERT_FALSE(world.step(1.0 / 60).has(kStepNanContained));
  ASSERT_EQ(world.fragmentEvents().size(), 1u);
  const double exact = first.leftVolume() - 0.4;
  const FragmentEvent& e = world.fragmentEvents()[0];
  // The held piece sags by under 1 mm (E = 1e7): its rigid fit places the cut to well within
  // that (a fit of the whole body would be off by a tenth of a metre).
  std::printf("second cut: new fragment %d (parent %d) volume %.9f, exact %.9f (rel. %.1e)\n",
              e.fragment, e.parent, e.volume, exact, std::abs(e.volume - exact) / exact);
  EXPECT_EQ(e.fragment, 2);
  EXPECT_EQ(e.parent, 0);
  EXPECT_NEAR(e.volume, exact, 1e-4 * exact);
}

// The piece cut off a body held at x = 0 falls freely: its centre of mass follows implicit
// Euler's free fall y_n = y_0 - g h^2 n (n + 1) / 2 over substeps of h, whatever dt, substeps
// and stiffness, while the held piece only sags.
TEST(XfemWorld, CutOffPieceFallsAsImplicitEuler) {
  const SlantedBlade cut;
  struct Case {
    double dt;
    int substeps;
    double youngs;
  };
  for (const Case c : {Case{1.0 / 60, 1, 1e7}, Case{1.0 / 60, 4, 1e7}, Case{1.0 / 120, 1, 1e6},
                       Case{1.0 / 30, 2, 1e8}}) {
    WorldDef wd;
    wd.substeps = c.substeps;
    wd.gravity = {0, float(-kG), 0};
    World world(wd);
    auto id = world.createBody(xfemBox(c.youngs, true));
    ASSERT_TRUE(id.ok()) << id.error().message;
    ASSERT_TRUE(world.cut(id.value(), cut.blade()).ok());
    const auto start = fragmentShapes(world.surface(id.value()));
    const int steps = 20;
    for (int s = 0; s < steps; ++s) ASSERT_FALSE(world.step(c.dt).has(kStepNanContained));
    const auto end = fragmentShapes(world.surface(id.value()));
    ASSERT_EQ(end.size(), 2u);
    // Fragment 1 is the new piece: the right one (x above the plane), which the grips do not hold.
    const double g = double(float(-kG));
    const double h = c.dt / c.substeps;
    const int n = steps * c.substeps;
    const double fall = -g * h * h * n * (n + 1) / 2;
    const glm::dvec3 moved = end.at(1).centroid() - start.at(1).centroid();
    const glm::dvec3 sag = end.at(0).centroid() - start.at(0).centroid();
    std::printf(
        "dt = 1/%.0f, %d substeps, E = %.0e: free piece fell %.9f m (implicit Euler %.9f, rel. "
        "error %.1e), drift %.1e m; held piece moved %.1e m\n",
        1 / c.dt, c.substeps, c.youngs, -moved.y, fall, std::abs(-moved.y - fall) / fall,
        std::hypot(moved.x, moved.z), glm::length(sag));
    EXPECT_NEAR(-moved.y, fall, 1e-5 * fall);
    EXPECT_LT(std::hypot(moved.x, moved.z), 1e-5 * fall);
    EXPECT_LT(glm::length(sag), 0.05 * fall);
  }
}

// Falling on the floor: no surface vertex (cut faces included) ends a step below the plane, and
// the pieces come to rest on it, for several time steps and stiffnesses.
TEST(XfemWorld, PiecesLandOnTheFloorWithoutPassingThrough) {
  const SlantedBlade cut;
  struct Case {
    double dt, youngs;
  };
  for (const Case c : {Case{1.0 / 60, 1e7}, Case{1.0 / 240, 1e7}, Case{1.0 / 30, 1e7},
                       Case{1.0 / 60, 1e6}, Case{1.0 / 60, 1e8}}) {
    const double dt = c.dt;
    WorldDef wd;
    wd.colliders.push_back(Collider{});  // the ground plane y = 0
    World world(wd);
    auto id = world.createBody(xfemBox(c.youngs, false));
    ASSERT_TRUE(id.ok()) << id.error().message;
    ASSERT_TRUE(world.cut(id.value(), cut.blade()).ok());
    double lowest = INFINITY, rise = 0;
    const auto energy = [&] {
      const BodyStats s = world.stats(id.value());
      return s.kineticEnergy + s.elasticEnergy + s.gravityEnergy;
    };
    double last = energy();
    const double scale = world.stats(id.value()).mass * kG;  // energy of a 1 m drop
    const int steps = int(std::ceil(3.0 / dt));
    int unconverged = 0;  // steps whose contact LCP missed its tolerance
    for (int s = 0; s < steps; ++s) {
      const StepStatus st = world.step(dt);
      ASSERT_FALSE(st.has(kStepNanContained));
      unconverged += st.has(kStepNotConverged);
      const SurfaceView v = world.surface(id.value());
      for (size_t i = 1; i < v.positions.size(); i += 3)
        lowest = std::min(lowest, double(v.positions[i]));
      // Implicit Euler and an inelastic contact only take energy out.
      const double e = energy();
      rise = std::max(rise, (e - last) / scale);
      last = e;
    }
    const BodyStats s = world.stats(id.value());
    const double speed = std::sqrt(2 * s.kineticEnergy / s.mass);
    const glm::dvec3 J = world.colliderImpulses()[0];
    std::printf(
        "dt = 1/%.0f, E = %.0e: lowest surface vertex over %d steps y = %.2e m; largest energy "
        "rise in "
        "a step %.1e of m g (1 m); after 3 s rms speed %.2e m/s, last step's floor impulse "
        "%.4f N s (weight x dt %.4f)\n",
        1 / dt, c.youngs, steps, lowest, rise, speed, J.y, s.mass * kG * dt);
    EXPECT_EQ(unconverged, 0);
    EXPECT_GE(lowest, -1e-6);
    EXPECT_LE(rise, 1e-9);
    EXPECT_LT(speed, 1e-3);
    // At rest the floor carries the weight: impulse m g dt per step.
    EXPECT_NEAR(J.y, s.mass * double(float(kG)) * dt, 1e-3 * s.mass * kG * dt);
  }
}

// What an Is-XFEM body cannot honour is refused at creation with the field named, and leaves
// the world as it was; so are the commands it cannot take.
TEST(XfemWorld, RefusesWhatItCannotHonourAndChangesNothing) {
  struct Bad {
    const char* field;
    void (*set)(BodyDef&);
  };
  const Bad bad[] = {
      {"fracture.enabled", [](BodyDef& d) { d.fracture.enabled = true; }},
      {"plasticity.enabled", [](BodyDef& d) { d.plasticity.enabled = true; }},
      {"material.fibreStiffness", [](BodyDef& d) { d.material.fibreStiffness = 1e5; }},
      {"material.massDamping", [](BodyDef& d) { d.material.massDamping = 0.1; }},
      {"forces",
       [](BodyDef& d) {
         d.forces.push_back({0, {0, 1, 0}});
       }},
      {"grips[0].velocity",
       [](BodyDef& d) {
         d.grips.push_back({{0}, {0, 1, 0}});
       }},
      {"contact", [](BodyDef& d) { d.contact = true; }},
      {"cutMode", [](BodyDef& d) { d.cutMode = static_cast<CutMode>(7); }},
  };
  World world{WorldDef{}};
  const uint64_t empty = world.stateHash();
  for (const Bad& b : bad) {
    BodyDef def = xfemBox(1e6, false);
    b.set(def);
    const auto checked = def.check();
    ASSERT_FALSE(checked.ok()) << b.field;
    EXPECT_EQ(checked.error().message.rfind(b.field, 0), 0u) << checked.error().message;
    auto r = world.createBody(def);
    ASSERT_FALSE(r.ok()) << b.field;
    EXPECT_NE(r.error().message.find(b.field), std::string::npos) << r.error().message;
    EXPECT_EQ(world.stateHash(), empty);
  }
  // A world with a box collider refuses an Is-XFEM body; one with an Is-XFEM body refuses a box.
  {
    // A grip that holds still is taken; one that moves is refused by setGripVelocity too.
    BodyDef held = xfemBox(1e6, true);
    World gripped{WorldDef{}};
    auto g = gripped.createBody(held);
    ASSERT_TRUE(g.ok()) << g.error().message;
    EXPECT_TRUE(gripped.setGripVelocity(g.value(), 0, {0, 0, 0}).ok());
    const auto moved = gripped.setGripVelocity(g.value(), 0, {0, 1, 0});
    ASSERT_FALSE(moved.ok());
    EXPECT_NE(moved.error().message.find("velocity 0 only"), std::string::npos);
  }
  {
    WorldDef wd;
    Collider box;
    box.kind = Collider::Kind::Box;
    wd.colliders.push_back(box);
    World boxed(wd);
    auto r = boxed.createBody(xfemBox(1e6, false));
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("colliders[0]"), std::string::npos) << r.error().message;
  }
  auto id = world.createBody(xfemBox(1e6, false));
  ASSERT_TRUE(id.ok()) << id.error().message;
  ASSERT_FALSE(world.step(1.0 / 60).has(kStepNanContained));
  const uint64_t hash = world.stateHash();
  Collider box;
  box.kind = Collider::Kind::Box;
  EXPECT_FALSE(world.setColliders(std::span<const Collider>(&box, 1)).ok());
  EXPECT_TRUE(world.colliders().empty());
  EXPECT_FALSE(world.applyForce(id.value(), {1, 1.5f, 0.5f}, {0, 10, 0}).ok());
  EXPECT_FALSE(world.applyImpulse(id.value(), {1, 1.5f, 0.5f}, {0, 10, 0}).ok());
  const std::vector<double> x(world.positions(id.value()).begin(),
                              world.positions(id.value()).end());
  EXPECT_FALSE(world.setPositions(id.value(), x).ok());
  EXPECT_FALSE(world.setMaterial(id.value(), Material::stableNeoHookean(1e7, 0.3, 1000)).ok());
  const WorldSnapshot snap = world.snapshot();
  const auto restored = world.restore(snap);
  ASSERT_FALSE(restored.ok());
  EXPECT_NE(restored.error().message.find("Xfem"), std::string::npos) << restored.error().message;
  // A blade that misses nothing but has a bad triangle is refused before anything changes.
  Blade broken = SlantedBlade{}.blade();
  broken.triangles[2] = 99;
  EXPECT_FALSE(world.cut(id.value(), broken).ok());
  EXPECT_EQ(world.fractureStats(id.value()).fragments, 1);
  EXPECT_EQ(world.stateHash(), hash);
}

}  // namespace
}  // namespace gf
