// graphfrac-demo (demo/demo_app.h) and the scene's Bullet world (tools/scene/bullet_scene.h):
// rigid shapes are closed and outward (enclosed volumes against the analytic ones), a Bullet
// ball falls as Bullet's integrator says with the scene's substeps taken at the bridge, a short
// run of the default demo scene draws its bodies (every pixel whose view ray passes through a
// ball inside a body's current surface differs from a floor-only image) and reports the
// World's fracture numbers, the renderer streams only dirty vertices after the first frame,
// the Vulkan validation layers stay silent, and the command line fails the way it says.
// Needs Bullet (tests/CMakeLists.txt defines GF_HAS_DEMO_APP when graphfrac-demo is built).
#ifdef GF_HAS_DEMO_APP
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <glm/ext/matrix_clip_space.hpp>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <numbers>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "common/render_mesh_checks.h"
#include "common/temp_dir.h"
#include "demo/render_checks.h"
#include "demo_app.h"
#include "renderer.h"
#include "scene/bullet_scene.h"
#include "scene/scene.h"
#include "scene_drawing.h"

namespace gf::demo {
namespace {

namespace fs = std::filesystem;
using scene::SceneRigidBody;

const std::string kDemoScene = GF_SOURCE_DIR "/scenes/demo.json";
// Bytes a dirty vertex costs: its position and normal, 3 floats each (MeshFrame's streams).
constexpr uint64_t kVertexBytes = 6 * sizeof(float);

using test::TempDir;

fs::path writeScene(const fs::path& dir, const std::string& text) {
  fs::create_directories(dir);
  const fs::path p = dir / "scene.json";
  std::ofstream(p) << text;
  return p;
}

/// Skips the calling test when no back end can render here.
#define SKIP_WITHOUT_RENDERER()                                          \
  do {                                                                   \
    RendererOptions ro_;                                                 \
    ro_.width = 16;                                                      \
    ro_.height = 16;                                                     \
    Result<std::unique_ptr<Renderer>> r_ = createRenderer(ro_);          \
    if (!r_) GTEST_SKIP() << "no renderer here: " << r_.error().message; \
  } while (0)

/// Volume a closed triangle mesh encloses (divergence theorem): positive when it is
/// counter-clockwise from outside.
double enclosedVolume(const ShapeMesh& m) {
  double v = 0;
  auto p = [&](uint32_t i) {
    return glm::dvec3(m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]);
  };
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3)
    v += glm::dot(p(m.indices[t]), glm::cross(p(m.indices[t + 1]), p(m.indices[t + 2]))) / 6;
  return v;
}

/// Largest angle [rad] between a triangle's geometric normal and its vertices' normals.
double worstNormalAngle(const ShapeMesh& m) {
  double worst = 0;
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    glm::dvec3 c[3], n(0);
    for (int k = 0; k < 3; ++k) {
      const uint32_t i = m.indices[t + size_t(k)];
      c[k] = {m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]};
      n += glm::dvec3(m.normals[3 * i], m.normals[3 * i + 1], m.normals[3 * i + 2]);
    }
    const glm::dvec3 g = glm::normalize(glm::cross(c[1] - c[0], c[2] - c[0]));
    worst = std::max(worst, std::acos(std::clamp(glm::dot(g, glm::normalize(n)), -1.0, 1.0)));
  }
  return worst;
}

TEST(DemoShapes, RigidMeshesAreClosedOutwardAndTheRightSize) {
  SceneRigidBody sphere;
  sphere.shape = SceneRigidBody::Shape::Sphere;
  sphere.radius = 0.3;
  const ShapeMesh s = rigidMesh(sphere);
  // A polyhedron inscribed in the sphere: a little under 4/3 pi r^3 (16 x 32 facets: ~1.3 %).
  const double ball = 4.0 / 3 * std::numbers::pi * std::pow(0.3, 3);
  EXPECT_LT(enclosedVolume(s), ball);
  EXPECT_GT(enclosedVolume(s), 0.97 * ball);
  for (size_t i = 0; i < s.positions.size(); i += 3)
    EXPECT_NEAR(std::hypot(s.positions[i], s.positions[i + 1], s.positions[i + 2]), 0.3, 1e-6);
  EXPECT_LT(worstNormalAngle(s), 0.25);  // vertex normals within a facet's angle

  SceneRigidBody box;
  box.shape = SceneRigidBody::Shape::Box;
  box.halfExtents = {0.1, 0.2, 0.3};
  const ShapeMesh b = rigidMesh(box);
  EXPECT_NEAR(enclosedVolume(b), 0.2 * 0.4 * 0.6, 1e-7);
  EXPECT_LT(worstNormalAngle(b), 1e-6);  // flat faces

  // A capsule: the sphere's facets plus a 32-sided prism between the halves; every vertex at
  // the radius from the segment along local y.
  SceneRigidBody capsule;
  capsule.shape = SceneRigidBody::Shape::Capsule;
  capsule.radius = 0.3;
  capsule.halfLength = 0.5;
  const ShapeMesh c = rigidMesh(capsule);
  const double prism = 0.5 * 32 * std::sin(2 * std::numbers::pi / 32) * 0.09 * 1.0;
  EXPECT_NEAR(enclosedVolume(c), enclosedVolume(s) + prism, 1e-6);  // float positions
  for (size_t i = 0; i < c.positions.size(); i += 3) {
    const double y = std::clamp(double(c.positions[i + 1]), -0.5, 0.5);
    EXPECT_NEAR(std::hypot(c.positions[i], c.positions[i + 1] - y, c.positions[i + 2]), 0.3, 1e-6);
  }
  EXPECT_LT(worstNormalAngle(c), 0.25);

  SceneRigidBody plane;
  plane.shape = SceneRigidBody::Shape::Plane;
  plane.normal = glm::normalize(glm::dvec3(0, 1, 1));
  plane.offset = 0.5;
  plane.renderSize = 2;
  const ShapeMesh q = rigidMesh(plane);
  ASSERT_EQ(q.indices.size(), 6u);
  double area = 0;
  for (size_t t = 0; t < 6; t += 3) {
    glm::dvec3 c[3];
    for (int k = 0; k < 3; ++k) {
      const uint32_t i = q.indices[t + size_t(k)];
      c[k] = {q.positions[3 * i], q.positions[3 * i + 1], q.positions[3 * i + 2]};
      EXPECT_NEAR(glm::dot(c[k], plane.normal), 0.5, 1e-6);  // on the plane
    }
    const glm::dvec3 n = glm::cross(c[1] - c[0], c[2] - c[0]);
    EXPECT_GT(glm::dot(n, plane.normal), 0);  // facing the normal's side
    area += 0.5 * glm::length(n);
  }
  EXPECT_NEAR(area, 4, 1e-6);
  EXPECT_LT(worstNormalAngle(q), 1e-6);
}

