// Embedded render meshes (thesis sec 7.3.2): an affine motion of the tets is reproduced to
// round-off, a bent beam's render surface stays on the deformed body, a shattered body's drawn
// fragments are measured for closedness, a body without a render mesh keeps the tet surface
// bit for bit, bad render meshes are refused with the field named, and the per-frame cost is
// printed against the step's.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <tuple>
#include <vector>

#include "common/sim_helpers.h"
#include "mesh/edge_graph.h"
#include "surface/crack_surface.h"
#include "surface/embedded_mesh.h"

namespace gf {
namespace {

// The welded surface of the lattice [0, n_x] x [0, n_y] x [0, n_z] scaled to the box
// [lo, lo + size], outward counter-clockwise, with normals (p - centre) / |p - centre| (any
// unit field will do; it tests the normal map, not the mesh).
RenderMesh boxSurface(glm::dvec3 lo, glm::dvec3 size, int nx, int ny, int nz) {
  RenderMesh m;
  const int n[3] = {nx, ny, nz};
  std::map<std::tuple<int, int, int>, uint32_t> ids;
  auto vertex = [&](int i, int j, int k) {
    auto [it, added] = ids.emplace(std::make_tuple(i, j, k), uint32_t(ids.size()));
    if (added) {
      const glm::dvec3 p = lo + size * glm::dvec3(double(i) / nx, double(j) / ny, double(k) / nz);
      const glm::dvec3 d = glm::normalize(p - (lo + 0.5 * size));
      m.positions.insert(m.positions.end(), {p.x, p.y, p.z});
      m.normals.insert(m.normals.end(), {float(d.x), float(d.y), float(d.z)});
      m.uvs.insert(m.uvs.end(), {float(p.x), float(p.y + p.z)});
    }
    return it->second;
  };
  for (int d = 0; d < 3; ++d) {
    const int u = (d + 1) % 3, v = (d + 2) % 3;  // e_u x e_v = e_d
    for (int side = 0; side < 2; ++side)
      for (int a = 0; a < n[u]; ++a)
        for (int b = 0; b < n[v]; ++b) {
          uint32_t q[4];
          const int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
          for (int c = 0; c < 4; ++c) {
            int ijk[3];
            ijk[d] = side * n[d];
            ijk[u] = a + du[c];
            ijk[v] = b + dv[c];
            q[c] = vertex(ijk[0], ijk[1], ijk[2]);
          }
          if (side == 1)
            m.indices.insert(m.indices.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
          else
            m.indices.insert(m.indices.end(), {q[0], q[2], q[1], q[0], q[3], q[2]});
        }
  }
  return m;
}

glm::dvec3 at(std::span<const double> p, size_t i) {
  return {p[3 * i], p[3 * i + 1], p[3 * i + 2]};
}

// Per fragment of a drawn surface: triangles, render triangles, and undirected edges not used
// exactly once in each direction by that fragment's triangles (0: closed and 2-manifold with
// consistent orientation).
struct FragmentClosure {
  int triangles = 0, renderTriangles = 0, openEdges = 0;
};
std::map<int32_t, FragmentClosure> closure(const SurfaceView& s) {
  std::map<int32_t, FragmentClosure> out;
  std::map<int32_t, std::map<std::pair<uint32_t, uint32_t>, int>> edges;  // +1 a<b, -1 a>b
  std::map<int32_t, std::map<std::pair<uint32_t, uint32_t>, int>> uses;
  for (size_t t = 0; t < s.indices.size() / 3; ++t) {
    const uint32_t* id = &s.indices[3 * t];
    const int32_t f = s.vertexFragment[id[0]];
    FragmentClosure& c = out[f];
    ++c.triangles;
    if (!s.crackMask[t]) ++c.renderTriangles;
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = id[k], b = id[(k + 1) % 3];
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      edges[f][key] += a < b ? 1 : -1;
      ++uses[f][key];
    }
  }
  for (auto& [f, e] : edges)
    for (auto& [key, balance] : e)
      if (balance != 0 || uses[f][key] != 2) ++out[f].openEdges;
  return out;
}

// A bar 1 x 0.1 x 0.1 m of 20 x 2 x 2 cells (6 tets each).
BodyDef bar() {
  BodyDef def;
  def.mesh = gen::box(1.0, 0.1, 0.1, 20, 2, 2);
  def.material = Material::stableNeoHookean(1e7, 0.3, 1000);
  return def;
}

// x = A X + b moves the embedded vertices to A P + b and maps their normals to A^-T N,
// normalised, to round-off, also for vertices outside the tets (the render mesh is 4 % larger
// than the bar) whose coordinates are extrapolated.
TEST(RenderMesh, AffineMotionIsReproducedToRoundOff) {
  BodyDef def = bar();
  const glm::dvec3 lo(-0.02, -0.002, -0.002), size(1.04, 0.104, 0.104);
  def.renderMesh = boxSurface(lo, size, 17, 5, 3);
  const glm::dmat3 A(1.1, 0.2, -0.1, 0.05, 0.9, 0.3, -0.2, 0.1, 1.3);  // columns
  const glm::dvec3 shift(0.3, -2.0, 0.7);
  std::vector<double> x(def.mesh.positions.size());
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    const glm::dvec3 p = A * at(def.mesh.positions, n) + shift;
    for (int c = 0; c < 3; ++c) x[3 * n + size_t(c)] = p[c];
  }

