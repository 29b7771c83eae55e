// Force-ratio split points of broken edges (thesis sec 4.4.1, fig 4.10) against independent
// truths: in static equilibrium the elastic force on a free node is minus the load applied to
// it, so a bar held at one end under a known load distribution breaks its edges at known
// ratios; a shattered body's surface stays closed with every ratio inside the clamp; a
// snapshot brings the split surface back.
#include <graphfrac/jobs.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <tuple>

#include "common/sim_helpers.h"
#include "kernels/split_point.h"

namespace gf {
namespace {

// Each undirected edge of each fragment's triangles is used exactly twice, once each way: the
// surface is closed and consistently oriented. Returns the number of bad edges.
int openEdges(const SurfaceView& v) {
  std::map<std::tuple<int32_t, uint32_t, uint32_t>, int> count;  // (fragment, lo, hi) -> +-1 sum
  std::map<std::tuple<int32_t, uint32_t, uint32_t>, int> uses;
  for (size_t t = 0; t < v.indices.size() / 3; ++t)
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = v.indices[3 * t + size_t(k)], b = v.indices[3 * t + size_t((k + 1) % 3)];
      const auto key = std::make_tuple(v.vertexFragment[a], std::min(a, b), std::max(a, b));
      count[key] += a < b ? 1 : -1;
      ++uses[key];
    }
  int bad = 0;
  for (const auto& [key, n] : uses) bad += (n != 2 || count[key] != 0) ? 1 : 0;
  return bad;
}

// Bar [0, 1] x [0, 0.1]^2 held at x = 0, every other node loaded along +x with F0 x^p: once
// static, each free node's elastic force is -F0 x^p, so edge (a, b) splits at
// clamp(x_b^p / (x_a^p + x_b^p)) from a. Every edge between free nodes is then given a tiny
// strength so the next step breaks all those in tension. Returns the largest error of a stress
// break's split and the number of breaks checked whose ratio is off the midpoint by > 0.05.
double barSplitError(int cells, double p, int* offMidpoint, int* checked, JobSystem* jobs = nullptr,
                     std::vector<std::pair<int32_t, float>>* splits = nullptr) {
  BodyDef def;
  def.mesh = gen::box(1.0, 0.1, 0.1, cells, 2, 2);
  def.material = Material::stableNeoHookean(1e9, 0.3, 1000);
  def.material.massDamping = 50;
  def.solver.newtonIterations = 20;
  def.solver.newtonTolerance = 1e-12;
  def.fracture.enabled = true;
  def.fracture.strength = 1e12;
  def.fracture.splitPoint = SplitPoint::ForceRatio;
  Grip hold;
  hold.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  def.grips = {hold};
  const double F0 = 1e3;
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    const double x = def.mesh.positions[3 * n];
    if (x > 1e-9) def.forces.push_back({int32_t(n), glm::vec3(float(F0 * std::pow(x, p)), 0, 0)});
  }
  World world(WorldDef{glm::vec3(0), Backend::Cpu, jobs, 1, {}});
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok()) << (id.ok() ? "" : id.error().message);
  if (!id.ok()) return 1;
  for (int s = 0; s < 10; ++s) (void)world.step(0.1);
  EXPECT_EQ(world.fractureStats(id.value()).brokenEdges, 0);

  const std::span<const int32_t> edges = world.edges(id.value());
  const double* X = def.mesh.positions.data();
  std::vector<double> strength(edges.size() / 2, 1e12);
  for (size_t e = 0; e < strength.size(); ++e)
    if (X[3 * size_t(edges[2 * e])] > 1e-9 && X[3 * size_t(edges[2 * e + 1])] > 1e-9)
      strength[e] = 1;
  EXPECT_TRUE(world.setEdgeStrengths(id.value(), strength).ok());
  (void)world.step(1e-4);
  double worst = 0;
  *offMidpoint = 0;
  *checked = 0;
  for (const FractureEvent& ev : world.fractureEvents()) {
    // A severed edge broke with no force on it (every tet around it split): midpoint.
    if (ev.cause == FractureEvent::Cause::Severed) continue;
    EXPECT_EQ(ev.cause, FractureEvent::Cause::Stress);
    const double fa = F0 * std::pow(X[3 * size_t(ev.nodeA)], p);
    const double fb = F0 * std::pow(X[3 * size_t(ev.nodeB)], p);
    const double expected = std::clamp(fb / (fa + fb), kMinSplitRatio, 1 - kMinSplitRatio);
    worst = std::max(worst, std::fabs(double(ev.split) - expected));
    *offMidpoint += std::fabs(expected - 0.5) > 0.05 ? 1 : 0;
    ++*checked;
    if (splits) splits->push_back({ev.edge, ev.split});
  }
  return worst;
}