// A ball dropped in the scene's Bullet world: with substeps taken at the bridge, Bullet makes
// 2 semi-implicit Euler steps of h = dt / 2 per frame: v_n = -g n h, y_n = y_0 - g h^2 n (n + 1)
// / 2 (one World step per frame would give y_0 - g dt^2 N (N + 1) / 2, 2.5 mm lower after 10
// frames). Then it comes to rest on the floor plane at its radius.
TEST(DemoBulletScene, BallFallsByBulletsStepsAndRestsOnTheFloor) {
  const std::string text = R"({
    "dt": 0.01, "frames": 200, "substeps": 2,
    "bodies": [{"name": "post", "mesh": {"generator": "box", "size": [0.1, 0.1, 0.1], "cells": 1},
                "translate": [3, 0, 0], "material": {"E": 1e6, "nu": 0.3, "rho": 1000},
                "pins": [{"region": {"min": [3, 0, 0], "max": [3.1, 0.1, 0.1]}}]}],
    "rigid_bodies": [
      {"name": "floor", "shape": "plane"},
      {"name": "ball", "shape": "sphere", "radius": 0.1, "mass": 1, "position": [0, 1, 0]},
      {"name": "sign", "shape": "box", "size": [0.1, 0.2, 0.3], "mass": 0,
       "position": [1, 2, 3], "orientation": {"axis": [0, 0, 1], "angle_deg": 90},
       "touches_bodies": false}]})";
  Result<scene::Scene> sc = scene::parseScene(text, "inline", "");
  ASSERT_TRUE(sc.ok()) << sc.error().message;
  Result<std::unique_ptr<scene::BulletScene>> made = scene::BulletScene::create(sc.value());
  ASSERT_TRUE(made.ok()) << made.error().message;
  scene::BulletScene& sim = *made.value();
  ASSERT_EQ(sim.rigidBodyCount(), 3u);

  const glm::mat4 sign = sim.rigidTransform(2);
  const glm::vec3 x = glm::vec3(sign * glm::vec4(1, 0, 0, 0));
  EXPECT_LT(glm::length(x - glm::vec3(0, 1, 0)), 1e-6f);  // +x turned onto +y
  EXPECT_LT(glm::length(glm::vec3(sign[3]) - glm::vec3(1, 2, 3)), 1e-6f);

  const double g = 9.81, h = 0.005;
  for (int f = 0; f < 10; ++f) {
    const StepStatus st = sim.step();
    EXPECT_EQ(st.flags & kStepInvalidInput, 0u) << st.message;
  }
  EXPECT_EQ(sim.frame(), 10);
  const double n = 20, expected = 1 - g * h * h * n * (n + 1) / 2;
  EXPECT_NEAR(sim.rigidTransform(1)[3][1], expected, 2e-5);
  EXPECT_GE(sim.timings().totalMs, sim.timings().world.totalMs);
  EXPECT_GE(sim.timings().bulletMs, 0);

  for (int f = 10; f < 150; ++f) (void)sim.step();
  EXPECT_NEAR(sim.rigidTransform(1)[3][1], 0.1, 2e-3);  // resting on y = 0
  EXPECT_EQ(sim.handedOff(), 0u);
}

struct Ball {
  glm::dvec3 centre;
  double radius;
};

/// The angle one pixel spans at the centre of an image `h` pixels high.
double pixelAngle(const Camera& cam, int h) {
  return 2 * std::tan(0.5 * double(cam.fovYDegrees) * std::numbers::pi / 180) / h;
}

