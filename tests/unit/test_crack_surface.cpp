// Crack surface: every fragment's surface closed and edge-manifold with consistent orientation,
// enclosed volumes (divergence theorem) equal to the fragments' corner-cell volumes, crack faces
// flagged and facing out, rigid motions reproduced exactly.
#include <graphfrac/mesh.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <random>
#include <utility>
#include <vector>

#include "graphfrac/jobs.h"
#include "mesh/edge_graph.h"
#include "surface/crack_surface.h"
#include "surface/fragments.h"

namespace gf::detail {
namespace {

struct Body {
  TetMesh mesh;
  EdgeGraph graph;
  std::vector<uint8_t> broken;
  std::vector<double> nodeVolume;
  explicit Body(TetMesh m) : mesh(std::move(m)) {
    graph = EdgeGraph::build(mesh.tets.data(), mesh.tetCount(), mesh.nodeCount());
    broken.assign(size_t(graph.edgeCount), 0);
    nodeVolume = Fragments::nodeVolumes(mesh.tets.data(), mesh.tetCount(), mesh.positions.data(),
                                        mesh.nodeCount());
  }
  void breakPlane(double nx, double ny, double nz, double d) {
    for (int32_t e = 0; e < graph.edgeCount; ++e) {
      double s[2];
      for (int k = 0; k < 2; ++k) {
        const double* p = &mesh.positions[3 * size_t(graph.edgeNodes[2 * size_t(e) + size_t(k)])];
        s[k] = nx * p[0] + ny * p[1] + nz * p[2] - d;
      }
      if ((s[0] < 0) != (s[1] < 0)) broken[size_t(e)] = 1;
    }
  }
};

double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
void cross3(const double* a, const double* b, double* c) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}

// Per fragment: closedness (every undirected edge in exactly two triangles, once in each
// direction), enclosed volume (sum of signed tetrahedra to the origin), area, crack area vector.
struct FragmentSurface {
  int triangles = 0, crackTriangles = 0;
  int badEdges = 0;  // undirected edges not used exactly once in each direction
  double volume = 0, area = 0, crackArea[3] = {0, 0, 0};
};

std::vector<FragmentSurface> inspect(const CrackSurface& s, int32_t fragments) {
  std::vector<FragmentSurface> out(static_cast<size_t>(fragments));
  std::vector<std::map<std::pair<uint32_t, uint32_t>, int>> directed(
      static_cast<size_t>(fragments));
  const auto idx = s.indices();
  const auto pos = s.positionsDouble();
  const auto frag = s.vertexFragment();
  for (uint32_t t = 0; t < s.triangleCount(); ++t) {
    const uint32_t v[3] = {idx[3 * t], idx[3 * t + 1], idx[3 * t + 2]};
    const int32_t f = frag[v[0]];
    EXPECT_EQ(frag[v[1]], f);
    EXPECT_EQ(frag[v[2]], f);
    EXPECT_TRUE(v[0] != v[1] && v[1] != v[2] && v[0] != v[2]);
    FragmentSurface& fs = out[size_t(f)];
    ++fs.triangles;
    for (int k = 0; k < 3; ++k) ++directed[size_t(f)][{v[k], v[(k + 1) % 3]}];
    const double* p0 = &pos[3 * v[0]];
    const double* p1 = &pos[3 * v[1]];
    const double* p2 = &pos[3 * v[2]];
    double c[3], e1[3], e2[3];
    cross3(p1, p2, c);
    fs.volume += dot3(p0, c) / 6;
    for (int k = 0; k < 3; ++k) {
      e1[k] = p1[k] - p0[k];
      e2[k] = p2[k] - p0[k];
    }
    cross3(e1, e2, c);
    fs.area += 0.5 * std::sqrt(dot3(c, c));
    if (s.crackFlags()[t]) {
      ++fs.crackTriangles;
      for (int k = 0; k < 3; ++k) fs.crackArea[k] += 0.5 * c[k];
    }
  }
  for (size_t f = 0; f < out.size(); ++f)
    for (const auto& [e, n] : directed[f]) {
      const auto rev = directed[f].find({e.second, e.first});
      if (n != 1 || rev == directed[f].end() || rev->second != 1) ++out[f].badEdges;
    }
  return out;
}

std::vector<double> fragmentVolumes(const std::vector<double>& nodeVolume, const int32_t* frag,
                                    int32_t count) {
  std::vector<double> v(size_t(count), 0.0);
  for (size_t i = 0; i < nodeVolume.size(); ++i) v[size_t(frag[i])] += nodeVolume[i];
  return v;
}

double boundaryArea(const TetMesh& m) {
  const std::vector<int32_t> f = m.boundaryFaces();
  double area = 0;
  for (size_t i = 0; i < f.size(); i += 3) {
    const double* a = &m.positions[3 * size_t(f[i])];
    const double* b = &m.positions[3 * size_t(f[i + 1])];
    const double* c = &m.positions[3 * size_t(f[i + 2])];
    double e1[3], e2[3], n[3];
    for (int k = 0; k < 3; ++k) {
      e1[k] = b[k] - a[k];
      e2[k] = c[k] - a[k];
    }
    cross3(e1, e2, n);
    area += 0.5 * std::sqrt(dot3(n, n));
  }
  return area;
}

// Every fragment closed and its enclosed volume equal to its cell volume; returns the largest
// relative mismatch.
double expectClosedWithVolumes(const CrackSurface& s, const Fragments& fr,
                               const std::vector<double>& cellVolume) {
  const std::vector<double> want =
      fragmentVolumes(cellVolume, fr.nodeFragment().data(), fr.count());
  const std::vector<FragmentSurface> got = inspect(s, fr.count());
  double worst = 0;
  for (int32_t f = 0; f < fr.count(); ++f) {
    const FragmentSurface& g = got[size_t(f)];
    EXPECT_GT(g.triangles, 0) << "fragment " << f;
    EXPECT_EQ(g.badEdges, 0) << "fragment " << f;
    const double rel = std::fabs(g.volume - want[size_t(f)]) / want[size_t(f)];
    worst = std::max(worst, rel);
    EXPECT_LT(rel, 1e-9) << "fragment " << f << ": " << g.volume << " vs " << want[size_t(f)];
  }
  return worst;
}

// Crack triangles face away from the corner node whose cell they bound; returns how many were
// checked.
int expectCrackNormalsOutward(const CrackSurface& s, const double* x) {
  const auto idx = s.indices();
  const auto pos = s.positionsDouble();
  int checked = 0;
  for (uint32_t t = 0; t < s.triangleCount(); ++t) {
    if (!s.crackFlags()[t]) continue;
    const double* p[3] = {&pos[3 * idx[3 * t]], &pos[3 * idx[3 * t + 1]], &pos[3 * idx[3 * t + 2]]};
    double e1[3], e2[3], n[3], c[3];
    const double* corner = x + 3 * size_t(s.triangleNode()[t]);
    for (int k = 0; k < 3; ++k) {
      e1[k] = p[1][k] - p[0][k];
      e2[k] = p[2][k] - p[0][k];
      c[k] = (p[0][k] + p[1][k] + p[2][k]) / 3 - corner[k];
    }
    cross3(e1, e2, n);
    EXPECT_GT(dot3(n, c), 0) << "triangle " << t;
    ++checked;
  }
  return checked;
}

TEST(CrackSurface, IntactBodyIsExactlyTheBoundary) {
  for (const TetMesh& m :
       {gen::box(2, 1, 1, 6, 3, 3), gen::sphere(1, 6), gen::cylinder(1, 2, 16, 3, 3)}) {
    Body b(m);
    Fragments fr;
    fr.build(b.graph, b.broken.data());
    CrackSurface s;
    s.init(b.mesh, b.graph);
    s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr);
    // Each boundary triangle gives 3 quads; vertices are its nodes, edge points and centroids.
    const std::vector<int32_t> bf = b.mesh.boundaryFaces();
    std::vector<int32_t> nodes(bf);
    std::sort(nodes.begin(), nodes.end());
    nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
    const size_t nf = bf.size() / 3, nbn = nodes.size(), nbe = nbn + nf - 2;  // Euler, sphere
    EXPECT_EQ(s.triangleCount(), 6 * nf);
    EXPECT_EQ(s.vertexCount(), nbn + nbe + nf);
    const auto got = inspect(s, 1);
    EXPECT_EQ(got[0].badEdges, 0);
    EXPECT_EQ(got[0].crackTriangles, 0);
    EXPECT_NEAR(got[0].area, boundaryArea(b.mesh), 1e-12 * got[0].area);
    EXPECT_NEAR(got[0].volume, b.mesh.volume(), 1e-12 * b.mesh.volume());
    // Normals: unit length, and on the sphere's boundary they point outward.
    for (uint32_t v = 0; v < s.vertexCount(); ++v) {
      const float* n = &s.normals()[3 * v];
      EXPECT_NEAR(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], 1.0, 1e-5);
    }
  }
}

