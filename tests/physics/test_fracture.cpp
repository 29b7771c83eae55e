// Graph-based fracture against independent truths: the tension bar breaks
// at sigma_th, a rigidly rotated fractured body feels no force, a planar cut splits a cylinder
// into two pieces whose volumes add up, closed cracks resist compression, and extreme cases stay
// finite.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <glm/gtc/quaternion.hpp>
#include <ostream>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "common/sim_helpers.h"

namespace gf {
namespace {

// Bar along x (L = 1, 0.1 x 0.1), nu = 0 so the stress is uniaxial; grips pull both ends
// apart quasi-statically. Returns the nominal stress E * strain at the first break.
double tensionBreakStress(DamageModel model, double strength, double* stressBefore) {
  const double L = 1.0, E = 1e6, speed = 0.01;  // strain rate 2 %/s
  BodyDef def;
  def.mesh = gen::box(L, 0.1, 0.1, 20, 2, 2);
  def.material = Material::stableNeoHookean(E, 0.0, 1000);
  def.material.massDamping = 5;
  def.fracture.enabled = true;
  def.fracture.strength = strength;
  def.fracture.model = model;
  Grip left, right;
  left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes = test::selectNodes(def.mesh, [&](double x, double, double) { return x > L - 1e-9; });
  left.velocity = glm::vec3(-speed, 0, 0);
  right.velocity = glm::vec3(speed, 0, 0);
  def.grips = {left, right};
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok()) << (id.ok() ? "" : id.error().message);
  if (!id.ok()) return 0;
  const double dt = 1e-2;
  double lastStress = 0;
  for (int s = 1; s < 2000; ++s) {
    // The criterion at the start of step s judges the state after s - 1 steps.
    const double stress = E * (2 * speed * (s - 1) * dt) / L;
    (void)world.step(dt);
    if (!world.fractureEvents().empty()) {
      *stressBefore = lastStress;
      return stress;
    }
    lastStress = stress;
  }
  return -1;
}

TEST(Fracture, TensionBarBreaksAtStrengthForBothModels) {
  const double strength = 2e4;  // 2 % strain
  for (DamageModel model : {DamageModel::Projection, DamageModel::Degradation}) {
    double before = 0;
    const double at = tensionBreakStress(model, strength, &before);
    std::printf(
        "tension bar, model %d: first break at nominal stress %.4e Pa (sigma_th %.4e),"
        " none at %.4e Pa\n",
        int(model), at, strength, before);
    EXPECT_NEAR(at, strength, 0.05 * strength);
    EXPECT_LT(before, strength);
  }
}

// A body with a cut through it, rigidly rotated from rest: every element (damaged or not) is
// unstrained, so a step with no gravity must not move anything.
TEST(Fracture, RotatedFracturedBodyFeelsNoForce) {
  for (DamageModel model : {DamageModel::Projection, DamageModel::Degradation}) {
    BodyDef def;
    def.mesh = gen::box(0.4, 0.2, 0.2, 8, 4, 4);
    def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
    def.fracture.enabled = true;
    def.fracture.strength = 1e9;
    def.fracture.model = model;
    World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
    auto id = world.createBody(def);
    ASSERT_TRUE(id.ok());
    Blade blade;  // plane x = 0.21, oblique in y
    blade.vertices = {{0.19f, -1, -1}, {0.23f, 1, -1}, {0.23f, 1, 1}, {0.19f, -1, 1}};
    blade.triangles = {0, 1, 2, 0, 2, 3};
    ASSERT_TRUE(world.cut(id.value(), blade).ok());
    (void)world.step(1e-3);  // applies the cut
    ASSERT_GT(world.fractureStats(id.value()).brokenEdges, 0);
    // Rotate the rest shape rigidly and put the body there at rest.
    const double a = 0.7, ca = std::cos(a), sa = std::sin(a);
    std::vector<double> x(def.mesh.positions);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
      const double px = x[3 * n], py = x[3 * n + 1];
      x[3 * n] = ca * px - sa * py + 0.3;
      x[3 * n + 1] = sa * px + ca * py - 0.1;
    }
    ASSERT_TRUE(world.setPositions(id.value(), x).ok());
    ASSERT_TRUE(world.setVelocity(id.value(), glm::dvec3(0)).ok());
    (void)world.step(1e-2);
    double worst = 0;
    for (double v : world.velocities(id.value())) worst = std::max(worst, std::abs(v));
    std::printf("rotated fractured body, model %d: max speed after a step %.3e m/s\n", int(model),
                worst);
    EXPECT_LT(worst, 1e-9);
  }
}

