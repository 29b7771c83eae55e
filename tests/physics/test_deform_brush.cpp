// The deform brush (thesis sec 7.2.3.4, eq 7.7): a sphere tool pressed into a free clay block.
// Without the brush the whole block is shoved away; with it the block gives way around the
// tool and its far side barely moves. With plasticity the dent stays after the tool leaves;
// without it the block springs back, so the shape is kept by the material, not by the damping.
#include <graphfrac/world.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <glm/geometric.hpp>
#include <string>
#include <vector>

#include "common/mesh_checks.h"
#include "common/temp_dir.h"
#include "kernels/clay.h"

namespace gf {
namespace {

TEST(DeformBrush, KernelIsOneAtTheToolAndFallsWithDistance) {
  const double rD = 0.03, k1 = 30, k2 = 30;
  EXPECT_EQ(clayDamping(0, rD, k1, k2), 1.0);
  double last = 1;
  for (int i = 1; i <= 200; ++i) {
    const double r = 0.001 * i, g = clayDamping(r, rD, k1, k2);
    EXPECT_LT(g, last) << r;
    EXPECT_GT(g, 0);
    // Beyond R_D the exp term holds the body harder than the inner law would.
    if (r >= rD) {
      EXPECT_LT(g, 1 / (1 + k1 * r));
    }
    last = g;
  }
}

constexpr double kDt = 1.0 / 60;
constexpr float kSide = 0.1f;

struct Press {
  double dentMax = 0, dentEnd = 0;  // top centre below the top face's rim [m]
  double farMove = 0;               // mean displacement of the bottom face at the press's end
  double nearMove = 0;              // displacement of the top centre at the press's end
};

Press pressClay(bool brush, bool plastic, const std::function<void(World&, BodyId)>& atEnd = {}) {
  BodyDef def;
  def.mesh = gen::box(kSide, kSide, kSide, 6, 6, 6);
  def.material = Material::stableNeoHookean(1e5, 0.3, 1800);
  def.plasticity.enabled = plastic;
  def.plasticity.yieldStress = 2e3;
  Collider tool;
  tool.kind = Collider::Kind::Sphere;
  tool.radius = 0.02f;
  tool.point = {0.05f, kSide + tool.radius, 0.05f};
  tool.velocity = {0, -0.03f, 0};
  WorldDef wd;
  wd.gravity = {0, 0, 0};
  wd.colliders.push_back(tool);
  World world(wd);
  const BodyId id = world.createBody(def).value();
  const std::vector<double> rest(world.positions(id).begin(), world.positions(id).end());
  std::vector<int32_t> top, rim, bottom;
  int32_t centre = -1;
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    const double x = rest[3 * n], y = rest[3 * n + 1], z = rest[3 * n + 2];
    if (y < 1e-9) bottom.push_back(int32_t(n));
    if (std::abs(y - kSide) > 1e-9) continue;
    if (std::abs(x - 0.05) < 1e-9 && std::abs(z - 0.05) < 1e-9) centre = int32_t(n);
    if (x < 1e-9 || z < 1e-9 || x > kSide - 1e-9 || z > kSide - 1e-9) rim.push_back(int32_t(n));
  }
  EXPECT_GE(centre, 0);
  const auto dent = [&] {
    const std::span<const double> x = world.positions(id);
    double rimY = 0;
    for (int32_t n : rim) rimY += x[3 * size_t(n) + 1];
    return rimY / double(rim.size()) - x[3 * size_t(centre) + 1];
  };
  const auto step = [&] {
    if (brush) {
      DeformBrush b;
      b.centre = world.colliders()[0].point;
      b.radius = 0.03f;
      b.k1 = 30;
      b.k2 = 30;
      EXPECT_TRUE(world.deform(id, b).ok());
    }
    EXPECT_TRUE(world.step(kDt).ok());
  };
  Press r;
  for (int k = 0; k < 40; ++k) step();  // 2 cm down: 1.3 cm into the top
  {
    const std::span<const double> x = world.positions(id);
    for (int32_t n : bottom)
      for (int i = 0; i < 3; ++i) {
        const double d = x[3 * size_t(n) + size_t(i)] - rest[3 * size_t(n) + size_t(i)];
        r.farMove += d * d;
      }
    r.farMove = std::sqrt(r.farMove / double(bottom.size()));
    const size_t c = 3 * size_t(centre);
    r.nearMove = std::hypot(x[c] - rest[c], x[c + 1] - rest[c + 1], x[c + 2] - rest[c + 2]);
  }
  r.dentMax = dent();
  // The tool goes away; the block rests for 2 s.
  tool.point = {0.05f, 10, 0.05f};
  tool.velocity = {0, 0, 0};
  EXPECT_TRUE(world.setColliders({&tool, 1}).ok());
  for (int k = 0; k < 120; ++k) EXPECT_TRUE(world.step(kDt).ok());
  r.dentEnd = dent();
  if (atEnd) atEnd(world, id);
  std::printf(
      "brush %d, plastic %d: top centre moved %.2f mm, bottom face %.2f mm (ratio %.3f); dent "
      "%.2f mm pressed, %.2f mm 2 s after\n",
      brush, plastic, 1e3 * r.nearMove, 1e3 * r.farMove, r.farMove / r.nearMove, 1e3 * r.dentMax,
      1e3 * r.dentEnd);
  return r;
}

TEST(DeformBrush, ClayGivesWayAroundTheToolAndKeepsTheDent) {
  const Press shoved = pressClay(false, true), clay = pressClay(true, true),
              elastic = pressClay(true, false);
  // Without the kernel the block is pushed away nearly as a whole.
  EXPECT_GT(shoved.farMove / shoved.nearMove, 0.5);
  // With it the far side moves a small fraction of the tool's travel into the block.
  EXPECT_LT(clay.farMove / clay.nearMove, 0.2 * shoved.farMove / shoved.nearMove);
  EXPECT_GT(clay.dentMax, 0.005);
  // The dent is the material's: it stays with plasticity, springs back without.
  EXPECT_GT(clay.dentEnd, 0.5 * clay.dentMax);
  EXPECT_LT(elastic.dentEnd, 0.2 * elastic.dentMax);
}

// The sculpted block saved as .msh and .obj and loaded back: the same nodes to the bit, the
// same tets, the dent in the surface, and a new body made from it rests in the sculpted shape.
TEST(DeformBrush, TheSculptedBodyIsSavedAndLoadsBackAsARestShape) {
  test::TempDir dir("sculpt_export");
  const std::string msh = (dir.path / "clay.msh").string(), obj = (dir.path / "clay.obj").string();
  TetMesh saved;
  (void)pressClay(true, true, [&](World& world, BodyId id) {
    const Result<TetMesh> m = world.currentMesh(id);
    ASSERT_TRUE(m.ok()) << m.error().message;
    saved = m.value();
    ASSERT_TRUE(saved.writeMsh(msh).ok());
    ASSERT_TRUE(saved.writeSurface(obj).ok());
    EXPECT_FALSE(world.currentMesh(BodyId{}).ok());
  });
  const Result<TetMesh> back = TetMesh::fromFile(msh);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back.value().positions, saved.positions);
  EXPECT_EQ(back.value().tets, saved.tets);
  EXPECT_LT(saved.volume(), kSide * kSide * kSide);  // the dent took material's place
  // The OBJ holds the boundary: one vertex line per boundary node, one face per boundary face.
  std::ifstream in(obj);
  int vertices = 0, faces = 0;
  for (std::string line; std::getline(in, line);) {
    vertices += line.rfind("v ", 0) == 0;
    faces += line.rfind("f ", 0) == 0;
  }
  EXPECT_EQ(faces, int(saved.boundaryFaces().size() / 3));
  EXPECT_EQ(vertices, 7 * 7 * 7 - 5 * 5 * 5);  // the 7^3 grid nodes less the 5^3 inside
  // As a new body's rest shape the sculpted block does not move.
  WorldDef wd;
  wd.gravity = {0, 0, 0};
  World world(wd);
  BodyDef def;
  def.mesh = back.value();
  def.material = Material::stableNeoHookean(1e5, 0.3, 1800);
  const BodyId id = world.createBody(def).value();
  for (int k = 0; k < 10; ++k) ASSERT_TRUE(world.step(kDt).ok());
  double moved = 0;
  for (size_t i = 0; i < saved.positions.size(); ++i)
    moved = std::max(moved, std::abs(world.positions(id)[i] - saved.positions[i]));
  EXPECT_LT(moved, 1e-9);
}

