// Fragment labelling and the fragments' sums as stages (step/executor.h), so that the CPU
// executor and the device executor (gpu/fragment_labels.h) run one source.
//
// Design: connected components of the nodes over unbroken edges by hooking and shortcutting in
// the manner of FastSV (Zhang, Azad, Hu 2020), which needs O(log n) rounds on the paths where
// plain min-label propagation needs their length. Labels form a forest of parent pointers to
// lower or equal nodes of the same component. A round reads only the last round's labels and
// lowers the new ones by a min-scatter: node u hooks its parent to the least grandparent among
// its unbroken neighbours (so whole trees merge in one step), and lowers its own label to that
// or to its grandparent (shortcut). A minimum does not depend on the order its terms arrive
// in, so the atomic min (device atomicMin, a compare-exchange loop on the CPU) gives the same
// bits for any thread count or launch shape. A round that changes nothing leaves every tree of
// depth one (shortcut) and equal labels across every unbroken edge (hooking), so each node
// holds its component's least node, which never moves: the canonical root that Fragments maps
// to its stable ids. A labelling runs over a list of nodes that is a union of whole components
// (every node on a build; on an update only the small sides that breaks cut off, found by
// bounded two-sided searches from each break's ends, FragmentMaySplitStage, or whole fragments
// where a search could not tell), so its cost follows the region the breaks touch.
#pragma once

#include <cstdint>

#include "kernels/gf_hd.h"
#include "step/reduce.h"
#include "step/segments.h"