TEST(CrackSurface, AffineMotionOfIntactBodyIsExact) {
  Body b(gen::sphere(1, 4));
  Fragments fr;
  fr.build(b.graph, b.broken.data());
  CrackSurface s;
  s.init(b.mesh, b.graph);
  s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr);
  const std::vector<double> rest(s.positionsDouble().begin(), s.positionsDouble().end());
  const double A[9] = {1.2, 0.1, -0.3, 0.05, 0.9, 0.2, 0.1, -0.15, 1.1}, t[3] = {3, -1, 0.5};
  std::vector<double> x(b.mesh.positions.size());
  auto apply = [&](const double* p, double* o) {
    for (int r = 0; r < 3; ++r)
      o[r] = A[3 * r] * p[0] + A[3 * r + 1] * p[1] + A[3 * r + 2] * p[2] + t[r];
  };
  for (size_t i = 0; i < b.mesh.nodeCount(); ++i) apply(&b.mesh.positions[3 * i], &x[3 * i]);
  const uint64_t topo = s.topologyVersion();
  s.updatePositions(x.data());
  EXPECT_EQ(s.topologyVersion(), topo);
  EXPECT_EQ(s.dirty().begin, 0u);
  EXPECT_EQ(s.dirty().end, s.vertexCount());
  for (uint32_t v = 0; v < s.vertexCount(); ++v) {
    double want[3];
    apply(&rest[3 * v], want);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.positionsDouble()[3 * v + k], want[k], 1e-12);
  }
  const double detA = A[0] * (A[4] * A[8] - A[5] * A[7]) - A[1] * (A[3] * A[8] - A[5] * A[6]) +
                      A[2] * (A[3] * A[7] - A[4] * A[6]);
  EXPECT_NEAR(inspect(s, 1)[0].volume, detA * b.mesh.volume(), 1e-12);
}