/// Which pixels of a W x H image (rows top to bottom) lie wholly inside the view cone of a
/// ball, so that anti-aliased silhouettes do not count. A ray at angle a from the direction to
/// a ball's centre passes d sin(a) from it: inside the ball for sin(a) < r / d.
std::vector<uint8_t> coveredPixels(const std::vector<Ball>& balls, const Camera& cam, int w,
                                   int h) {
  const glm::dvec3 eye(cam.eye);
  const glm::dvec3 fwd = glm::normalize(glm::dvec3(cam.target) - eye);
  const glm::dvec3 right = glm::normalize(glm::cross(fwd, glm::dvec3(cam.up)));
  const glm::dvec3 up = glm::cross(right, fwd);
  const double t = std::tan(0.5 * double(cam.fovYDegrees) * std::numbers::pi / 180);
  std::vector<uint8_t> mask(size_t(w) * size_t(h), 0);
  for (const Ball& b : balls) {
    const glm::dvec3 toC = b.centre - eye;
    const double d = glm::length(toC);
    if (!(d > b.radius)) continue;
    // Pixel centres within this angle have their whole pixel (half a diagonal away) inside.
    const double halfAngle = std::asin(b.radius / d) - 0.75 * pixelAngle(cam, h);
    if (halfAngle <= 0) continue;
    const glm::dvec3 dirC = toC / d;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double nx = (2 * (x + 0.5) / w - 1) * t * w / h, ny = (1 - 2 * (y + 0.5) / h) * t;
        const glm::dvec3 ray = glm::normalize(fwd + nx * right + ny * up);
        if (std::acos(std::clamp(glm::dot(ray, dirC), -1.0, 1.0)) < halfAngle)
          mask[size_t(y) * size_t(w) + size_t(x)] = 1;
      }
  }
  return mask;
}

/// Distance from p to the triangle (a, b, c) (Ericson, Real-Time Collision Detection 5.1.5).
double pointTriangleDistance(glm::dvec3 p, glm::dvec3 a, glm::dvec3 b, glm::dvec3 c) {
  const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return glm::length(p - a);
  const glm::dvec3 bp = p - b;
  const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return glm::length(p - b);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return glm::length(p - (a + d1 / (d1 - d3) * ab));
  const glm::dvec3 cp = p - c;
  const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return glm::length(p - c);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return glm::length(p - (a + d2 / (d2 - d6) * ac));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return glm::length(p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b)));
  const double denom = 1 / (va + vb + vc);
  return glm::length(p - (a + ab * (vb * denom) + ac * (vc * denom)));
}

/// Balls certainly inside a body: around its nodes, out to the nearest triangle of its render
/// surface (the boundary and every crack face, so each ball stays inside one fragment). Balls
/// seen from `eye` under less than `minAngle` are dropped (the search stops at the first
/// triangle that close).
std::vector<Ball> ballsInside(World& world, BodyId id, glm::dvec3 eye, double minAngle) {
  const SurfaceView s = world.surface(id);
  const std::span<const double> x = world.positions(id);
  std::vector<Ball> balls;
  for (size_t n = 0; 3 * n + 2 < x.size(); ++n) {
    const glm::dvec3 p(x[3 * n], x[3 * n + 1], x[3 * n + 2]);
    const double rMin = glm::length(p - eye) * std::sin(minAngle);
    double r = 1e300;
    for (size_t t = 0; t + 2 < s.indices.size() && r > rMin; t += 3) {
      auto v = [&](size_t k) {
        const uint32_t i = s.indices[t + k];
        return glm::dvec3(s.positions[3 * i], s.positions[3 * i + 1], s.positions[3 * i + 2]);
      };
      r = std::min(r, pointTriangleDistance(p, v(0), v(1), v(2)));
    }
    if (r > rMin) balls.push_back({p, r});
  }
  return balls;
}

// The demo's runner plays scene strokes through the same helper as `graphfrac run`, with a
// Bullet floor so that the bridge rewrites the colliders every step: the tool keeps its slot
// and dents the clay where it pushes, and barely moves the clay 10 cm away.
TEST(DemoBulletScene, SculptStrokesDentTheClayUnderTheTool) {
  Result<scene::Scene> sc =
      scene::loadScene(std::string(GF_SOURCE_DIR) + "/tests/data/scenes/sculpt_short.json");
  ASSERT_TRUE(sc.ok()) << sc.error().message;
  scene::SceneRigidBody floor;
  floor.name = "floor";
  floor.shape = scene::SceneRigidBody::Shape::Plane;
  floor.offset = -1;
  sc.value().rigidBodies.push_back(floor);
  Result<std::unique_ptr<scene::BulletScene>> made = scene::BulletScene::create(sc.value());
  ASSERT_TRUE(made.ok()) << made.error().message;
  scene::BulletScene& sim = *made.value();
  const std::vector<double> rest(sim.world().positions(sim.body(0)).begin(),
                                 sim.world().positions(sim.body(0)).end());
  const auto nodeAt = [&](double x, double y, double z) {
    size_t best = 0;
    double d = 1e9;
    for (size_t n = 0; 3 * n < rest.size(); ++n) {
      const double e = std::hypot(rest[3 * n] - x, rest[3 * n + 1] - y, rest[3 * n + 2] - z);
      if (e < d) d = e, best = n;
    }
    return best;
  };
  const size_t pushed = nodeAt(0.05, 0.1, 0.05), far = nodeAt(0.15, 0.1, 0.05);
  for (int f = 0; f < 30; ++f) {
    const StepStatus st = sim.step();
    ASSERT_EQ(st.flags & kStepInvalidInput, 0u) << st.message;
  }
  EXPECT_EQ(sim.world().colliders().size(), 2u);  // the tool, then the mirrored floor
  const std::span<const double> x = sim.world().positions(sim.body(0));
  const double dent = rest[3 * pushed + 1] - x[3 * pushed + 1];
  const double farMove = std::hypot(x[3 * far] - rest[3 * far], x[3 * far + 1] - rest[3 * far + 1],
                                    x[3 * far + 2] - rest[3 * far + 2]);
  std::printf("[ sculpt ] BulletScene, frame 30: dent %.2f mm, 10 cm away %.3f mm\n", 1e3 * dent,
              1e3 * farMove);
  // The tool's bottom is 1 cm below the top at frame 30.
  EXPECT_GT(dent, 0.004);
  EXPECT_LT(dent, 0.012);
  EXPECT_LT(farMove, 0.1 * dent);
}