// Volume of the tets whose nodes all lie in one fragment, plus split tets counted per node.
TEST(Fracture, PlanarCutSplitsCylinderInTwoWithVolumesAddingUp) {
  BodyDef def;
  def.mesh = gen::cylinder(0.2, 0.6, 16, 12, 3);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.fracture.enabled = true;
  def.fracture.strength = 1e9;
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  ASSERT_TRUE(id.ok());
  Blade blade;  // oblique plane through the middle of the cylinder (axis y)
  blade.vertices = {{-1, 0.25f, -1}, {1, 0.35f, -1}, {1, 0.35f, 1}, {-1, 0.25f, 1}};
  blade.triangles = {0, 1, 2, 0, 2, 3};
  ASSERT_TRUE(world.cut(id.value(), blade).ok());
  (void)world.step(1e-3);
  EXPECT_EQ(world.fractureStats(id.value()).fragments, 2);
  ASSERT_EQ(world.fragmentEvents().size(), 1u);
  // Fragment volumes from the nodes' corner cells (V/4 of each incident tet) must add up to
  // the mesh volume; compute the split independently from the node fragments.
  const auto frag = world.nodeFragments(id.value());
  double vol[2] = {0, 0};
  for (size_t t = 0; t < def.mesh.tetCount(); ++t) {
    const int32_t* tet = &def.mesh.tets[4 * t];
    const double* p0 = &def.mesh.positions[3 * tet[0]];
    double d[3][3];
    for (int k = 0; k < 3; ++k)
      for (int i = 0; i < 3; ++i) d[k][i] = def.mesh.positions[3 * tet[k + 1] + i] - p0[i];
    const double v6 = d[0][0] * (d[1][1] * d[2][2] - d[1][2] * d[2][1]) -
                      d[0][1] * (d[1][0] * d[2][2] - d[1][2] * d[2][0]) +
                      d[0][2] * (d[1][0] * d[2][1] - d[1][1] * d[2][0]);
    for (int a = 0; a < 4; ++a) vol[frag[tet[a]]] += v6 / 24;
  }
  const double total = def.mesh.volume();
  EXPECT_NEAR(vol[0] + vol[1], total, 1e-12 * total);
  const FragmentEvent& ev = world.fragmentEvents()[0];
  EXPECT_NEAR(ev.volume, vol[ev.fragment], 1e-9 * total);
  // The oblique plane at mid-height splits the volume roughly in half.
  EXPECT_NEAR(vol[1] / total, 0.5, 0.1);
  std::printf("cylinder cut: volumes %.6e + %.6e = %.6e (mesh %.6e)\n", vol[0], vol[1],
              vol[0] + vol[1], total);
}

// Projection model: a body cut in two and pressed together keeps its length (the broken edges
// still resist compression), where it would collapse if the crack carried nothing.
TEST(Fracture, ClosedCrackResistsCompression) {
  const double L = 0.4;
  BodyDef def;
  def.mesh = gen::box(L, 0.1, 0.1, 8, 2, 2);
  def.material = Material::stableNeoHookean(1e5, 0.3, 1000);
  def.material.massDamping = 5;
  def.fracture.enabled = true;
  def.fracture.strength = 1e9;
  def.fracture.model = DamageModel::Projection;
  Grip left, right;
  left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes = test::selectNodes(def.mesh, [&](double x, double, double) { return x > L - 1e-9; });
  const float speed = 0.02f;  // 10 % compression over 1 s
  left.velocity = glm::vec3(speed, 0, 0);
  right.velocity = glm::vec3(-speed, 0, 0);
  def.grips = {left, right};
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  ASSERT_TRUE(id.ok());
  Blade blade;
  blade.vertices = {{0.21f, -1, -1}, {0.21f, 1, -1}, {0.21f, 1, 1}, {0.21f, -1, 1}};
  blade.triangles = {0, 1, 2, 0, 2, 3};
  ASSERT_TRUE(world.cut(id.value(), blade).ok());
  for (int s = 0; s < 100; ++s) (void)world.step(1e-2);
  EXPECT_EQ(world.fractureStats(id.value()).fragments, 2);
  // Nodes left of the cut must stay left of the nodes right of it (no interpenetration), and
  // the compression spreads evenly: the cut plane's neighbours moved with the affine field.
  const auto x = world.positions(id.value());
  const auto frag = world.nodeFragments(id.value());
  double maxLeft = -1e9, minRight = 1e9;
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    if (frag[n] == frag[0])
      maxLeft = std::max(maxLeft, x[3 * n]);
    else
      minRight = std::min(minRight, x[3 * n]);
  }
  std::printf("closed crack: left piece ends at %.5f, right piece starts at %.5f\n", maxLeft,
              minRight);
  EXPECT_LE(maxLeft, minRight + 1e-4);
  EXPECT_TRUE(test::stateFinite(world, id.value()));
}