TEST(CrackSurface, PlanarCutGivesTwoClosedPiecesWithCrackFaces) {
  for (bool partial : {true, false}) {
    Body b(gen::box(2, 1, 1, 8, 4, 4));
    b.breakPlane(1, 0, 0, 1.1);
    Fragments fr;
    fr.build(b.graph, b.broken.data());
    ASSERT_EQ(fr.count(), 2);
    CrackSurface s;
    s.init(b.mesh, b.graph, CrackSurfaceOptions{partial});
    s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr);
    expectClosedWithVolumes(s, fr, b.nodeVolume);
    EXPECT_GT(expectCrackNormalsOutward(s, b.mesh.positions.data()), 0);
    // Divergence theorem on each closed piece: the crack faces' area vector balances the
    // end cap, so it is exactly +-(1 x 1) along x.
    const auto got = inspect(s, 2);
    EXPECT_NEAR(got[0].crackArea[0], 1.0, 1e-12);
    EXPECT_NEAR(got[1].crackArea[0], -1.0, 1e-12);
    for (int k = 1; k < 3; ++k) {
      EXPECT_NEAR(got[0].crackArea[k], 0.0, 1e-12);
      EXPECT_NEAR(got[1].crackArea[k], 0.0, 1e-12);
    }
    EXPECT_EQ(got[0].crackTriangles, got[1].crackTriangles);

    // Move the pieces apart: one translated, the other turned about an axis through a point.
    const double d[3] = {0.7, 0.2, -0.1}, angle = 0.9, axis[3] = {0.48, 0.6, 0.64};
    double R[9];
    {
      const double c = std::cos(angle), sn = std::sin(angle), u = 1 - c;
      const double x = axis[0], y = axis[1], z = axis[2];
      const double r[9] = {c + x * x * u,      x * y * u - z * sn, x * z * u + y * sn,
                           y * x * u + z * sn, c + y * y * u,      y * z * u - x * sn,
                           z * x * u - y * sn, z * y * u + x * sn, c + z * z * u};
      std::copy(r, r + 9, R);
    }
    const double pivot[3] = {0.5, 0.5, 0.5};
    std::vector<double> x(b.mesh.positions);
    auto rigid = [&](int32_t frag, const double* p, double* o) {
      if (frag == 1) {
        for (int k = 0; k < 3; ++k) o[k] = p[k] + d[k];
      } else {
        const double q[3] = {p[0] - pivot[0], p[1] - pivot[1], p[2] - pivot[2]};
        for (int k = 0; k < 3; ++k)
          o[k] = pivot[k] + R[3 * k] * q[0] + R[3 * k + 1] * q[1] + R[3 * k + 2] * q[2];
      }
    };
    for (size_t i = 0; i < b.mesh.nodeCount(); ++i)
      rigid(fr.nodeFragment()[i], &b.mesh.positions[3 * i], &x[3 * i]);
    const std::vector<double> rest(s.positionsDouble().begin(), s.positionsDouble().end());
    s.updatePositions(x.data());
    expectClosedWithVolumes(s, fr, b.nodeVolume);
    EXPECT_GT(expectCrackNormalsOutward(s, x.data()), 0);
    // Every render vertex moved with its piece, crack faces included.
    double worst = 0;
    for (uint32_t v = 0; v < s.vertexCount(); ++v) {
      double want[3];
      rigid(s.vertexFragment()[v], &rest[3 * v], want);
      for (int k = 0; k < 3; ++k)
        worst = std::max(worst, std::fabs(s.positionsDouble()[3 * v + k] - want[k]));
    }
    EXPECT_LT(worst, 1e-12);
  }
}

TEST(CrackSurface, DeformedPiecesKeepTheirVolume) {
  // The cut box, deformed. Vertices off the crack follow their tet's linear map exactly;
  // vertices on it follow their nodes' fitted affine maps: exact for an affine motion of each
  // piece, an approximation for a bend (acceptance bound 1 %).
  Body b(gen::box(2, 1, 1, 8, 4, 4));
  b.breakPlane(1, 0, 0, 1.1);
  Fragments fr;
  fr.build(b.graph, b.broken.data());
  CrackSurface s;
  s.init(b.mesh, b.graph);
  s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr);
  const std::vector<double> rest =
      fragmentVolumes(b.nodeVolume, fr.nodeFragment().data(), fr.count());
  auto mismatch = [&](const std::vector<double>& x, const std::vector<double>& want) {
    s.updatePositions(x.data());
    const auto got = inspect(s, 2);
    double worst = 0;
    for (size_t f = 0; f < 2; ++f) {
      EXPECT_EQ(got[f].badEdges, 0);
      worst = std::max(worst, std::fabs(got[f].volume - want[f]) / want[f]);
    }
    return worst;
  };

  // 2 % affine stretch with the right piece pulled away by 0.3: volumes scale by det F.
  const double F[3] = {1.02, 0.99, 1.015}, detF = F[0] * F[1] * F[2];
  std::vector<double> x(b.mesh.positions);
  for (size_t i = 0; i < b.mesh.nodeCount(); ++i)
    for (size_t k = 0; k < 3; ++k)
      x[3 * i + k] = F[k] * x[3 * i + k] + (k == 0 && fr.nodeFragment()[i] == 1 ? 0.3 : 0.0);
  const double stretch = mismatch(x, {detF * rest[0], detF * rest[1]});
  EXPECT_LT(stretch, 1e-12);

  // Bend about z (curvature 0.3) with a 5 % taper, pieces still touching: each corner cell
  // then moves with its tet's linear map, so a node owns a quarter of every incident tet's
  // deformed volume.
  x = b.mesh.positions;
  for (size_t i = 0; i < b.mesh.nodeCount(); ++i) {
    double* p = &x[3 * i];
    const double r = 1 / 0.3, a = p[0] / r, rr = r - p[1] * (1 + 0.05 * p[0]);
    p[0] = rr * std::sin(a);
    p[1] = r - rr * std::cos(a);
  }
  const std::vector<double> deformed =
      Fragments::nodeVolumes(b.mesh.tets.data(), b.mesh.tetCount(), x.data(), b.mesh.nodeCount());
  const double bend = mismatch(x, fragmentVolumes(deformed, fr.nodeFragment().data(), 2));
  EXPECT_LT(bend, 0.01);
  std::printf(
      "[ figures  ] deformed cut box: rel volume mismatch %.2e (2 %% stretch, pieces "
      "apart), %.2e (bend)\n",
      stretch, bend);
}

