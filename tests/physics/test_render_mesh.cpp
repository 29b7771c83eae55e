// Embedded render meshes (thesis sec 7.3.2): an affine motion of the tets is reproduced to
// round-off, a bent beam's render surface stays on the deformed body, a shattered body's drawn
// fragments are closed 2-manifolds that fill the render mesh's volume and nothing outside it
// (the same bits at 1, 2 and 4 threads), a body without a render mesh keeps the tet surface bit
// for bit, bad render meshes are refused with the field named, and the per-frame and per-fracture
// costs are printed against the step's.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <tuple>
#include <vector>

#include "common/embedded_setup.h"
#include "common/render_mesh_checks.h"
#include "common/sim_helpers.h"
#include "mesh/edge_graph.h"
#include "surface/crack_surface.h"
#include "surface/embedded_mesh.h"

namespace gf {
namespace {

using namespace test;

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
  const std::vector<Mat3> restInverse = tetRestInverses(def.mesh);
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

// After the brittle bar shatters, every fragment's drawn triangles are a closed 2-manifold
// (each edge used once in each direction by that fragment's triangles) and every vertex stays
// near its node. At rest positions the fragments' enclosed volumes add up to the render mesh's
// (nothing drawn twice or missing), and each fragment's is its corner cells' (a quarter of each
// of its nodes' tets: the render box is the tets' boundary) within its caps' area times a cell,
// since the cut follows the render edges and a cap's fan stands for the cells' facets.
TEST(RenderMesh, ShatteredBodyFragmentsAreClosedAndFillTheRenderVolume) {
  for (bool release : {false, true}) {
    BodyDef def = brittleBar();
    def.fracture.releaseEveryBatch = release;
    World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
    const BodyId id = world.createBody(def).value();

    // Whole: the artist's closed mesh, closed.
    {
      const SurfaceView sv = world.surface(id);
      const auto c = closure(sv);
      ASSERT_EQ(c.size(), 1u);
      EXPECT_EQ(c.begin()->second.openEdges, 0);
    }
    shatter(world, id, 40);
    const FractureStats fs = world.fractureStats(id);
    const SurfaceView sv = world.surface(id);
    ASSERT_GT(fs.fragments, 2);
    const std::span<const double> x = world.positions(id);
    for (size_t t = 0; t < sv.indices.size() / 3; ++t)
      for (int k = 1; k < 3; ++k)
        ASSERT_EQ(sv.vertexFragment[sv.indices[3 * t + size_t(k)]],
                  sv.vertexFragment[sv.indices[3 * t]]);
    // A vertex follows its fragment: it stays within two cell diagonals of its node (a cap's
    // centre, at most half the bar's diagonal section from its rim, too).
    const double cell = 0.025, reach = 2 * std::sqrt(3.0) * cell;
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

    // The same topology at rest positions.
    std::vector<double> rest(def.mesh.positions.begin(), def.mesh.positions.end());
    ASSERT_TRUE(world.setPositions(id, rest).ok());
    const SurfaceView atRest = world.surface(id);
    ASSERT_EQ(atRest.indices.size(), sv.indices.size());
    const std::map<int32_t, double> drawn = enclosedVolumes(atRest);
    double volume = 0;
    for (const auto& [f, v] : drawn) volume += v;
    const double want = 1.0 * 0.1 * 0.1;
    // Per fragment: its corner cells' volume and its caps' area. With the release a chip (a
    // one-node fragment, every tet around it split) is drawn by the fragments that share its
    // tets, so its quarter of a tet counts for the tet's other corners, evenly.
    const std::span<const int32_t> nodeFragment = world.nodeFragments(id);
    std::map<int32_t, int> nodes;
    for (int32_t f : nodeFragment) ++nodes[f];
    const auto isChip = [&](int32_t f) { return release && nodes.at(f) == 1; };
    std::map<int32_t, double> cells, capArea;
    int chips = 0, drawnChips = 0;
    for (const auto& [f, n] : nodes) {
      chips += isChip(f) ? 1 : 0;
      drawnChips += isChip(f) && drawn.count(f) ? 1 : 0;
    }
    for (size_t t = 0; t < def.mesh.tetCount(); ++t) {
      glm::dvec3 p[4];
      int32_t f[4];
      int whole = 0;
      for (int k = 0; k < 4; ++k) {
        p[k] = at(def.mesh.positions, size_t(def.mesh.tets[4 * t + k]));
        f[k] = nodeFragment[size_t(def.mesh.tets[4 * t + k])];
        whole += isChip(f[k]) ? 0 : 1;
      }
      const double v = glm::dot(p[1] - p[0], glm::cross(p[2] - p[0], p[3] - p[0])) / 6;
      for (int k = 0; k < 4; ++k)
        if (whole == 0 || !isChip(f[k])) cells[f[k]] += v / 4 * (whole ? 4.0 / whole : 1.0);
    }
    for (size_t t = 0; t < atRest.indices.size() / 3; ++t) {
      if (!atRest.crackMask[t]) continue;
      const uint32_t* id3 = &atRest.indices[3 * t];
      glm::dvec3 p[3];
      for (int k = 0; k < 3; ++k)
        p[k] = glm::dvec3(atRest.positions[3 * size_t(id3[k])],
                          atRest.positions[3 * size_t(id3[k]) + 1],
                          atRest.positions[3 * size_t(id3[k]) + 2]);
      capArea[atRest.vertexFragment[id3[0]]] +=
          glm::length(glm::cross(p[1] - p[0], p[2] - p[0])) / 2;
    }
    double worst = 0;  // the largest |drawn - cells| / (cap area * cell) over the fragments
    for (const auto& [f, v] : cells) {
      const double d = std::abs((drawn.count(f) ? drawn.at(f) : 0.0) - v);
      worst = std::max(worst, d / (capArea[f] * cell));
    }
    std::printf(
        "shattered bar (release_every_batch %d): %d fragments, %d broken edges; drawn: %zu "
        "triangles. Fragments "
        "with render triangles: %d, closed and 2-manifold %d (%d open edges in all); "
        "fragments of crack faces only: %d, closed %d; farthest vertex from its node %.3g "
        "m; at rest: fragments' volume %.8g m^3 against the render mesh's %.8g (%.2e relative), "
        "largest |fragment's volume - its cells'| = %.3f x its caps' area x a cell; %d chips, %d "
        "of them drawn\n",
        int(release), fs.fragments, fs.brokenEdges, sv.indices.size() / 3, withRender,
        closedWithRender, openEdges, crackOnly, closedCrackOnly, far, volume, want,
        (volume - want) / want, worst, chips, drawnChips);
    EXPECT_GT(withRender, 2);
    EXPECT_EQ(closedWithRender, withRender);
    EXPECT_EQ(closedCrackOnly, crackOnly);
    // Float positions: 1e-6 relative; caps shared by two fragments cancel.
    EXPECT_NEAR(volume, want, 1e-6 * want);
    EXPECT_LT(worst, 1.0);
    EXPECT_EQ(drawnChips, 0);
  }
}

// The brittle bar drawn with a render box over x in [0.15, 0.85] m only, so the box's ends lie
// inside the tets and the fragments near the bar's ends are outside it. After it shatters,
// fragments wholly outside the box draw nothing, the others are closed, and at rest nothing is
// drawn outside the box and the drawn volumes add up to the box's.
TEST(RenderMesh, ShatteredBodyDrawsOnlyWhatIsInsideItsRenderMesh) {
  BodyDef def = brittleBar();
  def.renderMesh = boxSurface(glm::dvec3(0.15, 0, 0), glm::dvec3(0.7, 0.1, 0.1), 42, 6, 6);
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(def).value();
  shatter(world, id, 40);
  ASSERT_GT(world.fractureStats(id).fragments, 2);
  const SurfaceView sv = world.surface(id);
  int open = 0;
  const auto c = closure(sv);
  for (const auto& [f, fc] : c) open += fc.openEdges;
  EXPECT_EQ(open, 0);

  // Fragments whose nodes all lie outside the box, found from the nodes alone.
  const std::span<const int32_t> nodeFragment = world.nodeFragments(id);
  std::map<int32_t, bool> outside;
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    const double X = def.mesh.positions[3 * n];
    const bool out = X < 0.15 - 1e-9 || X > 0.85 + 1e-9;
    auto [it, added] = outside.emplace(nodeFragment[n], out);
    if (!added) it->second = it->second && out;
  }
  int outsideFragments = 0, outsideDrawn = 0;
  for (const auto& [f, out] : outside)
    if (out) {
      ++outsideFragments;
      outsideDrawn += c.count(f) ? 1 : 0;
    }

