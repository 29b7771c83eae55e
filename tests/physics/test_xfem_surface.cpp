// The render surface of an Is-XFEM body (issue 21 item 4), checked against independent truths:
// every piece's surface is closed and edge-manifold (each undirected edge in exactly two
// triangles, in opposite directions), its volume by the divergence theorem is the piece's volume,
// its cut-face vertices lie on the cut, and after steps under gravity its vertices sit where the
// enriched field (eqs 3.2-3.4, evaluated here by hand) puts them. Cuts: a tilted plane, two planes
// and a blade, and a blade that ends inside the body (a cut that does not open: no hole).
#include <graphfrac/mesh.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <string>

#include "common/xfem_blades.h"
#include "xfem/cut_body.h"

namespace gf::detail {
namespace {

using test::planarBlade;

XfemBodyDef boxDef() { return test::xfemBox(1e6); }

struct SurfaceCheck {
  int openEdges = 0;  // directed edges without exactly one opposite twin
  double volume = 0;  // divergence theorem
  double area = 0;
};

SurfaceCheck checkSurface(const XfemPieceSurface& s, const std::vector<Vec3>& x) {
  SurfaceCheck r;
  std::map<std::pair<int32_t, int32_t>, int> directed;
  for (size_t t = 0; 3 * t < s.triangles.size(); ++t) {
    const int32_t* v = &s.triangles[3 * t];
    for (int k = 0; k < 3; ++k) ++directed[{v[k], v[(k + 1) % 3]}];
    const Vec3 a = x[size_t(v[0])], b = x[size_t(v[1])], c = x[size_t(v[2])];
    r.volume += dot(a, cross(b, c)) / 6;
    r.area += 0.5 * norm(cross(b - a, c - a));
  }
  for (const auto& [e, n] : directed) {
    const auto twin = directed.find({e.second, e.first});
    if (n != 1 || twin == directed.end() || twin->second != 1) ++r.openEdges;
  }
  return r;
}

std::vector<Vec3> restOf(const XfemPieceSurface& s) {
  std::vector<Vec3> x;
  for (const XfemSurfaceVertex& v : s.vertices) x.push_back(v.rest);
  return x;
}

// Every piece closed, manifold and of the piece's volume; cut vertices on their planes (planes
// only: blades' planes are checked by the caller).
void expectClosedPieces(const XfemBody& body, const std::vector<CutPlane>& planes,
                        const char* what) {
  double worstVolume = 0, worstPlane = 0;
  size_t triangles = 0;
  for (size_t p = 0; p < body.pieces().size(); ++p) {
    const XfemPieceSurface& s = body.surface()[p];
    const SurfaceCheck c = checkSurface(s, restOf(s));
    EXPECT_EQ(c.openEdges, 0) << what << ", piece " << p;
    const double v = body.pieces()[p].volume;
    worstVolume = std::max(worstVolume, std::abs(c.volume - v) / v);
    triangles += s.triangles.size() / 3;
    for (const XfemSurfaceVertex& x : s.vertices)
      for (size_t j = 0; j < planes.size(); ++j)
        if ((x.cuts >> j) & 1u)
          worstPlane = std::max(worstPlane, std::abs(planeDistance(planes[j], x.rest)));
  }
  std::printf(
      "%s: %zu pieces, %zu triangles; surface volume vs piece volume <= %.1e rel.; cut "
      "vertices off their plane <= %.1e\n",
      what, body.pieces().size(), triangles, worstVolume, worstPlane);
  EXPECT_LE(worstVolume, 1e-10) << what;
  EXPECT_LE(worstPlane, 1e-12) << what;
}

TEST(XfemSurface, TiltedPlaneGivesTwoClosedPiecesWithExactCutFaces) {
  XfemBodyDef def = boxDef();
  def.planes = {test::slantedPlane(0.93, 0.2, 0.1)};
  auto made = XfemBody::create(def);
  ASSERT_TRUE(made.ok()) << made.error().message;
  const XfemBody& body = *made.value();
  ASSERT_EQ(body.pieces().size(), 2u);
  expectClosedPieces(body, def.planes, "tilted plane");
  // Each piece's cut faces tile the section once: area sqrt(1 + b^2 + c^2).
  const double section = std::sqrt(1 + 0.04 + 0.01);
  for (size_t p = 0; p < 2; ++p) {
    const XfemPieceSurface& s = body.surface()[p];
    double area = 0;
    Vec3 normal;
    for (size_t t = 0; t < s.triangleCut.size(); ++t) {
      if (s.triangleCut[t] != 0) continue;
      const Vec3 a = s.vertices[size_t(s.triangles[3 * t])].rest,
                 b = s.vertices[size_t(s.triangles[3 * t + 1])].rest,
                 c = s.vertices[size_t(s.triangles[3 * t + 2])].rest;
      area += 0.5 * norm(cross(b - a, c - a));
      normal += 0.5 * cross(b - a, c - a);
    }
    EXPECT_NEAR(area, section, 1e-12 * section) << p;
    // Outward: the left piece (mask 0) faces +n, the right one -n.
    const double facing = dot(normal, def.planes[0].normal) / area;
    EXPECT_NEAR(facing, body.pieces()[p].mask == 0 ? 1.0 : -1.0, 1e-12) << p;
  }
}

TEST(XfemSurface, SeveralCutsIncludingABladeGiveClosedPieces) {
  // Two tilted planes crossing inside the body, then a third cut as a blade.
  XfemBodyDef def = boxDef();
  def.planes = {test::slantedPlane(0.71, 0.2, 0.1), {{0.1, 0.05, std::sqrt(1 - 0.0125)}, 0.47}};
  {
    auto made = XfemBody::create(def);
    ASSERT_TRUE(made.ok()) << made.error().message;
    EXPECT_EQ(made.value()->pieces().size(), 4u);
    expectClosedPieces(*made.value(), def.planes, "two planes");
  }
  {
    const std::vector<CutPlane> planes = {def.planes[0], def.planes[1],
                                          test::slantedPlane(1.43, -0.15, 0.2)};
    def.blades = {{planarBlade(1.43, -0.15, 0.2, -0.5, 1.5, 3), {}}};
    auto made = XfemBody::create(def);
    ASSERT_TRUE(made.ok()) << made.error().message;
    EXPECT_EQ(made.value()->pieces().size(), 6u);
    expectClosedPieces(*made.value(), planes, "two planes and a blade");
  }
  {
    // A swept blade: swept up across its plane with its edge inside the body (an L-shaped cut,
    // test_xfem_swept.cpp), and a plane as well.
    XfemBodyDef swept = boxDef();
    XfemBlade blade;
    blade.blade.vertices = {-1, 0.4, -1, -1, 0.4, 2, 0.9, 0.4, 2, 0.9, 0.4, -1};
    blade.blade.triangles = {0, 1, 2, 0, 2, 3};
    blade.to = BladePose{};
    blade.to->translation = {0, 2, 0};
    swept.blades = {blade};
    swept.planes = {{{0, 0, 1}, 0.52}};
    auto made = XfemBody::create(swept);
    ASSERT_TRUE(made.ok()) << made.error().message;
    EXPECT_EQ(made.value()->pieces().size(), 4u);
    expectClosedPieces(*made.value(), swept.planes, "a swept blade and a plane");
  }
  {
    // Three planes through one tet's region, one of them along a node layer (x = 1).
    XfemBodyDef three = boxDef();
    three.planes = {test::slantedPlane(0.93, 0.2, 0.1), {{0, 1, 0}, 0.41}, {{1, 0, 0}, 1.0}};
    auto made = XfemBody::create(three);
    ASSERT_TRUE(made.ok()) << made.error().message;
    // x = 1 crosses the tilted cut only where y < 0.41: 4 pieces below y = 0.41, 3 above.
    EXPECT_EQ(made.value()->pieces().size(), 7u);
    expectClosedPieces(*made.value(), three.planes, "three planes, one on a node layer");
  }
}

// The family: random planes (1 to 3, through the box's middle region, any tilt) on boxes of
// several resolutions; every piece's surface closed and of its piece's volume.
TEST(XfemSurface, RandomPlanesOnSeveralMeshesGiveClosedPieces) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  int bodies = 0, pieces = 0, open = 0;
  double worst = 0, worstPlane = 0;
  for (int res : {1, 2, 3, 5})
    for (int trial = 0; trial < 6; ++trial) {
      XfemBodyDef def;
      def.mesh = gen::box(2, 1, 1, 2 * res, res, res);
      def.dt = 1e-3;
      const int count = 1 + trial % 3;
      for (int j = 0; j < count; ++j) {
        Vec3 n{u(rng), u(rng), u(rng)};
        n = (1.0 / norm(n)) * n;
        const Vec3 through{1 + 0.6 * u(rng), 0.5 + 0.3 * u(rng), 0.5 + 0.3 * u(rng)};
        def.planes.push_back({n, dot(n, through)});
      }
      auto made = XfemBody::create(def);
      if (!made.ok()) continue;  // more cuts than a tet carries: not this test's subject
      const XfemBody& body = *made.value();
      ++bodies;
      for (size_t p = 0; p < body.pieces().size(); ++p, ++pieces) {
        const XfemPieceSurface& s = body.surface()[p];
        const SurfaceCheck c = checkSurface(s, restOf(s));
        open += c.openEdges;
        EXPECT_EQ(c.openEdges, 0) << "res " << res << " trial " << trial << " piece " << p;
        const double v = body.pieces()[p].volume;
        worst = std::max(worst, std::abs(c.volume - v) / v);
        for (const XfemSurfaceVertex& x : s.vertices)
          for (size_t j = 0; j < def.planes.size(); ++j)
            if ((x.cuts >> j) & 1u)
              worstPlane = std::max(worstPlane, std::abs(planeDistance(def.planes[j], x.rest)));
      }
    }
  std::printf(
      "random planes: %d bodies, %d pieces, %d open edges, surface volume vs piece volume <= "
      "%.1e rel., cut vertices off their plane <= %.1e\n",
      bodies, pieces, open, worst, worstPlane);
  EXPECT_GE(bodies, 20);
  EXPECT_LE(worst, 1e-10);
  EXPECT_LE(worstPlane, 1e-12);
}

// Cuts through nodes to rounding (node layers, a third of a cell apart through them, the bench's
// slanted blades one cell apart), as planes and as blades: the degenerate clips (a tet face on a
// cut, a cut through a node or an edge) still give closed pieces of their volumes.
TEST(XfemSurface, CutsThroughNodesGiveClosedPieces) {
  struct Set {
    const char* name;
    double b, c;
    std::vector<double> a;
  };
  const std::vector<Set> sets = {
      {"node layers x = k/4", 0, 0, {0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75}},
      {"h/3 apart through layers", 0, 0, {0.5, 0.5 + 1.0 / 12, 0.5 + 2.0 / 12, 0.75}},
      {"slanted one cell apart", 0.05, 0.03, {0.263, 0.513, 0.763, 1.013, 1.263}},
  };
  for (const Set& set : sets)
    for (bool blades : {false, true}) {
      XfemBodyDef def;
      def.mesh = gen::box(2, 1, 1, 8, 4, 4);
      const double len = std::sqrt(1 + set.b * set.b + set.c * set.c);
      for (double a : set.a) {
        if (blades)
          def.blades.push_back({planarBlade(a, set.b, set.c, -1, 2, 2), {}});
        else
          def.planes.push_back({{1 / len, -set.b / len, -set.c / len}, a / len});
      }
      auto made = XfemBody::create(def);
      ASSERT_TRUE(made.ok()) << set.name << ": " << made.error().message;
      EXPECT_EQ(made.value()->pieces().size(), set.a.size() + 1) << set.name;
      const std::string what = std::string(set.name) + (blades ? " (blades)" : " (planes)");
      expectClosedPieces(*made.value(), def.planes, what.c_str());
    }
}

// u(x) on a mesh edge (i, j) crossed by cut c at parameter s, on side h (eqs 3.2-3.4 by hand):
// sum over the edge's nodes of N_a (u_a + psi_a q_a), psi_a = h - k gamma - (1 - k) H_a.
Vec3 fieldOnEdge(const XfemBody& body, const XfemBodyDef& def, int32_t i, int32_t j, int32_t cut,
                 const CutPlane& plane, double s, double h) {
  const Eigen::VectorXd& u = body.displacement();
  const int32_t node[2] = {i, j};
  const double N[2] = {1 - s, s};
  double H[2];
  for (int a = 0; a < 2; ++a) {
    const Vec3 x{def.mesh.positions[3 * size_t(node[a])],
                 def.mesh.positions[3 * size_t(node[a]) + 1],
                 def.mesh.positions[3 * size_t(node[a]) + 2]};
    H[a] = planeDistance(plane, x) >= 0 ? 1 : 0;
  }
  const double gamma = N[0] * H[0] + N[1] * H[1];  // eq 3.3
  Vec3 r;
  for (int a = 0; a < 2; ++a) {
    const double psi = h - def.k * gamma - (1 - def.k) * H[a];  // eq 3.2
    const int32_t f = body.enrichedFunction(node[a], cut);
    for (int d = 0; d < 3; ++d)
      r[d] += N[a] * (u[3 * node[a] + d] + (f >= 0 ? psi * u[3 * f + d] : 0.0));  // eq 3.4
  }
  return r;
}

TEST(XfemSurface, VerticesFollowTheEnrichedFieldUnderGravity) {
  for (double k : {0.1, 0.0}) {
    XfemBodyDef def = boxDef();
    def.k = k;
    def.material.youngs = 1e9;  // stiff: the held piece's sag stays far below the fall
    // Each cut within one slab of tets clear of x = 1: the held nodes carry no enrichment, so
    // the outer pieces are free.
    def.planes = {test::slantedPlane(0.35, 0.2, 0.1), test::slantedPlane(1.38, 0.1, 0.15)};
    for (int32_t n = 0; n < int32_t(def.mesh.nodeCount()); ++n)
      if (std::abs(def.mesh.positions[3 * size_t(n)] - 1.0) < 1e-12) def.fixedNodes.push_back(n);
    auto made = XfemBody::create(def);
    ASSERT_TRUE(made.ok()) << made.error().message;
    XfemBody& body = *made.value();
    ASSERT_EQ(body.pieces().size(), 3u);
    for (int s = 0; s < 50; ++s) ASSERT_TRUE(body.step());
    body.updateSurface();
    const double scale = body.displacement().cwiseAbs().maxCoeff();
    double nodeErr = 0, edgeErr = 0, gap = INFINITY;
    int nodes = 0, edges = 0;
    for (size_t p = 0; p < body.pieces().size(); ++p) {
      const XfemPieceSurface& s = body.surface()[p];
      const unsigned mask = body.pieces()[p].mask;
      for (size_t v = 0; v < s.vertices.size(); ++v) {
        const XfemSurfaceVertex& x = s.vertices[v];
        const Vec3 moved = s.positions[v] - x.rest;
        if (x.simplex[1] < 0 && x.cuts == 0) {
          const int32_t n = x.simplex[0];
          const Vec3 un{body.displacement()[3 * n], body.displacement()[3 * n + 1],
                        body.displacement()[3 * n + 2]};
          nodeErr = std::max(nodeErr, norm(moved - un));
          ++nodes;
        } else if (x.simplex[2] < 0 && x.simplex[1] >= 0 && __builtin_popcount(x.cuts) == 1) {
          const int32_t cut = __builtin_ctz(x.cuts), i = x.simplex[0], j = x.simplex[1];
          const Vec3 xi{def.mesh.positions[3 * size_t(i)], def.mesh.positions[3 * size_t(i) + 1],
                        def.mesh.positions[3 * size_t(i) + 2]},
              xj{def.mesh.positions[3 * size_t(j)], def.mesh.positions[3 * size_t(j) + 1],
                 def.mesh.positions[3 * size_t(j) + 2]};
          const double t = norm(x.rest - xi) / norm(xj - xi);
          const Vec3 expect = fieldOnEdge(body, def, i, j, cut, def.planes[size_t(cut)], t,
                                          (mask >> cut) & 1u ? 1.0 : 0.0);
          edgeErr = std::max(edgeErr, norm(moved - expect));
          ++edges;
        }
      }
      EXPECT_EQ(checkSurface(s, s.positions).openEdges, 0);
    }
    // The outer pieces fall away from the held middle one: their cut faces part.
    for (size_t p = 0; p < 3; ++p) {
      if (body.pieces()[p].mask != 1u) continue;  // the middle piece: right of cut 0, left of 1
      for (size_t q = 0; q < 3; ++q) {
        if (q == p) continue;
        for (size_t v = 0; v < body.surface()[q].vertices.size(); ++v)
          for (size_t w = 0; w < body.surface()[p].vertices.size(); ++w)
            if (body.surface()[q].vertices[v].cuts && body.surface()[p].vertices[w].cuts &&
                norm(body.surface()[q].vertices[v].rest - body.surface()[p].vertices[w].rest) == 0)
              gap = std::min(gap,
                             norm(body.surface()[q].positions[v] - body.surface()[p].positions[w]));
      }
    }
    const double fall = 9.81 * 0.05 * 0.05 / 2;
    std::printf(
        "k = %.1f, 50 steps: %d node vertices off u_node by <= %.1e, %d cut-edge vertices off "
        "eq 3.4 by hand by <= %.1e (max |u| %.3e m); smallest gap between a cut vertex's "
        "copies in the held and a falling piece %.4f m (g t^2/2 = %.4f m)\n",
        k, nodes, nodeErr, edges, edgeErr, scale, gap, fall);
    EXPECT_GT(nodes, 0);
    EXPECT_GT(edges, 0);
    EXPECT_LE(nodeErr, 1e-12 * scale);
    EXPECT_LE(edgeErr, 1e-12 * scale);
    EXPECT_GT(gap, 0.9 * fall);
  }
}

TEST(XfemSurface, BladeEndingInsideMakesAClosedPocketNotAHole) {
  XfemBodyDef def = boxDef();
  def.blades = {{planarBlade(0.93, 0.2, 0.1, -0.5, 0.8, 1), {}}};
  for (int32_t n = 0; n < int32_t(def.mesh.nodeCount()); ++n)
    if (def.mesh.positions[3 * size_t(n)] == 0) def.fixedNodes.push_back(n);
  auto made = XfemBody::create(def);
  ASSERT_TRUE(made.ok()) << made.error().message;
  XfemBody& body = *made.value();
  ASSERT_EQ(body.pieces().size(), 1u);
  const XfemPieceSurface& s = body.surface()[0];
  const SurfaceCheck rest = checkSurface(s, restOf(s));
  EXPECT_EQ(rest.openEdges, 0);
  EXPECT_NEAR(rest.volume, 2.0, 1e-10 * 2.0);
  size_t pocket = 0;
  for (int32_t c : s.triangleCut) pocket += c == 0;
  for (int st = 0; st < 100; ++st) ASSERT_TRUE(body.step());
  body.updateSurface();
  const SurfaceCheck moved = checkSurface(s, s.positions);
  // The pocket opens with the field: its volume is the deformed volume's excess over the body's
  // (the body itself barely changes volume, nu = 0.3 and a small sag).
  std::printf(
      "blade ending inside: one piece, %zu triangles (%zu on the cut, a pocket), open edges %d "
      "at rest and %d deformed; volume %.12f at rest, %.6f deformed\n",
      s.triangles.size() / 3, pocket, rest.openEdges, moved.openEdges, rest.volume, moved.volume);
  EXPECT_GT(pocket, 0u);
  EXPECT_EQ(moved.openEdges, 0);
  EXPECT_TRUE(std::isfinite(moved.volume));
  // The pocket's vertices on mesh edges against eq 3.2-3.4 by hand: a point with two copies has
  // each on its side's field; a single (welded) one sits where both sides' fields agree (the
  // jump vanishes there), which is the rule that closes the pocket.
  const CutPlane plane = test::slantedPlane(0.93, 0.2, 0.1);
  std::map<std::array<double, 3>, int> copies;
  for (const XfemSurfaceVertex& v : s.vertices)
    if (v.cuts == 1u && v.simplex[1] >= 0 && v.simplex[2] < 0)
      ++copies[{v.rest.x, v.rest.y, v.rest.z}];
  const double scale = body.displacement().cwiseAbs().maxCoeff();
  double sideErr = 0, weldJump = 0, openJump = 0;
  int doubled = 0, welded = 0;
  for (size_t k = 0; k < s.vertices.size(); ++k) {
    const XfemSurfaceVertex& v = s.vertices[k];
    if (!(v.cuts == 1u && v.simplex[1] >= 0 && v.simplex[2] < 0)) continue;
    const int32_t i = v.simplex[0], j = v.simplex[1];
    const Vec3 xi{def.mesh.positions[3 * size_t(i)], def.mesh.positions[3 * size_t(i) + 1],
                  def.mesh.positions[3 * size_t(i) + 2]},
        xj{def.mesh.positions[3 * size_t(j)], def.mesh.positions[3 * size_t(j) + 1],
           def.mesh.positions[3 * size_t(j) + 2]};
    const double t = norm(v.rest - xi) / norm(xj - xi);
    const Vec3 pos = fieldOnEdge(body, def, i, j, 0, plane, t, 1.0),
               neg = fieldOnEdge(body, def, i, j, 0, plane, t, 0.0);
    const Vec3 moved = s.positions[k] - v.rest;
    if (copies[{v.rest.x, v.rest.y, v.rest.z}] == 2) {
      ++doubled;
      sideErr = std::max(sideErr, norm(moved - (v.sides & 1u ? pos : neg)));
      openJump = std::max(openJump, norm(pos - neg));
    } else {
      ++welded;
      weldJump = std::max(weldJump, norm(pos - neg));
      sideErr = std::max(sideErr, norm(moved - pos));
    }
  }
  std::printf(
      "pocket: %d edge points with two copies (each on its side's field to %.1e m; opening up to "
      "%.2e m), %d welded (jump there %.1e m; max |u| %.3e m)\n",
      doubled, sideErr, openJump, welded, weldJump, scale);
  EXPECT_GT(doubled, 0);
  EXPECT_GT(welded, 0);
  EXPECT_LE(sideErr, 1e-12 * scale);
  EXPECT_LE(weldJump, 1e-12 * scale);
  EXPECT_GT(openJump, 1e-6 * scale);
}

}  // namespace
}  // namespace gf::detail