  // The internal double output, to 1e-12.
  Result<detail::EmbeddedBinding> bound =
      detail::EmbeddedBinding::bind(def.mesh, *def.renderMesh, "renderMesh");
  ASSERT_TRUE(bound.ok()) << bound.error().message;
  const detail::EmbeddedBinding& b = bound.value();
  EXPECT_GT(b.outsideCount, 0);
  const detail::EdgeGraph graph =
      detail::EdgeGraph::build(def.mesh.tets.data(), def.mesh.tetCount(), def.mesh.nodeCount());
  std::vector<Mat3> restInverse(def.mesh.tetCount());
  for (size_t t = 0; t < def.mesh.tetCount(); ++t) {
    Vec3 P[4];
    for (int k = 0; k < 4; ++k) {
      const glm::dvec3 p = at(def.mesh.positions, size_t(def.mesh.tets[4 * t + size_t(k)]));
      P[k] = {p.x, p.y, p.z};
    }
    restInverse[t] = inverse(fromColumns(P[1] - P[0], P[2] - P[0], P[3] - P[0]));
  }
  const std::vector<uint8_t> broken(size_t(graph.edgeCount), 0);
  const std::vector<int32_t> fragment(def.mesh.nodeCount(), 0);
  detail::CrackSurface crack;
  crack.init(def.mesh, graph);
  detail::EmbeddedSurface surface;
  surface.init(b, def.mesh, graph, restInverse.data());
  surface.rebuild(broken.data(), fragment.data());
  crack.rebuild(broken.data(), fragment.data(), x.data());
  surface.update(x.data(), crack);
  const glm::dmat3 cof = glm::transpose(glm::inverse(A));
  double posErr = 0, nrmErr = 0;
  ASSERT_EQ(surface.embeddedVertexCount(), def.renderMesh->vertexCount());
  for (uint32_t v = 0; v < surface.embeddedVertexCount(); ++v) {
    const size_t s = size_t(surface.vertexSource()[v]);
    const glm::dvec3 want = A * at(def.renderMesh->positions, s) + shift;
    posErr = std::max(posErr, glm::length(at(surface.positionsDouble(), v) - want));
    const glm::dvec3 N(def.renderMesh->normals[3 * s], def.renderMesh->normals[3 * s + 1],
                       def.renderMesh->normals[3 * s + 2]);
    const glm::dvec3 wantN = glm::normalize(cof * glm::normalize(N));
    nrmErr = std::max(nrmErr, glm::length(at(surface.normalsDouble(), v) - wantN));
  }
  std::printf(
      "affine: %d of %zu vertices outside the tets (up to %.3g m); position error %.3g m, "
      "normal error %.3g\n",
      b.outsideCount, def.renderMesh->vertexCount(), b.maxOutside, posErr, nrmErr);
  EXPECT_LT(posErr, 1e-12);
  EXPECT_LT(nrmErr, 1e-12);

