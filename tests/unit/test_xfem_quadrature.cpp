// Is-XFEM moment-fitting quadrature (thesis eqs 3.8-3.12): on randomly cut tets, slivers
// included, every cell's volume rule and every cut face's surface rule integrate all monomials
// up to kCutRuleDegree exactly (1e-12 of the cell's volume or the face's area, with the
// monomials scaled to at most 1 on the cell), against exact integrals from an independent clip
// into tets and the closed-form simplex formula. A degree-5 monomial is not integrated exactly
// (the check has teeth). Cut-face vertices lie on their plane; cells tile the tet.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <utility>
#include <vector>

#include "common/exact_simplex.h"
#include "kernels/moment_fitting.h"

namespace gf {
namespace {

using test::Exponent;
using test::Tet;

struct Case {
  Tet tet;
  std::vector<CutPlane> planes;
  const char* kind;
};

Vec3 randomPoint(std::mt19937_64& rng, double lo, double hi) {
  std::uniform_real_distribution<double> u(lo, hi);
  return {u(rng), u(rng), u(rng)};
}

Vec3 unit(Vec3 v) { return (1.0 / norm(v)) * v; }

// A random tet of reasonable shape, positively oriented.
Tet randomTet(std::mt19937_64& rng) {
  for (;;) {
    Tet t{randomPoint(rng, -1, 1), randomPoint(rng, -1, 1), randomPoint(rng, -1, 1),
          randomPoint(rng, -1, 1)};
    const double v = dot(t[1] - t[0], cross(t[2] - t[0], t[3] - t[0])) / 6.0;
    if (std::abs(v) < 0.05) continue;
    if (v < 0) std::swap(t[1], t[2]);
    return t;
  }
}

// The plane parallel to the face opposite vertex a, at `fraction` of the height from vertex a
// (fromVertex) or from that face.
CutPlane parallelPlane(const Tet& t, int a, double fraction, bool fromVertex) {
  const Vec3 p = t[size_t((a + 1) % 4)], q = t[size_t((a + 2) % 4)], r = t[size_t((a + 3) % 4)];
  Vec3 n = unit(cross(q - p, r - p));
  if (dot(n, t[size_t(a)] - p) < 0) n = -n;  // towards vertex a
  const double h = dot(n, t[size_t(a)] - p);
  const double s = fromVertex ? h * (1 - fraction) : h * fraction;
  return {n, dot(n, p) + s};
}

std::vector<Case> makeCases() {
  std::mt19937_64 rng(20240521);
  std::vector<Case> cases;
  for (int i = 0; i < 60; ++i) {
    Case c{randomTet(rng), {}, "random"};
    const int planes = 1 + i % 3;
    Vec3 centroid = 0.25 * (c.tet[0] + c.tet[1] + c.tet[2] + c.tet[3]);
    for (int j = 0; j < planes; ++j) {
      const Vec3 n = unit(randomPoint(rng, -1, 1));
      const Vec3 through = centroid + 0.3 * randomPoint(rng, -1, 1);
      c.planes.push_back({n, dot(n, through)});
    }
    cases.push_back(c);
  }
  for (int i = 0; i < 16; ++i) {
    Case c{randomTet(rng), {}, "vertex sliver 1e-6"};
    c.planes.push_back(parallelPlane(c.tet, i % 4, 1e-6, true));
    cases.push_back(c);
    Case f{randomTet(rng), {}, "face sliver 1e-6"};
    f.planes.push_back(parallelPlane(f.tet, i % 4, 1e-6, false));
    cases.push_back(f);
    // A tilted plane 1e-6 of the height from a vertex, plus a random second cut.
    Case g{randomTet(rng), {}, "tilted sliver + cut"};
    // Tilted: cut off vertex a at 1e-6 of its nearest neighbour's distance along the normal.
    const int a = i % 4;
    const Vec3 straight = parallelPlane(g.tet, a, 0.5, true).normal;
    Vec3 tilt = unit(straight + 0.2 * randomPoint(rng, -1, 1));
    auto nearestAlong = [&](Vec3 n) {
      double nearest = -1e300;
      for (int b = 0; b < 4; ++b)
        if (b != a) nearest = std::max(nearest, dot(n, g.tet[size_t(b)] - g.tet[size_t(a)]));
      return nearest;
    };
    if (nearestAlong(tilt) >= 0) tilt = straight;  // the tilt moved a vertex across
    const double nearest = nearestAlong(tilt);
    CutPlane s{tilt, dot(tilt, g.tet[size_t(a)]) + 1e-6 * nearest};
    g.planes.push_back(s);
    const Vec3 n = unit(randomPoint(rng, -1, 1));
    g.planes.push_back({n, dot(n, 0.25 * (g.tet[0] + g.tet[1] + g.tet[2] + g.tet[3]))});
    cases.push_back(g);
  }
  return cases;
}

// The cell of `c` on sides `mask` as tets, by the independent clip.
std::vector<Tet> exactCell(const Case& c, unsigned mask) {
  std::vector<Tet> tets{c.tet};
  for (size_t j = 0; j < c.planes.size(); ++j) {
    std::vector<Tet> next;
    for (const Tet& t : tets)
      test::clipTetIntoTets(t, c.planes[j].normal, c.planes[j].offset, (mask >> j) & 1u ? 1 : -1,
                            next);
    tets.swap(next);
  }
  return tets;
}

struct Errors {
  double volume = 0, surface = 0, onPlane = 0, tiling = 0, degree5 = 0;
  double geometry = 0, geometryOwn = 0, volumeFlat = 0, volumeFlatScaled = 0;
  double smallestCell = 1;
};

// The cell as signed cones from its first vertex over fan triangles of its faces: a different
// split from the runtime's (which cones from the vertex average), integrated in closed form.
std::vector<std::pair<Tet, double>> coneTets(const CutPolytope& cell) {
  std::vector<std::pair<Tet, double>> out;
  const Vec3 apex = cell.faces[0].v[0];
  for (int f = 0; f < cell.faceCount; ++f) {
    const CutPolygon& g = cell.faces[f];
    for (int i = 1; i + 1 < g.count; ++i) {
      const Tet t{apex, g.v[0], g.v[i], g.v[i + 1]};
      const double v = dot(t[1] - t[0], cross(t[2] - t[0], t[3] - t[0])) / 6.0;
      if (v != 0) out.push_back({t, v});
    }
  }
  return out;
}

double monomialAt(Vec3 x, Vec3 o, double L, const Exponent& e) {
  return std::pow((x.x - o.x) / L, e[0]) * std::pow((x.y - o.y) / L, e[1]) *
         std::pow((x.z - o.z) / L, e[2]);
}

// Runs every case; `ownFrame` centres and scales the monomials on each cell (or face) itself,
// otherwise on its tet, so slivers are checked at their own scale and at the tet's.
Errors runCases(bool ownFrame) {
  Errors err;
  const std::vector<Exponent> exps = test::exponentsUpTo(kCutRuleDegree);
  for (const Case& c : makeCases()) {
    const Vec3 X[4] = {c.tet[0], c.tet[1], c.tet[2], c.tet[3]};
    const double tetV = test::tetVolume(c.tet);
    double tiled = 0;
    const int m = int(c.planes.size());
    for (unsigned mask = 0; mask < (1u << m); ++mask) {
      const CutPolytope cell = clipTet(X, c.planes.data(), m, mask);
      const std::vector<Tet> pieces = exactCell(c, mask);
      double exactV = 0;
      for (const Tet& t : pieces) exactV += test::tetVolume(t);
      if (cell.faceCount == 0) {
        EXPECT_LE(exactV, 1e-14 * tetV) << c.kind << ": empty cell with volume";
        continue;
      }
      const VolumeRule rule = fitVolumeRule(cell);
      EXPECT_EQ(rule.count, kVolumeRulePoints) << c.kind;
      if (rule.count == 0) continue;
      err.smallestCell = std::min(err.smallestCell, exactV / tetV);
      // Frame: the cell's vertex box (own) or the tet's.
      Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
      auto grow = [&](Vec3 p) {
        for (int a = 0; a < 3; ++a) {
          lo[a] = std::min(lo[a], p[a]);
          hi[a] = std::max(hi[a], p[a]);
        }
      };
      if (ownFrame) {
        for (const Tet& t : pieces)
          for (const Vec3& p : t) grow(p);
      } else {
        for (const Vec3& p : c.tet) grow(p);
      }
      const Vec3 o = 0.5 * (lo + hi);
      const double L = 0.5 * std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
      double ruleV = 0;
      for (int q = 0; q < rule.count; ++q) ruleV += rule.weights[q];
      tiled += ruleV;
      // The clipped cell's vertices carry rounding of eps times the tet's size, so two clips
      // of a 1e-18 sliver differ by ~1e-10 of its volume: the geometry is checked against the
      // independent clip at the tet's scale, the rule's exactness on the cell it was fitted to.
      err.geometry = std::max(err.geometry, std::abs(ruleV - exactV) / tetV);
      err.geometryOwn = std::max(err.geometryOwn, std::abs(ruleV - exactV) / exactV);
      const std::vector<std::pair<Tet, double>> cones = coneTets(cell);
      // Flatness: thickness over diameter. A cell 1e-6 thin whose vertices are stored in the
      // tet's coordinates has its thickness, so its volume, defined only to eps / flatness.
      double diameter = 0, maxArea = 0;
      for (int f = 0; f < cell.faceCount; ++f) {
        maxArea = std::max(maxArea, polygonArea(cell.faces[f]));
        for (int i = 0; i < cell.faces[f].count; ++i)
          for (int g = 0; g < cell.faceCount; ++g)
            for (int k = 0; k < cell.faces[g].count; ++k)
              diameter = std::max(diameter, norm(cell.faces[f].v[i] - cell.faces[g].v[k]));
      }
      const double flatness = ruleV / (maxArea * diameter);
      double coneV = 0;
      for (const auto& [t, v] : cones) coneV += v;
      for (const Exponent& e : exps) {
        double exact = 0, quad = 0;
        for (const auto& [t, v] : cones) exact += test::simplexMonomialIntegral<3>(t, v, o, L, e);
        for (int q = 0; q < rule.count; ++q)
          quad += rule.weights[q] * monomialAt(rule.points[q], o, L, e);
        const double rel = std::abs(quad - exact) / coneV;
        if (flatness >= 1e-3) {
          err.volume = std::max(err.volume, rel);
        } else {
          err.volumeFlat = std::max(err.volumeFlat, rel);
          err.volumeFlatScaled = std::max(err.volumeFlatScaled, rel * flatness);
        }
      }
      // Negative control: x^5 is beyond the rule's degree.
      if (exactV > 1e-3 * tetV) {
        const Exponent e5{5, 0, 0};
        double exact = 0, quad = 0;
        for (const auto& [t, v] : coneTets(cell))
          exact += test::simplexMonomialIntegral<3>(t, v, o, L, e5);
        for (int q = 0; q < rule.count; ++q)
          quad += rule.weights[q] * monomialAt(rule.points[q], o, L, e5);
        err.degree5 = std::max(err.degree5, std::abs(quad - exact) / exactV);
      }
      // Cut faces: vertices on their plane; the surface rule against fan triangles.
      for (int f = 0; f < cell.faceCount; ++f) {
        const CutPolygon& g = cell.faces[f];
        if (g.label < kCutFaceLabel) continue;
        const CutPlane& plane = c.planes[size_t(g.label - kCutFaceLabel)];
        for (int i = 0; i < g.count; ++i)
          err.onPlane = std::max(err.onPlane, std::abs(planeDistance(plane, g.v[i])));
        const SurfaceRule s = fitSurfaceRule(g);
        const double area = polygonArea(g);
        if (s.count == 0) {
          EXPECT_LE(area, 1e-14) << c.kind;
          continue;
        }
        EXPECT_NEAR(std::abs(dot(s.normal, plane.normal)), 1.0, 1e-12);
        Vec3 flo{1e300, 1e300, 1e300}, fhi{-1e300, -1e300, -1e300};
        for (int i = 0; i < g.count; ++i)
          for (int a = 0; a < 3; ++a) {
            flo[a] = std::min(flo[a], g.v[i][a]);
            fhi[a] = std::max(fhi[a], g.v[i][a]);
          }
        const Vec3 fo = ownFrame ? 0.5 * (flo + fhi) : o;
        const double fL =
            ownFrame ? 0.5 * std::max({fhi.x - flo.x, fhi.y - flo.y, fhi.z - flo.z}) : L;
        for (const Exponent& e : exps) {
          double exact = 0, quad = 0;
          for (int i = 1; i + 1 < g.count; ++i) {
            const std::array<Vec3, 3> tri{g.v[0], g.v[i], g.v[i + 1]};
            const double a = 0.5 * norm(cross(tri[1] - tri[0], tri[2] - tri[0]));
            exact += test::simplexMonomialIntegral<2>(tri, a, fo, fL, e);
          }
          for (int q = 0; q < s.count; ++q)
            quad += s.weights[q] * monomialAt(s.points[q], fo, fL, e);
          err.surface = std::max(err.surface, std::abs(quad - exact) / area);
        }
      }
    }
    err.tiling = std::max(err.tiling, std::abs(tiled - tetV) / tetV);
  }
  return err;
}

TEST(XfemQuadrature, ExactUpToDegreeOnRandomAndSliverCuts) {
  for (bool own : {false, true}) {
    const Errors e = runCases(own);
    std::printf(
        "flat cells (thickness < 1e-3 diameter): max volume error %.2e of the cell's "
        "volume, %.2e times the flatness\n",
        e.volumeFlat, e.volumeFlatScaled);
    std::printf(
        "moment fitting (%s frame): max volume error %.2e, surface %.2e (of the cell's volume / "
        "face's area), cut-face vertex off plane %.2e, cells vs tet %.2e, smallest cell %.2e of "
        "its tet, degree-5 error %.2e; cell volume vs independent clip %.2e of the tet (%.2e of "
        "the cell)\n",
        own ? "cell" : "tet", e.volume, e.surface, e.onPlane, e.tiling, e.smallestCell, e.degree5,
        e.geometry, e.geometryOwn);
    EXPECT_LE(e.geometry, 1e-14);
    EXPECT_LE(e.onPlane, 1e-12);
    if (own) continue;  // at a sliver's own scale, its points' storage in tet coordinates rules
    EXPECT_LE(e.volume, 1e-12);
    EXPECT_LE(e.volumeFlatScaled, 1e-14);
    EXPECT_LE(e.surface, 1e-12);
    EXPECT_LE(e.tiling, 1e-13);
    EXPECT_LT(e.smallestCell, 1e-15);  // the vertex slivers are in the set
    EXPECT_GT(e.degree5, 1e-8);        // and the rule is exactly of its degree
  }
}

// The rule of an uncut tet (no fitting) on random tets: every monomial up to degree 5 exact
// against the closed-form simplex integrals; degree 6 is not (the check has teeth).
TEST(XfemQuadrature, StandardTetRuleIsExactToDegreeFive) {
  std::mt19937_64 rng(77);
  double worst = 0, degree6 = 0;
  for (int n = 0; n < 40; ++n) {
    const Tet t = randomTet(rng);
    const double v = dot(t[1] - t[0], cross(t[2] - t[0], t[3] - t[0])) / 6.0;
    const VolumeRule rule = standardTetRule(t.data(), v);
    ASSERT_EQ(rule.count, 15);
    Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (const Vec3& x : t)
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], x[a]);
        hi[a] = std::max(hi[a], x[a]);
      }
    const Vec3 o = 0.5 * (lo + hi);
    const double L = 0.5 * std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    for (const Exponent& e : test::exponentsUpTo(6)) {
      double quad = 0;
      for (int q = 0; q < rule.count; ++q)
        quad += rule.weights[q] * monomialAt(rule.points[q], o, L, e);
      const double err = std::abs(quad - test::simplexMonomialIntegral<3>(t, v, o, L, e)) / v;
      if (e[0] + e[1] + e[2] <= 5)
        worst = std::max(worst, err);
      else
        degree6 = std::max(degree6, err);
    }
  }
  std::printf("standard tet rule: max error %.2e of the volume to degree 5, %.2e at degree 6\n",
              worst, degree6);
  EXPECT_LE(worst, 1e-13);
  EXPECT_GT(degree6, 1e-6);
}

