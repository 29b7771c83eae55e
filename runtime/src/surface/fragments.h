// Fragments: connected components of the node graph over unbroken edges (SPEC §2). A node is
// never split, so a fragment is a set of nodes and a body breaks into pieces only by losing
// edges; damage never heals, so fragments only ever split, never merge.
//
// Design:
// - Ids are dense, 0..count()-1, and stable: when a fragment splits, the piece that holds the
//   fragment's lowest node index keeps the old id and every other piece gets the next free id.
//   build() numbers fragments by increasing lowest node (the piece with node 0 is fragment 0).
// - update() is incremental. The batch of newly broken edges is applied one edge at a time
//   (edges later in the batch still count as intact), so every step removes one edge and can
//   only split one fragment in two. For each edge (a, b) still inside one fragment it runs
//   two breadth-first searches over unbroken edges, one from a and one from b, one node at a
//   time each. They stop as soon as they meet (a and b still connected: nothing to do) or one of
//   them runs out of nodes (that search holds the whole smaller piece). A split therefore costs
//   O(smaller piece), and a break that splits nothing costs O(the ball the searches covered).
//   The one exception is the id rule: when the smaller piece holds the lowest node, it keeps the
//   id and the larger rest is relabelled, O(rest).
// - Node lists are a permutation of the nodes in which every fragment's nodes are contiguous
//   (start and count per fragment); a split partitions the parent's range in place, so the
//   lists are ranges of one array rather than CSR in id order. Order inside a range is
//   unspecified.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "mesh/edge_graph.h"

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

/// Connected components of a body's nodes over unbroken edges, with stable ids.
class Fragments {
 public:
  /// Full computation from the broken flags (1 = broken, one per edge of `graph`). Fragments
  /// are numbered by increasing lowest node index.
  void build(const EdgeGraph& graph, const uint8_t* broken);
  /// Incremental update after the edges in `newlyBroken` were set in `broken` (all other flags
  /// unchanged since the last call). Entries that are not broken, repeated, or already between
  /// two fragments are ignored. Returns true when at least one fragment split; splits() then
  /// lists the new fragments.
  bool update(const EdgeGraph& graph, const uint8_t* broken, std::span<const int32_t> newlyBroken);

  /// Number of fragments (ids are 0..count()-1).
  int32_t count() const { return static_cast<int32_t>(m_start.size()); }
  /// Fragment id of every node.
  std::span<const int32_t> nodeFragment() const { return m_nodeFragment; }
  /// Nodes of fragment `f`, in unspecified order.
  std::span<const int32_t> nodes(int32_t f) const {
    return {m_order.data() + m_start[static_cast<size_t>(f)],
            static_cast<size_t>(m_count[static_cast<size_t>(f)])};
  }
  /// Lowest node index of fragment `f` (the node whose piece keeps `f` on a split).
  int32_t lowestNode(int32_t f) const { return m_minNode[static_cast<size_t>(f)]; }
  /// Fragments created by the last build() (none) or update(), in creation order.
  std::span<const FragmentSplit> splits() const { return m_splits; }
  /// Incremented whenever the partition changes (build, or an update that split something).
  uint64_t version() const { return m_version; }

  /// Volume, mass, centre of mass and velocity of every fragment. `nodeVolume` and `nodeMass`
  /// hold one value per node (see nodeVolumes()); `x` and `v` are 3 per node. A fragment of
  /// zero mass gets the plain mean of its nodes' positions and velocities. Reuses `out`'s
  /// storage; O(nodes).
  void compute(std::span<const double> nodeVolume, std::span<const double> nodeMass,
               const double* x, const double* v, FragmentProperties& out) const;

  /// Volume owned by each node: a quarter of the rest volume of every incident tet, which is
  /// exactly the volume of the node's corner cells when the tets are split at edge midpoints,
  /// face and tet centroids (the default split of CrackSurface; an affine map of the regular
  /// tet's symmetric split). Tets are 4 node indices each; `rest` is 3 per node.
  static std::vector<double> nodeVolumes(const int32_t* tets, size_t tetCount, const double* rest,
                                         size_t nodeCount);

 private:
  // Two interleaved searches from a and b; returns true and fills m_piece when they do not meet.
  bool separatePiece(const EdgeGraph& graph, const uint8_t* broken, int32_t a, int32_t b);
  void splitOff(int32_t f);
  void nextEpoch();

  std::vector<int32_t> m_nodeFragment;
  std::vector<int32_t> m_order;                      // nodes, each fragment's contiguous
  std::vector<int32_t> m_position;                   // node -> index in m_order
  std::vector<int32_t> m_start, m_count, m_minNode;  // per fragment
  std::vector<FragmentSplit> m_splits;
  // Search state: m_mark[node] == m_epoch (search from a) or m_epoch + 1 (search from b).
  std::vector<uint32_t> m_mark;
  uint32_t m_epoch = 0;
  uint32_t m_pieceMark = 0;
  std::vector<int32_t> m_queueA, m_queueB;
  std::vector<uint8_t> m_pending;  // per edge: in the current batch, not yet processed
  const std::vector<int32_t>* m_piece = nullptr;
  uint64_t m_version = 0;
};

}  // namespace gf::detail
