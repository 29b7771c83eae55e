// Cutting: a planar blade through a cylinder breaks exactly the edges whose
// endpoints lie on opposite sides (checked against the plane equation) and leaves two
// components, one per side; a swept blade breaks exactly the edges crossing the swept strip;
// a blade that misses breaks nothing; a node on the blade is kept on one side; 1 and 4 threads
// agree; the time of a 100k-edge cut is printed.
#include <graphfrac/jobs.h>
#include <graphfrac/mesh.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

#include "common/mesh_checks.h"
#include "fracture/cutting.h"
#include "mesh/edge_graph.h"

namespace gf::detail {
namespace {

using gf::test::components;

struct Body {
  TetMesh mesh;
  EdgeGraph graph;
};

Body makeBody(TetMesh mesh) {
  Body b;
  b.mesh = std::move(mesh);
  b.graph = EdgeGraph::build(b.mesh.tets.data(), b.mesh.tetCount(), b.mesh.nodeCount());
  return b;
}

// A square blade of half-size h centred at c spanned by orthonormal u, v (normal u x v),
// as two triangles, in blade-local = world coordinates.
Blade squareBlade(Vec3 c, Vec3 u, Vec3 v, double hu, double hv) {
  Blade b;
  const Vec3 p[4] = {c - hu * u - hv * v, c + hu * u - hv * v, c + hu * u + hv * v,
                     c - hu * u + hv * v};
  for (const Vec3& q : p) b.vertices.insert(b.vertices.end(), {q.x, q.y, q.z});
  b.triangles = {0, 1, 2, 0, 2, 3};
  return b;
}

Vec3 node(const Body& b, int32_t v) {
  return {b.mesh.positions[3 * v], b.mesh.positions[3 * v + 1], b.mesh.positions[3 * v + 2]};
}

Vec3 unit(Vec3 a) { return (1.0 / norm(a)) * a; }

TEST(Cutting, PlanarBladeSplitsACylinderIntoItsTwoSides) {
  Body b = makeBody(gen::cylinder(0.5, 2, 24, 12, 4));
  const Vec3 c{0.03, 0.87, -0.02};
  const Vec3 n = unit({0.3, 1, 0.2});
  const Vec3 u = unit(cross(n, {1, 0, 0}));
  const Vec3 v = cross(n, u);  // u x v = n
  const Blade blade = squareBlade(c, u, v, 3, 3);
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  CutWorkspace ws;
  CutStats stats;
  auto r = cutEdges(b.graph, b.mesh.positions.data(), blade, {}, {}, broken, events, ws,
                    serialJobs(), &stats);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(stats.triangles, 2);  // a static cut adds no swept quads

  const auto side = [&](int32_t i) { return dot(n, node(b, i) - c) >= 0; };
  double nearest = 1e9;
  for (int32_t i = 0; i < b.graph.nodeCount; ++i)
    nearest = std::min(nearest, std::fabs(dot(n, node(b, i) - c)));
  ASSERT_GT(nearest, 1e-6) << "set-up: a node lies on the plane";
  int expected = 0;
  for (int32_t e = 0; e < b.graph.edgeCount; ++e) {
    const bool crosses = side(b.graph.edgeNodes[2 * e]) != side(b.graph.edgeNodes[2 * e + 1]);
    EXPECT_EQ(broken[e] != 0, crosses) << "edge " << e;
    expected += crosses;
  }
  EXPECT_EQ(r.value(), expected);
  EXPECT_GT(expected, 100);
  ASSERT_EQ(events.size(), size_t(expected));
  for (size_t i = 0; i < events.size(); ++i) {
    if (i > 0) {
      EXPECT_LT(events[i - 1].edge, events[i].edge);
    }
    EXPECT_NEAR(dot(n, events[i].position - c), 0, 1e-12);
    const Vec3 a = node(b, b.graph.edgeNodes[2 * events[i].edge]);
    const Vec3 bb = node(b, b.graph.edgeNodes[2 * events[i].edge + 1]);
    EXPECT_NEAR(norm(a + events[i].split * (bb - a) - events[i].position), 0, 1e-12);
    EXPECT_EQ(events[i].tet, -1);
  }
  std::vector<int> label;
  ASSERT_EQ(components(b.graph, broken, label), 2);
  for (int32_t i = 0; i < b.graph.nodeCount; ++i)
    EXPECT_EQ(label[i] == label[0], side(i) == side(0)) << "node " << i;

  // Cutting again breaks nothing more.
  events.clear();
  auto again =
      cutEdges(b.graph, b.mesh.positions.data(), blade, {}, {}, broken, events, ws, serialJobs());
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again.value(), 0);
}

TEST(Cutting, SweptBladeBreaksOnlyTheSweptStrip) {
  Body b = makeBody(gen::box(1, 1, 1, 10, 10, 10));
  const double z = 0.537;
  // A strip x in [-0.3, -0.1] (outside the box) moving +0.65 in x to [0.35, 0.55].
  const Blade blade = squareBlade({-0.2, 0.5, z}, {1, 0, 0}, {0, 1, 0}, 0.1, 0.6);
  BladePose end;
  end.translation = {0.65, 0, 0};
  // Independent: where does each edge cross the plane z = 0.537?
  std::vector<double> crossX(b.graph.edgeCount, -1e9);
  for (int32_t e = 0; e < b.graph.edgeCount; ++e) {
    const Vec3 a = node(b, b.graph.edgeNodes[2 * e]), c = node(b, b.graph.edgeNodes[2 * e + 1]);
    if ((a.z >= z) == (c.z >= z)) continue;
    const double s = (z - a.z) / (c.z - a.z);
    crossX[e] = a.x + s * (c.x - a.x);
    ASSERT_GT(std::fabs(crossX[e] - 0.55), 1e-6);
    ASSERT_GT(std::fabs(crossX[e] - 0.35), 1e-6);
  }
  const auto run = [&](const BladePose& start, std::vector<uint8_t>& broken) {
    broken.assign(b.graph.edgeCount, 0);
    std::vector<EdgeBreak> events;
    CutWorkspace ws;
    auto r = cutEdges(b.graph, b.mesh.positions.data(), blade, start, end, broken, events, ws,
                      serialJobs());
    EXPECT_TRUE(r.ok());
    return r.ok() ? r.value() : -1;
  };
  std::vector<uint8_t> swept, still;
  const int32_t nSwept = run(BladePose{}, swept);
  const int32_t nStill = run(end, still);  // static blade at the end pose
  int expectSwept = 0, expectStill = 0;
  for (int32_t e = 0; e < b.graph.edgeCount; ++e) {
    const bool inSwept = crossX[e] > -1e8 && crossX[e] <= 0.55;
    const bool inStill = inSwept && crossX[e] >= 0.35;
    EXPECT_EQ(swept[e] != 0, inSwept) << "edge " << e << " crosses at x " << crossX[e];
    EXPECT_EQ(still[e] != 0, inStill) << "edge " << e << " crosses at x " << crossX[e];
    expectSwept += inSwept;
    expectStill += inStill;
  }
  EXPECT_EQ(nSwept, expectSwept);
  EXPECT_EQ(nStill, expectStill);
  EXPECT_GT(expectSwept, 2 * expectStill);
  std::vector<int> label;
  EXPECT_EQ(components(b.graph, swept, label), 1);  // half-way in: still one piece
}

TEST(Cutting, BladesThatMissBreakNothing) {
  Body b = makeBody(gen::box(1, 1, 1, 6, 6, 6));
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  CutWorkspace ws;
  // Far away, swept far away.
  const Blade far = squareBlade({5, 5, 5}, {1, 0, 0}, {0, 1, 0}, 1, 1);
  BladePose end;
  end.translation = {0, -2, 0};
  auto r =
      cutEdges(b.graph, b.mesh.positions.data(), far, {}, end, broken, events, ws, serialJobs());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.value(), 0);
  // A tiny triangle inside one tet, touching none of its edges.
  const TetMesh& m = b.mesh;
  Vec3 cen;
  for (int k = 0; k < 4; ++k) cen += 0.25 * node(b, m.tets[k]);
  const Blade tiny = squareBlade(cen, {1, 0, 0}, {0, 1, 0}, 1e-3, 1e-3);
  r = cutEdges(b.graph, m.positions.data(), tiny, {}, {}, broken, events, ws, serialJobs());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.value(), 0);
  EXPECT_TRUE(events.empty());
  // Bad input is an error, not a crash.
  Blade bad = far;
  bad.triangles.back() = 99;
  r = cutEdges(b.graph, m.positions.data(), bad, {}, {}, broken, events, ws, serialJobs());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("Blade.triangles[1]"), std::string::npos);
}