TEST(DemoApp, ShortRunDrawsTheBodiesAndReportsTheWorldsNumbers) {
  SKIP_WITHOUT_RENDERER();
  const TempDir tmp("demo_short");
  const fs::path out = tmp.path;
  DemoOptions opt;
  opt.scene = kDemoScene;
  opt.frames = 3;
  opt.width = 160;
  opt.height = 90;
  opt.out = out.string();
  opt.quiet = true;
  // The plain picture: shadows and text would differ from the floor-only image below.
  opt.shadows = false;
  opt.overlay = false;
  Result<DemoSummary> run = runDemo(opt);
  ASSERT_TRUE(run.ok()) << run.error().message;
  const DemoSummary& s = run.value();
  EXPECT_EQ(s.frames, 3);
  ASSERT_EQ(s.perFrame.size(), 3u);
  for (int f = 1; f <= 3; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%04d.png", f);
    EXPECT_TRUE(fs::is_regular_file(out / "frames" / name)) << name;
  }
  std::ifstream summaryFile(out / "summary.txt");
  std::stringstream summaryText;
  summaryText << summaryFile.rdbuf();
  EXPECT_EQ(summaryText.str(), formatSummary(s));

  // The same frames replayed (the run is deterministic): the summary reports this World.
  Result<scene::Scene> sc = scene::loadScene(kDemoScene);
  ASSERT_TRUE(sc.ok()) << sc.error().message;
  Result<std::unique_ptr<scene::BulletScene>> made = scene::BulletScene::create(sc.value());
  ASSERT_TRUE(made.ok()) << made.error().message;
  scene::BulletScene& sim = *made.value();
  World& world = sim.world();
  size_t edgeEvents = 0, handoffEvents = 0;
  for (int f = 0; f < 3; ++f) {
    (void)sim.step();
    edgeEvents += sim.fractureEvents().size();
    handoffEvents += sim.handoffEvents().size();
    for (size_t i = 0; i < sim.bodyCount(); ++i) (void)world.surface(sim.body(i));
  }
  int64_t broken = 0, fragments = 0, edges = 0;
  const Camera cam = s.perFrame.back().camera;  // the follow camera of frame 3
  std::vector<Ball> balls;
  ASSERT_EQ(s.bodies.size(), sim.bodyCount());
  for (size_t i = 0; i < sim.bodyCount(); ++i) {
    const FractureStats st = world.fractureStats(sim.body(i));
    // Each body's line of the summary is that body's own count in the replay.
    EXPECT_EQ(s.bodies[i].name, sc.value().bodies[i].name);
    EXPECT_EQ(s.bodies[i].brokenEdges, st.brokenEdges) << s.bodies[i].name;
    EXPECT_EQ(s.bodies[i].edgeCount, st.edgeCount) << s.bodies[i].name;
    EXPECT_EQ(s.bodies[i].fragments, st.edgeCount > 0 ? st.fragments : 1) << s.bodies[i].name;
    broken += st.brokenEdges;
    edges += st.edgeCount;
    fragments += st.edgeCount > 0 ? st.fragments : 1;
    const std::vector<Ball> b =
        ballsInside(world, sim.body(i), glm::dvec3(cam.eye), pixelAngle(cam, 90));
    balls.insert(balls.end(), b.begin(), b.end());
  }
  EXPECT_EQ(s.brokenEdges, broken);
  EXPECT_EQ(s.edgeCount, edges);
  EXPECT_EQ(s.fragments, fragments);
  EXPECT_EQ(s.handedOff, sim.handedOff());
  // The frame's events gather every substep's: one per broken edge, one per hand-off.
  EXPECT_EQ(int64_t(edgeEvents), broken);
  EXPECT_EQ(handoffEvents, sim.handedOff());
  EXPECT_EQ(s.perFrame.back().brokenEdges, broken);
  EXPECT_EQ(s.perFrame.back().fragments, fragments);
  std::printf("[ info ] after 3 frames: %lld broken edges, %lld fragments, %zu in Bullet\n",
              static_cast<long long>(broken), static_cast<long long>(fragments), sim.handedOff());

  // The last frame against the same view of the floor alone: every pixel whose view ray goes
  // through a ball inside a body shows something else than the floor or the sky.
  Result<Image> frame = readPng((out / "frames" / "frame_0003.png").string());
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  ASSERT_EQ(frame.value().width, 160);
  ASSERT_EQ(frame.value().height, 90);
  std::vector<ShapeMesh> planes;
  for (const SceneRigidBody& r : sc.value().rigidBodies)
    if (r.shape == SceneRigidBody::Shape::Plane) planes.push_back(rigidMesh(r));
  std::vector<MeshFrame> floorOnly;
  for (const ShapeMesh& m : planes) {
    MeshFrame f;
    f.positions = m.positions;
    f.normals = m.normals;
    f.indices = m.indices;
    f.topologyVersion = 1;
    f.dirtyEnd = uint32_t(m.positions.size() / 3);
    f.colour = sc.value().rigidBodies[0].colour;
    f.gridSpacing = kGroundCell;
    floorOnly.push_back(f);
  }
  RendererOptions ro;
  ro.width = 160;
  ro.height = 90;
  Result<std::unique_ptr<Renderer>> renderer = createRenderer(ro);
  ASSERT_TRUE(renderer.ok()) << renderer.error().message;
  ASSERT_EQ(renderer.value()->description(), s.renderer);
  Image reference;
  ASSERT_TRUE(renderer.value()->render(floorOnly, cam, reference).ok());
  const std::vector<uint8_t> covered = coveredPixels(balls, cam, 160, 90);
  int mustDiffer = 0, differ = 0, missing = 0;
  for (size_t p = 0; p < covered.size(); ++p) {
    int diff = 0;
    for (int c = 0; c < 3; ++c)
      diff = std::max(diff, std::abs(int(frame.value().rgba[4 * p + size_t(c)]) -
                                     int(reference.rgba[4 * p + size_t(c)])));
    const bool differs = diff > 4;  // outside the bodies both images are the same
    differ += differs;
    mustDiffer += covered[p];
    missing += covered[p] && !differs;
  }
  const double total = 160.0 * 90.0;
  std::printf(
      "[ info ] %d of %d pixels differ from the floor alone (%.1f %%); the bodies cover "
      "at least %d (%.1f %%)\n",
      differ, int(total), 100 * differ / total, mustDiffer, 100 * mustDiffer / total);
  EXPECT_GE(mustDiffer, 50);  // the floor is a real one, not 0
  // A face lit at a grazing angle can match the floor behind it by chance (one pixel of 132
  // did within 11 levels when the threshold was 12).
  EXPECT_LE(missing, mustDiffer / 50);
  EXPECT_GE(differ, mustDiffer);
}