TEST(XfemQuadrature, GrundmannMoellerWeightsSumToOne) {
  for (int s = 0; s <= 3; ++s) {
    double tet = 0, tri = 0;
    grundmannMoellerTet(s, [&](double w, const double*) { tet += w; });
    grundmannMoellerTriangle(s, [&](double w, const double*) { tri += w; });
    EXPECT_NEAR(tet, 1.0, 1e-14) << s;
    EXPECT_NEAR(tri, 1.0, 1e-14) << s;
  }
}

TEST(XfemQuadrature, PlaneThroughVertexLeavesNoSliver) {
  // A plane through vertex 0 and parallel to nothing special: the side holding only vertex 0
  // is empty, not a cell of rounding noise; a plane containing a face leaves one empty side.
  const Vec3 X[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const CutPlane face{{0, 0, 1}, 0};
  EXPECT_EQ(clipTet(X, &face, 1, 0u).faceCount, 0);
  const CutPolytope whole = clipTet(X, &face, 1, 1u);
  EXPECT_NEAR(polytopeVolume(whole), 1.0 / 6, 1e-15);
  const CutPlane edge{unit({1, -1, 0}), 0};  // contains the edge 0-3
  const double v0 = polytopeVolume(clipTet(X, &edge, 1, 0u));
  const double v1 = polytopeVolume(clipTet(X, &edge, 1, 1u));
  EXPECT_NEAR(v0, 1.0 / 12, 1e-15);
  EXPECT_NEAR(v1, 1.0 / 12, 1e-15);
}

}  // namespace
}  // namespace gf