TEST(CrackSurface, ObliquePlaneCutsCylinderAndSphereInTwo) {
  const double n[3] = {0.6, 0.64, 0.48};  // unit
  for (const TetMesh& m : {gen::cylinder(1, 2, 24, 8, 4), gen::sphere(1, 10)}) {
    Body b(m);
    double centre[3] = {0, 0, 0};
    for (size_t i = 0; i < b.mesh.nodeCount(); ++i)
      for (int k = 0; k < 3; ++k)
        centre[k] += b.mesh.positions[3 * i + size_t(k)] / double(b.mesh.nodeCount());
    b.breakPlane(n[0], n[1], n[2], dot3(n, centre) + 0.137);
    Fragments fr;
    fr.build(b.graph, b.broken.data());
    EXPECT_EQ(fr.count(), 2);
    CrackSurface s;
    s.init(b.mesh, b.graph);
    s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr);
    const double worst = expectClosedWithVolumes(s, fr, b.nodeVolume);
    EXPECT_GT(expectCrackNormalsOutward(s, b.mesh.positions.data()), 0);
    const auto got = inspect(s, fr.count());
    // Both pieces' volumes add up to the whole.
    EXPECT_NEAR(got[0].volume + got[1].volume, b.mesh.volume(), 1e-12 * b.mesh.volume());
    std::printf(
        "[ figures  ] oblique cut (%zu tets): 2 pieces, volumes %.6f + %.6f = %.6f, "
        "max rel mismatch %.2e, %d crack triangles\n",
        b.mesh.tetCount(), got[0].volume, got[1].volume, b.mesh.volume(), worst,
        got[0].crackTriangles + got[1].crackTriangles);
  }
}

TEST(CrackSurface, RandomDamageKeepsEveryFragmentClosed) {
  double worst = 0;
  int maxFragments = 0;
  for (bool partial : {true, false}) {
    for (uint32_t seed = 0; seed < 12; ++seed) {
      Body b(seed % 2 ? gen::sphere(1, 4) : gen::box(1, 1, 1, 4, 3, 3));
      std::mt19937 rng(seed);
      const double p = 0.05 + 0.26 * double(seed % 4);  // 5 % to 83 % of the edges
      for (auto& e : b.broken) e = std::uniform_real_distribution<double>(0, 1)(rng) < p;
      Fragments fr;
      fr.build(b.graph, b.broken.data());
      maxFragments = std::max(maxFragments, fr.count());
      CrackSurface s;
      s.init(b.mesh, b.graph, CrackSurfaceOptions{partial});
      s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr);
      worst = std::max(worst, expectClosedWithVolumes(s, fr, b.nodeVolume));
      expectCrackNormalsOutward(s, b.mesh.positions.data());
      const auto got = inspect(s, fr.count());
      double total = 0;
      for (const auto& g : got) total += g.volume;
      EXPECT_NEAR(total, b.mesh.volume(), 1e-12 * b.mesh.volume());

      // Every fragment moved rigidly on its own: still closed, same volumes.
      std::vector<double> x(b.mesh.positions);
      for (size_t i = 0; i < b.mesh.nodeCount(); ++i) {
        const int32_t f = fr.nodeFragment()[i];
        const double a = 0.3 * f, c = std::cos(a), sn = std::sin(a);
        const double* X = &b.mesh.positions[3 * i];
        x[3 * i] = c * X[0] - sn * X[1] + 0.5 * f;
        x[3 * i + 1] = sn * X[0] + c * X[1] - 0.2 * f;
        x[3 * i + 2] = X[2] + 0.1 * f;
      }
      s.updatePositions(x.data());
      worst = std::max(worst, expectClosedWithVolumes(s, fr, b.nodeVolume));
      if (!partial) continue;
      // Partial cracks show: every broken edge inside one tet gives 4 crack triangles per tet.
      size_t want = 0;
      for (int32_t e = 0; e < b.graph.edgeCount; ++e)
        if (b.broken[size_t(e)])
          want += 4 * size_t(b.graph.edgeTetStart[size_t(e) + 1] - b.graph.edgeTetStart[size_t(e)]);
      size_t crack = 0;
      for (uint8_t c : s.crackFlags()) crack += c;
      EXPECT_EQ(crack, want);
    }
  }
  EXPECT_GT(maxFragments, 20);
  std::printf("[ figures  ] random damage: up to %d fragments, max rel volume mismatch %.2e\n",
              maxFragments, worst);
}