// A body without fracture falls onto the floor next to a Bullet crate: no topology ever
// changes, so after the first frame only the body's dirty vertices are uploaded (6 floats
// each), the crate moves by its model matrix alone, and the mean is below a full upload.
TEST(DemoApp, AfterTheFirstFrameOnlyDirtyVerticesAreUploaded) {
  SKIP_WITHOUT_RENDERER();
  const TempDir tmp("demo_stream");
  const fs::path dir = tmp.path;
  const fs::path scenePath = writeScene(dir, R"({
    "dt": 0.02, "frames": 4, "substeps": 2,
    "bodies": [{"name": "block", "mesh": {"generator": "box", "size": [0.2, 0.2, 0.2], "cells": 2},
                "translate": [-0.1, 0.3, -0.1], "material": {"E": 1e6, "nu": 0.3, "rho": 1000}}],
    "rigid_bodies": [{"name": "floor", "shape": "plane", "render_size": 2},
                     {"name": "crate", "shape": "box", "size": [0.2, 0.2, 0.2], "mass": 1,
                      "position": [0.4, 0.5, 0]}],
    "camera": {"eye": [0, 0.6, 1.5], "target": [0, 0.3, 0]}})");
  DemoOptions opt;
  opt.scene = scenePath.string();
  opt.width = 64;
  opt.height = 36;
  opt.out = (dir / "out").string();
  opt.quiet = true;
  Result<DemoSummary> run = runDemo(opt);
  ASSERT_TRUE(run.ok()) << run.error().message;
  const DemoSummary& s = run.value();
  ASSERT_EQ(s.perFrame.size(), 4u);

  // The block's surface: the vertex count the World streams.
  Result<scene::Scene> sc = scene::loadScene(scenePath.string());
  ASSERT_TRUE(sc.ok());
  Result<std::unique_ptr<scene::BulletScene>> made = scene::BulletScene::create(sc.value());
  ASSERT_TRUE(made.ok());
  const uint64_t vertices =
      made.value()->world().surface(made.value()->body(0)).positions.size() / 3;
  ASSERT_GT(vertices, 0u);

  EXPECT_EQ(s.perFrame[0].topologyChanges, 3);  // every slot is new
  EXPECT_EQ(s.perFrame[0].uploadedBytes, s.perFrame[0].surfaceBytes);
  for (size_t f = 1; f < 4; ++f) {
    SCOPED_TRACE(f);
    const DemoFrame& d = s.perFrame[f];
    EXPECT_EQ(d.topologyChanges, 0);
    EXPECT_EQ(d.dirtyVertices, vertices);  // the falling block moves every vertex
    EXPECT_EQ(d.uploadedBytes, vertices * kVertexBytes);
    EXPECT_LT(d.uploadedBytes, d.surfaceBytes);
  }
  EXPECT_LT(s.uploadedBytesMean, s.surfaceBytesMean);
  EXPECT_DOUBLE_EQ(s.uploadedBytesMean, double(vertices * kVertexBytes));
}

