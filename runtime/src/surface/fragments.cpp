// Fragments over unbroken edges: full build, incremental splits, per-fragment totals.
#include "surface/fragments.h"

#include <algorithm>
#include <limits>

#include "surface/fragment_stages.h"

namespace gf::detail {

namespace {

FragmentGraphView graphView(const EdgeGraph& graph, const uint8_t* broken) {
  return {graph.nodeCount, graph.edgeNodes.data(), graph.nodeEdgeStart.data(),
          graph.nodeEdges.data(), broken};
}

// Root of a's set; every set's root is its lowest member (see update()).
int32_t findRoot(std::vector<int32_t>& parent, int32_t a) {
  while (parent[size_t(a)] != a) a = parent[size_t(a)] = parent[size_t(parent[size_t(a)])];
  return a;
}

}  // namespace

void Fragments::label(const CpuExecutor& exec, const EdgeGraph& graph, const uint8_t* broken,
                      const int32_t* nodes, int32_t count, FragmentScratch& s) const {
  s.label.resize(size_t(graph.nodeCount));
  s.next.resize(size_t(graph.nodeCount));
  s.changed.resize(size_t(count));
  s.rounds = labelComponents(exec, graphView(graph, broken), nodes, count, s.label.data(),
                             s.next.data(), s.changed.data());
}

void Fragments::assign(const CpuExecutor& exec, const int32_t* nodes, int32_t count,
                       FragmentScratch& s) {
  exec.run(count, 1024,
           FragmentAssignStage{nodes, s.label.data(), s.rootId.data(), m_nodeFragment.data()});
  m_lists.build(exec, m_nodeFragment.data(), int32_t(m_nodeFragment.size()), this->count(), s.scan);
  ++m_version;
}

void Fragments::build(const CpuExecutor& exec, const EdgeGraph& graph, const uint8_t* broken,
                      FragmentScratch& s) {
  const int32_t n = graph.nodeCount;
  m_nodeFragment.assign(size_t(n), 0);
  m_splits.clear();
  label(exec, graph, broken, nullptr, n, s);
  // Roots numbered in node order: ids follow the lowest node of each component.
  s.rootId.resize(size_t(n) + 1);
  exec.run(n, 1024, FragmentRootFlagStage{s.label.data(), s.rootId.data()});
  const int32_t roots = exclusiveScan(exec, s.rootId.data(), n, s.rootId.data(), s.scan);
  m_minNode.resize(size_t(roots));
  assign(exec, nullptr, n, s);
  // Each list is in index order, so its first node is the lowest.
  const Segments seg = m_lists.view();
  for (int32_t f = 0; f < roots; ++f) m_minNode[size_t(f)] = seg.order[seg.start[f]];
}

bool Fragments::update(const CpuExecutor& exec, const EdgeGraph& graph, const uint8_t* broken,
                       std::span<const int32_t> newlyBroken, FragmentScratch& s) {
  m_splits.clear();
  s.rounds = 0;
  const int32_t n = graph.nodeCount;
  // The batch in order: broken edges inside one fragment, each at its first listing (an edge
  // between two fragments broke before; a repeat is already applied).
  s.seen.resize(size_t(graph.edgeCount), 0);
  s.batch.clear();
  for (int32_t e : newlyBroken) {
    if (e < 0 || e >= graph.edgeCount || !broken[e] || s.seen[size_t(e)]) continue;
    const int32_t a = graph.edgeNodes[2 * size_t(e)], b = graph.edgeNodes[2 * size_t(e) + 1];
    const int32_t f = m_nodeFragment[size_t(a)];
    if (f != m_nodeFragment[size_t(b)]) continue;
    s.seen[size_t(e)] = 1;
    s.batch.push_back(e);
  }
  for (int32_t e : s.batch) s.seen[size_t(e)] = 0;
  if (s.batch.empty()) return false;
  const int32_t batchSize = int32_t(s.batch.size());
  auto fragmentOf = [&](int32_t i) {
    return m_nodeFragment[size_t(graph.edgeNodes[2 * size_t(s.batch[size_t(i)])])];
  };

  // Which removals split, by searches in each removal's own graph (later batch edges intact).
  s.batchOrder.resize(size_t(graph.edgeCount), -1);
  for (int32_t i = 0; i < batchSize; ++i) s.batchOrder[size_t(s.batch[size_t(i)])] = i;
  const FragmentSequentialGraph sequential{graphView(graph, broken), s.batchOrder.data()};
  s.status.resize(size_t(batchSize));
  s.sideSeed.resize(size_t(batchSize));
  s.sideSize.resize(size_t(batchSize));
  // Most searches meet within a few nodes: items in ranges of 16.
  exec.run(batchSize, 16,
           FragmentMaySplitStage{sequential, s.batch.data(), s.status.data(), s.sideSeed.data(),
                                 s.sideSize.data()});
  // Per fragment: 0 nothing split, 1 relabelled in the small sides only, 2 relabelled whole
  // (a search could not tell).
  s.mode.assign(size_t(count()), 0);
  bool any = false;
  for (int32_t i = 0; i < batchSize; ++i) {
    uint8_t& mode = s.mode[size_t(fragmentOf(i))];
    if (s.status[size_t(i)] == kFragmentUnknown) mode = 2;
    if (s.status[size_t(i)] == kFragmentSmallSide && mode == 0) mode = 1;
    any = any || s.status[size_t(i)] != kFragmentJoined;
  }
  if (!any) {
    for (int32_t e : s.batch) s.batchOrder[size_t(e)] = -1;
    return false;
  }

  // The small sides of fragments relabelled by sides. Every piece that leaves such a fragment
  // lies in a small side, and the nodes in none stay together with the fragment's lowest node
  // (design note), so the sides' union, de-duplicated, is the whole region to relabel unless it
  // holds the lowest node.
  s.sideEdge.clear();
  s.sideStart.assign(1, 0);
  s.relabel.clear();
  for (int32_t i = 0; i < batchSize; ++i)
    if (s.status[size_t(i)] == kFragmentSmallSide && s.mode[size_t(fragmentOf(i))] == 1) {
      s.sideEdge.push_back(i);
      s.sideStart.push_back(s.sideStart.back() + s.sideSize[size_t(i)]);
    }
  const int32_t sides = int32_t(s.sideEdge.size());
  for (int32_t j = 0; j < sides; ++j)
    s.sideSeed[size_t(j)] = s.sideSeed[size_t(s.sideEdge[size_t(j)])];
  const int32_t total = s.sideStart.back();
  s.region.resize(size_t(total));
  exec.run(sides, 1,
           FragmentSideStage{sequential, s.sideEdge.data(), s.sideSeed.data(), s.sideStart.data(),
                             s.region.data()});
  for (int32_t e : s.batch) s.batchOrder[size_t(e)] = -1;
  s.owner.resize(size_t(n), std::numeric_limits<int32_t>::max());
  s.holdsMin.assign(size_t(count()), 0);
  s.keep.resize(size_t(total) + 1);
  exec.run(total, 256, FragmentRegionClaimStage{s.region.data(), s.owner.data()});
  exec.run(total, 256,
           FragmentRegionKeepStage{s.region.data(), s.owner.data(), m_nodeFragment.data(),
                                   m_minNode.data(), s.holdsMin.data(), s.keep.data()});
  for (int32_t j = 0; j < sides; ++j) {
    const int32_t f = m_nodeFragment[size_t(s.sideSeed[size_t(j)])];
    if (s.holdsMin[size_t(f)]) s.mode[size_t(f)] = 2;
  }
  exec.run(total, 256,
           FragmentRegionModeStage{s.region.data(), m_nodeFragment.data(), s.mode.data(),
                                   s.keep.data()});
  s.position.resize(size_t(total) + 1);
  const int32_t regionNodes = exclusiveScan(exec, s.keep.data(), total, s.position.data(), s.scan);
  int32_t listed = regionNodes;
  for (int32_t i = 0; i < batchSize; ++i) {
    const int32_t f = fragmentOf(i);
    if (s.mode[size_t(f)] != 2) continue;
    s.mode[size_t(f)] = 3;  // listed once
    s.relabel.push_back(f);
    listed += int32_t(nodes(f).size());
  }
  s.nodes.resize(size_t(listed));
  exec.run(total, 256,
           FragmentRegionCompactStage{s.region.data(), s.keep.data(), s.position.data(),
                                      s.nodes.data()});
  exec.run(total, 256, FragmentRegionReleaseStage{s.region.data(), s.owner.data()});
  int32_t* tail = s.nodes.data() + regionNodes;
  for (int32_t f : s.relabel) tail = std::copy(nodes(f).begin(), nodes(f).end(), tail);

  // Ends outside the relabelled nodes stay with their fragment's lowest node.
  s.label.resize(size_t(n));
  for (int32_t e : s.batch)
    for (int k = 0; k < 2; ++k) {
      const int32_t u = graph.edgeNodes[2 * size_t(e) + size_t(k)];
      s.label[size_t(u)] = m_minNode[size_t(m_nodeFragment[size_t(u)])];
    }
  label(exec, graph, broken, s.nodes.data(), listed, s);

  // Adding the batch back in reverse over the final pieces: a join of two sets is a removal
  // that split them (design note). Sets are named by their lowest node, their union's is the
  // lower of the two, so a side's name is its lowest node. Every piece of a fragment that
  // split holds an end of the batch, so the ends' roots are all the roots there are.
  s.dsu.resize(size_t(n));
  s.rootId.resize(size_t(n));
  for (int32_t e : s.batch)
    for (int k = 0; k < 2; ++k) {
      const int32_t r = s.label[size_t(graph.edgeNodes[2 * size_t(e) + size_t(k)])];
      s.dsu[size_t(r)] = r;
      s.rootId[size_t(r)] = m_nodeFragment[size_t(r)];  // the id it keeps unless split off
    }
  s.mergeSide.clear();
  for (size_t i = s.batch.size(); i-- > 0;) {
    const int32_t e = s.batch[i];
    const int32_t x = findRoot(s.dsu, s.label[size_t(graph.edgeNodes[2 * size_t(e)])]);
    const int32_t y = findRoot(s.dsu, s.label[size_t(graph.edgeNodes[2 * size_t(e) + 1])]);
    if (x == y) continue;
    s.mergeSide.push_back(std::min(x, y));
    s.mergeSide.push_back(std::max(x, y));
    s.dsu[size_t(std::max(x, y))] = std::min(x, y);
  }
  if (s.mergeSide.empty()) return false;

  // The splits forwards: the side without the lowest node takes the next id, its parent the id
  // of the side that keeps it (the whole group's at that moment).
  for (size_t k = s.mergeSide.size(); k > 0; k -= 2) {
    const int32_t keep = s.mergeSide[k - 2], other = s.mergeSide[k - 1];
    const int32_t created = count();
    m_splits.push_back({created, s.rootId[size_t(keep)]});
    s.rootId[size_t(other)] = created;
    m_minNode.push_back(other);
  }
  assign(exec, s.nodes.data(), listed, s);
  return true;
}

void Fragments::build(const EdgeGraph& graph, const uint8_t* broken) {
  FragmentScratch s;
  build(CpuExecutor(serialJobs()), graph, broken, s);
}

bool Fragments::update(const EdgeGraph& graph, const uint8_t* broken,
                       std::span<const int32_t> newlyBroken) {
  FragmentScratch s;
  return update(CpuExecutor(serialJobs()), graph, broken, newlyBroken, s);
}

void Fragments::compute(const CpuExecutor& exec, std::span<const double> nodeVolume,
                        std::span<const double> nodeMass, const double* x, const double* v,
                        FragmentProperties& out, FragmentScratch& s) const {
  const int32_t n = int32_t(m_nodeFragment.size());
  const Segments seg = m_lists.view();
  const size_t nf = size_t(count());
  s.terms.resize(size_t(kFragmentTerms) * size_t(n));
  s.partials.resize(size_t(kFragmentTerms) * size_t(seg.chunks));
  s.sums.resize(size_t(kFragmentTerms) * nf);
  exec.run(n, 1024, FragmentTermStage{n, nodeVolume.data(), nodeMass.data(), x, v, s.terms.data()});
  segmentedReduce<SumOp>(exec, seg, s.terms.data(), n, kFragmentTerms, s.partials.data(),
                         s.sums.data());
  out.volume.resize(nf);
  out.mass.resize(nf);
  out.centre.resize(3 * nf);
  out.velocity.resize(3 * nf);
  exec.run(count(), 64,
           FragmentPropertyStage{count(), seg.start, s.sums.data(), out.volume.data(),
                                 out.mass.data(), out.centre.data(), out.velocity.data()});
}

void Fragments::compute(std::span<const double> nodeVolume, std::span<const double> nodeMass,
                        const double* x, const double* v, FragmentProperties& out) const {
  FragmentScratch s;
  compute(CpuExecutor(serialJobs()), nodeVolume, nodeMass, x, v, out, s);
}

std::vector<double> Fragments::nodeVolumes(const int32_t* tets, size_t tetCount, const double* rest,
                                           size_t nodeCount) {
  std::vector<double> out(nodeCount, 0.0);
  for (size_t t = 0; t < tetCount; ++t) {
    const int32_t* n = tets + 4 * t;
    const double* a = rest + 3 * static_cast<size_t>(n[0]);
    double e[3][3];
    for (int k = 0; k < 3; ++k) {
      const double* p = rest + 3 * static_cast<size_t>(n[k + 1]);
      for (int c = 0; c < 3; ++c) e[k][c] = p[c] - a[c];
    }
    const double sixV = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                        e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                        e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
    // Midpoint split: each corner cell is V/4 (an affine image of the regular tet's
    // symmetric split, and affine maps keep volume ratios).
    for (int k = 0; k < 4; ++k) out[static_cast<size_t>(n[k])] += sixV / 24.0;
  }
  return out;
}

}  // namespace gf::detail