// A 10 cm box of 2 x 2 x 2 cells gliding at 1 m/s along x in a world without gravity.
struct GlidingBox {
  World world;
  BodyDef def;
  BodyId id;
  explicit GlidingBox(int substeps = 1) : world(worldDef(substeps)) {
    def.mesh = gen::box(0.1, 0.1, 0.1, 2, 2, 2);
    id = world.createBody(def).value();
    EXPECT_TRUE(world.setVelocity(id, {1, 0, 0}).ok());
  }
  static WorldDef worldDef(int substeps) {
    WorldDef wd;
    wd.gravity = {0, 0, 0};
    wd.substeps = substeps;
    return wd;
  }
};

TEST(DeformBrush, BadBrushIsAClearErrorAndChangesNothing) {
  GlidingBox box;
  World& world = box.world;
  const BodyDef& def = box.def;
  const BodyId id = box.id;
  DeformBrush b;
  b.radius = 0;
  Result<void> r = world.deform(id, b);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("radius"), std::string::npos);
  b = {};
  b.k1 = NAN;
  r = world.deform(id, b);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("k1"), std::string::npos);
  b = {};
  b.k2 = -1;
  EXPECT_FALSE(world.deform(id, b).ok());
  b = {};
  b.centre.x = INFINITY;
  EXPECT_FALSE(world.deform(id, b).ok());
  EXPECT_FALSE(world.deform(BodyId{}, DeformBrush{}).ok());
  // Nothing was queued: the free body keeps its velocity through a step (a brush would have
  // scaled it down).
  EXPECT_TRUE(world.step(kDt).ok());
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
    EXPECT_NEAR(world.velocities(id)[3 * n], 1.0, 1e-9);
  // A brush so far away that exp(k2 r) overflows holds the body still, finitely.
  b = {};
  b.centre = {1000, 0, 0};
  b.k2 = 100;
  ASSERT_TRUE(world.deform(id, b).ok());
  EXPECT_TRUE(world.step(kDt).ok());
  for (double v : world.velocities(id)) {
    EXPECT_TRUE(std::isfinite(v));
    EXPECT_LE(std::abs(v), 1.01e-6);
  }
}