TEST(CrackSurface, PartialCrackIsAClosedSlit) {
  // Break only the lower half (z < 0.5) of the layer: the body stays in one piece.
  Body b(gen::box(2, 1, 1, 8, 4, 4));
  for (int32_t e = 0; e < b.graph.edgeCount; ++e) {
    const double* p = &b.mesh.positions[3 * size_t(b.graph.edgeNodes[2 * size_t(e)])];
    const double* q = &b.mesh.positions[3 * size_t(b.graph.edgeNodes[2 * size_t(e) + 1])];
    if ((p[0] < 1.1) != (q[0] < 1.1) && p[2] < 0.4 && q[2] < 0.4) b.broken[size_t(e)] = 1;
  }
  Fragments fr;
  fr.build(b.graph, b.broken.data());
  ASSERT_EQ(fr.count(), 1);
  for (bool partial : {true, false}) {
    CrackSurface s;
    s.init(b.mesh, b.graph, CrackSurfaceOptions{partial});
    s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr);
    const auto got = inspect(s, 1);
    EXPECT_EQ(got[0].badEdges, 0);
    EXPECT_NEAR(got[0].volume, b.mesh.volume(), 1e-12);
    if (partial) {
      EXPECT_GT(got[0].crackTriangles, 0);
      EXPECT_GT(expectCrackNormalsOutward(s, b.mesh.positions.data()), 0);
      // The slit's two sides cancel: no net crack area vector.
      for (double c : got[0].crackArea) EXPECT_NEAR(c, 0.0, 1e-12);
    } else {
      EXPECT_EQ(got[0].crackTriangles, 0);
      EXPECT_NEAR(got[0].area, boundaryArea(b.mesh), 1e-12);
    }
    // A rigid turn of the whole body moves the slit's sides with it: volume and area kept.
    std::vector<double> x(b.mesh.positions);
    const double c = std::cos(1.1), sn = std::sin(1.1);
    for (size_t i = 0; i < b.mesh.nodeCount(); ++i) {
      const double* X = &b.mesh.positions[3 * i];
      x[3 * i] = c * X[0] + sn * X[2];
      x[3 * i + 2] = -sn * X[0] + c * X[2];
    }
    s.updatePositions(x.data());
    const auto moved = inspect(s, 1);
    EXPECT_NEAR(moved[0].volume, b.mesh.volume(), 1e-12);
    EXPECT_NEAR(moved[0].area, got[0].area, 1e-12);
  }
}

TEST(CrackSurface, ForceRatioSplitPartitionsTheTets) {
  Body b(gen::sphere(1, 6));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uni(0.1, 0.9);
  std::vector<double> ratio(size_t(b.graph.edgeCount));
  for (double& r : ratio) r = uni(rng);
  CrackSurface s;
  s.init(b.mesh, b.graph);
  // Midpoints: the exact cell volumes are V/4 per tet.
  std::vector<double> cells = s.cellRestVolumes();
  for (size_t i = 0; i < cells.size(); ++i) EXPECT_NEAR(cells[i], b.nodeVolume[i], 1e-15);
  s.setSplitRatios(ratio.data());
  cells = s.cellRestVolumes();
  double moved = 0;
  for (size_t i = 0; i < cells.size(); ++i)
    moved = std::max(moved, std::fabs(cells[i] - b.nodeVolume[i]) / b.nodeVolume[i]);
  EXPECT_GT(moved, 0.05);  // the ratios really moved the cells
  EXPECT_NEAR(std::accumulate(cells.begin(), cells.end(), 0.0), b.mesh.volume(), 1e-12);

  for (uint32_t seed = 0; seed < 6; ++seed) {
    std::fill(b.broken.begin(), b.broken.end(), 0);
    std::mt19937 r2(seed);
    for (auto& e : b.broken) e = r2() % 3 == 0;
    Fragments fr;
    fr.build(b.graph, b.broken.data());
    s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr);
    expectClosedWithVolumes(s, fr, cells);
    expectCrackNormalsOutward(s, b.mesh.positions.data());
  }
}

TEST(CrackSurface, WritesObjAndPlyWithCrackMarks) {
  Body b(gen::box(1, 1, 1, 2, 2, 2));
  b.breakPlane(1, 0, 0, 0.6);
  Fragments fr;
  fr.build(b.graph, b.broken.data());
  CrackSurface s;
  s.init(b.mesh, b.graph);
  s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr);
  const std::filesystem::path dir = std::filesystem::temp_directory_path();
  const std::string obj = (dir / "gf_crack_surface_test.obj").string();
  const std::string ply = (dir / "gf_crack_surface_test.ply").string();
  ASSERT_TRUE(s.write(obj).ok());
  ASSERT_TRUE(s.write(ply).ok());
  std::ifstream in(obj);
  std::string line;
  int v = 0, f = 0, crackFaces = 0;
  bool inCrack = false;
  while (std::getline(in, line)) {
    if (line.rfind("v ", 0) == 0) ++v;
    if (line == "g crack") inCrack = true;
    if (line.rfind("f ", 0) == 0) {
      ++f;
      crackFaces += inCrack;
    }
  }
  size_t crack = 0;
  for (uint8_t c : s.crackFlags()) crack += c;
  EXPECT_EQ(uint32_t(v), s.vertexCount());
  EXPECT_EQ(uint32_t(f), s.triangleCount());
  EXPECT_EQ(size_t(crackFaces), crack);
  EXPECT_FALSE(s.write((dir / "x.stl").string()).ok());
  std::filesystem::remove(obj);
  std::filesystem::remove(ply);
}