  // Through the World: the same, as floats, with the UVs carried.
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(def).value();
  ASSERT_TRUE(world.setPositions(id, x).ok());
  const SurfaceView sv = world.surface(id);
  ASSERT_EQ(sv.positions.size(), 3 * def.renderMesh->vertexCount());
  ASSERT_EQ(sv.indices.size(), def.renderMesh->indices.size());
  ASSERT_EQ(sv.uvs.size(), def.renderMesh->uvs.size());
  EXPECT_EQ(sv.dirtyEnd, def.renderMesh->vertexCount());
  double worldErr = 0;
  for (size_t v = 0; v < sv.positions.size() / 3; ++v) {
    const glm::dvec3 got(sv.positions[3 * v], sv.positions[3 * v + 1], sv.positions[3 * v + 2]);
    worldErr = std::max(worldErr, glm::length(got - at(surface.positionsDouble(), v)));
    EXPECT_EQ(sv.uvs[2 * v], def.renderMesh->uvs[2 * size_t(surface.vertexSource()[v])]);
  }
  EXPECT_LT(worldErr, 1e-6);
}

// Point-triangle distance by sampling-free projection (independent of the library's).
double pointTriangle(glm::dvec3 p, glm::dvec3 a, glm::dvec3 b, glm::dvec3 c) {
  const glm::dvec3 n = glm::cross(b - a, c - a);
  const double nn = glm::dot(n, n);
  const glm::dvec3 q = p - glm::dot(p - a, n) / nn * n;
  // Inside when q is on the inner side of all three edges.
  const bool inside = glm::dot(glm::cross(b - a, q - a), n) >= 0 &&
                      glm::dot(glm::cross(c - b, q - b), n) >= 0 &&
                      glm::dot(glm::cross(a - c, q - c), n) >= 0;
  if (inside) return glm::length(p - q);
  auto segment = [&](glm::dvec3 s0, glm::dvec3 s1) {
    const double t = std::clamp(glm::dot(p - s0, s1 - s0) / glm::dot(s1 - s0, s1 - s0), 0.0, 1.0);
    return glm::length(p - (s0 + t * (s1 - s0)));
  };
  return std::min({segment(a, b), segment(b, c), segment(c, a)});
}

// A cantilever bar sagging under gravity, far more than a cell. A render mesh on the bar's
// surface at twice the resolution stays on the deformed tet boundary (linear interpolation
// keeps a point of a face on that face), and its vertices at nodes stay at the nodes; one 30 %
// of a cell outside stays within a cell of the deformed boundary.
TEST(RenderMesh, FollowsABentBeamWithinOneCell) {
  const double cell = 0.05;
  for (double offset : {0.0, 0.3 * cell}) {
    BodyDef def = bar();
    def.material = Material::stableNeoHookean(3e6, 0.3, 1000);
    def.material.massDamping = 20;
    def.renderMesh =
        boxSurface(glm::dvec3(-offset), glm::dvec3(1, 0.1, 0.1) + 2 * offset, 40, 4, 4);
    Grip pin;
    pin.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
    def.grips = {pin};
    World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
    const BodyId id = world.createBody(def).value();
    for (int s = 0; s < 60; ++s) (void)world.step(1.0 / 60);
    const std::span<const double> x = world.positions(id);
    double tip = 0;
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
      tip = std::max(tip, def.mesh.positions[3 * n + 1] - x[3 * n + 1]);
    ASSERT_GT(tip, 2 * cell) << "the bar must bend by more than two cells";

    const std::vector<int32_t> faces = def.mesh.boundaryFaces();
    const SurfaceView sv = world.surface(id);
    double worst = 0;
    int atNodes = 0;
    for (size_t v = 0; v < sv.positions.size() / 3; ++v) {
      const glm::dvec3 p(sv.positions[3 * v], sv.positions[3 * v + 1], sv.positions[3 * v + 2]);
      double d = HUGE_VAL;
      for (size_t f = 0; f < faces.size() / 3; ++f)
        d = std::min(d,
                     pointTriangle(p, at(x, size_t(faces[3 * f])), at(x, size_t(faces[3 * f + 1])),
                                   at(x, size_t(faces[3 * f + 2]))));
      worst = std::max(worst, d);
      // Render vertices at the bar's boundary nodes (even lattice indices) stay on them.
      double nearest = HUGE_VAL;
      for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
        nearest = std::min(nearest, glm::length(p - at(x, n)));
      atNodes += nearest < 1e-5 ? 1 : 0;
    }
    std::printf(
        "bent bar (tip sag %.3f m, cell %.3f m), render mesh %.3f m outside: farthest "
        "vertex from the deformed tet boundary %.3g m; %d vertices on nodes\n",
        tip, cell, offset, worst, atNodes);
    if (offset == 0) {
      std::vector<uint8_t> onBoundary(def.mesh.nodeCount(), 0);
      for (int32_t n : faces) onBoundary[size_t(n)] = 1;
      EXPECT_LT(worst, 1e-5);  // float positions
      EXPECT_EQ(atNodes, std::count(onBoundary.begin(), onBoundary.end(), 1));
    } else {
      EXPECT_LT(worst, cell);
    }
  }
}

// The brittle bar of Fracture.MoreBrittleRegionsMakeMoreFragments (fig 4.19) with a render mesh
// on its surface. Every triangle lies in one fragment; every vertex stays near its node;
// fragments drawn only with crack faces are closed; the closure of the others is measured.
TEST(RenderMesh, ShatteredBodyFragmentsAreMeasuredForClosure) {
  BodyDef def;
  def.mesh = gen::box(1.0, 0.1, 0.1, 40, 4, 4);
  def.material = Material::stableNeoHookean(1e7, 0.2, 2500);
  def.fracture.enabled = true;
  def.fracture.strength = 1e5;
  def.fracture.brittle = true;
  def.fracture.regions = 6;
  def.renderMesh = boxSurface(glm::dvec3(0), glm::dvec3(1, 0.1, 0.1), 60, 6, 6);
  Grip left, right;
  left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x > 1 - 1e-9; });
  left.velocity = glm::vec3(-0.05f, 0, 0);
  right.velocity = glm::vec3(0.05f, 0, 0);
  def.grips = {left, right};
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(def).value();

  // Whole: the artist's closed mesh, closed.
  {
    const SurfaceView sv = world.surface(id);
    const auto c = closure(sv);
    ASSERT_EQ(c.size(), 1u);
    EXPECT_EQ(c.begin()->second.openEdges, 0);
  }
  for (int s = 0; s < 40; ++s) {
    (void)world.step(1.0 / 60);
    (void)world.surface(id);  // as a game would, every frame
  }
  const FractureStats fs = world.fractureStats(id);
  const SurfaceView sv = world.surface(id);
  ASSERT_GT(fs.fragments, 2);
  const std::span<const double> x = world.positions(id);
  for (size_t t = 0; t < sv.indices.size() / 3; ++t)
    for (int k = 1; k < 3; ++k)
      ASSERT_EQ(sv.vertexFragment[sv.indices[3 * t + size_t(k)]],
                sv.vertexFragment[sv.indices[3 * t]]);
  // A vertex follows its fragment: it stays within two cell diagonals of its node.
  const double reach = 2 * std::sqrt(3.0) * 0.025;
  double far = 0;
  for (size_t v = 0; v < sv.vertexNode.size(); ++v) {
    const glm::dvec3 p(sv.positions[3 * v], sv.positions[3 * v + 1], sv.positions[3 * v + 2]);
    far = std::max(far, glm::length(p - at(x, size_t(sv.vertexNode[v]))));
  }
  EXPECT_LT(far, reach);

  int withRender = 0, closedWithRender = 0, crackOnly = 0, closedCrackOnly = 0, openEdges = 0;
  for (const auto& [f, c] : closure(sv)) {
    if (c.renderTriangles > 0) {
      ++withRender;
      closedWithRender += c.openEdges == 0 ? 1 : 0;
      openEdges += c.openEdges;
    } else {
      ++crackOnly;
      closedCrackOnly += c.openEdges == 0 ? 1 : 0;
    }
  }
  std::printf(
      "shattered bar: %d fragments, %d broken edges; drawn: %zu triangles. Fragments "
      "with render triangles: %d, closed and 2-manifold %d (%d open edges in all); "
      "fragments of crack faces only: %d, closed %d; farthest vertex from its node %.3g "
      "m\n",
      fs.fragments, fs.brokenEdges, sv.indices.size() / 3, withRender, closedWithRender, openEdges,
      crackOnly, closedCrackOnly, far);
  EXPECT_EQ(closedCrackOnly, crackOnly);
}

