// Fragment labelling on the executor (surface/fragment_stages.h) against a serial union-find on
// random graphs with random broken edges (many components, isolated nodes, long chains whose
// lowest node sits where min-label propagation needs many rounds), the same labels at 1/2/4
// threads, and Fragments::update's stable ids against a brute-force replay of the sequential
// rule (one edge removed at a time, components recomputed from scratch after each).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <numeric>
#include <random>
#include <utility>
#include <vector>

#include "common/union_find_labels.h"
#include "graphfrac/jobs.h"
#include "graphfrac/mesh.h"
#include "mesh/edge_graph.h"
#include "step/executor.h"
#include "surface/fragment_stages.h"
#include "surface/fragments.h"

namespace gf::detail {
namespace {

// An EdgeGraph of arbitrary edges (no tets): each pair once, smaller node first, sorted.
EdgeGraph makeGraph(int32_t n, std::vector<std::pair<int32_t, int32_t>> edges) {
  for (auto& e : edges)
    if (e.first > e.second) std::swap(e.first, e.second);
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  edges.erase(
      std::remove_if(edges.begin(), edges.end(), [](auto e) { return e.first == e.second; }),
      edges.end());
  EdgeGraph g;
  g.nodeCount = n;
  g.edgeCount = int32_t(edges.size());
  g.nodeEdgeStart.assign(size_t(n) + 1, 0);
  for (const auto& [a, b] : edges) {
    g.edgeNodes.push_back(a);
    g.edgeNodes.push_back(b);
    ++g.nodeEdgeStart[size_t(a) + 1];
    ++g.nodeEdgeStart[size_t(b) + 1];
  }
  for (int32_t u = 0; u < n; ++u) g.nodeEdgeStart[size_t(u) + 1] += g.nodeEdgeStart[size_t(u)];
  g.nodeEdges.resize(2 * edges.size());
  std::vector<int32_t> fill(g.nodeEdgeStart.begin(), g.nodeEdgeStart.end() - 1);
  for (int32_t e = 0; e < g.edgeCount; ++e)
    for (int k = 0; k < 2; ++k)
      g.nodeEdges[size_t(fill[size_t(g.edgeNodes[2 * size_t(e) + size_t(k)])]++)] = e;
  return g;
}

struct Labelled {
  std::vector<int32_t> label;
  int32_t rounds = 0;
};

Labelled labelOnExecutor(JobSystem& jobs, const EdgeGraph& g, const std::vector<uint8_t>& broken) {
  Labelled out;
  const size_t n = size_t(g.nodeCount);
  out.label.assign(n, -1);
  std::vector<int32_t> next(n);
  std::vector<double> changed(n);
  const FragmentGraphView view{g.nodeCount, g.edgeNodes.data(), g.nodeEdgeStart.data(),
                               g.nodeEdges.data(), broken.data()};
  std::vector<double> partials;
  out.rounds = labelComponents(CpuExecutor(jobs, &partials), view, nullptr, g.nodeCount,
                               out.label.data(), next.data(), changed.data());
  return out;
}

// Random graphs: a sparse random graph (many components, isolated nodes), paths under a random
// node order and in decreasing order from the lowest node (the worst case of min propagation),
// each with a random share of its edges broken.
struct RandomGraph {
  EdgeGraph graph;
  std::vector<uint8_t> broken;
  const char* kind;
};

std::vector<RandomGraph> randomGraphs() {
  std::vector<RandomGraph> out;
  for (uint32_t seed = 0; seed < 12; ++seed) {
    std::mt19937 rng(seed);
    const int32_t n = 200 + int32_t(rng() % 3000);
    std::vector<std::pair<int32_t, int32_t>> edges;
    // Sparse random graph: about one edge per node, so many components and isolated nodes.
    for (int32_t k = 0; k < n; ++k) edges.push_back({int32_t(rng() % n), int32_t(rng() % n)});
    out.push_back({makeGraph(n, edges), {}, "sparse"});
    // A path through a random permutation.
    std::vector<int32_t> perm(static_cast<size_t>(n));
    std::iota(perm.begin(), perm.end(), 0);
    std::shuffle(perm.begin(), perm.end(), rng);
    edges.clear();
    for (int32_t k = 0; k + 1 < n; ++k) edges.push_back({perm[size_t(k)], perm[size_t(k + 1)]});
    out.push_back({makeGraph(n, edges), {}, "random path"});
    // 0 - (n-1) - (n-2) - ... - 1: every node's smaller neighbour points away from node 0.
    edges.clear();
    edges.push_back({0, n - 1});
    for (int32_t k = n - 1; k > 1; --k) edges.push_back({k, k - 1});
    out.push_back({makeGraph(n, edges), {}, "descending path"});
    // Dense: a random graph with about six edges per node.
    edges.clear();
    for (int32_t k = 0; k < 6 * n; ++k) edges.push_back({int32_t(rng() % n), int32_t(rng() % n)});
    out.push_back({makeGraph(n, edges), {}, "dense"});
  }
  std::mt19937 rng(99);
  for (size_t i = 0; i < out.size(); ++i) {
    RandomGraph& r = out[i];
    // Break nothing, a few, or most edges, by the graph's index.
    const uint32_t share = uint32_t((i / 4) % 4) * 30;  // percent broken, by seed
    r.broken.assign(size_t(r.graph.edgeCount), 0);
    for (auto& b : r.broken) b = rng() % 100 < share;
  }
  return out;
}

TEST(FragmentLabels, MatchASerialUnionFindAtOneTwoAndFourThreads) {
  ThreadPoolJobSystem two(2), four(4);
  JobSystem* systems[] = {&serialJobs(), &two, &four};
  int components = 0, isolated = 0, maxRounds = 0;
  for (const RandomGraph& r : randomGraphs()) {
    const std::vector<int32_t> truth = test::unionFindLabels(r.graph, r.broken);
    ASSERT_EQ(truth.size(), size_t(r.graph.nodeCount));
    const Labelled one = labelOnExecutor(serialJobs(), r.graph, r.broken);
    ASSERT_EQ(one.label, truth) << r.kind << ", " << r.graph.nodeCount << " nodes";
    for (JobSystem* js : systems)
      ASSERT_EQ(labelOnExecutor(*js, r.graph, r.broken).label, one.label) << r.kind;
    for (int32_t u = 0; u < r.graph.nodeCount; ++u) {
      components += truth[size_t(u)] == u;
      isolated += r.graph.nodeEdgeStart[size_t(u)] == r.graph.nodeEdgeStart[size_t(u) + 1];
    }
    maxRounds = std::max(maxRounds, one.rounds);
  }
  std::printf("[ figures ] %d components, %d isolated nodes, at most %d label rounds\n", components,
              isolated, maxRounds);
  EXPECT_GT(components, 1000);
  EXPECT_GT(isolated, 100);
  // Hooking and shortcutting need O(log n) rounds where min-label propagation needed up to the
  // longest path (2729 rounds on these graphs).
  EXPECT_GE(maxRounds, 3);
  EXPECT_LE(maxRounds, 20);
}

// Paths up to 2^18 nodes, numbered so that labels spread one hop per round under plain
// min-label propagation: the rounds grow with log n, not with n.
TEST(FragmentLabels, RoundsGrowLogarithmicallyOnLongPaths) {
  ThreadPoolJobSystem four(4);
  for (int32_t logN = 8; logN <= 18; logN += 5) {
    const int32_t n = int32_t(1) << logN;
    std::mt19937 rng{uint32_t(logN)};
    std::vector<int32_t> perm(static_cast<size_t>(n));
    std::iota(perm.begin(), perm.end(), 0);
    std::shuffle(perm.begin(), perm.end(), rng);
    std::vector<std::pair<int32_t, int32_t>> descending{{0, n - 1}}, random;
    for (int32_t k = n - 1; k > 1; --k) descending.push_back({k, k - 1});
    for (int32_t k = 0; k + 1 < n; ++k) random.push_back({perm[size_t(k)], perm[size_t(k + 1)]});
    for (const auto* edges : {&descending, &random}) {
      const EdgeGraph g = makeGraph(n, *edges);
      const std::vector<uint8_t> none(size_t(g.edgeCount), 0);
      const Labelled l = labelOnExecutor(four, g, none);
      ASSERT_EQ(l.label, std::vector<int32_t>(size_t(n), 0));
      std::printf("[ figures ] %s path of 2^%d nodes: %d label rounds\n",
                  edges == &descending ? "descending" : "random", logN, l.rounds);
      EXPECT_LE(l.rounds, 2 * logN + 4);
    }
  }
}

// The sequential rule, brute force: each batch edge (first listing, broken, inside one fragment
// before the batch) removed in turn, components recomputed; a fragment whose two ends parted
// keeps its id on the side of its lowest node, the other side takes the next id.
struct Sequential {
  std::vector<int32_t> fragment, minNode;
  std::vector<FragmentSplit> splits;