// Everything a rebuild() gives, bit for bit.
struct SurfaceCopy {
  std::vector<uint32_t> indices;
  std::vector<uint8_t> crack;
  std::vector<int32_t> triNode, vertexNode, vertexFragment, nodeFrame;
  std::vector<double> positions, normals, frames;
  explicit SurfaceCopy(const CrackSurface& s)
      : indices(s.indices().begin(), s.indices().end()),
        crack(s.crackFlags().begin(), s.crackFlags().end()),
        triNode(s.triangleNode().begin(), s.triangleNode().end()),
        vertexNode(s.vertexNode().begin(), s.vertexNode().end()),
        vertexFragment(s.vertexFragment().begin(), s.vertexFragment().end()),
        nodeFrame(s.nodeFrame().begin(), s.nodeFrame().end()),
        positions(s.positionsDouble().begin(), s.positionsDouble().end()),
        normals(s.normalsDouble().begin(), s.normalsDouble().end()),
        frames(s.frameMaps().begin(), s.frameMaps().end()) {}
  bool operator==(const SurfaceCopy&) const = default;
};

// The serial tet walk's order, which rebuild() keeps on any thread count: vertices are
// numbered by first use in the triangle list, and each vertex's normal sums its triangles by
// increasing index.
void expectSerialOrder(const CrackSurface& s) {
  const auto idx = s.indices();
  uint32_t next = 0;
  for (size_t k = 0; k < idx.size(); ++k) {
    ASSERT_LE(idx[k], next) << "vertex " << idx[k] << " used before vertex " << next;
    if (idx[k] == next) ++next;
  }
  EXPECT_EQ(next, s.vertexCount());
  const auto pos = s.positionsDouble();
  // Normals: the area-weighted sum over each vertex's triangles in increasing order.
  std::vector<std::vector<uint32_t>> tris(s.vertexCount());
  for (uint32_t t = 0; t < s.triangleCount(); ++t)
    for (int k = 0; k < 3; ++k) tris[idx[3 * t + size_t(k)]].push_back(t);
  auto areaNormal = [&](uint32_t t, double* n) {
    const double* p0 = &pos[3 * idx[3 * t]];
    const double* p1 = &pos[3 * idx[3 * t + 1]];
    const double* p2 = &pos[3 * idx[3 * t + 2]];
    double e1[3], e2[3];
    for (int k = 0; k < 3; ++k) {
      e1[k] = p1[k] - p0[k];
      e2[k] = p2[k] - p0[k];
    }
    cross3(e1, e2, n);
  };
  int wrong = 0;
  for (uint32_t v = 0; v < s.vertexCount(); ++v) {
    double sum[3] = {0, 0, 0}, weight = 0, n[3];
    for (uint32_t t : tris[v]) {
      areaNormal(t, n);
      for (int k = 0; k < 3; ++k) sum[k] += n[k];
      weight += std::sqrt(dot3(n, n));
    }
    const double len = std::sqrt(dot3(sum, sum));
    if (!(len > 1e-6 * weight && len > 0)) continue;  // crack fronts: the first triangle's
    for (int k = 0; k < 3; ++k) wrong += s.normalsDouble()[3 * v + size_t(k)] != sum[k] / len;
  }
  EXPECT_EQ(wrong, 0) << "normals not summed over the triangles in increasing order";
}

