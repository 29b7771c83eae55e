// A box cut by N parallel planes with Is-XFEM (thesis ch 3), as planes and as blades (triangle
// meshes): N = 1 to 20, spacings from several cells down to a third of a cell (several planes
// through one tet), axis-aligned, slanted and tilted sets, and sets that pass through nodes to
// rounding (node layers, and the slopes of `graphfrac bench xfem`, whose 20 blades one cell apart
// hit nodes and once left the body whole). Each must give N + 1 pieces whose volumes equal the
// exact split, computed independently by inclusion-exclusion over the box's corners, with cut
// faces on their planes. With both ends held, the slabs in between fall exactly as implicit
// Euler free fall (they really separate). A tet crossed by more than kMaxCutPlanes cuts is a
// clear error, never a wrong volume.
#include <graphfrac/mesh.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "common/xfem_blades.h"
#include "xfem/cut_body.h"

namespace gf::detail {
namespace {

// Volume of {p in [0, L0] x [0, L1] x [0, L2] : n . p <= d}. Mirroring each axis with a negative
// component makes n >= 0; over the axes with n_i > 0 (m of them), the volume is
// sum over the corners v of (-1)^(upper corners) max(0, d - n . v)^m / (m! prod n_i) (the m-th
// mixed difference of max(0, t)^m / m!), times the lengths of the axes with n_i = 0.
double exactBelow(Vec3 n, double d, const double L[3]) {
  double scale = 1, denominator = 1;
  int axes[3], m = 0;
  for (int i = 0; i < 3; ++i) {
    if (n[i] < 0) {
      d -= n[i] * L[i];
      n[i] = -n[i];
    }
    if (n[i] == 0) {
      scale *= L[i];
    } else {
      axes[m++] = i;
      denominator *= n[i] * m;  // m! prod n_i
    }
  }
  if (m == 0) return d >= 0 ? scale : 0.0;
  double sum = 0;
  for (int corner = 0; corner < (1 << m); ++corner) {
    double t = d;
    int upper = 0;
    for (int k = 0; k < m; ++k)
      if ((corner >> k) & 1) {
        t -= n[axes[k]] * L[axes[k]];
        ++upper;
      }
    sum += (upper % 2 ? -1.0 : 1.0) * std::pow(std::max(t, 0.0), m);
  }
  return scale * sum / denominator;
}

// N parallel cuts x = a_k + b y + c z (normal along +x - b y - c z), a_k ascending.
struct ParallelSet {
  const char* name;
  double b, c;
  std::vector<double> a;
};

struct Outcome {
  size_t pieces = 0;
  double worstVolume = 0, worstFace = 0;
  bool created = false;
};

Outcome cutBox(const TetMesh& mesh, const double L[3], const ParallelSet& set, bool blades) {
  XfemBodyDef def;
  def.mesh = mesh;
  def.material = {1e7, 0.3, 1000};
  const double len = std::sqrt(1 + set.b * set.b + set.c * set.c);
  const Vec3 n{1 / len, -set.b / len, -set.c / len};
  std::vector<CutPlane> planes;
  for (double a : set.a) planes.push_back({n, a / len});
  if (blades) {
    for (double a : set.a) def.blades.push_back({test::planarBlade(a, set.b, set.c, -1, 2, 2), {}});
  } else {
    def.planes = planes;
  }
  Outcome out;
  auto made = XfemBody::create(def);
  EXPECT_TRUE(made.ok()) << set.name << ": " << made.error().message;
  if (!made.ok()) return out;
  out.created = true;
  const XfemBody& body = *made.value();
  out.pieces = body.pieces().size();
  // Piece k lies on the positive side of cuts 0..k-1 and the negative side of the rest.
  const size_t N = set.a.size();
  double below = 0;
  for (size_t k = 0; k <= N; ++k) {
    const double next = k == N ? L[0] * L[1] * L[2] : exactBelow(n, planes[k].offset, L);
    const double exact = next - below;
    below = next;
    const int p = body.pieceWithMask(unsigned((1ull << k) - 1));
    EXPECT_GE(p, 0) << set.name << ": no piece between cuts " << k - 1 << " and " << k;
    if (p < 0) {
      out.worstVolume = INFINITY;
      continue;
    }
    const double got = body.pieces()[size_t(p)].volume;
    out.worstVolume = std::max(out.worstVolume, std::abs(got - exact) / exact);
  }
  for (const XfemCutFace& f : body.cutFaces())
    for (int i = 0; i < f.polygon.count; ++i)
      out.worstFace =
          std::max(out.worstFace, std::abs(planeDistance(planes[size_t(f.plane)], f.polygon.v[i])));
  return out;
}

std::vector<double> spaced(double first, double spacing, int count) {
  std::vector<double> a;
  for (int k = 0; k < count; ++k) a.push_back(first + spacing * k);
  return a;
}

TEST(XfemParallelCuts, EveryPieceHasTheExactVolume) {
  // 2 x 1 x 1 box, cells h = 0.25 (768 tets).
  const double L[3] = {2, 1, 1}, h = 0.25;
  const TetMesh mesh = gen::box(2, 1, 1, 8, 4, 4);
  std::vector<ParallelSet> sets;
  // Slopes: the bench's slant, axis-aligned, and two tilted directions (the plane function
  // varies by h (1 + |b| + |c|) over a cell, so a third of a cell apart is at most 4 cuts per
  // tet for the first two and half a cell for the tilted ones).
  struct Slope {
    const char* name;
    double b, c, minSpacing;
  };
  const Slope slopes[] = {{"slanted", 0.05, 0.03, h / 3},
                          {"axis", 0, 0, h / 3},
                          {"tilted", -0.4, -0.3, h / 2},
                          {"tilted2", 0.35, -0.45, h / 2}};
  for (const Slope& s : slopes)
    for (double spacing : {2.4 * h, 1.03 * h, 0.52 * h, 0.34 * h}) {
      if (spacing < s.minSpacing) continue;
      // Offsets over the range where every plane crosses the box, off the node layers.
      const double lo = std::max(0.0, -s.b) + std::max(0.0, -s.c) + 0.031;
      const double hi = 2 - std::max(0.0, s.b) - std::max(0.0, s.c) - 0.031;
      const int most = std::min(20, int((hi - lo) / spacing) + 1);
      for (int N : {1, 2, 5, most})
        if (N <= most) sets.push_back({s.name, s.b, s.c, spaced(lo + 0.0123, spacing, N)});
    }
  // Through nodes: node layers (x = k h), and planes through nodes of the tilted set.
  sets.push_back({"node layers", 0, 0, spaced(h, h, 7)});
  sets.push_back({"node layers h/3 apart", 0, 0, spaced(h, h / 3, 18)});
  sets.push_back({"tilted through nodes", -0.4, -0.3, spaced(0.75, h, 4)});
  int runs = 0;
  double worstVolume = 0, worstFace = 0;
  for (const ParallelSet& set : sets)
    for (bool blades : {false, true}) {
      const Outcome o = cutBox(mesh, L, set, blades);
      if (!o.created) continue;
      ++runs;
      EXPECT_EQ(o.pieces, set.a.size() + 1)
          << set.name << (blades ? " blades" : " planes") << ", N = " << set.a.size();
      EXPECT_LE(o.worstVolume, 1e-10)
          << set.name << (blades ? " blades" : " planes") << ", N = " << set.a.size();
      EXPECT_LE(o.worstFace, 1e-12) << set.name;
      worstVolume = std::max(worstVolume, o.worstVolume);
      worstFace = std::max(worstFace, o.worstFace);
    }
  std::printf(
      "%d cut bodies (planes and blades, N = 1..20, 0.34 to 2.4 cells apart): worst piece volume "
      "rel. error %.1e, cut-face vertices off their plane <= %.1e\n",
      runs, worstVolume, worstFace);
}

// The bench's cuts at its own spacing: x = 0.063 + 0.1 k + 0.05 y + 0.03 z on cells of 0.1
// pass through the nodes (x, 0.5, 0.4) to rounding; before node snapping, the blades were
// partial there and the body stayed whole.
TEST(XfemParallelCuts, BenchCutsThroughNodesSeparate) {
  const double L[3] = {1, 0.5, 0.5};
  const TetMesh mesh = gen::box(1, 0.5, 0.5, 10, 5, 5);
  const ParallelSet set{"bench through nodes", 0.05, 0.03, spaced(0.063, 0.1, 9)};
  for (bool blades : {false, true}) {
    const Outcome o = cutBox(mesh, L, set, blades);
    std::printf("bench cuts through nodes (%s): %zu pieces, volumes rel. error %.1e\n",
                blades ? "blades" : "planes", o.pieces, o.worstVolume);
    EXPECT_EQ(o.pieces, 10u);
    EXPECT_LE(o.worstVolume, 1e-10);
    EXPECT_LE(o.worstFace, 1e-12);
  }
}

TEST(XfemParallelCuts, SlabsBetweenHeldEndsFallFreely) {
  // Five blades a third of a cell apart, or through node layers: with x = 0
  // and x = 2 held, the four slabs in between have no support and fall as implicit Euler free
  // fall, u_n = -g dt^2 n (n + 1) / 2, whatever the tets crossed by several cuts do.
  for (const ParallelSet& set : {ParallelSet{"third of a cell", 0.05, 0.03, spaced(0.9, 0.085, 5)},
                                 ParallelSet{"through nodes", 0, 0, spaced(0.5, 0.25, 5)}}) {
    XfemBodyDef def;
    def.mesh = gen::box(2, 1, 1, 8, 4, 4);
    def.material = {1e9, 0.3, 1000};  // stiff: the held end slabs barely sag
    def.dt = 1e-3;
    for (double a : set.a) def.blades.push_back({test::planarBlade(a, set.b, set.c, -1, 2, 2), {}});
    for (int32_t n = 0; n < int32_t(def.mesh.nodeCount()); ++n) {
      const double x = def.mesh.positions[3 * size_t(n)];
      if (x == 0 || x == 2) def.fixedNodes.push_back(n);
    }
    auto made = XfemBody::create(def);
    ASSERT_TRUE(made.ok()) << made.error().message;
    XfemBody& body = *made.value();
    ASSERT_EQ(body.pieces().size(), 6u) << set.name;
    const int steps = 50;
    for (int s = 0; s < steps; ++s) body.step();
    const double freeFall = -9.81 * def.dt * def.dt * steps * (steps + 1) / 2;
    double worst = 0;
    for (unsigned k = 1; k < 5; ++k) {
      const int p = body.pieceWithMask((1u << k) - 1);
      ASSERT_GE(p, 0);
      const Vec3 u = body.pieceMeanDisplacement(p);
      worst = std::max(worst, std::abs(u.y - freeFall) / std::abs(freeFall));
      EXPECT_LE(std::abs(u.x) + std::abs(u.z), 1e-9 * std::abs(freeFall)) << set.name << " " << k;
    }
    const double endSag = body.pieceMeanDisplacement(body.pieceWithMask(0u)).y;
    std::printf(
        "%s: 4 free slabs fall %.6e m vs implicit Euler %.6e m (worst rel. %.1e); held end "
        "slab %.2e m\n",
        set.name, body.pieceMeanDisplacement(body.pieceWithMask(1u)).y, freeFall, worst, endSag);
    EXPECT_LE(worst, 1e-8) << set.name;
    EXPECT_LT(std::abs(endSag), 0.05 * std::abs(freeFall));
  }
}

TEST(XfemParallelCuts, MoreCutsThanATetCarriesIsAnError) {
  // A sixth of a cell apart: tets are crossed by 6 planes, more than kMaxCutPlanes; the
  // body is refused with the tet and the limit named, never built with a wrong volume.
  for (bool blades : {false, true}) {
    XfemBodyDef def;
    def.mesh = gen::box(2, 1, 1, 8, 4, 4);
    const std::vector<double> a = spaced(0.76, 0.04, 6);  // six inside the cells x in [0.75, 1]
    const Vec3 n{1, 0, 0};
    for (double x : a) {
      if (blades)
        def.blades.push_back({test::planarBlade(x, 0, 0, -1, 2, 1), {}});
      else
        def.planes.push_back({n, x});
    }
    auto made = XfemBody::create(def);
    ASSERT_FALSE(made.ok());
    const std::string& message = made.error().message;
    std::printf("%s: %s\n", blades ? "blades" : "planes", message.c_str());
    EXPECT_NE(message.find("tet "), std::string::npos);
    EXPECT_NE(message.find("at most " + std::to_string(kMaxCutPlanes)), std::string::npos);
  }
}

}  // namespace
}  // namespace gf::detail