// Projection model: a bar cut across with one end held lets the other piece fall past the crack
// face as a free body falls (implicit Euler: y_n = -g dt^2 n (n + 1) / 2). Before split tets
// could slide, touching crack faces were locked in shear and the piece hung in the air (6.7 mm
// of 213 mm here). The cut runs between two node layers, so the crack is flat; on an oblique
// cut through the mesh it is rough at the cell scale and a piece may rest on its treads
// (docs/validation.md). Bars along x and z, two resolutions (direct solver and multigrid),
// two time steps, a compressible and a nearly incompressible material.
TEST(Fracture, CutPieceSlidesOffTheCrackFaceInFreeFall) {
  const double L = 0.4, duration = 0.2;
  for (const double nu : {0.3, 0.499})
    for (const int axis : {0, 2})
      for (const int cells : {2, 4})  // 81 nodes (direct solver) and 425 (multigrid)
        for (const double dt : {1.0 / 60, 1.0 / 30}) {
          const int steps = int(std::lround(duration / dt));
          const double fall = 9.81 * dt * dt * steps * (steps + 1) / 2;
          BodyDef def;
          def.mesh = axis == 0 ? gen::box(L, 0.1, 0.1, 4 * cells, cells, cells)
                               : gen::box(0.1, 0.1, L, cells, cells, 4 * cells);
          def.material = Material::stableNeoHookean(1e8, nu, 1000);
          def.fracture.enabled = true;
          def.fracture.strength = 1e12;
          def.fracture.model = DamageModel::Projection;
          Grip held;
          held.nodes = test::selectNodes(
              def.mesh, [&](double x, double, double z) { return (axis == 0 ? x : z) < 1e-9; });
          def.grips = {held};
          World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
          auto id = world.createBody(def);
          ASSERT_TRUE(id.ok());
          // The plane (axis) = 0.21 m, between node layers at both resolutions.
          Blade blade;
          for (const float u : {-1.0f, 1.0f})
            for (const float y : {-1.0f, 1.0f}) {
              glm::vec3 v(u, y, u);
              v[axis] = 0.21f;
              blade.vertices.push_back(v);
            }
          blade.triangles = {0, 1, 3, 0, 3, 2};
          ASSERT_TRUE(world.cut(id.value(), blade).ok());
          const auto start = world.positions(id.value());
          const std::vector<double> x0(start.begin(), start.end());
          for (int s = 0; s < steps; ++s) (void)world.step(dt);
          ASSERT_EQ(world.fractureStats(id.value()).fragments, 2);
          const auto x = world.positions(id.value());
          const auto frag = world.nodeFragments(id.value());
          double dropFree = 0, dropHeld = 0;
          int nFree = 0;
          for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
            const double dy = x[3 * n + 1] - x0[3 * n + 1];
            if (frag[n] == frag[0]) {
              dropHeld = std::min(dropHeld, dy);
            } else {
              dropFree += dy;
              ++nFree;
            }
          }
          dropFree /= nFree;
          std::printf(
              "nu %.3f, cut across %c, %d cells across, dt %.4f: free piece (%d nodes) fell %.6f "
              "m (free fall %.6f), held piece %.2e m\n",
              nu, "xyz"[axis], cells, dt, nFree, -dropFree, fall, -dropHeld);
          EXPECT_NEAR(-dropFree, fall, 1e-3 * fall);
          EXPECT_LT(-dropHeld, 0.01 * fall);
          EXPECT_TRUE(test::stateFinite(world, id.value()));
        }
}

// Projection model: a column cut across between two node layers and tilted by alpha, its foot
// held: the piece above the cut rests on an incline made by the crack itself, and slides down
// it as a frictionless block does, at g sin(alpha) (implicit Euler: s_n = a dt^2 n (n + 1) / 2;
// the crack faces carry no friction). Measured over the first 1-3 mm, under 6 % of the cell:
// the sliding branch's contact is a plane only for slides small against the cell (design.md).
TEST(Fracture, CutPieceSlidesDownItsCrackAsAFrictionlessBlock) {
  const double dt = 1e-3;
  const int steps = 30;
  for (const double alphaDeg : {15.0, 30.0, 45.0}) {
    const double alpha = alphaDeg * M_PI / 180;
    BodyDef def;
    def.mesh = gen::box(0.2, 0.4, 0.2, 4, 8, 4);
    Grip foot;
    foot.nodes = test::selectNodes(def.mesh, [](double, double y, double) { return y < 1e-9; });
    def.grips = {foot};
    const std::vector<int32_t> top =
        test::selectNodes(def.mesh, [](double, double y, double) { return y > 0.31; });
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
      const double x = def.mesh.positions[3 * n], y = def.mesh.positions[3 * n + 1];
      def.mesh.positions[3 * n] = x * std::cos(alpha) - y * std::sin(alpha);
      def.mesh.positions[3 * n + 1] = x * std::sin(alpha) + y * std::cos(alpha);
    }
    def.material = Material::stableNeoHookean(1e8, 0.3, 1000);
    def.fracture.enabled = true;
    def.fracture.strength = 1e12;
    def.fracture.model = DamageModel::Projection;
    World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
    auto id = world.createBody(def);
    ASSERT_TRUE(id.ok());
    // The cut: the rest plane y = 0.31 (between node layers), turned with the column.
    Blade blade;
    for (const float u : {-2.0f, 2.0f})
      for (const float z : {-2.0f, 2.0f}) {
        const double x = u, y = 0.31;
        blade.vertices.push_back({float(x * std::cos(alpha) - y * std::sin(alpha)),
                                  float(x * std::sin(alpha) + y * std::cos(alpha)), z});
      }
    blade.triangles = {0, 1, 3, 0, 3, 2};
    ASSERT_TRUE(world.cut(id.value(), blade).ok());
    const auto downhill = [&]() {
      const auto x = world.positions(id.value());
      double s = 0;
      for (int32_t n : top) s -= x[3 * n] * std::cos(alpha) + x[3 * n + 1] * std::sin(alpha);
      return s / double(top.size());
    };
    const double s0 = downhill();
    for (int k = 0; k < steps; ++k) (void)world.step(dt);
    const double s = downhill() - s0;
    const double expected = 9.81 * std::sin(alpha) * dt * dt * steps * (steps + 1) / 2;
    std::printf("crack incline %.0f deg: slid %.4e m, frictionless block %.4e m (%+.2f %%)\n",
                alphaDeg, s, expected, 100 * (s / expected - 1));
    EXPECT_EQ(world.fractureStats(id.value()).fragments, 2);
    EXPECT_NEAR(s, expected, 0.05 * expected);
    EXPECT_TRUE(test::stateFinite(world, id.value()));
  }
}

