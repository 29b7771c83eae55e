// Render surface with crack faces (SPEC §3, thesis sec 4.4.1, fig 4.9 and 4.10). The
// computational mesh is never changed; this surface is derived from it.
//
// Design note.
// - Corner cells. Every tet is split into 4 corner cells, one per node (fig 4.9): the cell of
//   node a in tet abcd is bounded by 3 quads on the tet's faces, (a, e_ab, f_abc, e_ac), and by
//   3 inner quads, one per other node b: (e_ab, f_abc, c, f_abd). Split points: e_ab on the edge
//   (midpoint, or at a per-edge ratio t from the lower node, the force-ratio point of fig 4.10),
//   f the face centroids and c the tet centroid. Split points belong to edges and faces, so
//   neighbouring tets agree on them, and the union of a node's corner cells is its dual cell.
// - Visible faces. Outer quads are visible where the tet face is on the mesh boundary; outer
//   quads on interior faces separate two cells of the same node and never show. The inner quad
//   of edge ab shows, as two copies with opposite orientation (one per side), when the cells of
//   a and b are not joined, where "joined" is:
//     renderPartialCracks (default): edge ab is unbroken. Every broken edge shows, including
//       cracks that have not (yet) separated the body, which is what the thesis renders.
//     otherwise: a and b are in the same fragment. Only separated pieces show crack faces.
// - Vertices. A render vertex is a split point together with a group of its parent nodes (the
//   nodes whose cells meet there: 1 for a node, 2 for an edge point, 3 for a face centroid, 4
//   for a tet centroid), where a group is a connected component of the parents under "joined".
//   This is the thesis's child-node rule ("SF2 and SF3 follow the average movement of PF2 and
//   PF3"). Faces of cells in one group share the vertex and faces of other groups get their
//   own copy, so a split point is duplicated exactly where the surface opens. That makes each
//   fragment's surface closed and edge-manifold, also for partial cracks: a crack that has not
//   separated the body is a slit whose two sides are distinct vertices in its interior and
//   share vertices along its front, where the two sides meet (each front edge then has one
//   triangle from each side, with opposite directions). Groups never join cells of different
//   fragments, so every triangle and vertex belongs to one fragment.
// - Triangulation. Outer quads are cut along (corner node, face centroid), inner quads along
//   (edge point, tet centroid). Both copies of an inner quad use the same diagonal, so the
//   cells partition each tet exactly (also for non-planar quads from ratio splits), and the
//   edge point is never shared by the two copies, so the diagonal never joins the two sides.
// - Orientation. For positively oriented tets the inner quad (e_ab, f_abp, c, f_abq) faces b
//   when (a, p, q, b) is an even permutation of the local nodes: its area vector dotted with
//   X_b - X_a is det[X_p - X_a, X_q - X_a, X_b - X_a] / 6, whatever the ratio t. So the
//   orientation is combinatorial and exact.
// - Motion. A vertex whose group holds all parents of its split point is placed at
//   sum_j w_j x_j (it moves with the element, exactly affine). A vertex of a partial group
//   follows only the parents in the group: the mean over group nodes j of
//   x_j + M_j (P - X_j), with P the split point's rest position and M_j the map that best
//   takes node j's rest neighbourhood onto its current one: the least-squares affine map when
//   the neighbourhood spans a volume and the map is not (nearly) inverted, otherwise the best
//   rotation (polar part of the covariance). The neighbourhood is the 1-ring over unbroken
//   edges, grown ring by ring (still over unbroken edges, so inside the fragment, about 64
//   nodes at most) until it spans a volume; a piece that is all on one line gets the smallest
//   rotation that turns the line, and a lone node keeps the identity (it only translates).
//   Rigid and affine motions of a piece are therefore reproduced exactly, and crack faces
//   stretch with the material around them.
// - Volumes. With midpoints every corner cell has volume V/4 and all quads are planar at rest,
//   so a fragment's surface encloses exactly the sum of its nodes' V/4 (Fragments::
//   nodeVolumes()). With ratio splits the cells are still a partition of each tet but no longer
//   V/4; cellRestVolumes() gives their exact volumes.
// - Normals are area-weighted vertex normals. At the front of a partial crack the two sides
//   cancel; such a vertex takes the normal of its first triangle.
// - Cost: nothing unless called. rebuild() is O(tets) (tets with no boundary face and no
//   unjoined edge are skipped at once), runs on the JobSystem over fixed chunks of tets with the
//   serial walk's numbering (docs/design.md, the render surface), and allocates only when the
//   surface outgrows its previous capacity. A chunk lists its quads again only when an edge of
//   its tets changed from joined to not or back (the quads depend on nothing else); the rest,
//   numbering included, is redone whole, so a kept surface equals a fresh one bit for bit.
//   updatePositions() is O(vertices + triangles): each triangle's area vector once, then each
//   vertex sums its triangles' in increasing order.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "graphfrac/jobs.h"
#include "graphfrac/mesh.h"
#include "graphfrac/status.h"
#include "kernels/split_point.h"
#include "mesh/edge_graph.h"