TEST(DemoApp, VulkanValidationLayersReportNothingOverAShortRun) {
  RendererOptions ro;
  ro.kind = RendererKind::Vulkan;
  ro.width = 16;
  ro.height = 16;
  ro.validation = true;
  if (Result<std::unique_ptr<Renderer>> r = createRenderer(ro); !r)
    GTEST_SKIP() << "no Vulkan renderer with validation layers: " << r.error().message;
  DemoOptions opt;
  opt.scene = kDemoScene;
  opt.frames = 2;
  opt.width = 160;
  opt.height = 90;
  const TempDir tmp("demo_validation");
  opt.out = tmp.path.string();
  opt.renderer = RendererKind::Vulkan;
  opt.validation = true;
  opt.quiet = true;
  Result<DemoSummary> run = runDemo(opt);
  ASSERT_TRUE(run.ok()) << run.error().message;
  EXPECT_TRUE(run.value().validation);
  EXPECT_TRUE(run.value().validationMessages.empty())
      << run.value().validationMessages.size()
      << " messages; first: " << run.value().validationMessages.front();
}

int callMain(std::vector<std::string> args) {
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  return demoMain(int(argv.size()), argv.data());
}

// A scripted cut (Scene::cuts, World::cut) shows its blade: each frame rendered with every slot
// and again without the blade's differs where the blade is in the frames from kBladeLead before
// the cut to kBladeTrail after it, and nowhere before or after that.
TEST(DemoApp, ScriptedCutShowsItsBladeAroundTheCutOnly) {
  SKIP_WITHOUT_RENDERER();
  const TempDir tmp("demo_blade");
  const int cutFrame = 5, frames = cutFrame + kBladeTrail + 3;
  const fs::path scenePath = writeScene(tmp.path, R"({
    "name": "blade", "dt": 0.03333333333333333, "frames": 16, "substeps": 4,
    "gravity": [0, -9.81, 0],
    "bodies": [
      {"name": "column", "mesh": {"generator": "box", "size": [0.08, 0.24, 0.08], "cells": [2, 6, 2]},
       "translate": [-0.04, 0.002, -0.04],
       "material": {"model": "stable_neo_hookean", "E": 1e8, "nu": 0.3, "rho": 2700},
       "fracture": {"strength": 1e12, "radius": 0}, "solver": {"linear": "direct"}}
    ],
    "cuts": [
      {"frame": 5, "body": "column",
       "blade": {"type": "plane", "point": [0, 0.15, 0], "normal": [0.707, 0.707, 0], "size": 0.3}}
    ],
    "rigid_bodies": [
      {"name": "floor", "shape": "plane", "normal": [0, 1, 0], "offset": 0, "render_size": 2}
    ]
  })");
  Result<scene::Scene> sc = scene::loadScene(scenePath.string());
  ASSERT_TRUE(sc.ok()) << sc.error().message;
  Result<std::unique_ptr<scene::BulletScene>> made = scene::BulletScene::create(sc.value());
  ASSERT_TRUE(made.ok()) << made.error().message;
  scene::BulletScene& sim = *made.value();
  SceneDrawing drawing(sc.value());
  const size_t blade = drawing.bladeSlot(0);
  ASSERT_EQ(blade + 1, drawing.meshes().size());  // the last slot, so the others keep theirs
  RendererOptions ro;
  ro.width = 160;
  ro.height = 90;
  Result<std::unique_ptr<Renderer>> withBlade = createRenderer(ro);
  Result<std::unique_ptr<Renderer>> without = createRenderer(ro);
  ASSERT_TRUE(withBlade.ok() && without.ok());
  Camera cam;
  cam.eye = {0.55f, 0.35f, 0.75f};
  cam.target = {0.0f, 0.12f, 0.0f};
  for (int f = 1; f <= frames; ++f) {
    ASSERT_EQ(sim.step().flags & kStepInvalidInput, 0u);
    (void)drawing.update(sim, 0);
    const std::span<const MeshFrame> all = drawing.meshes();
    Image a, b;
    ASSERT_TRUE(withBlade.value()->render(all, cam, a).ok());
    ASSERT_TRUE(without.value()->render(all.first(blade), cam, b).ok());
    Result<ImageDiff> d = compareImages(a, b, 8);
    ASSERT_TRUE(d.ok()) << d.error().message;
    const int pixels = int(std::lround(d.value().fractionOver * 160 * 90));
    const bool expected = f >= cutFrame - kBladeLead && f <= cutFrame + kBladeTrail;
    std::printf("[ blade ] frame %2d: %4d blade pixels%s\n", f, pixels,
                expected ? " (around the cut)" : "");
    EXPECT_EQ(drawing.bladeShown(0), expected) << "frame " << f;
    if (expected)
      EXPECT_GE(pixels, 200) << "frame " << f;  // a 0.3 m sheet across a 0.24 m column
    else
      EXPECT_EQ(pixels, 0) << "frame " << f;
  }
  // The blade really cut: the column is in two pieces (and loose chips along the cut).
  const FractureStats fs = sim.world().fractureStats(sim.body(0));
  EXPECT_EQ(fs.fragments - fs.chips, 2) << fs.fragments << " fragments, " << fs.chips << " chips";
}

