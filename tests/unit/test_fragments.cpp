// Fragments: partitions against an independent union-find, incremental update against a full
// build, the stable-id rule, and volume/mass/centre/velocity against hand values.
#include <graphfrac/mesh.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <vector>

#include "common/union_find_labels.h"
#include "mesh/edge_graph.h"
#include "surface/fragments.h"

namespace gf::detail {
namespace {

// Same partition (labels equal up to a bijection) and the fragment count equals the number of
// distinct truth labels.
void expectSamePartition(std::span<const int32_t> ids, const std::vector<int32_t>& truth,
                         int32_t count) {
  ASSERT_EQ(ids.size(), truth.size());
  std::vector<int32_t> idToTruth(size_t(count), -1), truthToId(truth.size(), -1);
  for (size_t v = 0; v < truth.size(); ++v) {
    ASSERT_GE(ids[v], 0);
    ASSERT_LT(ids[v], count);
    int32_t& a = idToTruth[size_t(ids[v])];
    int32_t& b = truthToId[size_t(truth[v])];
    if (a < 0) a = truth[v];
    if (b < 0) b = ids[v];
    ASSERT_EQ(a, truth[v]) << "node " << v;
    ASSERT_EQ(b, ids[v]) << "node " << v;
  }
  for (int32_t f = 0; f < count; ++f) EXPECT_GE(idToTruth[size_t(f)], 0) << "empty id " << f;
}

// Node lists are a partition consistent with nodeFragment and lowestNode.
void expectConsistentLists(const Fragments& fr, size_t nodeCount) {
  std::vector<int> seen(nodeCount, 0);
  for (int32_t f = 0; f < fr.count(); ++f) {
    int32_t lowest = INT32_MAX;
    ASSERT_FALSE(fr.nodes(f).empty());
    for (int32_t v : fr.nodes(f)) {
      ++seen[size_t(v)];
      EXPECT_EQ(fr.nodeFragment()[size_t(v)], f);
      lowest = std::min(lowest, v);
    }
    EXPECT_EQ(fr.lowestNode(f), lowest);
  }
  for (size_t v = 0; v < nodeCount; ++v) ASSERT_EQ(seen[v], 1) << "node " << v;
}

std::vector<int32_t> straddling(const TetMesh& m, const EdgeGraph& g, double nx, double ny,
                                double nz, double d) {
  std::vector<int32_t> out;
  for (int32_t e = 0; e < g.edgeCount; ++e) {
    double s[2];
    for (int k = 0; k < 2; ++k) {
      const double* p = &m.positions[3 * size_t(g.edgeNodes[2 * size_t(e) + size_t(k)])];
      s[k] = nx * p[0] + ny * p[1] + nz * p[2] - d;
    }
    if ((s[0] < 0) != (s[1] < 0)) out.push_back(e);
  }
  return out;
}

TEST(Fragments, PlanarLayerSplitsBoxInTwo) {
  const TetMesh m = gen::box(2, 1, 1, 8, 4, 4);
  const EdgeGraph g = EdgeGraph::build(m.tets.data(), m.tetCount(), m.nodeCount());
  std::vector<uint8_t> broken(size_t(g.edgeCount), 0);
  Fragments inc;
  inc.build(g, broken.data());
  EXPECT_EQ(inc.count(), 1);

  const std::vector<int32_t> cut = straddling(m, g, 1, 0, 0, 1.1);
  ASSERT_GT(cut.size(), 16u);
  for (int32_t e : cut) broken[size_t(e)] = 1;
  EXPECT_TRUE(inc.update(g, broken.data(), cut));
  Fragments full;
  full.build(g, broken.data());
  for (const Fragments* fr : {&inc, &full}) {
    EXPECT_EQ(fr->count(), 2);
    expectSamePartition(fr->nodeFragment(), test::unionFindLabels(g, broken), fr->count());
    expectConsistentLists(*fr, m.nodeCount());
    // Geometry: the piece of node 0 (x = 0) is exactly the nodes left of the plane.
    for (size_t v = 0; v < m.nodeCount(); ++v)
      EXPECT_EQ(fr->nodeFragment()[v], m.positions[3 * v] < 1.1 ? 0 : 1);
  }
  ASSERT_EQ(inc.splits().size(), 1u);
  EXPECT_EQ(inc.splits()[0].created, 1);
  EXPECT_EQ(inc.splits()[0].parent, 0);
  // Breaking them again changes nothing.
  const uint64_t version = inc.version();
  EXPECT_FALSE(inc.update(g, broken.data(), cut));
  EXPECT_EQ(inc.version(), version);
}

TEST(Fragments, LowestNodeKeepsIdWhenItsPieceIsSmall) {
  const TetMesh m = gen::box(1, 1, 1, 3, 3, 3);
  const EdgeGraph g = EdgeGraph::build(m.tets.data(), m.tetCount(), m.nodeCount());
  std::vector<uint8_t> broken(size_t(g.edgeCount), 0);
  Fragments fr;
  fr.build(g, broken.data());
  // Isolate node 0: its piece is the small one but holds the lowest node, so it keeps id 0 and
  // the large rest is the new fragment 1.
  std::vector<int32_t> ring;
  for (int32_t s = g.nodeEdgeStart[0]; s < g.nodeEdgeStart[1]; ++s)
    ring.push_back(g.nodeEdges[size_t(s)]);
  for (int32_t e : ring) broken[size_t(e)] = 1;
  EXPECT_TRUE(fr.update(g, broken.data(), ring));
  ASSERT_EQ(fr.count(), 2);
  EXPECT_EQ(fr.nodeFragment()[0], 0);
  EXPECT_EQ(fr.nodes(0).size(), 1u);
  EXPECT_EQ(fr.nodes(1).size(), m.nodeCount() - 1);
  EXPECT_EQ(fr.lowestNode(1), 1);
  expectConsistentLists(fr, m.nodeCount());
}

TEST(Fragments, IncrementalMatchesFullBuildUnderRandomBreaks) {
  const TetMesh meshes[] = {gen::box(1, 1, 1, 4, 3, 3), gen::sphere(1, 4)};
  int splitsSeen = 0;
  for (const TetMesh& m : meshes) {
    const EdgeGraph g = EdgeGraph::build(m.tets.data(), m.tetCount(), m.nodeCount());
    for (uint32_t seed = 0; seed < 40; ++seed) {
      std::mt19937 rng(seed);
      std::vector<uint8_t> broken(size_t(g.edgeCount), 0);
      std::vector<int32_t> order(size_t(g.edgeCount));
      std::iota(order.begin(), order.end(), 0);
      std::shuffle(order.begin(), order.end(), rng);
      Fragments inc;
      inc.build(g, broken.data());
      size_t next = 0;
      while (next < order.size() * 3 / 4) {
        // A batch of breaks (sometimes with a repeated or stale entry), then one update.
        const size_t batch = 1 + rng() % 24;
        std::vector<int32_t> newly;
        for (size_t k = 0; k < batch && next < order.size(); ++k) newly.push_back(order[next++]);
        for (int32_t e : newly) broken[size_t(e)] = 1;
        if (rng() % 4 == 0) newly.push_back(newly.front());
        // Remember which fragment every old id's lowest node was in.
        std::vector<int32_t> oldLowest(size_t(inc.count()));
        for (int32_t f = 0; f < inc.count(); ++f) oldLowest[size_t(f)] = inc.lowestNode(f);
        const std::vector<int32_t> oldIds(inc.nodeFragment().begin(), inc.nodeFragment().end());
        const int32_t oldCount = inc.count();

        const bool split = inc.update(g, broken.data(), newly);
        const std::vector<int32_t> truth = test::unionFindLabels(g, broken);
        expectSamePartition(inc.nodeFragment(), truth, inc.count());
        expectConsistentLists(inc, m.nodeCount());
        Fragments full;
        full.build(g, broken.data());
        ASSERT_EQ(full.count(), inc.count());
        expectSamePartition(full.nodeFragment(), truth, full.count());

        // Stable ids: an old id stays with its lowest node; new ids are appended, each the
        // child of the fragment its nodes were in.
        for (int32_t f = 0; f < oldCount; ++f)
          ASSERT_EQ(inc.nodeFragment()[size_t(oldLowest[size_t(f)])], f);
        EXPECT_EQ(split, inc.count() > oldCount);
        ASSERT_EQ(inc.splits().size(), size_t(inc.count() - oldCount));
        // A parent is an old id or one created earlier in the same update; following the
        // chain back to an old id gives the fragment every node of the new one was in.
        std::vector<int32_t> root(size_t(inc.count()), -1);
        for (int32_t f = 0; f < oldCount; ++f) root[size_t(f)] = f;
        for (size_t k = 0; k < inc.splits().size(); ++k) {
          const FragmentSplit s = inc.splits()[k];
          ASSERT_EQ(s.created, oldCount + int32_t(k));
          ASSERT_GE(s.parent, 0);
          ASSERT_LT(s.parent, s.created);
          root[size_t(s.created)] = root[size_t(s.parent)];
          for (int32_t v : inc.nodes(s.created))
            EXPECT_EQ(oldIds[size_t(v)], root[size_t(s.created)]);
        }
        splitsSeen += int(inc.splits().size());
      }
    }
  }
  EXPECT_GT(splitsSeen, 200);  // the sequences really did split things
}

TEST(Fragments, VolumesAddUpToTheMesh) {
  for (const TetMesh& m :
       {gen::box(2, 1, 1, 8, 4, 4), gen::sphere(1, 6), gen::cylinder(1, 2, 16, 4, 3)}) {
    const EdgeGraph g = EdgeGraph::build(m.tets.data(), m.tetCount(), m.nodeCount());
    const std::vector<double> nodeVol =
        Fragments::nodeVolumes(m.tets.data(), m.tetCount(), m.positions.data(), m.nodeCount());
    const double total = m.volume();
    EXPECT_NEAR(std::accumulate(nodeVol.begin(), nodeVol.end(), 0.0), total, 1e-12 * total);

    std::vector<uint8_t> broken(size_t(g.edgeCount), 0);
    std::mt19937 rng(7);
    for (auto& b : broken) b = rng() % 5 != 0;  // four fifths broken: many pieces
    Fragments fr;
    fr.build(g, broken.data());
    FragmentProperties props;
    const std::vector<double> mass(m.nodeCount(), 1.0), vel(3 * m.nodeCount(), 0.0);
    fr.compute(nodeVol, mass, m.positions.data(), vel.data(), props);
    EXPECT_GT(fr.count(), 10);
    EXPECT_NEAR(std::accumulate(props.volume.begin(), props.volume.end(), 0.0), total,
                1e-12 * total);
    EXPECT_NEAR(std::accumulate(props.mass.begin(), props.mass.end(), 0.0), double(m.nodeCount()),
                1e-9);
  }
}

TEST(Fragments, MassCentreAndVelocityOfMovingBody) {
  const TetMesh m = gen::box(2, 1, 1, 8, 4, 4);
  const EdgeGraph g = EdgeGraph::build(m.tets.data(), m.tetCount(), m.nodeCount());
  const size_t n = m.nodeCount();
  const std::vector<double> vol =
      Fragments::nodeVolumes(m.tets.data(), m.tetCount(), m.positions.data(), n);
  const double rho = 1000;
  std::vector<double> mass(n);
  for (size_t v = 0; v < n; ++v) mass[v] = rho * vol[v];  // lumped masses rho V / 4 per tet

  // Rigid translation by d with velocity u.
  const double d[3] = {0.3, -2, 5}, u[3] = {1.5, -0.25, 4};
  std::vector<double> x(3 * n), v(3 * n);
  for (size_t i = 0; i < n; ++i)
    for (size_t c = 0; c < 3; ++c) {
      x[3 * i + c] = m.positions[3 * i + c] + d[c];
      v[3 * i + c] = u[c];
    }
  std::vector<uint8_t> broken(size_t(g.edgeCount), 0);
  Fragments fr;
  fr.build(g, broken.data());
  FragmentProperties p;
  fr.compute(vol, mass, x.data(), v.data(), p);
  // Lumped masses put a quarter of each tet at its nodes, whose mean is the tet centroid: the
  // centre is the box's centre (1, 0.5, 0.5), moved by d.
  const double centre[3] = {1.0, 0.5, 0.5};
  ASSERT_EQ(fr.count(), 1);
  EXPECT_NEAR(p.mass[0], rho * 2.0, 1e-9);
  EXPECT_NEAR(p.volume[0], 2.0, 1e-12);
  for (size_t c = 0; c < 3; ++c) {
    EXPECT_NEAR(p.centre[c], centre[c] + d[c], 1e-12);
    EXPECT_NEAR(p.velocity[c], u[c], 1e-12);
  }

  // Cut in two: both pieces keep the body's velocity, masses and moments add up.
  const std::vector<int32_t> cut = straddling(m, g, 1, 0, 0, 1.1);
  for (int32_t e : cut) broken[size_t(e)] = 1;
  fr.update(g, broken.data(), cut);
  ASSERT_EQ(fr.count(), 2);
  fr.compute(vol, mass, x.data(), v.data(), p);
  EXPECT_NEAR(p.mass[0] + p.mass[1], rho * 2.0, 1e-9);
  for (size_t c = 0; c < 3; ++c) {
    EXPECT_NEAR((p.mass[0] * p.centre[c] + p.mass[1] * p.centre[3 + c]) / (rho * 2.0),
                centre[c] + d[c], 1e-12);
    EXPECT_NEAR(p.velocity[c], u[c], 1e-12);
    EXPECT_NEAR(p.velocity[3 + c], u[c], 1e-12);
  }
  EXPECT_LT(p.centre[0], 1.1 + d[0]);
  EXPECT_GT(p.centre[3], 1.1 + d[0]);

  // Spinning about the origin, v = w x X: momentum / mass = w x centre for each piece.
  const double w[3] = {0.5, -1, 2};
  for (size_t i = 0; i < n; ++i) {
    const double* X = &m.positions[3 * i];
    v[3 * i] = w[1] * X[2] - w[2] * X[1];
    v[3 * i + 1] = w[2] * X[0] - w[0] * X[2];
    v[3 * i + 2] = w[0] * X[1] - w[1] * X[0];
  }
  fr.compute(vol, mass, m.positions.data(), v.data(), p);
  for (size_t f = 0; f < 2; ++f) {
    const double* cc = &p.centre[3 * f];
    const double expect[3] = {w[1] * cc[2] - w[2] * cc[1], w[2] * cc[0] - w[0] * cc[2],
                              w[0] * cc[1] - w[1] * cc[0]};
    for (size_t c = 0; c < 3; ++c) EXPECT_NEAR(p.velocity[3 * f + c], expect[c], 1e-12);
  }
}

}  // namespace
}  // namespace gf::detail