namespace gf::detail {

/// Options of CrackSurface.
struct CrackSurfaceOptions {
  /// Show every broken edge's crack faces, also before the crack separates the body (see the
  /// design note); false: only faces between different fragments.
  bool renderPartialCracks = true;
};

/// Half-open range of vertices whose positions or normals changed.
struct DirtyRange {
  uint32_t begin = 0;  ///< First changed vertex.
  uint32_t end = 0;    ///< One past the last changed vertex.
};

/// The render surface of one body: boundary and crack faces of the corner-cell split.
class CrackSurface {
 public:
  /// Smallest split ratio accepted (ratios are clamped to [kMinRatio, 1 - kMinRatio] so no
  /// boundary facet degenerates; kernels/split_point.h says why this bound).
  static constexpr double kMinRatio = kMinSplitRatio;

  /// Precomputes the face table of the rest mesh (O(T log T), once per body). `rest` must be
  /// valid and positively oriented (as after validate()); `graph` must be built from it. Both
  /// must outlive this object.
  void init(const TetMesh& rest, const EdgeGraph& graph, const CrackSurfaceOptions& options = {});
  /// Per-edge split ratio t in (0, 1), measured from the edge's lower node (the force-ratio
  /// point of fig 4.10), or nullptr for midpoints. Copied; used from the next rebuild().
  /// Values are clamped to [kMinRatio, 1 - kMinRatio]; non-finite values mean 0.5.
  void setSplitRatios(const double* ratio);

  /// Rebuilds the topology from the broken flags (1 per edge) and the node fragments (1 per
  /// node), then places the vertices at `x` (3 per node; nullptr: rest positions).
  /// Increments topologyVersion(); all vertices are dirty. Call it after every step that broke
  /// an edge (with renderPartialCracks) or split a fragment (without); otherwise only
  /// updatePositions().
  /// `jobs` (null: the calling thread) runs the per-vertex work (surface/surface_stages.h).
  void rebuild(const uint8_t* broken, const int32_t* nodeFragment, const double* x,
               JobSystem* jobs = nullptr);
  /// Nodes that get a local map (design note: Motion) at every rebuild() besides the surface's
  /// own, for other vertices that follow partial groups (the embedded render mesh). Copied;
  /// used from the next rebuild(). Their maps come after the surface's own, so a surface
  /// without extra nodes is the same bit for bit.
  void setExtraFrameNodes(std::span<const int32_t> nodes) {
    m_extraFrameNodes.assign(nodes.begin(), nodes.end());
  }
  /// Places only the vertices of the fragments f with drawn[f] != 0 (none past its end), for a
  /// surface that lends a few of its faces to another (the embedded render mesh): their
  /// triangles hold no other vertex, so their positions and normals are the same bits as when
  /// every vertex is placed. The local maps are made for all. positions(), normals() and dirty()
  /// are then not kept, and positionsDouble() and normalsDouble() hold the drawn vertices only.
  /// With no fragment drawn the surface has no vertex at all, and only the extra frame nodes
  /// (setExtraFrameNodes) get local maps, the same bits, numbered in their order.
  /// Copied; used from the next rebuild().
  void setDrawnFragments(std::span<const uint8_t> drawn) {
    m_drawnFragment.assign(drawn.begin(), drawn.end());
    m_drawnOnly = true;
  }
  /// Per node: the index of its local map in frameMaps(), or -1 when it has none.
  std::span<const int32_t> nodeFrame() const { return m_nodeFrame; }
  /// The current local maps, 9 per map (row-major), as of the last updatePositions().
  std::span<const double> frameMaps() const { return m_frameR; }
  /// Unit normals in double, 3 per vertex.
  std::span<const double> normalsDouble() const { return m_normals; }
  /// Recomputes positions and normals for node positions `x` (3 per node); topology unchanged.
  /// Widens the dirty range to cover the vertices whose position or normal changed.
  void updatePositions(const double* x, JobSystem* jobs = nullptr);