// --compare: each half of a composed frame is that scene's own frame, pixel for pixel, and
// scenes of different dt are refused before anything runs.
TEST(DemoApp, CompareDrawsTwoScenesSideBySide) {
  SKIP_WITHOUT_RENDERER();
  const TempDir tmp("demo_compare");
  const fs::path dir = tmp.path;
  auto scene = [&](const std::string& name, const std::string& solver, double dt) {
    const fs::path sub = dir / name;
    char text[768];
    std::snprintf(text, sizeof text, R"({"name": "%s", "dt": %g, "frames": 3,
      "bodies": [{"mesh": {"generator": "box", "size": [0.4, 0.1, 0.1], "cells": [4, 1, 1]},
                  "material": {"E": 1e5, "nu": 0.3, "rho": 1000}, "solver": {"linear": "%s"},
                  "pins": [{"region": {"min": [0, 0, 0], "max": [0, 0.1, 0.1]}}]}],
      "camera": {"eye": [0.2, 0.1, 1.0], "target": [0.2, 0, 0]}})",
                  name.c_str(), dt, solver.c_str());
    return writeScene(sub, text).string();
  };
  DemoOptions opt;
  opt.scene = scene("direct", "direct", 0.04);
  opt.compare = scene("pcg", "pcg", 0.04);
  opt.width = 66;
  opt.height = 24;
  opt.out = (dir / "out").string();
  opt.sheetFrames = 2;
  opt.quiet = true;
  Result<DemoSummary> run = runDemo(opt);
  ASSERT_TRUE(run.ok()) << run.error().message;
  const DemoSummary& s = run.value();
  ASSERT_EQ(s.halves.size(), 2u);
  EXPECT_EQ(s.halves[0].scene, "direct");
  EXPECT_EQ(s.halves[1].scene, "pcg");
  EXPECT_EQ(s.frames, 3);
  EXPECT_EQ(s.width, 66);  // two halves of 32 and the 2-pixel gap
  EXPECT_TRUE(fs::exists(dir / "out" / "sheet.png"));
  for (int frame = 1; frame <= 3; ++frame) {
    SCOPED_TRACE(frame);
    char name[32];
    std::snprintf(name, sizeof name, "frame_%04d.png", frame);
    Result<Image> both = readPng((dir / "out" / "frames" / name).string());
    ASSERT_TRUE(both.ok()) << both.error().message;
    ASSERT_EQ(both.value().width, 66);
    ASSERT_EQ(both.value().height, 24);
    for (int k = 0; k < 2; ++k) {
      Result<Image> halfImage =
          readPng((dir / "out" / (k == 0 ? "left" : "right") / "frames" / name).string());
      ASSERT_TRUE(halfImage.ok()) << halfImage.error().message;
      ASSERT_EQ(halfImage.value().width, 32);
      size_t differing = 0;
      for (int y = 0; y < 24; ++y)
        for (int x = 0; x < 32 * 4; ++x)
          differing += both.value().rgba[size_t(y) * 66 * 4 + size_t(k) * 34 * 4 + size_t(x)] !=
                       halfImage.value().rgba[size_t(y) * 32 * 4 + size_t(x)];
      EXPECT_EQ(differing, 0u) << (k == 0 ? "left" : "right");
    }
  }

  opt.compare = scene("slow", "pcg", 0.02);
  Result<DemoSummary> mismatch = runDemo(opt);
  ASSERT_FALSE(mismatch.ok());
  EXPECT_NE(mismatch.error().message.find("dt 0.02 differs from the first scene's 0.04"),
            std::string::npos)
      << mismatch.error().message;
}

TEST(DemoApp, CommandLineErrorsAndVideo) {
  EXPECT_EQ(callMain({"graphfrac-demo"}), 2);  // no scene
  EXPECT_EQ(callMain({"graphfrac-demo", "x.json", "--size", "0x10"}), 2);
  EXPECT_EQ(callMain({"graphfrac-demo", "x.json", "--size", "640"}), 2);
  EXPECT_EQ(callMain({"graphfrac-demo", "x.json", "--renderer", "metal"}), 2);
  EXPECT_EQ(callMain({"graphfrac-demo", "x.json", "--frames", "0"}), 2);
  EXPECT_EQ(callMain({"graphfrac-demo", "x.json", "--bogus"}), 2);
  EXPECT_EQ(callMain({"graphfrac-demo", "x.json", "--backend", "gpu"}), 2);
  EXPECT_EQ(callMain({"graphfrac-demo", "x.json", "--compare"}), 2);
  EXPECT_EQ(callMain({"graphfrac-demo", "--help"}), 0);
  const TempDir tmp("demo_cli");
  const fs::path dir = tmp.path;
  EXPECT_EQ(callMain({"graphfrac-demo", (dir / "missing.json").string(), "--quiet"}), 1);

  SKIP_WITHOUT_RENDERER();
  const fs::path scenePath = writeScene(dir, R"({"dt": 0.04, "frames": 3,
    "bodies": [{"mesh": {"generator": "box", "size": [0.2, 0.2, 0.2], "cells": 1},
                "material": {"E": 1e6, "nu": 0.3, "rho": 1000}}]})");
  // Without ffmpeg on PATH the video is skipped, and that is no error.
  const std::string path = std::getenv("PATH") ? std::getenv("PATH") : "";
  setenv("PATH", dir.c_str(), 1);
  DemoOptions opt;
  opt.scene = scenePath.string();
  opt.width = 33;  // odd: the video pads it
  opt.height = 19;
  opt.out = (dir / "out").string();
  opt.video = true;
  opt.quiet = true;
  Result<DemoSummary> noFfmpeg = runDemo(opt);
  setenv("PATH", path.c_str(), 1);
  ASSERT_TRUE(noFfmpeg.ok()) << noFfmpeg.error().message;
  EXPECT_TRUE(noFfmpeg.value().video.empty());
  std::ifstream summary(dir / "out" / "summary.txt");
  std::stringstream text;
  text << summary.rdbuf();
  EXPECT_NE(text.str().find("ffmpeg is not on PATH"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("  backend:    cpu: "), std::string::npos) << text.str();

  if (std::system("command -v ffmpeg > /dev/null 2>&1") != 0) GTEST_SKIP() << "no ffmpeg here";
  Result<DemoSummary> withVideo = runDemo(opt);
  ASSERT_TRUE(withVideo.ok()) << withVideo.error().message;
  EXPECT_FALSE(withVideo.value().video.empty());
  EXPECT_GT(fs::file_size(dir / "out" / "demo.mp4"), 0u);
}