// A body gliding at 1 m/s with nothing acting on it but a brush 10 m away, where G_d of eq 7.7
// is about 0.5 and varies by 0.5 % across the body: each node leaves the step with its velocity
// near G_d at its distance (the elastic forces of that variation move it by as much), with one
// step or four substeps. With one step the drag's balance is exact: backward Euler gives
// m_i (1 + w_i) v_i = m_i v0 + h f_i with 1 + w_i = 1 / G_i, and the internal forces sum to
// zero, so the sum of m_i v_i / G_i keeps the momentum the body had, to the solver's tolerance.
TEST(DeformBrush, AFreeNodeLeavesTheStepWithItsVelocityTimesTheKernel) {
  for (int substeps : {1, 4}) {
    GlidingBox box(substeps);
    World& world = box.world;
    const BodyDef& def = box.def;
    const BodyId id = box.id;
    DeformBrush b;
    b.centre = {-10, 0, 0};
    b.radius = 100;
    b.k1 = 0.1;
    ASSERT_TRUE(world.deform(id, b).ok());
    const std::vector<double> x0(world.positions(id).begin(), world.positions(id).end());
    ASSERT_TRUE(world.step(kDt).ok());
    const TetMesh& m = def.mesh;
    const std::vector<double> mass = test::lumpedMasses(m, def.material.density);
    double worst = 0, balanced = 0, before = 0;
    for (size_t n = 0; n < m.nodeCount(); ++n) {
      const double r = std::hypot(x0[3 * n] + 10, x0[3 * n + 1], x0[3 * n + 2]);
      const double g = clayDamping(r, 100, 0.1, 10), v = world.velocities(id)[3 * n];
      worst = std::max(worst, std::abs(v / g - 1));
      balanced += mass[n] * v / g;
      before += mass[n];
    }
    std::printf(
        "%d substep(s): velocity / G_d within %.2e of 1; sum m v / G_d over the momentum "
        "before: %.12f\n",
        substeps, worst, balanced / before);
    EXPECT_LT(worst, 1e-2);
    if (substeps == 1) {
      EXPECT_NEAR(balanced / before, 1.0, 1e-9);
    }
    // The next step has no brush: the body glides on with the momentum it has.
    double p1 = 0, p2 = 0;
    for (size_t n = 0; n < m.nodeCount(); ++n) p1 += mass[n] * world.velocities(id)[3 * n];
    ASSERT_TRUE(world.step(kDt).ok());
    for (size_t n = 0; n < m.nodeCount(); ++n) p2 += mass[n] * world.velocities(id)[3 * n];
    EXPECT_NEAR(p2, p1, 1e-9 * p1);
  }
}

}  // namespace
}  // namespace gf
