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
// to its stable ids. Nodes of fragments in which no break may have split anything
// (FragmentMaySplitStage) keep their fragment's lowest node as label and are skipped.
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

/// Node u's first label (in both buffers): itself when its fragment is relabelled (`active`
/// null: every node), else its fragment's lowest node, which is already its root.
struct FragmentLabelInitStage {
  const uint8_t* active = nullptr;           ///< per fragment
  const int32_t* nodeFragment = nullptr;     ///< with active
  const int32_t* fragmentMinNode = nullptr;  ///< with active
  int32_t* label = nullptr;
  int32_t* next = nullptr;

  GF_HD void operator()(int32_t u) const {
    const int32_t l = !active || active[nodeFragment[u]] ? u : fragmentMinNode[nodeFragment[u]];
    label[u] = l;
    next[u] = l;
  }
};

/// One round's hooking and shortcutting from node u: reads `label` (the last round's), lowers
/// entries of `next` (equal to `label` on entry) by atomicMinLabel only.
struct FragmentLabelHookStage {
  FragmentGraphView graph;
  const uint8_t* active = nullptr;  ///< per fragment, as in FragmentLabelInitStage
  const int32_t* nodeFragment = nullptr;
  const int32_t* label = nullptr;
  int32_t* next = nullptr;

  GF_HD void operator()(int32_t u) const {
    if (active && !active[nodeFragment[u]]) return;
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

/// Ends a round: changed[u] says whether u's label moved; label = next, so both buffers hold
/// the round's result.
struct FragmentLabelSyncStage {
  const int32_t* next = nullptr;
  int32_t* label = nullptr;
  double* changed = nullptr;

  GF_HD void operator()(int32_t u) const {
    const int32_t l = next[u];
    changed[u] = l != label[u] ? 1.0 : 0.0;
    label[u] = l;
  }
};

/// Labels every node with the least node of its component over unbroken edges (see the design
/// note); `next` and `changed` are scratch of nodeCount items. Fragments not marked in `active`
/// (null: all relabelled) keep their lowest node. Returns the number of rounds that changed a
/// label. Exec is CpuExecutor or gpu::Executor; every pointer is in its memory.
template <class Exec>
int32_t labelComponents(const Exec& exec, const FragmentGraphView& graph, const uint8_t* active,
                        const int32_t* nodeFragment, const int32_t* fragmentMinNode, int32_t* label,
                        int32_t* next, double* changed) {
  const int32_t n = graph.nodeCount;
  exec.run(n, 1024, FragmentLabelInitStage{active, nodeFragment, fragmentMinNode, label, next});
  int32_t rounds = 0;
  for (;;) {
    exec.run(n, 256, FragmentLabelHookStage{graph, active, nodeFragment, label, next});
    exec.run(n, 1024, FragmentLabelSyncStage{next, label, changed});
    if (!(exec.template reduce<MaxOp>(n, ArrayTerm{changed}) > 0)) break;
    ++rounds;
  }
  return rounds;
}

/// Nodes a FragmentMaySplitStage search expands, and the slots of its visited set (open
/// addressing, a power of two, at most a quarter full).
constexpr int32_t kFragmentSearchNodes = 512;
constexpr int32_t kFragmentSearchSlots = 2048;

/// Batch edge i (a, b): whether its removal may have split a fragment. A breadth-first search
/// from a over unbroken edges, bounded to kFragmentSearchNodes nodes in fixed-size local
/// arrays, looks for b: found, a and b stay connected in the final graph, so no removal order
/// splits them (0); not found within the bound, maybe (1). Only fragments with a possible split
/// are labelled. Around a crack front the ends of a new break are usually a few edges apart.
struct FragmentMaySplitStage {
  FragmentGraphView graph;
  const int32_t* batch = nullptr;
  uint8_t* maySplit = nullptr;

  // Adds u to the visited set; false when it was there.
  GF_HD static bool visit(int32_t* slots, int32_t u) {
    uint32_t h = (uint32_t(u) * 2654435761u) & uint32_t(kFragmentSearchSlots - 1);
    while (slots[h] >= 0) {
      if (slots[h] == u) return false;
      h = (h + 1) & uint32_t(kFragmentSearchSlots - 1);
    }
    slots[h] = u;
    return true;
  }

  GF_HD void operator()(int32_t i) const {
    const int32_t e = batch[i];
    const int32_t a = graph.edgeNodes[2 * int64_t(e)], b = graph.edgeNodes[2 * int64_t(e) + 1];
    int32_t queue[kFragmentSearchNodes];
    int32_t slots[kFragmentSearchSlots];
    for (int32_t k = 0; k < kFragmentSearchSlots; ++k) slots[k] = -1;
    int32_t head = 0, tail = 0;
    queue[tail++] = a;
    visit(slots, a);
    maySplit[i] = 1;
    while (head < tail) {
      const int32_t u = queue[head++];
      for (int32_t s = graph.nodeEdgeStart[u]; s < graph.nodeEdgeStart[u + 1]; ++s) {
        const int32_t f = graph.nodeEdges[s];
        if (graph.broken[f]) continue;
        const int32_t p = graph.edgeNodes[2 * int64_t(f)], q = graph.edgeNodes[2 * int64_t(f) + 1];
        const int32_t w = p == u ? q : p;
        if (w == b) {
          maySplit[i] = 0;
          return;
        }
        if (!visit(slots, w)) continue;
        if (tail == kFragmentSearchNodes) return;
        queue[tail++] = w;
      }
    }
  }
};

/// 1 for a root (a node that is its own label), else 0: scanned, the roots' ids by lowest node.
struct FragmentRootFlagStage {
  const int32_t* label = nullptr;
  int32_t* flag = nullptr;
  GF_HD void operator()(int32_t u) const { flag[u] = label[u] == u ? 1 : 0; }
};

/// At a root u (its own label): its fragment before the update, the id it keeps unless a split
/// gives it a new one.
struct FragmentRootOldIdStage {
  const int32_t* label = nullptr;
  const int32_t* nodeFragment = nullptr;
  int32_t* rootId = nullptr;
  GF_HD void operator()(int32_t u) const {
    if (label[u] == u) rootId[u] = nodeFragment[u];
  }
};

/// Node u's fragment: its root's id (rootId indexed by node, meaningful at roots).
struct FragmentAssignStage {
  const int32_t* label = nullptr;
  const int32_t* rootId = nullptr;
  int32_t* nodeFragment = nullptr;
  GF_HD void operator()(int32_t u) const { nodeFragment[u] = rootId[label[u]]; }
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