// A body whose render mesh has two materials (the unit cube's surface, x < 0.5 material 0 in
// red, x > 0.5 material 1 in green) is drawn by SceneDrawing with each triangle in its own
// material's colour by both back ends: pixels of the front face (z = 1) left and right of x = 0.5
// against the shading model evaluated on the CPU; with the same table and no ids it is one colour.
TEST(DemoMaterials, EachTriangleIsDrawnInItsMaterialsColourByBothBackEnds) {
  Result<scene::Scene> parsed = scene::parseScene(
      R"({"gravity": [0, 0, 0], "bodies": [{"name": "cube", "mesh": {"generator": "box",
          "size": [1, 1, 1], "cells": 2}, "material": {"E": 1e6, "nu": 0.3, "rho": 1000},
          "colour": [0.2, 0.3, 0.9]}]})",
      "inline", "");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  scene::Scene sc = parsed.value();
  // Normals from the triangles: (0, 0, 1) on the front face away from its edges' cells.
  RenderMesh rm = test::boxSurface(glm::dvec3(0), glm::dvec3(1), 8, 8, 8);
  rm.normals.clear();
  for (size_t t = 0; t < rm.triangleCount(); ++t) {
    double cx = 0;
    for (int k = 0; k < 3; ++k) cx += rm.positions[3 * size_t(rm.indices[3 * t + size_t(k)])] / 3;
    rm.materials.push_back(cx < 0.5 ? 0 : 1);
  }
  sc.bodies[0].def.renderMesh = rm;
  const glm::vec3 red(0.8f, 0.1f, 0.1f), green(0.1f, 0.7f, 0.2f);
  sc.bodies[0].materials = {{"red", red, ""}, {"green", green, ""}};
  Camera cam;
  cam.eye = {0.5f, 0.5f, 3.0f};
  cam.target = {0.5f, 0.5f, 0.5f};
  const int w = 64, h = 64;
  const glm::mat4 viewProj = glm::perspective(glm::radians(cam.fovYDegrees), float(w) / float(h),
                                              cam.nearPlane, cam.farPlane) *
                             glm::lookAt(cam.eye, cam.target, cam.up);
  int backEnds = 0;
  for (RendererKind kind : {RendererKind::Vulkan, RendererKind::Gl}) {
    RendererOptions ro;
    ro.kind = kind;
    ro.width = w;
    ro.height = h;
    ro.samples = 1;
    Result<std::unique_ptr<Renderer>> renderer = createRenderer(ro);
    if (!renderer) continue;
    ++backEnds;
    for (bool withIds : {true, false}) {
      scene::Scene one = sc;
      if (!withIds) one.bodies[0].def.renderMesh->materials.clear();
      Result<std::unique_ptr<scene::BulletScene>> made = scene::BulletScene::create(one);
      ASSERT_TRUE(made.ok()) << made.error().message;
      SceneDrawing drawing(one);
      ASSERT_TRUE(drawing.loadTextures(one));
      (void)drawing.update(*made.value(), 0);
      Image im;
      Result<FrameStats> r = renderer.value()->render(drawing.meshes(), cam, im);
      ASSERT_TRUE(r) << r.error().message;
      for (const float x : {0.2f, 0.3f, 0.4f, 0.6f, 0.7f, 0.8f})
        for (const float y : {0.2f, 0.5f, 0.8f}) {
          const glm::vec4 c = viewProj * glm::vec4(x, y, 1.0f, 1.0f);
          const int px = int((c.x / c.w * 0.5f + 0.5f) * w),
                    py = int((0.5f - c.y / c.w * 0.5f) * h);
          const glm::vec3 base = withIds ? (x < 0.5f ? red : green) : red;
          const glm::dvec3 want = test::shade(glm::dvec3(base), {0, 0, 1}, {x, y, 1}, cam.eye);
          const uint8_t* got = &im.rgba[4 * (size_t(py) * size_t(w) + size_t(px))];
          for (int k = 0; k < 3; ++k)
            EXPECT_NEAR(double(got[k]), want[k], 4.0)
                << renderer.value()->description() << (withIds ? "" : ", no ids") << ": x " << x
                << ", y " << y << ", channel " << k;
        }
    }
  }
  if (backEnds == 0) GTEST_SKIP() << "no renderer here";
}

}  // namespace
}  // namespace gf::demo

#endif  // GF_HAS_DEMO_APP