  std::vector<double> rest(def.mesh.positions.begin(), def.mesh.positions.end());
  ASSERT_TRUE(world.setPositions(id, rest).ok());
  const SurfaceView atRest = world.surface(id);
  double lo = HUGE_VAL, hi = -HUGE_VAL, volume = 0;
  for (size_t v = 0; v < atRest.positions.size() / 3; ++v) {
    lo = std::min(lo, double(atRest.positions[3 * v]));
    hi = std::max(hi, double(atRest.positions[3 * v]));
  }
  for (const auto& [f, v] : enclosedVolumes(atRest)) volume += v;
  const double want = 0.7 * 0.1 * 0.1;
  std::printf(
      "bar drawn over x in [0.15, 0.85] m: %d fragments, %zu drawn, %d open edges; %d fragments "
      "wholly outside the render mesh, %d of them drawn; at rest drawn x in [%.6f, %.6f], "
      "volume %.8g m^3 against %.8g (%.2e relative)\n",
      world.fractureStats(id).fragments, c.size(), open, outsideFragments, outsideDrawn, lo, hi,
      volume, want, (volume - want) / want);
  EXPECT_GT(outsideFragments, 0);
  EXPECT_EQ(outsideDrawn, 0);
  EXPECT_GT(c.size(), 2u);  // the box is cut between fragments
  EXPECT_GT(lo, 0.15 - 1e-6);
  EXPECT_LT(hi, 0.85 + 1e-6);
  EXPECT_NEAR(volume, want, 1e-6 * want);
}

// A fragment that owns no render vertex and lies inside the render mesh (here the four nodes of
// a tet in the middle of a cube, every edge to the rest broken) is drawn with its tet surface:
// closed, enclosing its corner cells' volume (a quarter of each of its tets per node). The rest
// of the cube is one fragment drawn with the whole render mesh. A chip (the middle node alone,
// no whole tet) is not drawn: free matter with no volume of its own, its cells are the rest's.
TEST(RenderMesh, InteriorFragmentWithoutRenderVerticesIsDrawnWithItsTetFaces) {
  const TetMesh mesh = gen::box(0.1, 0.1, 0.1, 4, 4, 4);
  const RenderMesh render = boxSurface(glm::dvec3(0), glm::dvec3(0.1), 6, 6, 6);
  const detail::EmbeddedBinding b =
      detail::EmbeddedBinding::bind(mesh, render, "renderMesh").value();
  const detail::EdgeGraph graph =
      detail::EdgeGraph::build(mesh.tets.data(), mesh.tetCount(), mesh.nodeCount());
  const std::vector<Mat3> restInverse = tetRestInverses(mesh);
  int32_t centre = -1;
  for (size_t n = 0; n < mesh.nodeCount(); ++n)
    if (glm::length(at(mesh.positions, n) - glm::dvec3(0.05)) < 1e-9) centre = int32_t(n);
  ASSERT_GE(centre, 0);
  // A tet at the centre with no node on the cube's surface.
  auto interior = [&](int32_t n) {
    const glm::dvec3 p = at(mesh.positions, size_t(n));
    bool in = true;
    for (int k = 0; k < 3; ++k) in = in && p[k] > 1e-9 && p[k] < 0.1 - 1e-9;
    return in;
  };
  int32_t middle = -1;
  for (size_t t = 0; t < mesh.tetCount() && middle < 0; ++t) {
    bool has = false, inside = true;
    for (int k = 0; k < 4; ++k) {
      has = has || mesh.tets[4 * t + size_t(k)] == centre;
      inside = inside && interior(mesh.tets[4 * t + size_t(k)]);
    }
    if (has && inside) middle = int32_t(t);
  }
  ASSERT_GE(middle, 0);
  for (bool chip : {false, true}) {
    std::vector<int32_t> fragment(mesh.nodeCount(), 0);
    fragment[size_t(centre)] = 1;
    if (!chip)
      for (int k = 0; k < 4; ++k) fragment[size_t(mesh.tets[4 * size_t(middle) + size_t(k)])] = 1;
    double cells = 0;
    for (size_t t = 0; t < mesh.tetCount(); ++t) {
      glm::dvec3 p[4];
      int in = 0;
      for (int k = 0; k < 4; ++k) {
        p[k] = at(mesh.positions, size_t(mesh.tets[4 * t + size_t(k)]));
        in += fragment[size_t(mesh.tets[4 * t + size_t(k)])];
      }
      cells += in * glm::dot(p[1] - p[0], glm::cross(p[2] - p[0], p[3] - p[0])) / 24;
    }
    std::vector<uint8_t> broken(size_t(graph.edgeCount), 0);
    for (int32_t e = 0; e < graph.edgeCount; ++e)
      broken[size_t(e)] = fragment[size_t(graph.edgeNodes[2 * size_t(e)])] !=
                          fragment[size_t(graph.edgeNodes[2 * size_t(e) + 1])];
    detail::CrackSurface crack;
    crack.init(mesh, graph);
    detail::EmbeddedSurface surface;
    surface.init(b, mesh, graph, restInverse.data());
    surface.setChipsDrawnByNeighbours(true);
    surface.rebuild(broken.data(), fragment.data());
    crack.setExtraFrameNodes(surface.frameNodes());
    crack.rebuild(broken.data(), fragment.data(), mesh.positions.data());
    surface.update(mesh.positions.data(), crack);

    SurfaceView sv;
    sv.positions = surface.positions();
    sv.indices = surface.indices();
    sv.crackMask = surface.crackFlags();
    sv.vertexFragment = surface.vertexFragment();
    const auto c = closure(sv);
    const auto volumes = enclosedVolumes(sv);
    ASSERT_EQ(c.count(0), 1u);
    std::printf(
        "interior %s: %zu drawn fragments; its cells %.6g m^3%s; the rest: %d triangles, %d open "
        "edges, volume %.6g m^3\n",
        chip ? "chip" : "tet", c.size(), cells, chip ? " (not drawn)" : "", c.at(0).triangles,
        c.at(0).openEdges, volumes.at(0));
    EXPECT_EQ(c.at(0).openEdges, 0);
    EXPECT_NEAR(volumes.at(0), 1e-3, 1e-6 * 1e-3);
    if (chip) {
      EXPECT_EQ(c.size(), 1u);
      continue;
    }
    ASSERT_EQ(c.size(), 2u);
    ASSERT_EQ(c.count(1), 1u);
    EXPECT_EQ(c.at(1).renderTriangles, 0);
    EXPECT_EQ(c.at(1).openEdges, 0);
    EXPECT_NEAR(volumes.at(1), cells, 1e-6 * cells);
  }
}

// The cut and capped render mesh of the shattered bar is the same bit for bit with 1, 2 and 4
// threads.
TEST(RenderMesh, ShatteredSurfaceDoesNotDependOnThreadCount) {
  auto run = [](JobSystem* jobs) {
    World world(WorldDef{glm::vec3(0), Backend::Cpu, jobs, 1, {}});
    const BodyId id = world.createBody(brittleBar()).value();
    shatter(world, id, 25);
    EXPECT_GT(world.fractureStats(id).fragments, 2);
    const SurfaceView sv = world.surface(id);
    return std::make_pair(std::vector<float>(sv.positions.begin(), sv.positions.end()),
                          std::vector<uint32_t>(sv.indices.begin(), sv.indices.end()));
  };
  ThreadPoolJobSystem pool2(2), pool4(4);
  const auto one = run(nullptr), two = run(&pool2), four = run(&pool4);
  ASSERT_FALSE(one.first.empty());
  EXPECT_TRUE(one == two);
  EXPECT_TRUE(one == four);
}

// A bar 0.4 x 0.1 x 0.1 m (cells 0.025 x 0.0125 x 0.0125 m) with a notch: a blade on the plane
// x = 0.204 m breaks every edge it crosses at y >= 0.049 m, the upper half of the section, so
// the body stays one fragment. Drawn with a render mesh of 0.01 m edges, at rest the surface is
// closed and 2-manifold and encloses the render box's volume; then the half right of the crack
// is turned rigidly by 0.1 rad about the crack front (the line x = 0.204, y = 0.05), which
// opens the crack by 0.1 rad x the height above the front. Each pair of drawn vertices that
// coincide at rest and follow opposite sides must then be as far apart as the two sides'
// motions carry that rest point (within the opening's change over a cell, near the front where
// the local maps mix both sides), the surface stays closed, and no render triangle above the
// front stretches (one spanning the crack would by the opening).
TEST(RenderMesh, PartlyCrackedBarShowsItsOpeningCrack) {
  const double xc = 0.204, yf = 0.05, angle = 0.1, cell = 0.025;
  auto notched = [&](World& world) {
    BodyDef def;
    def.mesh = gen::box(0.4, 0.1, 0.1, 16, 8, 8);
    def.material = Material::stableNeoHookean(1e7, 0.3, 1000);
    def.fracture.enabled = true;
    def.fracture.strength = 1e12;  // only the blade breaks edges
    def.renderMesh = boxSurface(glm::dvec3(0), glm::dvec3(0.4, 0.1, 0.1), 40, 10, 10);
    const BodyId id = world.createBody(def).value();
    Blade blade;
    blade.vertices = {
        {float(xc), 0.049f, -1}, {float(xc), 1, -1}, {float(xc), 1, 1}, {float(xc), 0.049f, 1}};
    blade.triangles = {0, 1, 2, 0, 2, 3};
    EXPECT_TRUE(world.cut(id, blade).ok());
    (void)world.step(1.0 / 60);  // applies the cut
    EXPECT_TRUE(world.setPositions(id, def.mesh.positions).ok());
    return std::make_pair(id, def);
  };
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const auto made = notched(world);
  const BodyId id = made.first;
  const BodyDef& def = made.second;
  const FractureStats fs = world.fractureStats(id);
  ASSERT_GT(fs.brokenEdges, 0);
  ASSERT_EQ(fs.fragments, 1);

  // At rest: closed, 2-manifold, the render box's volume.
  const SurfaceView rest = world.surface(id);
  const std::vector<float> restPos(rest.positions.begin(), rest.positions.end());
  const std::vector<uint32_t> restIdx(rest.indices.begin(), rest.indices.end());
  const auto c0 = closure(rest);
  ASSERT_EQ(c0.size(), 1u);
  // The crack faces fold along the front: every cap's centre (its triangles' first vertex) lies
  // near the front line's middle (x = 0.2125 m, where the corner cells of the node layers
  // x = 0.2 and 0.225 m meet and so the graph's crack is drawn; y = z = 0.05 m): within a render
  // edge (0.01 m) in x, within a cell (0.0125 m) in y and z.
  int crackTriangles = 0;
  double centreOff = 0;
  for (size_t t = 0; t < rest.crackMask.size(); ++t) {
    if (!rest.crackMask[t]) continue;
    ++crackTriangles;
    const glm::dvec3 m(restPos[3 * size_t(restIdx[3 * t])], restPos[3 * size_t(restIdx[3 * t]) + 1],
                       restPos[3 * size_t(restIdx[3 * t]) + 2]);
    centreOff = std::max({centreOff, std::abs(m.x - 0.2125) / 0.01, std::abs(m.y - yf) / 0.0125,
                          std::abs(m.z - 0.05) / 0.0125});
  }
  double volume = 0;
  for (const auto& [f, v] : enclosedVolumes(rest)) volume += v;
  const double want = 0.4 * 0.1 * 0.1;

  // Open the crack: the right side turned about the front.
  const double ca = std::cos(angle), sa = std::sin(angle);
  auto turn = [&](glm::dvec3 p) {
    const double dx = p.x - xc, dy = p.y - yf;
    return glm::dvec3(xc + ca * dx + sa * dy, yf - sa * dx + ca * dy, p.z);
  };
  std::vector<double> x(def.mesh.positions.size());
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    const glm::dvec3 X = at(def.mesh.positions, n);
    const glm::dvec3 p = X.x < xc ? X : turn(X);
    for (int c = 0; c < 3; ++c) x[3 * n + size_t(c)] = p[c];
  }
  ASSERT_TRUE(world.setPositions(id, x).ok());
  const SurfaceView sv = world.surface(id);
  ASSERT_TRUE(std::equal(sv.indices.begin(), sv.indices.end(), restIdx.begin(), restIdx.end()));
  const auto c1 = closure(sv);
  // Pairs of drawn vertices at one rest point that follow opposite sides above the front.
  const CrackPairs cp = crackPairs(
      restPos, sv, def.mesh.positions, yf - 1e-9, [&](glm::dvec3 N) { return N.x < xc; },
      [&](glm::dvec3 P) { return glm::length(turn(P) - P); });
  const int pairs = cp.pairs;
  const double widest = cp.widest, worst = cp.worst;
  // Render triangles wholly above the front by a cell keep their edge lengths.
  const auto [above, stretch] = stretchAbove(restPos, restIdx, sv, yf + cell);
  std::printf(
      "notched bar: %d broken edges, %d fragment; drawn %zu triangles (%d crack faces, their "
      "fans' centres off the front's middle by %.2f of the allowance), %d open edges at rest, %d "
      "opened; at "
      "rest volume %.8g m^3 against %.8g (%.2e relative). Opened by "
      "%.2f rad: %d vertex pairs across the crack, widest gap %.4f m (the nodes' opening at the "
      "top: %.4f m), largest |gap - the sides' motion| %.3g m (a cell's change of the opening: "
      "%.3g m); %d render triangles above the front, largest change of an edge's length %.3g m\n",
      fs.brokenEdges, fs.fragments, restIdx.size() / 3, crackTriangles, centreOff,
      c0.begin()->second.openEdges, c1.begin()->second.openEdges, volume, want,
      (volume - want) / want, angle, pairs, widest, 2 * std::sin(angle / 2) * (0.1 - yf), worst,
      angle * cell, above, stretch);
  EXPECT_EQ(c0.begin()->second.openEdges, 0);
  EXPECT_EQ(c1.size(), 1u);
  EXPECT_EQ(c1.begin()->second.openEdges, 0);
  EXPECT_GT(crackTriangles, 0);
  EXPECT_LT(centreOff, 1.0);
  EXPECT_NEAR(volume, want, 1e-6 * want);
  // At least one pair per render edge crossing the crack on the top face.
  EXPECT_GE(pairs, 10);
  EXPECT_GT(widest, 0.8 * 2 * std::sin(angle / 2) * (0.1 - yf));
  EXPECT_LT(worst, angle * cell);
  EXPECT_GT(above, 0);
  EXPECT_LT(stretch, 1e-5);