TEST(SplitPoints, LoadedBarBreaksAtTheRatioOfItsNodalForces) {
  // Linear and quadratic loads (a spinning bar's and a steeper one) on two resolutions, and a
  // quartic one whose ratios near the held end reach the clamp.
  const std::tuple<int, double> cases[] = {{10, 1.0}, {16, 1.0}, {10, 2.0}, {16, 2.0}, {10, 4.0}};
  for (const auto& [cells, p] : cases) {
    int off = 0, checked = 0;
    const double err = barSplitError(cells, p, &off, &checked);
    std::printf(
        "bar %d cells, load x^%.0f: %d stress breaks, %d off the midpoint, worst split "
        "error %.2e\n",
        cells, p, checked, off, err);
    EXPECT_GT(checked, 4 * cells) << cells << " cells, p " << p;
    EXPECT_GT(off, cells) << cells << " cells, p " << p;
    EXPECT_LT(err, 1e-3) << cells << " cells, p " << p;
  }
}

// The split stage sums each node's element forces in element order, so the ratios are the same
// bits for any thread count (ARCHITECTURE: determinism).
TEST(SplitPoints, RatiosAreTheSameBitsForAnyThreadCount) {
  ThreadPoolJobSystem pool2(2), pool4(4);
  std::vector<std::pair<int32_t, float>> serial, two, four;
  int off = 0, checked = 0;
  (void)barSplitError(16, 2.0, &off, &checked, nullptr, &serial);
  (void)barSplitError(16, 2.0, &off, &checked, &pool2, &two);
  (void)barSplitError(16, 2.0, &off, &checked, &pool4, &four);
  EXPECT_GT(serial.size(), 100u);
  EXPECT_EQ(serial, two);
  EXPECT_EQ(serial, four);
}

TEST(SplitPoints, MidpointSettingKeepsEveryEdgeAtItsMiddle) {
  BodyDef def;
  def.mesh = gen::box(1.0, 0.1, 0.1, 10, 2, 2);
  def.material = Material::stableNeoHookean(1e6, 0.0, 1000);
  def.fracture.enabled = true;
  def.fracture.strength = 1e4;
  Grip left, right;
  left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x > 1 - 1e-9; });
  left.velocity = glm::vec3(-0.2f, 0, 0);
  right.velocity = glm::vec3(0.2f, 0, 0);
  def.grips = {left, right};
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  ASSERT_TRUE(world.createBody(def).ok());
  int events = 0;
  for (int s = 0; s < 60 && events == 0; ++s) {
    (void)world.step(1e-2);
    for (const FractureEvent& ev : world.fractureEvents()) {
      EXPECT_EQ(ev.split, 0.5f);
      ++events;
    }
  }
  EXPECT_GT(events, 0);
}

// Thesis Table 4.1's glass bunny thrown at a ball (as ShatteredSurfaceStaysOnTheMaterial):
// with force-ratio splits every broken edge's ratio lies in the clamp, many differ from the
// midpoint, and every fragment's surface is closed after every step.
TEST(SplitPoints, ShatteredBunnyStaysClosedWithRatiosInTheClamp) {
  Result<TetMesh> mesh = TetMesh::fromFile(GF_SOURCE_DIR "/scenes/meshes/bunny_small.msh");
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  BodyDef def;
  def.mesh = std::move(mesh.value());
  for (double& p : def.mesh.positions) p *= 0.03;
  test::makeTableGlass(def);
  def.fracture.splitPoint = SplitPoint::ForceRatio;
  def.initialVelocity = glm::vec3(-20, 0, 0);
  Collider ball;
  ball.kind = Collider::Kind::Sphere;
  ball.point = glm::vec3(-0.26f, 0.12f, 0);
  ball.radius = 0.08f;
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {ball}});
  const BodyId id = world.createBody(def).value();
  int stress = 0, plane = 0, stressOff = 0, planeOff = 0, clamped = 0, bad = 0;
  float lo = 1, hi = 0;
  for (int s = 0; s < 30; ++s) {
    (void)world.step(1e-3);
    for (const FractureEvent& ev : world.fractureEvents()) {
      lo = std::min(lo, ev.split);
      hi = std::max(hi, ev.split);
      const bool off = std::fabs(ev.split - 0.5f) > 0.05f;
      clamped += (ev.split == float(kMinSplitRatio) || ev.split == float(1 - kMinSplitRatio));
      if (ev.cause == FractureEvent::Cause::Stress) {
        ++stress;
        stressOff += off;
      } else {
        ++plane;
        planeOff += off;
      }
    }
    bad += openEdges(world.surface(id));
  }
  const FractureStats f = world.fractureStats(id);
  std::printf(
      "bunny, force ratio: %d broken edges, %d fragments; %d stress breaks (%d off the "
      "midpoint), %d plane breaks (%d off); ratios in [%.3f, %.3f], %d at the clamp; "
      "open edges %d\n",
      f.brokenEdges, f.fragments, stress, stressOff, plane, planeOff, double(lo), double(hi),
      clamped, bad);
  EXPECT_GT(f.fragments, 1);
  EXPECT_GT(stressOff, 0);
  EXPECT_GE(lo, float(kMinSplitRatio));
  EXPECT_LE(hi, float(1 - kMinSplitRatio));
  EXPECT_EQ(bad, 0);
}