TEST(CrackSurface, RebuildIsTheSameOnAnyThreadCountAndAfterEveryCrack) {
  // A bar of 16 x 6 x 6 cells (3456 tets, 7 chunks of the parallel rebuild) bent and cracked in
  // steps: a crack grows from one face through the section and splits the bar, a step changes
  // nothing, random edges break, one edge breaks, then the cut heals. After each step the
  // surfaces kept and rebuilt on 1 and 2 threads (which list again only the chunks whose edges
  // changed) equal a surface made fresh for that step, bit for bit, in both crack modes.
  for (const bool partial : {true, false}) {
    Body b(gen::box(2, 0.75, 0.75, 16, 6, 6));
    ThreadPoolJobSystem two(2);
    const CrackSurfaceOptions options{partial};
    CrackSurface kept1, kept2;
    kept1.init(b.mesh, b.graph, options);
    kept2.init(b.mesh, b.graph, options);
    std::mt19937 rng(7);
    std::vector<double> x(b.mesh.positions);
    int steps = 0, maxFragments = 0;
    for (int step = 0; step < 10; ++step) {
      if (step < 5) {
        // The crack front at z < depth on the plane x = 1.03 (a slit until step 4 splits it).
        const double depth = 0.2 * (step + 1);
        for (int32_t e = 0; e < b.graph.edgeCount; ++e) {
          const double* p = &b.mesh.positions[3 * size_t(b.graph.edgeNodes[2 * size_t(e)])];
          const double* q = &b.mesh.positions[3 * size_t(b.graph.edgeNodes[2 * size_t(e) + 1])];
          if ((p[0] < 1.03) != (q[0] < 1.03) && p[2] < depth && q[2] < depth)
            b.broken[size_t(e)] = 1;
        }
      } else if (step == 5) {
        // Nothing breaks.
      } else if (step < 8) {
        for (int k = 0; k < 150; ++k) b.broken[rng() % b.broken.size()] = 1;
      } else if (step == 8) {
        size_t e = rng() % b.broken.size();
        while (b.broken[e]) e = (e + 1) % b.broken.size();
        b.broken[e] = 1;
      } else {
        std::fill(b.broken.begin(), b.broken.end(), 0);  // healed
        for (int k = 0; k < 40; ++k) b.broken[rng() % b.broken.size()] = 1;
      }
      // Bent about y, so vertices of partial groups turn through their local maps.
      for (size_t i = 0; i < b.mesh.nodeCount(); ++i) {
        const double* X = &b.mesh.positions[3 * i];
        const double a = 0.1 * step * (X[0] - 1), c = std::cos(a), sn = std::sin(a);
        x[3 * i] = 1 + c * (X[0] - 1) + sn * X[2];
        x[3 * i + 1] = X[1];
        x[3 * i + 2] = -sn * (X[0] - 1) + c * X[2];
      }
      Fragments fr;
      fr.build(b.graph, b.broken.data());
      maxFragments = std::max(maxFragments, fr.count());
      kept1.rebuild(b.broken.data(), fr.nodeFragment().data(), x.data(), &serialJobs());
      kept2.rebuild(b.broken.data(), fr.nodeFragment().data(), x.data(), &two);
      CrackSurface fresh;
      fresh.init(b.mesh, b.graph, options);
      fresh.rebuild(b.broken.data(), fr.nodeFragment().data(), x.data(), &two);
      const SurfaceCopy a(kept1), c(kept2), f(fresh);
      EXPECT_TRUE(a == c) << "1 and 2 threads differ at step " << step << ", partial " << partial;
      EXPECT_TRUE(a == f) << "kept and fresh surfaces differ at step " << step << ", partial "
                          << partial;
      if (partial) {
        EXPECT_GT(a.frames.size(), step == 0 ? 0u : 9u);
      }
      expectSerialOrder(kept1);
      expectSerialOrder(kept2);
      for (const auto& g : inspect(kept2, fr.count())) EXPECT_EQ(g.badEdges, 0);
      // Placed again on the other thread count than the rebuild's: still the same bits.
      kept1.updatePositions(x.data(), &two);
      kept2.updatePositions(x.data(), &serialJobs());
      EXPECT_TRUE(SurfaceCopy(kept1) == f) << "update on 2 threads differs at step " << step;
      EXPECT_TRUE(SurfaceCopy(kept2) == f) << "update on 1 thread differs at step " << step;
      ++steps;
    }
    EXPECT_EQ(steps, 10);
    EXPECT_GE(maxFragments, 2);
  }
}