  // The same bits at 1, 2 and 4 threads.
  ThreadPoolJobSystem pool2(2), pool4(4);
  for (JobSystem* jobs : {static_cast<JobSystem*>(&pool2), static_cast<JobSystem*>(&pool4)}) {
    World other(WorldDef{glm::vec3(0), Backend::Cpu, jobs, 1, {}});
    const BodyId oid = notched(other).first;
    ASSERT_TRUE(other.setPositions(oid, x).ok());
    const SurfaceView o = other.surface(oid);
    EXPECT_TRUE(std::equal(o.positions.begin(), o.positions.end(), sv.positions.begin(),
                           sv.positions.end()));
    EXPECT_TRUE(
        std::equal(o.indices.begin(), o.indices.end(), sv.indices.begin(), sv.indices.end()));
  }
}

// Cracks that have not separated the body, at angles and render resolutions unrelated to the
// tets: a blade plane tilted about two axes breaks what it crosses down to a slanted front that
// ends inside the bar, so the cut crosses tets obliquely and ends in render triangles at any
// place. The drawn surface is closed and 2-manifold and, at rest, encloses the render mesh's
// volume; opened, it shows the opening above the front and no render triangle spans it.
TEST(RenderMesh, ObliquePartialCracksAreClosed) {
  struct Case {
    double tiltX, tiltZ, depth;  // the blade's tilts [rad]; its lowest y at z = 0.05 [m]
    int nx, ny, nz;              // render mesh resolution
  };
  const Case cases[] = {
      {0.3, 0.2, 0.045, 37, 9, 11}, {-0.5, 0.4, 0.06, 23, 7, 5}, {0.15, -0.6, 0.03, 61, 13, 17}};
  for (const Case& c : cases) {
    BodyDef def;
    def.mesh = gen::box(0.4, 0.1, 0.1, 16, 8, 8);
    def.material = Material::stableNeoHookean(1e7, 0.3, 1000);
    def.fracture.enabled = true;
    def.fracture.strength = 1e12;
    def.renderMesh = boxSurface(glm::dvec3(0), glm::dvec3(0.4, 0.1, 0.1), c.nx, c.ny, c.nz);
    World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
    const BodyId id = world.createBody(def).value();
    // The blade: a quad in its plane through (0.203, depth, 0.05), x = 0.203 + tan(tiltX)
    // (y - depth) + tan(tiltZ) (z - 0.05), from y = depth up and across all z.
    auto X = [&](double y, double z) {
      return float(0.203 + std::tan(c.tiltX) * (y - c.depth) + std::tan(c.tiltZ) * (z - 0.05));
    };
    Blade blade;
    blade.vertices = {{X(c.depth, -1), float(c.depth), -1},
                      {X(1, -1), 1, -1},
                      {X(1, 1), 1, 1},
                      {X(c.depth, 1), float(c.depth), 1}};
    blade.triangles = {0, 1, 2, 0, 2, 3};
    ASSERT_TRUE(world.cut(id, blade).ok());
    (void)world.step(1.0 / 60);
    ASSERT_TRUE(world.setPositions(id, def.mesh.positions).ok());
    const FractureStats fs = world.fractureStats(id);
    const SurfaceView sv = world.surface(id);
    const auto cl = closure(sv);
    int open = 0, crackTriangles = 0;
    for (const auto& [f, fc] : cl) open += fc.openEdges;
    for (uint8_t m : sv.crackMask) crackTriangles += m;
    double volume = 0;
    for (const auto& [f, v] : enclosedVolumes(sv)) volume += v;
    const double want = 0.4 * 0.1 * 0.1;
    std::printf(
        "oblique partial crack (tilts %.2f, %.2f rad, lowest at y = %.3f m; render %dx%dx%d): %d "
        "broken edges, %d fragment(s) (chips included); %zu drawn triangles, %d crack faces, %d "
        "open edges; at rest volume %.2e relative\n",
        c.tiltX, c.tiltZ, c.depth, c.nx, c.ny, c.nz, fs.brokenEdges, fs.fragments,
        sv.indices.size() / 3, crackTriangles, open, (volume - want) / want);
    // One piece: the other fragments are chips, nodes whose every tet the blade split, released
    // (docs/design.md "Severed edges") and drawn with the piece.
    EXPECT_GT(fs.brokenEdges, 0);
    EXPECT_EQ(fs.fragments - fs.chips, 1);
    EXPECT_EQ(cl.size(), 1u);
    EXPECT_GT(crackTriangles, 0);
    EXPECT_EQ(open, 0);
    EXPECT_NEAR(volume, want, 1e-6 * want);

    // Open it: the far side turned by 0.1 rad about the front line (the blade's lowest edge).
    // Vertex pairs across the crack part as the two sides carry their rest point, and render
    // triangles more than two cells above the front keep their edge lengths (each side moves
    // rigidly there; one spanning the crack would stretch by the opening).
    const std::vector<float> restPos(sv.positions.begin(), sv.positions.end());
    const std::vector<uint32_t> restIdx(sv.indices.begin(), sv.indices.end());
    const glm::dvec3 p0(0.203, c.depth, 0.05),
        axis = glm::normalize(glm::dvec3(std::tan(c.tiltZ), 0, 1));
    const double angle = -0.1, cellY = 0.0125;
    auto far = [&](glm::dvec3 P) { return P.x > double(X(P.y, P.z)); };
    auto turn = [&](glm::dvec3 P) {
      const glm::dvec3 r = P - p0;
      return p0 + r * std::cos(angle) + glm::cross(axis, r) * std::sin(angle) +
             axis * glm::dot(axis, r) * (1 - std::cos(angle));
    };
    std::vector<double> x(def.mesh.positions.size());
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
      const glm::dvec3 P = at(def.mesh.positions, n), q = far(P) ? turn(P) : P;
      for (int k = 0; k < 3; ++k) x[3 * n + size_t(k)] = q[k];
    }
    ASSERT_TRUE(world.setPositions(id, x).ok());
    const SurfaceView opened = world.surface(id);
    ASSERT_TRUE(
        std::equal(opened.indices.begin(), opened.indices.end(), restIdx.begin(), restIdx.end()));
    const CrackPairs cp = crackPairs(restPos, opened, def.mesh.positions, c.depth + cellY, far,
                                     [&](glm::dvec3 P) { return glm::length(turn(P) - P); });
    const int pairs = cp.pairs;
    const double widest = cp.widest, worst = cp.worst;
    const auto [above, stretch] = stretchAbove(restPos, restIdx, opened, c.depth + 2 * cellY);
    std::printf(
        "  opened by %.2f rad: %d vertex pairs across the crack a cell above the front, widest "
        "gap %.4f m, largest |gap - the sides' motion| %.3g m; %d render triangles two cells "
        "above the front, largest change of an edge's length %.3g m\n",
        -angle, pairs, widest, worst, above, stretch);
    EXPECT_GT(pairs, 0);
    EXPECT_LT(worst, -angle * 0.025);
    EXPECT_GT(above, 0);
    EXPECT_LT(stretch, 1e-5);
  }
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
      {"BodyDef.renderMesh.materials: 3 ids for ", [](RenderMesh& m) { m.materials.assign(3, 1); }},
      {"BodyDef.renderMesh.materials[4]: 65535 is reserved",
       [](RenderMesh& m) {
         m.materials.assign(m.triangleCount(), 2);
         m.materials[4] = kInteriorMaterial;
       }},
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

  // A body that nobody draws pays nothing: with its render mesh bound but its surface never
  // asked for, the same 20 steps (processor time, alternated with the body without a render
  // mesh) and the same bits.
  auto undrawn = [](const BodyDef& d, std::vector<double>& x) {
    World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
    const BodyId id = world.createBody(d).value();
    const std::clock_t c0 = std::clock();
    for (int s = 0; s < 21; ++s) (void)world.step(1.0 / 60);
    const std::clock_t c1 = std::clock();
    x.assign(world.positions(id).begin(), world.positions(id).end());
    return 1e3 * double(c1 - c0) / CLOCKS_PER_SEC / 21;
  };
  std::vector<double> xPlain, xBound;
  double plainMs = 0, boundMs = 0;
  for (int round = 0; round < 2; ++round) {
    plainMs += undrawn(def, xPlain) / 2;
    boundMs += undrawn(drawn, xBound) / 2;
  }
  std::printf(
      "never drawn: step %.3f ms with the render mesh bound, %.3f ms without (ratio %.3f, "
      "processor time); positions %s\n",
      boundMs, plainMs, boundMs / plainMs, xPlain == xBound ? "bit-identical" : "DIFFER");
  EXPECT_TRUE(xPlain == xBound);

  // Fracture: the brittle bar with a 1/240 m render mesh, pulled apart. On a step that broke
  // edges the surface is cut and capped again (rebuild); on the others it only moves.
  BodyDef brittle = brittleBar();
  brittle.renderMesh = boxSurface(glm::dvec3(0), glm::dvec3(1, 0.1, 0.1), 240, 24, 24);
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(brittle).value();
  (void)world.surface(id);
  double stepMs = 0, rebuildMs = 0, moveMs = 0;
  int rebuilds = 0, moves = 0;
  uint64_t version = world.surface(id).topologyVersion;
  for (int s = 0; s < 40; ++s) {
    const auto t0 = Clock::now();
    (void)world.step(1.0 / 60);
    const auto t1 = Clock::now();
    const SurfaceView sv = world.surface(id);
    const auto t2 = Clock::now();
    stepMs += std::chrono::duration<double, std::milli>(t1 - t0).count();
    const double ms = std::chrono::duration<double, std::milli>(t2 - t1).count();
    if (sv.topologyVersion != version) {
      rebuildMs += ms;
      ++rebuilds;
    } else {
      moveMs += ms;
      ++moves;
    }
    version = sv.topologyVersion;
  }
  const SurfaceView sv = world.surface(id);
  std::printf(
      "shattering, %zu tets, render mesh of %zu vertices, 1 thread: step %.3f ms on average; "
      "surface on the %d steps that broke edges (cut and capped again) %.3f ms = %.1f %% of "
      "the step, on the %d others %.3f ms = %.1f %%; %zu drawn vertices, %d fragments at the "
      "end\n",
      brittle.mesh.tetCount(), brittle.renderMesh->vertexCount(), stepMs / 40, rebuilds,
      rebuilds ? rebuildMs / rebuilds : 0.0,
      rebuilds ? 100 * rebuildMs / rebuilds / (stepMs / 40) : 0.0, moves,
      moves ? moveMs / moves : 0.0, moves ? 100 * moveMs / moves / (stepMs / 40) : 0.0,
      sv.positions.size() / 3, world.fractureStats(id).fragments);
  EXPECT_GT(rebuilds, 0);

  // The rebuild's parts for the final state, on their own: the render mesh cut and capped, the
  // tet surface (and its local maps) rebuilt, the first placement (which composes the buffers).
  const detail::EmbeddedBinding binding =
      detail::EmbeddedBinding::bind(brittle.mesh, *brittle.renderMesh, "renderMesh").value();
  const detail::EdgeGraph graph = detail::EdgeGraph::build(
      brittle.mesh.tets.data(), brittle.mesh.tetCount(), brittle.mesh.nodeCount());
  const std::vector<Mat3> restInverse = tetRestInverses(brittle.mesh);
  const std::span<const uint8_t> broken = world.brokenEdges(id);
  const std::span<const int32_t> fragment = world.nodeFragments(id);
  const std::span<const double> x = world.positions(id);
  detail::CrackSurface crack;
  crack.init(brittle.mesh, graph);
  detail::EmbeddedSurface embedded;
  embedded.init(binding, brittle.mesh, graph, restInverse.data());
  // Processor time (one thread), not wall time: the parts are short and a shared machine's
  // waits would swamp them.
  const std::clock_t r0 = std::clock();
  embedded.rebuild(broken.data(), fragment.data());
  crack.setExtraFrameNodes(embedded.frameNodes());
  const std::clock_t r1 = std::clock();
  crack.rebuild(broken.data(), fragment.data(), x.data());
  const std::clock_t r2 = std::clock();
  embedded.update(x.data(), crack);
  const std::clock_t r3 = std::clock();
  // Once more, as on a later fracture step: the buffers keep their capacity.
  const std::clock_t r4 = std::clock();
  embedded.rebuild(broken.data(), fragment.data());
  crack.setExtraFrameNodes(embedded.frameNodes());
  const std::clock_t r5 = std::clock();
  crack.rebuild(broken.data(), fragment.data(), x.data());
  const std::clock_t r6 = std::clock();
  embedded.update(x.data(), crack);
  const std::clock_t r7 = std::clock();
  auto ms = [](std::clock_t a, std::clock_t b) { return 1e3 * double(b - a) / CLOCKS_PER_SEC; };
  std::printf(
      "rebuild of the final state, processor time: render mesh cut and capped %.3f ms (%u caps, "
      "%zu local maps asked for), tet surface %.3f ms, first placement %.3f ms; again: %.3f, "
      "%.3f and %.3f ms\n",
      ms(r0, r1), embedded.capCount(), embedded.frameNodes().size(), ms(r1, r2), ms(r2, r3),
      ms(r4, r5), ms(r5, r6), ms(r6, r7));
}

}  // namespace
}  // namespace gf