// The split ratios are state: restoring a snapshot taken after force-ratio breaks gives back
// the surface of that moment bit for bit.
TEST(SplitPoints, SnapshotRestoresTheSplitSurface) {
  BodyDef def;
  def.mesh = gen::box(0.4, 0.1, 0.1, 8, 2, 2);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.fracture.enabled = true;
  def.fracture.strength = 2e4;
  def.fracture.splitPoint = SplitPoint::ForceRatio;
  Grip left, right;
  left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes =
      test::selectNodes(def.mesh, [](double x, double, double) { return x > 0.4 - 1e-9; });
  left.velocity = glm::vec3(-0.2f, 0, 0);
  right.velocity = glm::vec3(0.3f, 0.05f, 0);
  def.grips = {left, right};
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(def).value();
  int s = 0;
  for (; s < 200 && world.fractureStats(id).brokenEdges == 0; ++s) (void)world.step(1e-2);
  ASSERT_GT(world.fractureStats(id).brokenEdges, 0);
  const WorldSnapshot snap = world.snapshot();
  const SurfaceView before = world.surface(id);
  const std::vector<float> positions(before.positions.begin(), before.positions.end());
  const std::vector<uint32_t> indices(before.indices.begin(), before.indices.end());
  for (int k = 0; k < 20; ++k) (void)world.step(1e-2);
  ASSERT_TRUE(world.restore(snap).ok());
  const SurfaceView after = world.surface(id);
  EXPECT_EQ(std::vector<float>(after.positions.begin(), after.positions.end()), positions);
  EXPECT_EQ(std::vector<uint32_t>(after.indices.begin(), after.indices.end()), indices);
}

// What the crack faces of a surface look like against a reference plane (unit normal n
// through point p): area-weighted RMS distance of their triangles' centroids from the plane,
// area-weighted mean angle [deg] between their normals and the plane's (either side), and the
// mean and smallest triangle quality 4 sqrt(3) A / sum(l^2) (1 for an equilateral triangle).
struct CrackLook {
  int triangles = 0;
  double rmsDistance = 0, meanAngleDeg = 0, meanQuality = 0, minQuality = 1;
};
CrackLook crackLook(const SurfaceView& v, glm::dvec3 n, glm::dvec3 p) {
  CrackLook c;
  double area = 0, d2 = 0, angle = 0, q = 0;
  for (size_t t = 0; t < v.crackMask.size(); ++t) {
    if (!v.crackMask[t]) continue;
    glm::dvec3 x[3];
    for (int k = 0; k < 3; ++k) {
      const uint32_t i = v.indices[3 * t + size_t(k)];
      x[k] = {v.positions[3 * i], v.positions[3 * i + 1], v.positions[3 * i + 2]};
    }
    const glm::dvec3 a = glm::cross(x[1] - x[0], x[2] - x[0]);
    const double A = 0.5 * glm::length(a);
    if (A <= 0) {
      c.minQuality = 0;
      continue;
    }
    const double l2 = glm::dot(x[1] - x[0], x[1] - x[0]) + glm::dot(x[2] - x[1], x[2] - x[1]) +
                      glm::dot(x[0] - x[2], x[0] - x[2]);
    const double quality = 4 * std::sqrt(3.0) * A / l2;
    const double dist = glm::dot((x[0] + x[1] + x[2]) / 3.0 - p, n);
    area += A;
    d2 += A * dist * dist;
    angle += A * std::acos(std::min(1.0, std::fabs(glm::dot(a, n)) / (2 * A)));
    q += quality;
    c.minQuality = std::min(c.minQuality, quality);
    ++c.triangles;
  }
  if (c.triangles == 0) return c;
  c.rmsDistance = std::sqrt(d2 / area);
  c.meanAngleDeg = angle / area * 180 / M_PI;
  c.meanQuality = q / c.triangles;
  return c;
}