// A body without a render mesh shows its tet surface exactly as a CrackSurface built from the
// same state, also when a body with a render mesh shares its world.
TEST(RenderMesh, BodyWithoutRenderMeshKeepsTheTetSurfaceBitForBit) {
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  BodyDef plain = bar();
  plain.fracture.enabled = true;
  plain.fracture.strength = 1e3;  // breaks under its own sag
  Grip pin;
  pin.nodes = test::selectNodes(plain.mesh, [](double x, double, double) { return x < 1e-9; });
  plain.grips = {pin};
  BodyDef drawn = plain;
  drawn.renderMesh = boxSurface(glm::dvec3(0), glm::dvec3(1, 0.1, 0.1), 40, 4, 4);
  const BodyId a = world.createBody(plain).value();
  const BodyId b = world.createBody(drawn).value();
  for (int s = 0; s < 10; ++s) {
    (void)world.step(1.0 / 60);
    (void)world.surface(a);
    (void)world.surface(b);
  }
  ASSERT_GT(world.fractureStats(a).brokenEdges, 0);
  const SurfaceView sv = world.surface(a);
  EXPECT_TRUE(sv.uvs.empty());

  const detail::EdgeGraph graph = detail::EdgeGraph::build(
      plain.mesh.tets.data(), plain.mesh.tetCount(), plain.mesh.nodeCount());
  const std::span<const uint8_t> broken = world.brokenEdges(a);
  ASSERT_EQ(broken.size(), size_t(graph.edgeCount));
  detail::CrackSurface ref;
  ref.init(plain.mesh, graph);
  ref.rebuild(broken.data(), world.nodeFragments(a).data(), world.positions(a).data());
  ASSERT_EQ(sv.positions.size(), ref.positions().size());
  ASSERT_EQ(sv.indices.size(), ref.indices().size());
  EXPECT_TRUE(std::equal(sv.positions.begin(), sv.positions.end(), ref.positions().begin()));
  EXPECT_TRUE(std::equal(sv.normals.begin(), sv.normals.end(), ref.normals().begin()));
  EXPECT_TRUE(std::equal(sv.indices.begin(), sv.indices.end(), ref.indices().begin()));
  EXPECT_TRUE(std::equal(sv.crackMask.begin(), sv.crackMask.end(), ref.crackFlags().begin()));
}