// Every edge broken at once: planes midway between the node layers of a 3x3x3-cell box cross
// every edge, so each node becomes a fragment of its own. The pieces fall and land; nothing
// may become non-finite or gain energy.
TEST(Fracture, EveryEdgeBrokenAtOnceStaysFiniteAndBounded) {
  Blade blade;
  for (int axis = 0; axis < 3; ++axis)
    for (int i = 0; i < 3; ++i) {
      const float c = 0.05f + 0.1f * float(i) + (axis == 1 ? 0.2f : 0.0f);
      const uint32_t base = uint32_t(blade.vertices.size());
      for (int k = 0; k < 4; ++k) {
        glm::vec3 v;
        v[axis] = c;
        v[(axis + 1) % 3] = (k == 1 || k == 2) ? 2.0f : -2.0f;
        v[(axis + 2) % 3] = (k >= 2) ? 2.0f : -2.0f;
        blade.vertices.push_back(v);
      }
      for (uint32_t t : {0u, 1u, 2u, 0u, 2u, 3u}) blade.triangles.push_back(base + t);
    }
  for (DamageModel model : {DamageModel::Projection, DamageModel::Degradation}) {
    for (double dt : {1.0 / 60, 5e-2}) {
      BodyDef def;
      def.mesh = gen::box(0.3, 0.3, 0.3, 3, 3, 3);
      for (size_t n = 0; n < def.mesh.nodeCount(); ++n) def.mesh.positions[3 * n + 1] += 0.2;
      def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
      def.fracture.enabled = true;
      def.fracture.strength = 1e4;
      def.fracture.model = model;
      WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
      wd.colliders.push_back(Collider{});
      World world(wd);
      auto id = world.createBody(def);
      ASSERT_TRUE(id.ok());
      ASSERT_TRUE(world.cut(id.value(), blade).ok());
      const double E0 = test::totalEnergy(world.stats(id.value()));
      double maxE = E0;
      for (int s = 0; s < 60; ++s) {
        (void)world.step(dt);
        maxE = std::max(maxE, test::totalEnergy(world.stats(id.value())));
      }
      const FractureStats fs = world.fractureStats(id.value());
      std::printf(
          "all edges, model %d dt %.3f: %d of %d broken, %d fragments, E0 %.3f J, max E"
          " %.3f J\n",
          int(model), dt, fs.brokenEdges, fs.edgeCount, fs.fragments, E0, maxE);
      EXPECT_TRUE(test::stateFinite(world, id.value()));
      EXPECT_EQ(fs.brokenEdges, fs.edgeCount);
      EXPECT_EQ(fs.fragments, int32_t(def.mesh.nodeCount()));
      EXPECT_LE(maxE, E0 + 1e-6 * std::abs(E0) + 1e-9);
    }
  }
}

}  // namespace
}  // namespace gf