TEST(Cutting, BladeThroughANodeLayerKeepsEachNodeOnOneSide) {
  Body b = makeBody(gen::box(1, 1, 1, 6, 6, 6));
  const double z = b.mesh.positions[3 * 0 + 2];  // find the z of a mid layer from the mesh
  double layer = z;
  for (size_t i = 0; i < b.mesh.nodeCount(); ++i) {
    const double zi = b.mesh.positions[3 * i + 2];
    if (std::fabs(zi - 0.5) < 1e-9) layer = zi;
  }
  ASSERT_NEAR(layer, 0.5, 1e-9);
  const Blade blade = squareBlade({0.5, 0.5, layer}, {1, 0, 0}, {0, 1, 0}, 2, 2);  // normal +z
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  CutWorkspace ws;
  auto r =
      cutEdges(b.graph, b.mesh.positions.data(), blade, {}, {}, broken, events, ws, serialJobs());
  ASSERT_TRUE(r.ok());
  // Nodes on the blade count as its front (+z) side: only edges reaching below break.
  for (int32_t e = 0; e < b.graph.edgeCount; ++e) {
    const bool below0 = node(b, b.graph.edgeNodes[2 * e]).z < layer;
    const bool below1 = node(b, b.graph.edgeNodes[2 * e + 1]).z < layer;
    EXPECT_EQ(broken[e] != 0, below0 != below1) << "edge " << e;
  }
  std::vector<int> label;
  ASSERT_EQ(components(b.graph, broken, label), 2);
  for (int32_t i = 0; i < b.graph.nodeCount; ++i)
    EXPECT_EQ(label[i] == label[0], (node(b, i).z < layer) == (node(b, 0).z < layer));
}