// Bad render meshes are refused with the field named, and the world stays as it was.
TEST(RenderMesh, BadRenderMeshIsRefusedAndNothingChanges) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyDef good = [] {
    BodyDef d = bar();
    d.renderMesh = boxSurface(glm::dvec3(0), glm::dvec3(1, 0.1, 0.1), 4, 2, 2);
    return d;
  }();
  struct Case {
    const char* want;
    void (*spoil)(RenderMesh&);
  };
  const Case cases[] = {
      {"BodyDef.renderMesh.positions: empty", [](RenderMesh& m) { m.positions.clear(); }},
      {"BodyDef.renderMesh.indices: empty", [](RenderMesh& m) { m.indices.clear(); }},
      {"BodyDef.renderMesh.positions[3]: not finite",
       [](RenderMesh& m) { m.positions[10] = std::nan(""); }},
      {"BodyDef.renderMesh.normals[2]: not finite", [](RenderMesh& m) { m.normals[7] = INFINITY; }},
      {"BodyDef.renderMesh.normals[1]: zero length",
       [](RenderMesh& m) { m.normals[3] = m.normals[4] = m.normals[5] = 0; }},
      {"BodyDef.renderMesh.indices[5]: vertex 99999 out of range",
       [](RenderMesh& m) { m.indices[5] = 99999; }},
      {"BodyDef.renderMesh.uvs: ", [](RenderMesh& m) { m.uvs.pop_back(); }},
      {"BodyDef.renderMesh.positions[0]: (-5, 0, 0) lies",
       [](RenderMesh& m) { m.positions[0] = -5; }},
  };
  const uint64_t hash = world.stateHash();
  for (const Case& c : cases) {
    BodyDef def = good;
    c.spoil(*def.renderMesh);
    Result<BodyId> r = world.createBody(def);
    ASSERT_FALSE(r.ok()) << c.want;
    EXPECT_NE(r.error().message.find(c.want), std::string::npos)
        << "want '" << c.want << "' in: " << r.error().message;
    if (std::string(c.want).find(" lies") == std::string::npos) {
      EXPECT_FALSE(def.check().ok()) << c.want;  // BodyDef::check sees the fields too
    }
  }
  EXPECT_EQ(world.stateHash(), hash);
  const Result<BodyId> ok = world.createBody(good);
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  EXPECT_EQ(ok.value().index, 1u);  // no slot was taken by the refused bodies
}