namespace gf {
namespace {

// Doormat-like tearing (fig 4.4): a thin slab whose bottom edge is pulled apart at the middle
// opens a mode-I tear. Broken edges after 2 s, for R_d = 0, 2, 5 mean edge lengths: the local
// criterion cuts a narrow tear (and sheds debris), averaging spreads the damage wider.
int32_t tearSlab(double radius, int32_t* fragments) {
  const double L = 0.8, W = 0.4;
  BodyDef def;
  def.mesh = gen::slab(L, W, 0.02, 32, 16);
  def.material = Material::stableNeoHookean(1e6, 0.3, 300);
  def.material.massDamping = 2;
  def.fracture.enabled = true;
  def.fracture.strength = 3e4;
  def.fracture.radius = radius;
  Grip left, right;
  left.nodes = test::selectNodes(
      def.mesh, [&](double x, double, double z) { return z < 1e-9 && x < 0.5 * L - 1e-9; });
  right.nodes = test::selectNodes(
      def.mesh, [&](double x, double, double z) { return z < 1e-9 && x > 0.5 * L + 1e-9; });
  left.velocity = glm::vec3(-0.1f, 0, 0);
  right.velocity = glm::vec3(0.1f, 0, 0);
  def.grips = {left, right};
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok());
  for (int s = 0; s < 120; ++s) (void)world.step(1.0 / 60);
  EXPECT_TRUE(test::stateFinite(world, id.value()));
  *fragments = world.fractureStats(id.value()).fragments;
  return world.fractureStats(id.value()).brokenEdges;
}

TEST(Fracture, BrokenEdgesGrowWithNonLocalRadius) {
  int32_t f0 = 0, f2 = 0, f5 = 0;
  const int32_t b0 = tearSlab(0, &f0), b2 = tearSlab(2, &f2), b5 = tearSlab(5, &f5);
  std::printf("doormat tear: broken edges R_d=0: %d, R_d=2: %d, R_d=5: %d (fragments %d %d %d)\n",
              b0, b2, b5, f0, f2, f5);
  EXPECT_GT(b0, 0);
  EXPECT_LT(b0, b2);
  EXPECT_LT(b2, b5);
}

// Brittle mode (fig 4.19): more crack regions, more debris.
int32_t shatterBar(int regions) {
  BodyDef def;
  def.mesh = gen::box(1.0, 0.1, 0.1, 40, 4, 4);
  def.material = Material::stableNeoHookean(1e7, 0.2, 2500);
  def.fracture.enabled = true;
  def.fracture.strength = 1e5;
  def.fracture.brittle = true;
  def.fracture.regions = regions;
  Grip left, right;
  left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x > 1 - 1e-9; });
  left.velocity = glm::vec3(-0.05f, 0, 0);
  right.velocity = glm::vec3(0.05f, 0, 0);
  def.grips = {left, right};
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok());
  for (int s = 0; s < 40; ++s) (void)world.step(1.0 / 60);
  EXPECT_TRUE(test::stateFinite(world, id.value()));
  const FractureStats st = world.fractureStats(id.value());
  std::printf("brittle bar, %d regions: %d fragments, %d of them chips\n", regions, st.fragments,
              st.chips);
  EXPECT_GE(st.fragments, 2);
  return st.fragments - st.chips;
}

// Pieces (fragments with a whole tet): the loose nodes the planes used to leave counted as
// fragments too, and the criterion's breaks at the grips still leave some.
TEST(Fracture, MoreBrittleRegionsMakeMoreFragments) {
  const int32_t f1 = shatterBar(1), f3 = shatterBar(3), f6 = shatterBar(6);
  std::printf("brittle bar: pieces with 1 / 3 / 6 regions: %d / %d / %d\n", f1, f3, f6);
  EXPECT_GE(f1, 1);
  EXPECT_GT(f3, f1);
  EXPECT_GT(f6, f3);
}

}  // namespace
}  // namespace gf

namespace gf {
namespace {

// Plasticity (eq 2.3-2.5): a free bar released from a 20 % stretch springs back to its rest
// length when elastic, and keeps a permanent set when its stress exceeded the yield stress.
double settledLength(bool plastic) {
  BodyDef def;
  def.mesh = gen::box(0.5, 0.1, 0.1, 10, 2, 2);
  def.material = Material::stableNeoHookean(1e5, 0.3, 1000);
  def.material.massDamping = 20;
  def.plasticity.enabled = plastic;
  def.plasticity.yieldStress = 5e3;  // the stretch gives about 2e4 Pa
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok());
  std::vector<double> x(def.mesh.positions);
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) x[3 * n] *= 1.2;
  EXPECT_TRUE(world.setPositions(id.value(), x).ok());
  for (int s = 0; s < 300; ++s) (void)world.step(1.0 / 60);
  EXPECT_TRUE(test::stateFinite(world, id.value()));
  const auto p = world.positions(id.value());
  double lo = 1e9, hi = -1e9;
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    lo = std::min(lo, p[3 * n]);
    hi = std::max(hi, p[3 * n]);
  }
  return hi - lo;
}

TEST(Plasticity, YieldedBarKeepsAPermanentSet) {
  const double elastic = settledLength(false), plastic = settledLength(true);
  std::printf(
      "bar released from 20 %% stretch: elastic settles at %.4f m, plastic at %.4f m "
      "(rest 0.5 m)\n",
      elastic, plastic);
  EXPECT_NEAR(elastic, 0.5, 1e-3);
  EXPECT_GT(plastic, 0.5 + 0.01);  // a permanent set of more than 2 %
  EXPECT_LT(plastic, 0.6);         // but not more than the imposed stretch
}

}  // namespace
}  // namespace gf

