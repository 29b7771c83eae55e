// Brittle crack planes (sec 4.5.1.2, fig 4.19): a bar in uniaxial tension splits along one
// plane normal to the load into exactly two pieces (counted by a BFS over unbroken edges),
// every broken edge straddles that plane and every straddling edge is broken; more regions
// give more pieces.
#include <graphfrac/jobs.h>
#include <graphfrac/mesh.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "common/mesh_checks.h"
#include "fracture/brittle.h"
#include "fracture/fracture_model.h"
#include "mesh/edge_graph.h"

namespace gf::detail {
namespace {

using gf::test::components;

struct Body {
  TetMesh mesh;
  EdgeGraph graph;
  FractureModel model;
};

Body makeBody(TetMesh mesh, int regions, bool brittle = true) {
  Body b;
  b.mesh = std::move(mesh);
  b.graph = EdgeGraph::build(b.mesh.tets.data(), b.mesh.tetCount(), b.mesh.nodeCount());
  FractureSettings s;
  s.enabled = true;
  s.strength = 1e6;
  s.brittle = brittle;
  s.regions = regions;
  auto m = FractureModel::build(restView(b.mesh), b.graph, s);
  EXPECT_TRUE(m.ok());
  b.model = std::move(m).value();
  return b;
}

// Per-tet stress sigma(x_c) * n n^T at the tet's rest centroid.
template <class Profile>
std::vector<double> uniaxial(const Body& b, Vec3 n, Profile profile) {
  n = (1.0 / norm(n)) * n;
  std::vector<double> s(6 * b.mesh.tetCount());
  for (size_t t = 0; t < b.mesh.tetCount(); ++t) {
    const double sig = profile(b.model.centroids[3 * t]);
    double* v = &s[6 * t];
    v[0] = sig * n.x * n.x;
    v[1] = sig * n.y * n.y;
    v[2] = sig * n.z * n.z;
    v[3] = sig * n.x * n.y;
    v[4] = sig * n.x * n.z;
    v[5] = sig * n.y * n.z;
  }
  return s;
}

// Uniaxial x tension peaking near x = 2.1, so the seed sits mid-bar.
double peakNear21(double x) { return 1e6 * (1 + 0.2 * std::exp(-(x - 2.1) * (x - 2.1) / 0.25)); }

// The plane of `seed` splits the (convex) bar: exactly the straddling edges are broken, the
// graph has two components, and each is on one side.
void expectCleanSplit(const Body& b, const BrittleSeed& seed, const std::vector<uint8_t>& broken) {
  const auto side = [&](int32_t v) {
    const double* x = &b.mesh.positions[3 * v];
    return seed.normal.x * (x[0] - seed.point.x) + seed.normal.y * (x[1] - seed.point.y) +
               seed.normal.z * (x[2] - seed.point.z) >=
           0;
  };
  int straddling = 0;
  for (int32_t e = 0; e < b.graph.edgeCount; ++e) {
    const bool crosses = side(b.graph.edgeNodes[2 * e]) != side(b.graph.edgeNodes[2 * e + 1]);
    EXPECT_EQ(broken[e] != 0, crosses) << "edge " << e;
    straddling += crosses;
  }
  EXPECT_GT(straddling, 0);
  std::vector<int> label;
  ASSERT_EQ(components(b.graph, broken, label), 2);
  for (int32_t v = 0; v < b.graph.nodeCount; ++v) EXPECT_EQ(label[v], side(v) == side(0) ? 0 : 1);
}

TEST(Brittle, OneRegionSplitsABarInTwoNormalToTheLoad) {
  Body b = makeBody(gen::box(4, 1, 1, 16, 4, 4), 1);
  const auto stress = uniaxial(b, {1, 0, 0}, peakNear21);
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  auto r = startBrittleCracks(b.model, b.graph, restView(b.mesh), b.model.strength.data(),
                              stress.data(), broken, events, serialJobs());
  ASSERT_TRUE(r.ok()) << r.error().message;
  const std::vector<BrittleSeed>& seeds = r.value();
  ASSERT_EQ(seeds.size(), 1u);
  EXPECT_NEAR(std::fabs(seeds[0].normal.x), 1.0, 1e-12);
  EXPECT_NEAR(seeds[0].point.x, 2.1, 0.25);
  expectCleanSplit(b, seeds[0], broken);
  EXPECT_EQ(seeds[0].edgesBroken, int32_t(events.size()));
  for (size_t i = 0; i < events.size(); ++i) {
    if (i > 0) {
      EXPECT_LT(events[i - 1].edge, events[i].edge);
    }
    EXPECT_NEAR(events[i].position.x, seeds[0].point.x, 1e-12);  // on the plane
    EXPECT_GE(events[i].split, 0.0);
    EXPECT_LE(events[i].split, 1.0);
    EXPECT_EQ(events[i].tet, seeds[0].tet);
  }
}

TEST(Brittle, TiltedPrincipalDirectionGivesATiltedPlane) {
  Body b = makeBody(gen::box(4, 1, 1, 16, 4, 4), 1);
  const Vec3 n{1, 0.5, 0.2};
  const auto stress = uniaxial(
      b, n, [](double x) { return 1e6 * (1 + 0.2 * std::exp(-(x - 1.9) * (x - 1.9) / 0.25)); });
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  auto r = startBrittleCracks(b.model, b.graph, restView(b.mesh), b.model.strength.data(),
                              stress.data(), broken, events, serialJobs());
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r.value().size(), 1u);
  const BrittleSeed& seed = r.value()[0];
  EXPECT_NEAR(std::fabs(dot(seed.normal, (1.0 / norm(n)) * n)), 1.0, 1e-10);
  expectCleanSplit(b, seed, broken);
}

TEST(Brittle, MoreRegionsGiveMorePieces) {
  // Three equal stress peaks along a long bar (x = 4/3, 4, 20/3).
  const auto profile = [](double x) {
    return 1e6 * (2 + std::cos(2 * M_PI * (x - 4.0 / 3.0) / (8.0 / 3.0)));
  };
  int pieces[2];
  for (int i = 0; i < 2; ++i) {
    const int regions = i == 0 ? 1 : 3;
    Body b = makeBody(gen::box(8, 1, 1, 32, 4, 4), regions);
    const auto stress = uniaxial(b, {1, 0, 0}, profile);
    std::vector<uint8_t> broken(b.graph.edgeCount, 0);
    std::vector<EdgeBreak> events;
    auto r = startBrittleCracks(b.model, b.graph, restView(b.mesh), b.model.strength.data(),
                                stress.data(), broken, events, serialJobs());
    ASSERT_TRUE(r.ok());
    ASSERT_EQ(r.value().size(), size_t(regions));
    std::vector<int> label;
    pieces[i] = components(b.graph, broken, label);
    int32_t total = 0;
    for (const BrittleSeed& s : r.value()) total += s.edgesBroken;
    EXPECT_EQ(total, int32_t(events.size()));
  }
  EXPECT_EQ(pieces[0], 2);
  EXPECT_EQ(pieces[1], 4);
}

TEST(Brittle, FailsWithoutFaceAdjacencyAndIgnoresCompression) {
  Body b = makeBody(gen::box(2, 1, 1, 4, 2, 2), 1, /*brittle=*/false);
  std::vector<double> stress(6 * b.mesh.tetCount(), 0.0);
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  auto r = startBrittleCracks(b.model, b.graph, restView(b.mesh), b.model.strength.data(),
                              stress.data(), broken, events, serialJobs());
  EXPECT_FALSE(r.ok());
  b.model.buildFaceAdjacency(restView(b.mesh));
  // Pure compression: no tensile principal stress, no seed, nothing breaks.
  for (size_t t = 0; t < b.mesh.tetCount(); ++t) stress[6 * t] = -1e7;
  r = startBrittleCracks(b.model, b.graph, restView(b.mesh), b.model.strength.data(), stress.data(),
                         broken, events, serialJobs());
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r.value().empty());
  EXPECT_TRUE(events.empty());
  // Face adjacency: each interior face pairs two tets, each boundary face is -1.
  int boundary = 0;
  for (size_t i = 0; i < b.model.faceNeighbours.size(); ++i) {
    const int32_t nb = b.model.faceNeighbours[i];
    if (nb < 0) {
      ++boundary;
      continue;
    }
    bool back = false;
    for (int f = 0; f < 4; ++f)
      back |= b.model.faceNeighbours[4 * size_t(nb) + f] == int32_t(i / 4);
    EXPECT_TRUE(back);
  }
  EXPECT_EQ(size_t(boundary), b.mesh.boundaryFaces().size() / 3);
}