  /// Positions, 3 floats per vertex (for the renderer).
  std::span<const float> positions() const { return m_positionsF; }
  /// Positions in double, 3 per vertex (for export and checks).
  std::span<const double> positionsDouble() const { return m_positions; }
  /// Unit normals, 3 floats per vertex.
  std::span<const float> normals() const { return m_normalsF; }
  /// Triangles, 3 vertex indices each, outward oriented (counter-clockwise seen from outside).
  std::span<const uint32_t> indices() const { return m_indices; }
  /// Per triangle: 1 for a crack face, 0 for a face of the mesh boundary.
  std::span<const uint8_t> crackFlags() const { return m_triCrack; }
  /// Per triangle: the corner node whose cell the face bounds (where a renderer's or a
  /// collider's hit on this face acts, thesis sec 4.4.2).
  std::span<const int32_t> triangleNode() const { return m_triNode; }
  /// Per vertex: its parent node (the lowest node index of its group).
  std::span<const int32_t> vertexNode() const { return m_vertexNode; }
  /// Per vertex: the fragment of its parent node (every triangle's vertices share it).
  std::span<const int32_t> vertexFragment() const { return m_vertexFragment; }
  /// Number of vertices.
  uint32_t vertexCount() const { return static_cast<uint32_t>(m_vertexNode.size()); }
  /// Number of triangles.
  uint32_t triangleCount() const { return static_cast<uint32_t>(m_triCrack.size()); }
  /// Incremented by every rebuild().
  uint64_t topologyVersion() const { return m_topologyVersion; }
  /// Incremented by every rebuild() and updatePositions().
  uint64_t positionVersion() const { return m_positionVersion; }
  /// The smallest range holding every vertex changed since the last clearDirty() (empty when
  /// none changed; everything after a rebuild()).
  DirtyRange dirty() const { return m_dirty; }
  /// Marks everything as uploaded.
  void clearDirty() { m_dirty = {}; }

  /// Exact rest volume of every node's corner cells for the current split ratios (equal to
  /// Fragments::nodeVolumes() for midpoints). One value per node.
  std::vector<double> cellRestVolumes() const;

  /// Writes the surface as OBJ (crack faces in group `crack`, the rest in `surface`) or PLY
  /// (a per-face `crack` property), chosen by extension. Errors name the path and the reason.
  Result<void> write(const std::string& path) const;

 private:
  double splitRatio(int32_t edge) const;
  // rebuild()'s last parts: the frames' neighbourhoods, and each vertex's triangles.
  void buildFrames(const uint8_t* broken, JobSystem& jobs);
  void buildVertexTriangles(JobSystem& jobs);

  // Rest data from init().
  const TetMesh* m_rest = nullptr;
  const EdgeGraph* m_graph = nullptr;
  CrackSurfaceOptions m_options;
  int32_t m_faceCount = 0;
  std::vector<int32_t> m_tetFace;       // 4 per tet (local face l, opposite node l) -> face
  std::vector<int32_t> m_faceNodes;     // 3 per face, ascending
  std::vector<int32_t> m_faceEdges;     // 3 per face: edges (n0 n1), (n0 n2), (n1 n2)
  std::vector<uint8_t> m_faceBoundary;  // 1 when the face has one tet
  std::vector<uint8_t> m_tetHasBoundary;
  std::vector<double> m_ratio;  // per edge; empty: midpoints