namespace gf {
namespace {

// Steel (A516 Gr.70 at -40 C, SPEC §7: E 2.2e11, nu 0.28, rho 7700, sigma_th 6.55e8) torn apart
// by grips moving 0.5 m/s: it breaks and stays finite, and the fragments' kinetic energy is
// bounded by what can feed it: the strain energy the bar holds at sigma_th (1/2 sigma^2 / E per
// volume), the grips' speed and gravity over the run.
// shift > 0 moves every node's start by up to that fraction of its coordinates, a fixed
// pseudo-random pattern per seed: a last-bit change of the kind round-off makes.
double steelTearMaxKinetic(DamageModel model, int substeps, double* bound, int* fragments,
                           double shift = 0, uint32_t seed = 0,
                           LinearSolverKind solver = LinearSolverKind::Multigrid) {
  BodyDef def;
  def.solver.linearSolver = solver;
  def.mesh = gen::box(0.2, 0.02, 0.02, 20, 2, 2);
  def.material = Material::stableNeoHookean(2.2e11, 0.28, 7700);
  def.fracture.enabled = true;
  def.fracture.strength = 6.55e8;
  def.fracture.model = model;
  const float speed = 0.5f;
  Grip left, right;
  left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes =
      test::selectNodes(def.mesh, [](double x, double, double) { return x > 0.2 - 1e-9; });
  left.velocity = glm::vec3(-speed, 0, 0);
  right.velocity = glm::vec3(speed, 0, 0);
  def.grips = {left, right};
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, substeps, {}});
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok());
  if (shift > 0) {
    std::vector<double> x(def.mesh.positions);
    uint64_t state = 0x9E3779B97F4A7C15ull * (seed + 1);
    for (double& c : x) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      const double u = double(state >> 11) * 0x1.0p-53;  // [0, 1)
      c += (2 * u - 1) * shift * c;
    }
    EXPECT_TRUE(world.setPositions(id.value(), x).ok());
  }
  double maxKe = 0;
  for (int s = 0; s < 60; ++s) {
    (void)world.step(1.0 / 60);
    maxKe = std::max(maxKe, world.stats(id.value()).kineticEnergy);
  }
  EXPECT_TRUE(test::stateFinite(world, id.value()));
  const double mass = world.stats(id.value()).mass, volume = def.mesh.volume();
  *bound = 0.5 * 6.55e8 * 6.55e8 / 2.2e11 * volume + 0.5 * mass * (speed * speed + 9.81 * 9.81);
  *fragments = world.fractureStats(id.value()).fragments;
  return maxKe;
}

TEST(Fracture, SteelTornAtGameTimeStepStaysBounded) {
  struct Case {
    DamageModel model;
    int substeps;
  };
  // The projection model once threw this tear's fragments too fast at 60 Hz (up to three
  // times the bound, docs/validation.md): its energy had a ridge where a broken edge switched
  // between tension and compression (kernels/damage.h). It runs with substeps and without.
  for (Case c : {Case{DamageModel::Degradation, 1}, Case{DamageModel::Projection, 8},
                 Case{DamageModel::Projection, 1}}) {
    double bound = 0;
    int fragments = 0;
    const double ke = steelTearMaxKinetic(c.model, c.substeps, &bound, &fragments);
    std::printf(
        "steel tear, model %d, %d substep(s) at 60 Hz: %d fragments, max KE %.3e J "
        "(bound %.3e J)\n",
        int(c.model), c.substeps, fragments, ke, bound);
    EXPECT_GE(fragments, 2);
    EXPECT_LT(ke, bound);
  }
}

// The same tear from starts shifted by 1e-15..1e-12 of their coordinates (issue 19). A patch
// that changed only the Hessians' round-off threw the projection model's fragments at 1.04e5 J;
// from shifted starts the plain run did the same in 4 of 12 multigrid, 12 of 12 PCG and 12 of 12
// direct-solver runs (up to 5e8 J): an open-crack Newton step thousands of metres long, of
// which the line search accepted a fraction. CI runs two shifted starts per model and solver;
// GF_FULL_VALIDATION=1 runs three shifts x four seeds.
struct TearCase {
  DamageModel model;
  LinearSolverKind solver;
  double shift;
  uint32_t seed;
};

std::vector<TearCase> perturbedTearCases() {
  const bool full = std::getenv("GF_FULL_VALIDATION") != nullptr;
  std::vector<std::pair<double, uint32_t>> starts;
  if (full) {
    for (double shift : {1e-15, 1e-13, 1e-12})
      for (uint32_t seed = 0; seed < 4; ++seed) starts.push_back({shift, seed});
  } else {
    starts = {{1e-15, 0}, {1e-12, 3}};  // both threw the multigrid run before the fix
  }
  std::vector<TearCase> cases;
  for (DamageModel model : {DamageModel::Projection, DamageModel::Degradation})
    for (LinearSolverKind solver :
         {LinearSolverKind::Multigrid, LinearSolverKind::PCG, LinearSolverKind::Direct})
      for (auto [shift, seed] : starts) cases.push_back({model, solver, shift, seed});
  return cases;
}

void PrintTo(const TearCase& c, std::ostream* os) {
  *os << "model " << int(c.model) << ", solver " << int(c.solver) << ", shift " << c.shift
      << ", seed " << c.seed;
}

class PerturbedSteelTear : public ::testing::TestWithParam<TearCase> {};

TEST_P(PerturbedSteelTear, StaysBounded) {
  const TearCase c = GetParam();
  double bound = 0;
  int fragments = 0;
  const double ke = steelTearMaxKinetic(c.model, 1, &bound, &fragments, c.shift, c.seed, c.solver);
  std::printf(
      "steel tear, model %d, solver %d, start shifted %.0e (seed %u): %d fragments, max KE "
      "%.3e J (bound %.3e J)\n",
      int(c.model), int(c.solver), c.shift, c.seed, fragments, ke, bound);
  EXPECT_GE(fragments, 2);
  EXPECT_LT(ke, bound);
}