// A crack plane carries its seed's principal stress: an edge stronger than that (a steel pin
// through glass, a seam an artist reinforced with World::setEdgeStrengths) survives the plane
// through it, and the crack stops in the tets around it; weaker edges elsewhere still break.
TEST(Brittle, EdgesStrongerThanThePlaneStressHold) {
  Body b = makeBody(gen::box(4, 1, 1, 16, 4, 4), 1);
  const auto stress = uniaxial(b, {1, 0, 0}, peakNear21);
  // Without strong edges: which edges the plane crosses.
  std::vector<uint8_t> reference(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> referenceEvents;
  auto ref = startBrittleCracks(b.model, b.graph, restView(b.mesh), b.model.strength.data(),
                                stress.data(), reference, referenceEvents, serialJobs());
  ASSERT_TRUE(ref.ok());
  // Reinforce every crossed edge in the half of the bar (y above or below 0.5) away from the
  // seed: a band the crack cannot pass.
  const double away = ref.value()[0].point.y < 0.5 ? 1 : -1;
  int reinforced = 0;
  for (const EdgeBreak& e : referenceEvents) {
    const double ya = b.mesh.positions[3 * size_t(b.graph.edgeNodes[2 * size_t(e.edge)]) + 1];
    const double yb = b.mesh.positions[3 * size_t(b.graph.edgeNodes[2 * size_t(e.edge) + 1]) + 1];
    if (away * (ya - 0.5) > 1e-9 && away * (yb - 0.5) > 1e-9) {
      b.model.strength[size_t(e.edge)] = 1e12;
      ++reinforced;
    }
  }
  ASSERT_GT(reinforced, 0);
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  auto r = startBrittleCracks(b.model, b.graph, restView(b.mesh), b.model.strength.data(),
                              stress.data(), broken, events, serialJobs());
  ASSERT_TRUE(r.ok());
  int held = 0;
  for (int32_t e = 0; e < b.graph.edgeCount; ++e) {
    if (b.model.strength[size_t(e)] > 1e11) {
      EXPECT_EQ(broken[size_t(e)], 0) << "edge " << e << " of strength 1e12 broke";
      ++held;
    }
    if (broken[size_t(e)]) {
      EXPECT_TRUE(reference[size_t(e)]);  // no edge off the plane
    }
  }
  EXPECT_EQ(held, reinforced);
  EXPECT_GT(events.size(), 0u);                      // the weak half still cracks
  EXPECT_LT(events.size(), referenceEvents.size());  // but not through the band
  EXPECT_GT(r.value()[0].tetsArrested, 0);
  std::vector<int> label;
  EXPECT_EQ(components(b.graph, broken, label), 1);  // the reinforced band holds the bar together
  std::printf(
      "  brittle plane: %zu edges broken without strong edges, %zu with %d of them at "
      "1e12 Pa (%d tets arrested)\n",
      referenceEvents.size(), events.size(), reinforced, r.value()[0].tetsArrested);
}

// Sec 4.5.1.2: every plane runs to the boundary through the body's own material. The second
// region is stressed to only 0.6 of the strength (it seeds because the criterion fired at the
// first): it must still split the bar, not stop in its seed tet because it carried only its
// own stress (the old rule, under which the demo's glass bunny only chipped).
TEST(Brittle, APlaneSeededBelowTheStrengthStillRunsToTheBoundary) {
  Body b = makeBody(gen::box(4, 1, 1, 16, 4, 4), 2);
  const auto stress = uniaxial(b, {1, 0, 0}, [](double x) {
    return 1.2e6 * std::exp(-(x - 1) * (x - 1) / 0.25) +
           0.6e6 * std::exp(-(x - 3) * (x - 3) / 0.25);
  });
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  auto r = startBrittleCracks(b.model, b.graph, restView(b.mesh), b.model.strength.data(),
                              stress.data(), broken, events, serialJobs());
  ASSERT_TRUE(r.ok()) << r.error().message;
  const std::vector<BrittleSeed>& seeds = r.value();
  ASSERT_EQ(seeds.size(), 2u);
  EXPECT_LT(seeds[1].principal, 0.7 * b.model.settings.strength);  // the weak region
  EXPECT_NEAR(seeds[1].point.x, 3, 0.25);
  EXPECT_EQ(seeds[1].carried, b.model.settings.strength);
  std::printf(
      "  weak plane: principal %.3g Pa (strength %.3g), %d tets cut, %d edges broken, "
      "%d tets arrested\n",
      seeds[1].principal, b.model.settings.strength, seeds[1].tetsCut, seeds[1].edgesBroken,
      seeds[1].tetsArrested);
  EXPECT_EQ(seeds[1].tetsArrested, 0);
  EXPECT_EQ(seeds[0].tetsArrested, 0);
  std::vector<int> label;
  EXPECT_EQ(components(b.graph, broken, label), 3);  // two planes across the bar: three pieces
}

}  // namespace
}  // namespace gf::detail