namespace gf::detail {

/// The node-edge graph a labelling runs over (EdgeGraph's arrays; device copies on the GPU).
struct FragmentGraphView {
  int32_t nodeCount = 0;
  const int32_t* edgeNodes = nullptr;      ///< 2 per edge
  const int32_t* nodeEdgeStart = nullptr;  ///< nodeCount + 1
  const int32_t* nodeEdges = nullptr;
  const uint8_t* broken = nullptr;  ///< per edge, 1 = broken; null: none
};

/// *p = min(*p, v), safe against concurrent calls; the result is the same in any order.
GF_HD void atomicMinLabel(int32_t* p, int32_t v) {
#if defined(__CUDA_ARCH__)
  atomicMin(p, v);
#else
  int32_t cur = __atomic_load_n(p, __ATOMIC_RELAXED);
  while (v < cur &&
         !__atomic_compare_exchange_n(p, &cur, v, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {
  }
#endif
}

/// *p = v, safe against concurrent stores of the same value.
GF_HD void atomicStoreLabel(int32_t* p, int32_t v) {
#if defined(__CUDA_ARCH__)
  *reinterpret_cast<volatile int32_t*>(p) = v;
#else
  __atomic_store_n(p, v, __ATOMIC_RELAXED);
#endif
}

/// Item k of a node list (null: the identity).
GF_HD int32_t listedNode(const int32_t* nodes, int32_t k) { return nodes ? nodes[k] : k; }

/// A listed node's first label (in both buffers): itself.
struct FragmentLabelInitStage {
  const int32_t* nodes = nullptr;
  int32_t* label = nullptr;
  int32_t* next = nullptr;

  GF_HD void operator()(int32_t k) const {
    const int32_t u = listedNode(nodes, k);
    label[u] = u;
    next[u] = u;
  }
};

/// One round's hooking and shortcutting from listed node u: reads `label` (the last round's),
/// lowers entries of `next` (equal to `label` on entry) by atomicMinLabel only.
struct FragmentLabelHookStage {
  FragmentGraphView graph;
  const int32_t* nodes = nullptr;
  const int32_t* label = nullptr;
  int32_t* next = nullptr;

  GF_HD void operator()(int32_t k) const {
    const int32_t u = listedNode(nodes, k);
    const int32_t p = label[u];
    const int32_t gp = label[p];
    // Least grandparent over u's unbroken neighbours (INT32_MAX: none).
    int32_t m = 0x7fffffff;
    for (int32_t s = graph.nodeEdgeStart[u]; s < graph.nodeEdgeStart[u + 1]; ++s) {
      const int32_t e = graph.nodeEdges[s];
      if (graph.broken && graph.broken[e]) continue;
      const int32_t a = graph.edgeNodes[2 * int64_t(e)], b = graph.edgeNodes[2 * int64_t(e) + 1];
      const int32_t gw = label[label[a == u ? b : a]];
      m = gw < m ? gw : m;
    }
    if (m < gp) atomicMinLabel(&next[p], m);  // stochastic hooking: u's tree joins w's
    const int32_t own = m < gp ? m : gp;      // aggressive hooking, shortcut
    if (own < p) atomicMinLabel(&next[u], own);
  }
};

/// Ends a round: changed[k] says whether listed node u's label moved; label = next, so both
/// buffers hold the round's result.
struct FragmentLabelSyncStage {
  const int32_t* nodes = nullptr;
  const int32_t* next = nullptr;
  int32_t* label = nullptr;
  double* changed = nullptr;

  GF_HD void operator()(int32_t k) const {
    const int32_t u = listedNode(nodes, k);
    const int32_t l = next[u];
    changed[k] = l != label[u] ? 1.0 : 0.0;
    label[u] = l;
  }
};

/// Labels every listed node (`nodes`, `count` distinct nodes; null: nodes 0..count-1) with the
/// least node of its component over unbroken edges (see the design note). The list must be a
/// union of whole components: no unbroken edge leaves it, so nothing outside it is read or
/// written. `next` holds a node's worth of scratch like `label`, `changed` one per listed node.
/// Returns the number of rounds that changed a label. Exec is CpuExecutor or gpu::Executor;
/// every pointer is in its memory.
template <class Exec>
int32_t labelComponents(const Exec& exec, const FragmentGraphView& graph, const int32_t* nodes,
                        int32_t count, int32_t* label, int32_t* next, double* changed) {
  exec.run(count, 1024, FragmentLabelInitStage{nodes, label, next});
  int32_t rounds = 0;
  for (;;) {
    exec.run(count, 256, FragmentLabelHookStage{graph, nodes, label, next});
    exec.run(count, 1024, FragmentLabelSyncStage{nodes, next, label, changed});
    if (!(exec.template reduce<MaxOp>(count, ArrayTerm{changed}) > 0)) break;
    ++rounds;
  }
  return rounds;
}

/// Nodes each side of a FragmentMaySplitStage search may reach, and the slots of its visited
/// set (open addressing, a power of two, at most half full: both sides' nodes fit).
constexpr int32_t kFragmentSearchNodes = 512;
constexpr int32_t kFragmentSearchSlots = 2048;

/// What the removal of a batch edge does under the sequential rule (FragmentMaySplitStage).
enum FragmentSplitStatus : uint8_t {
  kFragmentJoined = 0,     ///< its ends stay joined: no split
  kFragmentSmallSide = 1,  ///< a split, and one side (at most kFragmentSearchNodes) is known
  kFragmentUnknown = 2,    ///< the bounded search could not tell
};

/// Open-addressing set of visited nodes with the side each was reached from, in fixed-size
/// local arrays (no allocation inside a kernel). It starts at kMinSlots and doubles, re-adding
/// the searches' queues (which hold every visited node), so a search that meets after a few
/// nodes clears a few slots, not the whole table; at most half full.
struct FragmentVisitedSet {
  static constexpr int32_t kMinSlots = 64;
  int32_t slots[kFragmentSearchSlots];
  uint8_t side[kFragmentSearchSlots];
  int32_t size = 0, count = 0;

  GF_HD void reset(int32_t slotCount) {
    size = slotCount;
    count = 0;
    for (int32_t k = 0; k < size; ++k) slots[k] = -1;
  }
  GF_HD uint32_t home(int32_t u) const {
    // Fibonacci hashing keeps the high bits, which mix all of u's bits.
    return uint32_t((uint64_t(uint32_t(u)) * 11400714819323198485ull) >> 40) & uint32_t(size - 1);
  }
  GF_HD void insert(int32_t u, uint8_t from) {
    uint32_t h = home(u);
    while (slots[h] >= 0) h = (h + 1) & uint32_t(size - 1);
    slots[h] = u;
    side[h] = from;
    ++count;
  }
  // Adds u from `from`; returns -1 when it was new, else the side that reached it first.
  // queue[s][0 .. length[s]) are every node visited so far, from side s.
  GF_HD int32_t visit(int32_t u, uint8_t from, const int32_t* const* queue, const int32_t* length) {
    uint32_t h = home(u);
    while (slots[h] >= 0) {
      if (slots[h] == u) return side[h];
      h = (h + 1) & uint32_t(size - 1);
    }
    if (2 * (count + 1) > size && size < kFragmentSearchSlots) {
      reset(2 * size);
      for (uint8_t s = 0; s < 2; ++s)
        for (int32_t k = 0; k < length[s]; ++k) insert(queue[s][k], s);
    }
    insert(u, from);
    return -1;
  }
};

/// The graph in which batch edge i is removed under the sequential rule: the final broken
/// flags, but the batch's later edges (batchOrder[f] > i) still intact.
struct FragmentSequentialGraph {
  FragmentGraphView graph;
  const int32_t* batchOrder = nullptr;  ///< per edge: its position in the batch, -1 if none

  GF_HD bool passable(int32_t f, int32_t i) const { return !graph.broken[f] || batchOrder[f] > i; }
  GF_HD int32_t other(int32_t f, int32_t u) const {
    const int32_t p = graph.edgeNodes[2 * int64_t(f)], q = graph.edgeNodes[2 * int64_t(f) + 1];
    return p == u ? q : p;
  }
};

/// Batch edge i (a, b): whether its removal splits its fragment under the sequential rule,
/// that is whether a and b are apart once the batch's edges 0..i are gone and its later ones
/// still stand. Two breadth-first searches, from a and from b, advance one node in turn (as the
/// old serial search did), each bounded to kFragmentSearchNodes nodes: when they meet, joined;
/// when one runs out of nodes first, its nodes are the whole smaller side of a split (the side
/// seed and size are written); when a bound is hit first, unknown. Around a crack front a
/// break's ends are joined a few edges away, often through a later edge of the same batch.
struct FragmentMaySplitStage {
  FragmentSequentialGraph g;
  const int32_t* batch = nullptr;
  uint8_t* status = nullptr;
  int32_t* sideSeed = nullptr;  ///< for kFragmentSmallSide: the end whose side ran out
  int32_t* sideSize = nullptr;  ///< and its node count

  GF_HD void operator()(int32_t i) const {
    const int32_t e = batch[i];
    const int32_t ends[2] = {g.graph.edgeNodes[2 * int64_t(e)],
                             g.graph.edgeNodes[2 * int64_t(e) + 1]};
    int32_t queue[2][kFragmentSearchNodes];
    const int32_t* queues[2] = {queue[0], queue[1]};
    FragmentVisitedSet visited;
    visited.reset(FragmentVisitedSet::kMinSlots);
    int32_t head[2] = {0, 0}, tail[2] = {1, 1};
    for (uint8_t side = 0; side < 2; ++side) {
      queue[side][0] = ends[side];
      visited.insert(ends[side], side);
    }
    for (uint8_t side = 0;; side ^= 1) {
      if (head[side] == tail[side]) {
        status[i] = kFragmentSmallSide;
        sideSeed[i] = ends[side];
        sideSize[i] = tail[side];
        return;
      }
      const int32_t u = queue[side][head[side]++];
      for (int32_t s = g.graph.nodeEdgeStart[u]; s < g.graph.nodeEdgeStart[u + 1]; ++s) {
        const int32_t f = g.graph.nodeEdges[s];
        if (!g.passable(f, i)) continue;
        const int32_t w = g.other(f, u);
        const int32_t seen = visited.visit(w, side, queues, tail);
        if (seen < 0) {
          if (tail[side] == kFragmentSearchNodes) {
            status[i] = kFragmentUnknown;
            return;
          }
          queue[side][tail[side]++] = w;
        } else if (seen != side) {
          status[i] = kFragmentJoined;
          return;
        }
      }
    }
  }
};

/// Small side j: the nodes reachable from seed[j] in batch edge edgeIndex[j]'s sequential graph
/// (FragmentMaySplitStage found them to be at most kFragmentSearchNodes), in breadth-first
/// order into out[offset[j]] onwards.
struct FragmentSideStage {
  FragmentSequentialGraph g;
  const int32_t* edgeIndex = nullptr;
  const int32_t* seed = nullptr;
  const int32_t* offset = nullptr;
  int32_t* out = nullptr;

  GF_HD void operator()(int32_t j) const {
    const int32_t i = edgeIndex[j];
    int32_t* queue = out + offset[j];
    const int32_t size = offset[j + 1] - offset[j];
    FragmentVisitedSet visited;
    visited.reset(FragmentVisitedSet::kMinSlots);
    int32_t tail = 1;
    queue[0] = seed[j];
    visited.insert(seed[j], 0);
    const int32_t* queues[2] = {queue, nullptr};
    int32_t lengths[2] = {0, 0};
    for (int32_t head = 0; head < tail; ++head) {
      const int32_t u = queue[head];
      for (int32_t s = g.graph.nodeEdgeStart[u]; s < g.graph.nodeEdgeStart[u + 1]; ++s) {
        const int32_t f = g.graph.nodeEdges[s];
        if (!g.passable(f, i)) continue;
        const int32_t w = g.other(f, u);
        lengths[0] = tail;
        if (visited.visit(w, 0, queues, lengths) < 0 && tail < size) queue[tail++] = w;
      }
    }
  }
};

/// Region entry k (node region[k]) claims its node: owner[u] becomes the least entry holding u
/// (owner is INT32_MAX where unclaimed), so one entry per node survives de-duplication.
struct FragmentRegionClaimStage {
  const int32_t* region = nullptr;
  int32_t* owner = nullptr;
  GF_HD void operator()(int32_t k) const { atomicMinLabel(&owner[region[k]], k); }
};

/// keep[k] = 1 for the entry that owns its node; an owner that is its fragment's lowest node
/// flags the fragment (its lowest node leaves with a small side: relabel it whole).
struct FragmentRegionKeepStage {
  const int32_t* region = nullptr;
  const int32_t* owner = nullptr;
  const int32_t* nodeFragment = nullptr;
  const int32_t* fragmentMinNode = nullptr;
  uint8_t* holdsMin = nullptr;  ///< per fragment
  int32_t* keep = nullptr;

  GF_HD void operator()(int32_t k) const {
    const int32_t u = region[k];
    const bool mine = owner[u] == k;
    keep[k] = mine ? 1 : 0;
    if (mine && fragmentMinNode[nodeFragment[u]] == u) holdsMin[nodeFragment[u]] = 1;
  }
};

/// Entry k's node into out[position[k]] when kept and its fragment is relabelled by regions
/// (mode 1); every entry's owner back to INT32_MAX afterwards is FragmentRegionReleaseStage.
struct FragmentRegionCompactStage {
  const int32_t* region = nullptr;
  const int32_t* keep = nullptr;
  const int32_t* position = nullptr;
  int32_t* out = nullptr;
  GF_HD void operator()(int32_t k) const {
    if (keep[k]) out[position[k]] = region[k];
  }
};

/// keep[k] cleared where entry k's fragment is not relabelled by regions after all.
struct FragmentRegionModeStage {
  const int32_t* region = nullptr;
  const int32_t* nodeFragment = nullptr;
  const uint8_t* mode = nullptr;  ///< per fragment: 1 = by regions
  int32_t* keep = nullptr;
  GF_HD void operator()(int32_t k) const {
    if (mode[nodeFragment[region[k]]] != 1) keep[k] = 0;
  }
};

/// Releases entry k's node (owner back to INT32_MAX; several entries may store it at once).
struct FragmentRegionReleaseStage {
  const int32_t* region = nullptr;
  int32_t* owner = nullptr;
  GF_HD void operator()(int32_t k) const { atomicStoreLabel(&owner[region[k]], 0x7fffffff); }
};

/// 1 for a root (a node that is its own label), else 0: scanned, the roots' ids by lowest node.
struct FragmentRootFlagStage {
  const int32_t* label = nullptr;
  int32_t* flag = nullptr;
  GF_HD void operator()(int32_t u) const { flag[u] = label[u] == u ? 1 : 0; }
};

/// Listed node u's fragment: its root's id (rootId indexed by node, meaningful at roots).
struct FragmentAssignStage {
  const int32_t* nodes = nullptr;
  const int32_t* label = nullptr;
  const int32_t* rootId = nullptr;
  int32_t* nodeFragment = nullptr;
  GF_HD void operator()(int32_t k) const {
    const int32_t u = listedNode(nodes, k);
    nodeFragment[u] = rootId[label[u]];
  }
};

/// Number of per-node terms of a fragment's sums (FragmentTermStage).
constexpr int kFragmentTerms = 14;

/// Node u's terms of its fragment's sums, component k at terms[k nodeCount + u]: rest volume,
/// mass, mass-weighted position and velocity, plain position and velocity (for massless pieces).
struct FragmentTermStage {
  int32_t nodeCount = 0;
  const double* nodeVolume = nullptr;
  const double* nodeMass = nullptr;
  const double* x = nullptr;
  const double* v = nullptr;
  double* terms = nullptr;

  GF_HD void operator()(int32_t u) const {
    const int64_t n = nodeCount;
    const double m = nodeMass[u];
    terms[u] = nodeVolume[u];
    terms[n + u] = m;
    for (int c = 0; c < 3; ++c) {
      const double xc = x[3 * int64_t(u) + c], vc = v[3 * int64_t(u) + c];
      terms[(2 + c) * n + u] = m * xc;
      terms[(5 + c) * n + u] = m * vc;
      terms[(8 + c) * n + u] = xc;
      terms[(11 + c) * n + u] = vc;
    }
  }
};

/// Fragment f's volume, mass, centre of mass and velocity from its summed terms (sums[k count
/// + f]); a massless fragment gets the plain mean of its nodes.
struct FragmentPropertyStage {
  int32_t count = 0;
  const int32_t* start = nullptr;  ///< count + 1: the fragments' node counts
  const double* sums = nullptr;
  double* volume = nullptr;
  double* mass = nullptr;
  double* centre = nullptr;    ///< 3 per fragment
  double* velocity = nullptr;  ///< 3 per fragment

  GF_HD void operator()(int32_t f) const {
    const int64_t F = count;
    const double m = sums[F + f];
    volume[f] = sums[f];
    mass[f] = m;
    const double inv = 1.0 / double(start[f + 1] - start[f]);
    for (int c = 0; c < 3; ++c) {
      centre[3 * int64_t(f) + c] = m > 0 ? sums[(2 + c) * F + f] / m : sums[(8 + c) * F + f] * inv;
      velocity[3 * int64_t(f) + c] =
          m > 0 ? sums[(5 + c) * F + f] / m : sums[(11 + c) * F + f] * inv;
    }
  }
};

}  // namespace gf::detail