std::string tearName(const ::testing::TestParamInfo<TearCase>& info) {
  const TearCase& c = info.param;
  const char* solver = c.solver == LinearSolverKind::Multigrid ? "multigrid"
                       : c.solver == LinearSolverKind::PCG     ? "pcg"
                                                               : "direct";
  return std::string(c.model == DamageModel::Projection ? "projection_" : "degradation_") + solver +
         "_shift" + std::to_string(int(std::lround(-std::log10(c.shift)))) + "_seed" +
         std::to_string(c.seed);
}

INSTANTIATE_TEST_SUITE_P(Fracture, PerturbedSteelTear, ::testing::ValuesIn(perturbedTearCases()),
                         tearName);
// The direct solver's projection run reached 154 J from every shifted start after the retry
// (docs/validation.md): a single Newton step the line search took whole turned the step's stored
// energy into motion. Since a cracked step whose decrease falls short of its Newton model's goes
// on (Integrator::solve, kModelAgreement) it stays at 12.3 J from all twelve starts.

}  // namespace
}  // namespace gf

namespace gf {
namespace {

// The render surface must stay on the material. The glass bunny of scenes/glass_bunny.json
// (thesis fig 4.14) shatters against a ball; every surface vertex lies in a corner cell of its
// node, so it can be no farther from that node than the node's longest current edge, plus the
// error of the frame that places vertices of partly cracked cells. Frames fitted to thin or
// torn neighbourhoods once threw vertices metres away (large orange spikes in the demo). A
// node's reach is its longest edge, at rest or now (vertices of a frame that only rotates
// keep their rest offsets).
TEST(Fracture, ShatteredSurfaceStaysOnTheMaterial) {
  Result<TetMesh> mesh = TetMesh::fromFile(GF_SOURCE_DIR "/scenes/meshes/bunny_small.msh");
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  BodyDef def;
  def.mesh = std::move(mesh.value());
  for (double& p : def.mesh.positions) p *= 0.03;
  test::makeTableGlass(def);
  def.initialVelocity = glm::vec3(-20, 0, 0);
  Collider ball;
  ball.kind = Collider::Kind::Sphere;
  ball.point = glm::vec3(-0.26f, 0.12f, 0);
  ball.radius = 0.08f;
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {ball}});
  const BodyId id = world.createBody(def).value();
  const std::vector<int32_t>& tets = def.mesh.tets;
  double worst = 0;
  for (int s = 0; s < 30; ++s) {
    (void)world.step(1e-3);
    const std::span<const double> x = world.positions(id);
    // Longest edge at each node, at rest or now.
    std::vector<double> reach(x.size() / 3, 0.0);
    for (size_t t = 0; t < tets.size() / 4; ++t)
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) {
          const size_t i = size_t(tets[4 * t + a]), j = size_t(tets[4 * t + b]);
          const double* X = def.mesh.positions.data();
          const double d =
              std::max(glm::length(glm::dvec3(x[3 * i] - x[3 * j], x[3 * i + 1] - x[3 * j + 1],
                                              x[3 * i + 2] - x[3 * j + 2])),
                       glm::length(glm::dvec3(X[3 * i] - X[3 * j], X[3 * i + 1] - X[3 * j + 1],
                                              X[3 * i + 2] - X[3 * j + 2])));
          reach[i] = std::max(reach[i], d);
          reach[j] = std::max(reach[j], d);
        }
    const SurfaceView sv = world.surface(id);
    for (size_t v = 0; v < sv.vertexNode.size(); ++v) {
      const size_t n = size_t(sv.vertexNode[v]);
      const double d = glm::length(glm::dvec3(sv.positions[3 * v] - x[3 * n],
                                              sv.positions[3 * v + 1] - x[3 * n + 1],
                                              sv.positions[3 * v + 2] - x[3 * n + 2]));
      worst = std::max(worst, d / reach[n]);
    }
  }
  const FractureStats f = world.fractureStats(id);
  std::printf("bunny: %d broken edges, %d fragments; worst vertex distance / node reach %.3f\n",
              f.brokenEdges, f.fragments, worst);
  EXPECT_GT(f.fragments, 1);
  EXPECT_LT(worst, 2.0);
}

}  // namespace
}  // namespace gf

