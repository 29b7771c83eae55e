// Fragments: connected components of the node graph over unbroken edges (SPEC §2). A node is
// never split, so a fragment is a set of nodes and a body breaks into pieces only by losing
// edges; damage never heals, so fragments only ever split, never merge.
//
// Design:
// - Ids are dense, 0..count()-1, and stable: when a fragment splits, the piece that holds the
//   fragment's lowest node index keeps the old id and every other piece gets the next free id.
//   build() numbers fragments by increasing lowest node (the piece with node 0 is fragment 0).
// - The components themselves come from the executor (surface/fragment_stages.h: min-label
//   propagation with pointer jumping over unbroken edges, one source for the CPU and the
//   device), each node labelled with the lowest node of its piece; build() numbers the roots
//   by a scan. update() relabels only around the new breaks. For each batch edge, two bounded
//   searches from its ends, taking turns one node at a time in the graph its removal sees (the
//   batch's later edges still intact), tell whether the removal splits (FragmentMaySplitStage):
//   joined (most breaks: their ends meet a few edges away, often through a later edge of the
//   batch), split with the side that ran out of nodes first known whole (at most 512 nodes), or
//   unknown. Where every split of a fragment has a known small side, only the union of those
//   sides is relabelled: each piece that leaves the fragment lies in one, and the nodes in none
//   stay in one piece with the fragment's lowest node (by induction over the removals: a split
//   cuts a small side off the piece it lies in). A fragment with an unknown break, or whose
//   lowest node lies in a small side (the rest then changes id), is relabelled whole.
// - update() keeps the ids of the sequential rule: the batch of newly broken edges is applied
//   one edge at a time (edges later in the batch still count as intact), so each removal splits
//   at most one fragment in two, and the new ids follow the order of the removals that split.
//   Which removals split is found without replaying them on the node graph: the removal of the
//   i-th edge separates its ends exactly when they are apart in the final pieces joined by the
//   batch's later edges, so a union-find over the final pieces (the roots) that adds the batch
//   edges back in reverse order finds every split and its two sides (each side named by its
//   lowest node); walking those splits forwards gives each side that does not hold the lowest
//   node the next id. This host pass costs O(batch), not O(nodes). Assigning the new ids
//   touches only the relabelled nodes; the node lists are still rebuilt whole (O(nodes), by
//   the stages of step/segments.h) on a step that split.
// - Node lists hold every fragment's nodes in increasing index order (SegmentLists: a stable
//   radix sort by fragment on the executor, rebuilt when the partition changes), and the
//   per-fragment sums are segmented reductions over them in step/segments.h's fixed order: same
//   bits for any thread count.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "mesh/edge_graph.h"
#include "step/executor.h"
#include "step/scan.h"
#include "step/segments.h"

namespace gf::detail {

/// Per-fragment totals indexed by fragment id (filled by Fragments::compute()).
struct FragmentProperties {
  std::vector<double> volume;    ///< Rest volume: sum of the nodes' corner-cell volumes.
  std::vector<double> mass;      ///< Sum of the nodes' lumped masses.
  std::vector<double> centre;    ///< 3 per fragment: mass-weighted mean of current positions.
  std::vector<double> velocity;  ///< 3 per fragment: momentum / mass.
};

/// A fragment that appeared in the last update(): its id and the id it split from.
struct FragmentSplit {
  int32_t created = -1;  ///< Id of the new fragment.
  /// Id of the fragment it came out of: one that existed before the update, or one created
  /// earlier in the same update (always less than `created`).
  int32_t parent = -1;
};

/// Scratch of the labelling and the sums, kept by the caller (not part of a snapshot) so that a
/// step allocates nothing after warm-up.
struct FragmentScratch {
  std::vector<int32_t> label, next, rootId, flag, dsu;
  std::vector<double> changed, terms, partials, sums;
  std::vector<uint8_t> seen, status, mode, holdsMin;
  std::vector<int32_t> batch;
  std::vector<int32_t> batchOrder;  // per edge: position in the batch; -1 between calls
  std::vector<int32_t> sideSeed, sideSize, sideEdge, sideStart;
  std::vector<int32_t> region, owner, keep, position;  // owner: INT32_MAX between calls
  std::vector<int32_t> nodes;                          // the nodes relabelled by the last update()
  std::vector<int32_t> relabel;                        // fragments relabelled whole
  std::vector<int32_t> mergeSide;  // per split found: the two sides' lowest nodes
  ScanScratch scan;
  int32_t rounds = 0;  ///< label rounds of the last build() or update()
};

/// Connected components of a body's nodes over unbroken edges, with stable ids.
class Fragments {
 public:
  /// Full computation from the broken flags (1 = broken, one per edge of `graph`; null: none).
  /// Fragments are numbered by increasing lowest node index.
  void build(const CpuExecutor& exec, const EdgeGraph& graph, const uint8_t* broken,
             FragmentScratch& scratch);
  /// Incremental update after the edges in `newlyBroken` were set in `broken` (all other flags
  /// unchanged since the last call). Entries that are not broken, repeated, or already between
  /// two fragments are ignored. Returns true when at least one fragment split; splits() then
  /// lists the new fragments.
  bool update(const CpuExecutor& exec, const EdgeGraph& graph, const uint8_t* broken,
              std::span<const int32_t> newlyBroken, FragmentScratch& scratch);
  /// The same on the calling thread with scratch of its own (tests, tools).
  void build(const EdgeGraph& graph, const uint8_t* broken);
  bool update(const EdgeGraph& graph, const uint8_t* broken, std::span<const int32_t> newlyBroken);