// A wavy 1k-triangle blade swept diagonally through a ~100k-edge box; 1 and 4 threads agree.
TEST(Cutting, LargeSweptCutTimingAndThreadIndependence) {
  Body b = makeBody(gen::box(1, 1, 1, 24, 24, 24));
  Blade blade;
  const int n = 22;  // 22 x 22 quads = 968 triangles
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const double u = -0.2 + 1.4 * i / n, v = -0.2 + 1.4 * j / n;
      blade.vertices.insert(blade.vertices.end(),
                            {u, v, 0.05 * std::sin(6.0 * u) * std::cos(5.0 * v)});
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int32_t a = j * (n + 1) + i;
      blade.triangles.insert(blade.triangles.end(), {a, a + 1, a + n + 2, a, a + n + 2, a + n + 1});
    }
  BladePose start, end;
  start.translation = {0, 0, 0.31};
  const double ang = 0.2;
  end.rotation(0, 0) = std::cos(ang);
  end.rotation(0, 2) = std::sin(ang);
  end.rotation(2, 0) = -std::sin(ang);
  end.rotation(2, 2) = std::cos(ang);
  end.translation = {0.02, 0.01, 0.36};
  ASSERT_GT(b.graph.edgeCount, 90000);

  SerialJobSystem serial;
  ThreadPoolJobSystem pool(4);
  std::vector<uint8_t> f1(b.graph.edgeCount, 0), f4 = f1;
  std::vector<EdgeBreak> e1, e4;
  CutWorkspace w1, w4;
  CutStats stats;
  const auto t0 = std::chrono::steady_clock::now();
  auto r1 =
      cutEdges(b.graph, b.mesh.positions.data(), blade, start, end, f1, e1, w1, serial, &stats);
  const auto t1 = std::chrono::steady_clock::now();
  auto r4 = cutEdges(b.graph, b.mesh.positions.data(), blade, start, end, f4, e4, w4, pool);
  const auto t2 = std::chrono::steady_clock::now();
  ASSERT_TRUE(r1.ok());
  ASSERT_TRUE(r4.ok());
  std::printf(
      "[cut] %d edges, %zu blade triangles -> %d swept triangles, %d cells, %d edges in range, "
      "%lld tests, %d broken: %.2f ms serial, %.2f ms on 4 threads\n",
      b.graph.edgeCount, blade.triangles.size() / 3, stats.triangles, stats.cells,
      stats.edgesInRange, static_cast<long long>(stats.triangleTests), r1.value(),
      std::chrono::duration<double, std::milli>(t1 - t0).count(),
      std::chrono::duration<double, std::milli>(t2 - t1).count());
  EXPECT_GT(r1.value(), 1000);
  EXPECT_EQ(f1, f4);
  ASSERT_EQ(e1.size(), e4.size());
  for (size_t i = 0; i < e1.size(); ++i) {
    EXPECT_EQ(e1[i].edge, e4[i].edge);
    EXPECT_EQ(e1[i].split, e4[i].split);
  }
}

}  // namespace
}  // namespace gf::detail