  void update(const EdgeGraph& g, const std::vector<uint8_t>& broken,
              const std::vector<int32_t>& newly) {
    splits.clear();
    std::vector<uint8_t> intact(size_t(g.edgeCount));
    for (int32_t e = 0; e < g.edgeCount; ++e) intact[size_t(e)] = !broken[size_t(e)];
    std::vector<int32_t> batch;
    for (int32_t e : newly) {
      if (e < 0 || e >= g.edgeCount || !broken[size_t(e)]) continue;
      if (std::find(batch.begin(), batch.end(), e) != batch.end()) continue;
      if (fragment[size_t(g.edgeNodes[2 * size_t(e)])] !=
          fragment[size_t(g.edgeNodes[2 * size_t(e) + 1])])
        continue;
      batch.push_back(e);
      intact[size_t(e)] = 1;  // pending edges still hold until their turn
    }
    for (int32_t e : batch) {
      intact[size_t(e)] = 0;
      std::vector<uint8_t> asBroken(intact.size());
      for (size_t i = 0; i < intact.size(); ++i) asBroken[i] = !intact[i];
      const std::vector<int32_t> comp = test::unionFindLabels(g, asBroken);
      const int32_t a = g.edgeNodes[2 * size_t(e)], b = g.edgeNodes[2 * size_t(e) + 1];
      if (comp[size_t(a)] == comp[size_t(b)]) continue;
      const int32_t f = fragment[size_t(a)];
      const int32_t keepRoot = comp[size_t(minNode[size_t(f)])];
      const int32_t otherRoot = comp[size_t(a)] == keepRoot ? comp[size_t(b)] : comp[size_t(a)];
      const int32_t created = int32_t(minNode.size());
      for (size_t u = 0; u < comp.size(); ++u)
        if (comp[u] == otherRoot) fragment[u] = created;
      minNode.push_back(otherRoot);  // a union-find root here is its set's least node
      splits.push_back({created, f});
    }
  }
};

// What the update paths did over a replay: batch edges the bounded searches found joined, split
// with a known small side, or could not tell; fragments relabelled whole; nodes relabelled.
struct ReplayCounts {
  int splits = 0, multiSplitBatches = 0;
  int joined = 0, smallSide = 0, unknown = 0, wholeFragments = 0;
  int64_t relabelled = 0;
};

// Breaks `order`'s edges in batches of 1..maxBatch (random order, with repeats, stale and
// out-of-range entries now and then) and compares every update with the brute-force replay of
// the sequential rule: ids, splits and their parents, lowest nodes and node lists.
void replayAgainstSequentialRule(const EdgeGraph& g, const std::vector<int32_t>& order,
                                 size_t maxBatch, std::mt19937& rng, JobSystem& jobs,
                                 ReplayCounts& counts) {
  const int32_t n = g.nodeCount;
  std::vector<uint8_t> broken(size_t(g.edgeCount), 0);
  FragmentScratch scratch;
  Fragments fr;
  fr.build(CpuExecutor(jobs), g, broken.data(), scratch);
  Sequential seq;
  seq.fragment = test::unionFindLabels(g, broken);
  // Build numbers the roots in node order.
  std::vector<int32_t> rootId(size_t(n), -1);
  for (int32_t u = 0; u < n; ++u)
    if (seq.fragment[size_t(u)] == u) {
      rootId[size_t(u)] = int32_t(seq.minNode.size());
      seq.minNode.push_back(u);
    }
  for (int32_t u = 0; u < n; ++u) seq.fragment[size_t(u)] = rootId[size_t(seq.fragment[size_t(u)])];
  ASSERT_EQ(std::vector<int32_t>(fr.nodeFragment().begin(), fr.nodeFragment().end()), seq.fragment);

  size_t next = 0;
  while (next < order.size()) {
    const size_t batch = 1 + rng() % maxBatch;
    std::vector<int32_t> newly;
    for (size_t k = 0; k < batch && next < order.size(); ++k) newly.push_back(order[next++]);
    for (int32_t e : newly) broken[size_t(e)] = 1;
    if (rng() % 3 == 0) newly.push_back(newly.front());
    if (rng() % 5 == 0) newly.push_back(g.edgeCount + 3);
    if (rng() % 5 == 0 && next > batch) newly.insert(newly.begin(), order[next - batch - 1]);
    const int32_t before = fr.count();
    scratch.status.clear();
    scratch.relabel.clear();
    scratch.nodes.clear();
    const bool split = fr.update(CpuExecutor(jobs), g, broken.data(), newly, scratch);
    seq.update(g, broken, newly);
    ASSERT_EQ(std::vector<int32_t>(fr.nodeFragment().begin(), fr.nodeFragment().end()),
              seq.fragment);
    ASSERT_EQ(fr.splits().size(), seq.splits.size());
    for (size_t k = 0; k < seq.splits.size(); ++k) {
      EXPECT_EQ(fr.splits()[k].created, seq.splits[k].created);
      EXPECT_EQ(fr.splits()[k].parent, seq.splits[k].parent);
    }
    ASSERT_EQ(fr.count(), int32_t(seq.minNode.size()));
    for (int32_t f = 0; f < fr.count(); ++f) {
      EXPECT_EQ(fr.lowestNode(f), seq.minNode[size_t(f)]);
      const std::span<const int32_t> nodes = fr.nodes(f);
      EXPECT_TRUE(std::is_sorted(nodes.begin(), nodes.end()));
      for (int32_t u : nodes) EXPECT_EQ(fr.nodeFragment()[size_t(u)], f);
    }
    EXPECT_EQ(split, fr.count() > before);
    counts.splits += int(seq.splits.size());
    counts.multiSplitBatches += seq.splits.size() > 1;
    for (uint8_t st : scratch.status) {
      counts.joined += st == kFragmentJoined;
      counts.smallSide += st == kFragmentSmallSide;
      counts.unknown += st == kFragmentUnknown;
    }
    counts.wholeFragments += int(scratch.relabel.size());
    counts.relabelled += int64_t(scratch.nodes.size());
  }
}

TEST(FragmentLabels, UpdateKeepsTheIdsOfTheSequentialRule) {
  ThreadPoolJobSystem two(2);
  ReplayCounts counts;
  for (uint32_t seed = 0; seed < 6; ++seed) {
    std::mt19937 rng(1000 + seed);
    const int32_t n = 60 + int32_t(rng() % 120);
    std::vector<std::pair<int32_t, int32_t>> edges;
    for (int32_t k = 0; k < 2 * n; ++k) edges.push_back({int32_t(rng() % n), int32_t(rng() % n)});
    for (int32_t k = 0; k + 1 < n; k += 1 + int32_t(rng() % 3)) edges.push_back({k, k + 1});
    const EdgeGraph g = makeGraph(n, edges);
    std::vector<int32_t> order(size_t(g.edgeCount));
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    replayAgainstSequentialRule(g, order, 16, rng, two, counts);
  }
  std::printf("[ figures ] %d splits, %d batches with more than one\n", counts.splits,
              counts.multiSplitBatches);
  EXPECT_GT(counts.splits, 300);
  EXPECT_GT(counts.multiSplitBatches, 30);  // parents created earlier in the same batch
}

// Graphs large enough that the bounded searches cannot always tell (so whole fragments are
// relabelled) and small sides that hold their fragment's lowest node: long paths broken one
// edge at a time (every break splits; the middle ones leave two long sides), a lattice shattered
// at random (most breaks do not split, the late ones chip off small pieces, several per batch,
// some nested), and a crack plane broken in a few large batches (each break's ends joined only
// through the batch's later edges, the last batch parting the body).
TEST(FragmentLabels, UpdateOnlyAroundTheBreaksKeepsTheSequentialRule) {
  ThreadPoolJobSystem four(4);
  ReplayCounts path, lattice, plane;
  {
    std::mt19937 rng(7);
    const int32_t n = 20000;
    std::vector<int32_t> perm(static_cast<size_t>(n));
    std::iota(perm.begin(), perm.end(), 0);
    std::shuffle(perm.begin(), perm.end(), rng);
    std::vector<std::pair<int32_t, int32_t>> edges;
    for (int32_t k = 0; k + 1 < n; ++k) edges.push_back({perm[size_t(k)], perm[size_t(k + 1)]});
    const EdgeGraph g = makeGraph(n, edges);
    std::vector<int32_t> order(size_t(g.edgeCount));
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    order.resize(200);
    replayAgainstSequentialRule(g, order, 1, rng, four, path);
  }
  const TetMesh mesh = gen::box(1.0, 1.0, 1.0, 7, 7, 7);
  const EdgeGraph g = EdgeGraph::build(mesh.tets.data(), mesh.tetCount(), mesh.nodeCount());
  {
    std::mt19937 rng(8);
    std::vector<int32_t> order(size_t(g.edgeCount));
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    replayAgainstSequentialRule(g, order, 40, rng, four, lattice);
  }
  {
    std::mt19937 rng(9);
    std::vector<std::pair<double, int32_t>> crossing;
    for (int32_t e = 0; e < g.edgeCount; ++e) {
      const double* p = &mesh.positions[3 * size_t(g.edgeNodes[2 * size_t(e)])];
      const double* q = &mesh.positions[3 * size_t(g.edgeNodes[2 * size_t(e) + 1])];
      if ((p[0] < 0.45) != (q[0] < 0.45)) crossing.emplace_back(p[1] + q[1] + 1e-3 * p[2], e);
    }
    std::sort(crossing.begin(), crossing.end());
    std::vector<int32_t> order;
    for (const auto& c : crossing) order.push_back(c.second);
    replayAgainstSequentialRule(g, order, 60, rng, four, plane);
  }
  for (const auto& [name, c] : {std::pair<const char*, ReplayCounts*>{"path", &path},
                                {"lattice", &lattice},
                                {"plane", &plane}})
    std::printf(
        "[ figures ] %s: %d splits; batch edges joined %d, small side %d, unknown %d; %d "
        "fragments relabelled whole, %lld nodes relabelled\n",
        name, c->splits, c->joined, c->smallSide, c->unknown, c->wholeFragments,
        static_cast<long long>(c->relabelled));
  EXPECT_EQ(path.splits, 200);
  EXPECT_GT(path.unknown, 0);
  EXPECT_GT(path.smallSide, 0);
  EXPECT_GT(path.wholeFragments, 0);
  EXPECT_GT(lattice.splits, 100);
  EXPECT_GT(lattice.joined, 1000);
  EXPECT_GT(lattice.smallSide, 100);
  EXPECT_GT(lattice.multiSplitBatches, 10);
  EXPECT_GE(plane.splits, 1);
  EXPECT_GT(plane.joined, 50);
}

// FragmentMaySplitStage against a union-find over each removal's own graph (the batch's later
// edges intact): "joined" exactly when the ends are joined there; a small side is the whole
// component of the end it names, and the ends are apart.
TEST(FragmentLabels, SplitSearchMatchesEachRemovalsGraph) {
  int joined = 0, small = 0, unknown = 0;
  for (uint32_t seed = 0; seed < 8; ++seed) {
    std::mt19937 rng(200 + seed);
    const int32_t n = seed % 2 ? 4000 + int32_t(rng() % 4000) : 400 + int32_t(rng() % 2600);
    std::vector<std::pair<int32_t, int32_t>> edges;
    const int32_t degree = 1 + int32_t(seed % 3);
    for (int32_t k = 0; k < degree * n; ++k)
      edges.push_back({int32_t(rng() % n), int32_t(rng() % n)});
    if (seed % 2) {
      // A ring through every node: a break on it leaves its ends joined only the long way round.
      edges.clear();
      std::vector<int32_t> perm(static_cast<size_t>(n));
      std::iota(perm.begin(), perm.end(), 0);
      std::shuffle(perm.begin(), perm.end(), rng);
      for (int32_t k = 0; k < n; ++k) edges.push_back({perm[size_t(k)], perm[size_t((k + 1) % n)]});
    }
    const EdgeGraph g = makeGraph(n, edges);
    std::vector<uint8_t> broken(size_t(g.edgeCount));
    for (auto& b : broken) b = rng() % 100 < (seed % 2 ? 0 : 20);
    std::vector<int32_t> batch, batchOrder(size_t(g.edgeCount), -1);
    for (int32_t e = 0; e < g.edgeCount; ++e)
      if (!broken[size_t(e)] && rng() % uint32_t(seed % 2 ? n / 8 : 8) == 0) batch.push_back(e);
    std::shuffle(batch.begin(), batch.end(), rng);
    for (size_t i = 0; i < batch.size(); ++i) {
      broken[size_t(batch[i])] = 1;
      batchOrder[size_t(batch[i])] = int32_t(i);
    }
    const int32_t count = int32_t(batch.size());
    std::vector<uint8_t> status(static_cast<size_t>(count));
    std::vector<int32_t> sideSeed(static_cast<size_t>(count)), sideSize(static_cast<size_t>(count));
    const FragmentGraphView view{g.nodeCount, g.edgeNodes.data(), g.nodeEdgeStart.data(),
                                 g.nodeEdges.data(), broken.data()};
    ThreadPoolJobSystem two(2);
    CpuExecutor(two).run(count, 1,
                         FragmentMaySplitStage{{view, batchOrder.data()},
                                               batch.data(),
                                               status.data(),
                                               sideSeed.data(),
                                               sideSize.data()});
    std::vector<uint8_t> removed(size_t(g.edgeCount));
    for (int32_t i = 0; i < count; ++i) {
      for (int32_t e = 0; e < g.edgeCount; ++e)
        removed[size_t(e)] = broken[size_t(e)] && batchOrder[size_t(e)] <= i;
      const std::vector<int32_t> comp = test::unionFindLabels(g, removed);
      const int32_t e = batch[size_t(i)];
      const int32_t a = g.edgeNodes[2 * size_t(e)], b = g.edgeNodes[2 * size_t(e) + 1];
      const bool apart = comp[size_t(a)] != comp[size_t(b)];
      switch (status[size_t(i)]) {
        case kFragmentJoined:
          EXPECT_FALSE(apart) << "edge " << e;
          ++joined;
          break;
        case kFragmentSmallSide: {
          EXPECT_TRUE(apart) << "edge " << e;
          const int32_t seedNode = sideSeed[size_t(i)];
          EXPECT_TRUE(seedNode == a || seedNode == b);
          const auto size = std::count(comp.begin(), comp.end(), comp[size_t(seedNode)]);
          EXPECT_EQ(sideSize[size_t(i)], size) << "edge " << e;
          ++small;
          break;
        }
        default:
          EXPECT_EQ(status[size_t(i)], kFragmentUnknown);
          ++unknown;
      }
    }
  }
  std::printf("[ figures ] split searches: %d joined, %d small side, %d unknown\n", joined, small,
              unknown);
  EXPECT_GT(joined, 100);
  EXPECT_GT(small, 100);
  EXPECT_GT(unknown, 5);
}

TEST(FragmentLabels, SumsHaveTheSameBitsAtOneTwoAndFourThreads) {
  std::mt19937 rng(5);
  const int32_t n = 5000;
  std::vector<std::pair<int32_t, int32_t>> edges;
  for (int32_t k = 0; k < 2 * n; ++k) edges.push_back({int32_t(rng() % n), int32_t(rng() % n)});
  const EdgeGraph g = makeGraph(n, edges);
  std::vector<uint8_t> broken(size_t(g.edgeCount));
  for (auto& b : broken) b = rng() % 3 == 0;
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> vol(static_cast<size_t>(n)), mass(static_cast<size_t>(n)), x(3 * size_t(n)),
      v(3 * size_t(n));
  for (auto* a : {&vol, &mass, &x, &v})
    for (double& d : *a) d = u(rng) * std::exp(6 * u(rng));
  for (double& m : mass) m = std::fabs(m);
  ThreadPoolJobSystem two(2), four(4);
  std::vector<FragmentProperties> props;
  for (JobSystem* js :
       {&serialJobs(), static_cast<JobSystem*>(&two), static_cast<JobSystem*>(&four)}) {
    FragmentScratch s;
    Fragments fr;
    fr.build(CpuExecutor(*js), g, broken.data(), s);
    FragmentProperties p;
    fr.compute(CpuExecutor(*js), vol, mass, x.data(), v.data(), p, s);
    // Independent check of one sum per fragment: the volume in index order agrees to rounding.
    std::vector<double> plain(size_t(fr.count()), 0.0);
    for (int32_t k = 0; k < n; ++k) plain[size_t(fr.nodeFragment()[size_t(k)])] += vol[size_t(k)];
    for (int32_t f = 0; f < fr.count(); ++f)
      EXPECT_NEAR(p.volume[size_t(f)], plain[size_t(f)], 1e-9 * (1 + std::fabs(plain[size_t(f)])));
    props.push_back(std::move(p));
  }
  ASSERT_GT(props[0].mass.size(), 100u);
  for (size_t k = 1; k < props.size(); ++k) {
    EXPECT_EQ(0, std::memcmp(props[k].centre.data(), props[0].centre.data(),
                             props[0].centre.size() * sizeof(double)));
    EXPECT_EQ(0, std::memcmp(props[k].velocity.data(), props[0].velocity.data(),
                             props[0].velocity.size() * sizeof(double)));
    EXPECT_EQ(0, std::memcmp(props[k].mass.data(), props[0].mass.data(),
                             props[0].mass.size() * sizeof(double)));
  }
}

}  // namespace
}  // namespace gf::detail