// The column of scenes/demo.json cut by its 45-degree plane blade.
CrackLook cutColumn(SplitPoint mode) {
  BodyDef def;
  def.mesh = gen::box(0.08, 0.24, 0.08, 4, 12, 4);
  def.material = Material::stableNeoHookean(1e10, 0.3, 2700);
  def.fracture.enabled = true;
  def.fracture.strength = 1e12;
  def.fracture.splitPoint = mode;
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(def).value();
  const glm::dvec3 n = glm::normalize(glm::dvec3(1, 1, 0)), p(0.04, 0.15, 0.04);
  Blade blade;
  const glm::dvec3 u = glm::normalize(glm::dvec3(1, -1, 0)), w(0, 0, 1);
  for (const auto& [s, t] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}})
    blade.vertices.push_back(glm::vec3(p + 0.3 * (double(s) * u + double(t) * w)));
  blade.triangles = {0, 1, 2, 0, 2, 3};
  EXPECT_TRUE(world.cut(id, blade).ok());
  (void)world.step(1e-3);
  // Two pieces; the other fragments are chips, nodes whose every tet the blade split
  // (docs/design.md "Severed edges").
  const FractureStats fs = world.fractureStats(id);
  EXPECT_EQ(fs.fragments - fs.chips, 2);
  return crackLook(world.surface(id), n, p);
}

// A bar torn by its grips (stress breaks): the ideal crack is a plane across the bar (x = const
// through the crack faces' mean, taken from the midpoint run).
CrackLook tornBar(SplitPoint mode, double* crackX) {
  BodyDef def;
  def.mesh = gen::box(0.4, 0.1, 0.1, 16, 4, 4);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.fracture.enabled = true;
  def.fracture.strength = 3e4;
  def.fracture.radius = 1;
  def.fracture.splitPoint = mode;
  Grip left, right;
  left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes =
      test::selectNodes(def.mesh, [](double x, double, double) { return x > 0.4 - 1e-9; });
  left.velocity = glm::vec3(-0.1f, 0, 0);
  right.velocity = glm::vec3(0.1f, 0, 0);
  def.grips = {left, right};
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(def).value();
  for (int s = 0; s < 400 && world.fractureStats(id).fragments < 2; ++s) (void)world.step(5e-3);
  EXPECT_GE(world.fractureStats(id).fragments, 2);
  const SurfaceView v = world.surface(id);
  if (*crackX < 0) {
    double sx = 0, n = 0;
    for (size_t t = 0; t < v.crackMask.size(); ++t)
      if (v.crackMask[t])
        for (int k = 0; k < 3; ++k) {
          sx += v.positions[3 * v.indices[3 * t + size_t(k)]];
          ++n;
        }
    *crackX = sx / n;
  }
  return crackLook(v, {1, 0, 0}, {*crackX, 0, 0});
}

TEST(SplitPoints, CrackFacesOfBothSettings) {
  const CrackLook cutMid = cutColumn(SplitPoint::Midpoint);
  const CrackLook cutRatio = cutColumn(SplitPoint::ForceRatio);
  double crackX = -1;
  const CrackLook barMid = tornBar(SplitPoint::Midpoint, &crackX);
  const CrackLook barRatio = tornBar(SplitPoint::ForceRatio, &crackX);
  auto print = [](const char* what, const CrackLook& c) {
    std::printf(
        "%-28s %5d crack triangles: rms distance from the plane %.3f mm, mean normal "
        "angle %.1f deg, quality mean %.3f min %.3f\n",
        what, c.triangles, 1e3 * c.rmsDistance, c.meanAngleDeg, c.meanQuality, c.minQuality);
  };
  print("45-degree cut, midpoint", cutMid);
  print("45-degree cut, force ratio", cutRatio);
  print("torn bar, midpoint", barMid);
  print("torn bar, force ratio", barRatio);
  for (const CrackLook* c : {&cutMid, &cutRatio, &barMid, &barRatio}) {
    EXPECT_GT(c->triangles, 0);
    EXPECT_GT(c->minQuality, 0.0);
  }
}

}  // namespace
}  // namespace gf