namespace gf {
namespace {

// Thesis Table 4.1's solid glass (StVK, E = 1e10 Pa, nu = 0.45, rho = 1e3, sigma_th = 5e7 Pa,
// brittle, 8 regions), a 16 x 8 x 8 cm block thrown at 20 m/s and spinning at 10 rad/s, one
// second of flight at 60 Hz. Its real centrifugal stress is about rho w^2 r^2 / 2 = 0.3 Pa; a
// step that stretched it by (w dt)^2 / 2 = 1.4 % would see 1.4e8 Pa and shatter it.
int glassBrokenInFlight(bool corotatedInertia) {
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  BodyDef def;
  def.mesh = gen::box(0.16, 0.08, 0.08, 8, 4, 4);
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
    for (int a = 0; a < 3; ++a) def.mesh.positions[3 * n + a] -= a == 0 ? 0.08 : 0.04;
  test::makeTableGlass(def);
  def.solver.corotatedInertia = corotatedInertia;
  const BodyId id = world.createBody(def).value();
  std::vector<double> v(def.mesh.positions.size());
  for (size_t n = 0; n < v.size() / 3; ++n) {
    const double x = def.mesh.positions[3 * n], y = def.mesh.positions[3 * n + 1];
    v[3 * n] = -20 - 10 * y;  // w = 10 rad/s about z
    v[3 * n + 1] = 10 * x;
  }
  EXPECT_TRUE(world.setVelocities(id, v).ok());
  for (int s = 0; s < 60; ++s) EXPECT_TRUE(world.step(1.0 / 60).ok());
  return world.fractureStats(id).brokenEdges;
}

TEST(Fracture, SpinningGlassStaysWholeInFlight) {
  const int turning = glassBrokenInFlight(true), plain = glassBrokenInFlight(false);
  std::printf(
      "glass thrown spinning at 10 rad/s, 1 s at 60 Hz: %d edges broken in the turning "
      "frame, %d with plain backward Euler\n",
      turning, plain);
  EXPECT_EQ(turning, 0);
  EXPECT_GT(plain, 0);  // the test sees the stretch it guards against
}

// A piece handed to rigid physics moves by its prescribed rigid velocity field between the
// game's transform updates: after k steps its nodes have gone k dt (v + w x r) along straight
// lines, a stretch of about (k w dt)^2 / 2 that is no load (the element pass gives its tets
// no strain and no stress, docs/design.md "Pieces in Bullet"). The criterion must not break
// the piece's edges on it. Returns the edges inside the piece (both ends in it) broken after
// it went to rigid physics; `fragmentsAfter` gets the body's fragments at the end.
int32_t edgesBrokenInSpinningPiece(DamageModel model, double spin, int32_t* fragmentsAfter) {
  BodyDef def;
  def.mesh = gen::box(0.2, 0.1, 0.1, 8, 4, 4);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.fracture.enabled = true;
  def.fracture.strength = 2e4;  // a strain of about 2 %
  def.fracture.model = model;
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(def).value();
  Blade blade;  // the plane x = 0.1025, between the node layers at 0.1 and 0.125
  blade.vertices = {{0.1025f, -1, -1}, {0.1025f, 1, -1}, {0.1025f, 1, 1}, {0.1025f, -1, 1}};
  blade.triangles = {0, 1, 2, 0, 2, 3};
  EXPECT_TRUE(world.cut(id, blade).ok());
  (void)world.step(1e-3);
  EXPECT_EQ(world.fractureStats(id).fragments, 2);
  // The piece at x > 0.1 goes to rigid physics, spinning about the x axis through its centre
  // (its nodes stay in their planes x = const); the game does not update its transform for 30
  // steps of 1 ms (at 50 rad/s a 1.5 rad turn, ~100 % stretch).
  const std::vector<int32_t> fragmentOf(world.nodeFragments(id).begin(),
                                        world.nodeFragments(id).end());
  const int32_t piece = fragmentOf.back();
  const std::vector<uint8_t> before(world.brokenEdges(id).begin(), world.brokenEdges(id).end());
  EXPECT_TRUE(world.detachFragment(id, piece).ok());
  EXPECT_TRUE(world
                  .setFragmentTransform(id, piece, glm::dvec3(0), glm::dquat(1, 0, 0, 0),
                                        glm::dvec3(0), glm::dvec3(spin, 0, 0))
                  .ok());
  for (int s = 0; s < 30; ++s) (void)world.step(1e-3);
  *fragmentsAfter = world.fractureStats(id).fragments;
  const std::span<const int32_t> edges = world.edges(id);
  const std::span<const uint8_t> broken = world.brokenEdges(id);
  int32_t inside = 0;
  for (size_t e = 0; e < broken.size(); ++e)
    inside += broken[e] && !before[e] && fragmentOf[size_t(edges[2 * e])] == piece &&
              fragmentOf[size_t(edges[2 * e + 1])] == piece;
  return inside;
}

TEST(Fracture, PieceInRigidPhysicsDoesNotCrackFromItsPrescribedMotion) {
  for (const DamageModel model : {DamageModel::Projection, DamageModel::Degradation})
    for (const double spin : {5.0, 50.0}) {
      int32_t fragments = 0;
      const int32_t broken = edgesBrokenInSpinningPiece(model, spin, &fragments);
      std::printf(
          "%s model, piece spun at %g rad/s for 30 ms between transform updates: %d "
          "of its edges broken, %d fragments in the body\n",
          model == DamageModel::Projection ? "projection" : "degradation", spin, broken, fragments);
      EXPECT_EQ(broken, 0) << spin;
    }
}

}  // namespace
}  // namespace gf