TEST(CrackSurface, DrawnFragmentsAreTheSameBitsAsTheWholeSurface) {
  // A sphere broken at random into many fragments, deformed: a surface that places only the
  // vertices of some fragments (the ones an embedded render mesh borrows) gives them the same
  // positions and normals, bit for bit, as the surface that places every vertex, with the same
  // topology and local maps, through rebuilds and position updates, on 1 and 2 threads. With
  // no fragment drawn (steps 2 and 4) it has no vertex, and the extra nodes' local maps are
  // still the same bits; a full rebuild after such a step (step 3) is the same again.
  Body b(gen::sphere(1, 5));
  std::mt19937 rng(3);
  ThreadPoolJobSystem two(2);
  for (int k = 0; k < int(b.broken.size()) / 3; ++k) b.broken[rng() % b.broken.size()] = 1;
  std::vector<int32_t> extra;
  for (int32_t n = 0; n < int32_t(b.mesh.nodeCount()); n += 7) extra.push_back(n);
  std::vector<double> x(b.mesh.positions);
  int checked = 0, skipped = 0, maps = 0;
  for (JobSystem* jobs : {&serialJobs(), static_cast<JobSystem*>(&two)}) {
    CrackSurface whole, drawn;
    whole.init(b.mesh, b.graph);
    drawn.init(b.mesh, b.graph);
    whole.setExtraFrameNodes(extra);
    drawn.setExtraFrameNodes(extra);
    for (int step = 0; step < 5; ++step) {
      // Step 3 breaks nothing: its rebuild lists again what step 2 left stale.
      for (int k = 0; k < 200 && step != 3; ++k) b.broken[rng() % b.broken.size()] = 1;
      Fragments fr;
      fr.build(b.graph, b.broken.data());
      // Every third fragment drawn but the first (the body's bulk), or none.
      const bool none = step == 2 || step == 4;
      std::vector<uint8_t> chosen(size_t(fr.count()), 0);
      for (size_t f = 1; f < chosen.size() && !none; f += 3) chosen[f] = 1;
      drawn.setDrawnFragments(chosen);
      for (size_t i = 0; i < b.mesh.nodeCount(); ++i) {
        const double* X = &b.mesh.positions[3 * i];
        const double a = 0.2 * step * X[2], c = std::cos(a), sn = std::sin(a);
        x[3 * i] = c * X[0] - sn * X[1] + 0.01 * fr.nodeFragment()[i];
        x[3 * i + 1] = sn * X[0] + c * X[1];
        x[3 * i + 2] = 1.1 * X[2];
      }
      for (int pass = 0; pass < 2; ++pass) {
        if (pass == 0) {
          whole.rebuild(b.broken.data(), fr.nodeFragment().data(), x.data(), jobs);
          drawn.rebuild(b.broken.data(), fr.nodeFragment().data(), x.data(), jobs);
        } else {
          for (double& c : x) c *= 1.01;
          whole.updatePositions(x.data(), jobs);
          drawn.updatePositions(x.data(), jobs);
        }
        for (int32_t n : extra) {
          const auto w = whole.frameMaps().subspan(9 * size_t(whole.nodeFrame()[size_t(n)]), 9);
          const auto d = drawn.frameMaps().subspan(9 * size_t(drawn.nodeFrame()[size_t(n)]), 9);
          EXPECT_TRUE(std::ranges::equal(w, d)) << "node " << n << " at step " << step;
          ++maps;
        }
        if (none) {
          EXPECT_EQ(drawn.vertexCount(), 0u);
          EXPECT_EQ(drawn.triangleCount(), 0u);
          continue;
        }
        ASSERT_EQ(whole.vertexCount(), drawn.vertexCount());
        EXPECT_TRUE(std::ranges::equal(whole.indices(), drawn.indices()));
        EXPECT_TRUE(std::ranges::equal(whole.frameMaps(), drawn.frameMaps()));
        EXPECT_TRUE(std::ranges::equal(whole.nodeFrame(), drawn.nodeFrame()));
        for (uint32_t v = 0; v < whole.vertexCount(); ++v) {
          if (!chosen[size_t(whole.vertexFragment()[v])]) {
            ++skipped;
            continue;
          }
          for (size_t k = 3 * size_t(v); k < 3 * size_t(v) + 3; ++k) {
            EXPECT_EQ(whole.positionsDouble()[k], drawn.positionsDouble()[k]) << "vertex " << v;
            EXPECT_EQ(whole.normalsDouble()[k], drawn.normalsDouble()[k]) << "vertex " << v;
          }
          ++checked;
        }
      }
    }
  }
  EXPECT_GT(checked, 100);
  EXPECT_GT(skipped, 10 * checked);
  std::printf(
      "[ figures  ] drawn fragments: %d vertex placements compared, %d skipped, %d local maps\n",
      checked, skipped, maps);
}

TEST(CrackSurface, CostOfRebuildAndUpdate) {
  // About 30k tets: a 17^3 box (29,478 tets), a plane cut plus 2,000 random broken edges.
  Body b(gen::box(1, 1, 1, 17, 17, 17));
  b.breakPlane(1, 0.3, 0.1, 0.61);
  std::mt19937 rng(1);
  for (int k = 0; k < 2000; ++k) b.broken[rng() % b.broken.size()] = 1;
  using Clock = std::chrono::steady_clock;
  auto ms = [](Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); };

  Fragments fr;
  auto t0 = Clock::now();
  fr.build(b.graph, b.broken.data());
  const double buildMs = ms(Clock::now() - t0);
  CrackSurface s;
  s.init(b.mesh, b.graph);
  s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr);  // warm-up (capacity)
  const int reps = 5;
  t0 = Clock::now();
  for (int r = 0; r < reps; ++r) s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr);
  const double rebuildMs = ms(Clock::now() - t0) / reps;
  ThreadPoolJobSystem two(2);
  s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr, &two);
  t0 = Clock::now();
  for (int r = 0; r < reps; ++r)
    s.rebuild(b.broken.data(), fr.nodeFragment().data(), nullptr, &two);
  const double rebuild2Ms = ms(Clock::now() - t0) / reps;
  std::vector<double> x(b.mesh.positions);
  for (double& c : x) c *= 1.01;
  t0 = Clock::now();
  for (int r = 0; r < reps; ++r) s.updatePositions(x.data());
  const double updateMs = ms(Clock::now() - t0) / reps;
  // Incremental fragments: one more break that splits nothing.
  int32_t e = 0;
  while (b.broken[size_t(e)]) ++e;
  b.broken[size_t(e)] = 1;
  t0 = Clock::now();
  fr.update(b.graph, b.broken.data(), std::span<const int32_t>(&e, 1));
  const double updateFragMs = ms(Clock::now() - t0);
  const auto got = inspect(s, fr.count());
  int bad = 0;
  for (const auto& g : got) bad += g.badEdges;
  EXPECT_EQ(bad, 0);
  std::printf(
      "[ figures  ] %zu tets, %d fragments, %u vertices, %u triangles: fragments build "
      "%.2f ms, update %.3f ms; surface rebuild %.2f ms (2 threads %.2f ms), updatePositions "
      "%.2f ms\n",
      b.mesh.tetCount(), fr.count(), s.vertexCount(), s.triangleCount(), buildMs, updateFragMs,
      rebuildMs, rebuild2Ms, updateMs);
}

}  // namespace
}  // namespace gf::detail