// The per-frame cost of the embedded mesh against the step: a 1 x 0.2 x 0.2 m bar of 6480
// tets with a 58k-vertex render mesh, sagging, one surface update per step.
TEST(RenderMesh, PerFrameCostAgainstTheStep) {
  BodyDef def;
  def.mesh = gen::box(1.0, 0.2, 0.2, 30, 6, 6);
  def.material = Material::stableNeoHookean(1e7, 0.3, 1000);
  Grip pin;
  pin.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  def.grips = {pin};
  BodyDef drawn = def;
  drawn.renderMesh = boxSurface(glm::dvec3(0), glm::dvec3(1, 0.2, 0.2), 240, 48, 48);
  using Clock = std::chrono::steady_clock;
  auto run = [](const BodyDef& d, double& stepMs, double& surfaceMs, size_t& vertices) {
    World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
    const BodyId id = world.createBody(d).value();
    (void)world.step(1.0 / 60);
    vertices = world.surface(id).positions.size() / 3;  // built once, outside the timing
    stepMs = surfaceMs = 0;
    const int frames = 20;
    for (int s = 0; s < frames; ++s) {
      const auto t0 = Clock::now();
      (void)world.step(1.0 / 60);
      const auto t1 = Clock::now();
      (void)world.surface(id);
      const auto t2 = Clock::now();
      stepMs += std::chrono::duration<double, std::milli>(t1 - t0).count() / frames;
      surfaceMs += std::chrono::duration<double, std::milli>(t2 - t1).count() / frames;
    }
  };
  double stepTet, surfTet, stepDrawn, surfDrawn;
  size_t vTet, vDrawn;
  run(def, stepTet, surfTet, vTet);
  run(drawn, stepDrawn, surfDrawn, vDrawn);
  std::printf(
      "per frame, %zu tets, 1 thread: step %.3f ms; tet surface (%zu vertices) %.3f ms "
      "= %.1f %% of the step; render mesh (%zu vertices) %.3f ms = %.1f %% of the step\n",
      def.mesh.tetCount(), stepTet, vTet, surfTet, 100 * surfTet / stepTet, vDrawn, surfDrawn,
      100 * surfDrawn / stepDrawn);
  EXPECT_GT(vDrawn, 50000u);
  EXPECT_GT(stepDrawn, 0);
}

}  // namespace
}  // namespace gf