  /// Number of fragments (ids are 0..count()-1).
  int32_t count() const { return static_cast<int32_t>(m_minNode.size()); }
  /// Fragment id of every node.
  std::span<const int32_t> nodeFragment() const { return m_nodeFragment; }
  /// Nodes of fragment `f`, in increasing index order.
  std::span<const int32_t> nodes(int32_t f) const {
    const Segments s = m_lists.view();
    return {s.order + s.start[f], static_cast<size_t>(s.start[f + 1] - s.start[f])};
  }
  /// The node lists as segments of a reduction (one per fragment).
  Segments segments() const { return m_lists.view(); }
  /// Lowest node index of fragment `f` (the node whose piece keeps `f` on a split).
  int32_t lowestNode(int32_t f) const { return m_minNode[static_cast<size_t>(f)]; }
  /// Fragments created by the last build() (none) or update(), in creation order.
  std::span<const FragmentSplit> splits() const { return m_splits; }
  /// Incremented whenever the partition changes (build, or an update that split something).
  uint64_t version() const { return m_version; }

  /// Volume, mass, centre of mass and velocity of every fragment. `nodeVolume` and `nodeMass`
  /// hold one value per node (see nodeVolumes()); `x` and `v` are 3 per node. A fragment of
  /// zero mass gets the plain mean of its nodes' positions and velocities. Each sum runs over
  /// the fragment's nodes in step/segments.h's order. Reuses `out`'s storage; O(nodes).
  void compute(const CpuExecutor& exec, std::span<const double> nodeVolume,
               std::span<const double> nodeMass, const double* x, const double* v,
               FragmentProperties& out, FragmentScratch& scratch) const;
  /// The same on the calling thread.
  void compute(std::span<const double> nodeVolume, std::span<const double> nodeMass,
               const double* x, const double* v, FragmentProperties& out) const;

  /// Volume owned by each node: a quarter of the rest volume of every incident tet, which is
  /// exactly the volume of the node's corner cells when the tets are split at edge midpoints,
  /// face and tet centroids (the default split of CrackSurface; an affine map of the regular
  /// tet's symmetric split). Tets are 4 node indices each; `rest` is 3 per node.
  static std::vector<double> nodeVolumes(const int32_t* tets, size_t tetCount, const double* rest,
                                         size_t nodeCount);

 private:
  // Labels the components of the listed nodes (null: all count nodes) into s.label.
  void label(const CpuExecutor& exec, const EdgeGraph& graph, const uint8_t* broken,
             const int32_t* nodes, int32_t count, FragmentScratch& s) const;
  // nodeFragment of the listed nodes from s.label and s.rootId, then the node lists.
  void assign(const CpuExecutor& exec, const int32_t* nodes, int32_t count, FragmentScratch& s);

  std::vector<int32_t> m_nodeFragment;
  std::vector<int32_t> m_minNode;  // per fragment
  SegmentLists m_lists;            // nodes by fragment, in index order
  std::vector<FragmentSplit> m_splits;
  uint64_t m_version = 0;
};

}  // namespace gf::detail