  // Vertex slots: one per (split point, parent), filled for the lowest parent of each group,
  // and the first chunk of tets that uses the slot.
  std::vector<int32_t> m_slotVertex;
  std::vector<int32_t> m_slotChunk;

  // rebuild() runs over fixed chunks of tets (their number does not depend on the threads): a
  // chunk lists its quads as vertex slots, and creates the vertices of the slots no earlier
  // chunk uses, in the order of first use, so the numbering is the serial tet walk's.
  struct TetChunk {
    std::vector<int32_t> slot;     // 4 per quad: the slot of each corner, in creation order
    std::vector<uint8_t> group;    // per corner: its vertex's group mask
    std::vector<uint8_t> crack;    // per quad
    std::vector<int32_t> corner;   // per quad: its corner node
    std::vector<int32_t> owned;    // the corners that create a vertex, in creation order
    std::vector<int64_t> framing;  // (node, key) pairs of the partial vertices' group nodes
    int32_t vertexBase = 0, quadBase = 0;
    uint8_t stale = 1;  // an edge of its tets changed since slot .. corner were listed
  };
  std::vector<TetChunk> m_chunks;
  std::vector<uint8_t> m_edgeJoined;  // per edge, as the chunks' quads were last listed
  std::vector<int64_t> m_nodeKey;     // per node: 4 v + k of the first partial vertex v it frames

  // Scratch of each chunk of frames: its neighbourhoods and a visited set.
  struct FrameChunk {
    std::vector<int32_t> ring, bfs, seen;
    std::vector<uint32_t> seenStamp;
    uint32_t stamp = 0;
  };
  std::vector<FrameChunk> m_frameChunks;

  // Vertex recipes: up to 4 parents (unused: -1) with rest weights, the group mask over them
  // and the rest position.
  std::vector<int32_t> m_vParent;
  std::vector<double> m_vWeight;
  std::vector<uint8_t> m_vGroup;
  std::vector<double> m_vRest;

  // Local maps for nodes in partial groups: their neighbourhoods (CSR), whether the affine
  // fit is usable with its inverse rest covariance, and the current map.
  std::vector<int32_t> m_nodeFrame;  // node -> frame or -1
  std::vector<int32_t> m_extraFrameNodes;
  std::vector<int32_t> m_frameNode;
  std::vector<int32_t> m_frameRingStart, m_frameRing;
  std::vector<uint8_t> m_frameAffine;
  std::vector<double> m_frameCinv;  // 9 per frame
  std::vector<double> m_frameR;     // 9 per frame, row-major: the current map M

  // Output.
  std::vector<double> m_positions, m_normals;
  std::vector<double> m_triAreaNormals;  // 4 per triangle, updatePositions()'s scratch
  // setDrawnFragments(): the fragments, and the vertices and triangles placed, ascending.
  bool m_drawnOnly = false;
  std::vector<uint8_t> m_drawnFragment;
  std::vector<int32_t> m_drawnVertices, m_drawnTriangles;
  std::vector<int32_t> m_vertexTriStart, m_vertexTri;  // each vertex's triangles, ascending
  std::vector<int32_t> m_vertexTriFill, m_blockAt, m_blockStart, m_pairs;  // their scratch
  std::vector<float> m_positionsF, m_normalsF;
  std::vector<uint32_t> m_indices;
  std::vector<uint8_t> m_triCrack;
  std::vector<int32_t> m_triNode, m_vertexNode, m_vertexFragment;
  std::vector<double> m_partials;  // the dirty range's reductions, chunk by chunk
  uint64_t m_topologyVersion = 0, m_positionVersion = 0;
  DirtyRange m_dirty;
};

}  // namespace gf::detail
