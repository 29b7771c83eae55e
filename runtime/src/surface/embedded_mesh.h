// Detailed render meshes embedded in the tets (thesis sec 7.3.2, the multi-resolution
// framework: a fine surface driven by the coarse simulation mesh).
//
// Design note.
// - Binding (once, at body creation). Each render vertex P gets the tet that contains it, or,
//   for vertices outside the tets (an artist's surface is rarely inside a lattice mesh
//   everywhere), the nearest tet by Euclidean distance, found through a uniform grid over the
//   tets' bounding boxes. Its barycentric coordinates w in that tet (sum 1, negative outside)
//   place it at sum_k w_k X_k = P, so any affine motion of the tet moves it exactly.
// - Motion (every rendered frame, one stage over the vertices). An intact tet carries the
//   vertex by its own linear interpolation, sum_k w_k x_k, and the normal by the cofactor of the
//   tet's deformation gradient F = Ds Dm^-1 (Nanson's formula, n ~ cof(F) N). The cofactor is
//   chosen over normals recomputed from the deformed triangles because it keeps the artist's
//   normals (smoothing groups, hard edges split at seams) and needs no adjacency pass; it is
//   exact for affine motions. Its price is that F is constant per tet, so under bending the
//   shading steps at tet faces where the artist's surface crosses them.
// - Fracture: labels. A rest point belongs to the corner cell of its tet's node with the largest
//   weight (with midpoint splits that cell is exactly {w_a = max_k w_k}, crack_surface.h), and
//   so to that node's fragment. Each render vertex gets that label and a copy in its fragment;
//   the copy follows its group (the nodes of the tet joined to that node over unbroken edges):
//   a whole tet carries it by interpolation as above, a partial group through the local map
//   of its cell node (the group node of the largest weight), so it follows its side of the
//   crack. Not the mean of the group nodes' maps, as a partial CrackSurface vertex: an unbroken
//   edge whose tets are all split holds nothing (degradation model), so a group's nodes can
//   drift apart by many cells, and the mean drew the vertex between them
//   (RenderMesh.DrawnVerticesStayWithTheirFragmentAsPiecesFlyApart).
// - Fracture: chips (setChipsDrawnByNeighbours). A fragment that holds no whole tet (in the
//   degradation model, a node whose every tet is split, released as its own fragment:
//   docs/design.md "Severed edges") has mass and no stiffness and no volume of its own. Drawn as
//   pieces, a shattered bunny's 801 one-node chips made the pieces' cycles meet at more junctions
//   and left the cores between them uncovered (0.547 of its volume covered against 0.807 with the
//   chips' cells drawn by their neighbours), and interior chips drawn with their tet faces added
//   their cells twice. A chip that shares a tet with a fragment with a whole tet is given whole
//   to the fragment that drew most of its cells when they were shared out tet by tet,
//   unless its neighbours there lie on two sides of a crack within that fragment: its node takes
//   that fragment's label, its edges to it are not cracks as drawn, and in each tet it joins the
//   group of that fragment's node nearest to it. So the pieces' cells meet along faces, where
//   shared out tet by tet they met only at a chip's node or edge and no triple line bounded both
//   (the shattered bunny: 0.915 of its volume covered against 0.843). A copy does not follow a chip
//   given away: it follows the other nodes of its group, or, in a tet with no node of its fragment,
//   that fragment's node next to the tet nearest to it; a chip that flies off leaves its cells
//   drawn by that fragment (up to 2.5 mean edges from its nodes). Other chips (among chips only, or
//   across a crack) keep the old rule: labels skip their nodes, a vertex in such a cell takes the
//   strongest node of its tet outside chips (all four when every one is a chip) and follows that
//   node's group.
// - Fracture: which render edges are cut. A render edge is cut when its ends lie on different
//   sides of a crack: in different fragments, or, within one fragment, when an end's tet holds
//   the other end's cell node outside its own group. The groups are what move the copies, so
//   an edge is cut exactly where its ends would be carried apart: a crack that has not
//   separated the body (a notch, a torn but attached flap) is drawn as soon as it splits tets,
//   and a lone broken edge whose tets stay joined is not (nothing would open). A render edge
//   whose ends' tets hold neither cell node (an edge across a face diagonal the tets do not
//   have, or one longer than a cell) is cut when no unbroken path of at most two graph edges
//   joins the two cell nodes: across a crack such a path exists only near its front. The rule
//   needs a render mesh about as fine as the cells where a crack has not separated the body:
//   an edge spanning more than two cells is cut wherever its cell nodes are not joined within
//   two edges and both touch a broken edge (a slit whose sides move together: extra triangles,
//   nothing seen).
// - Fracture: refinement. A render edge is cut at most once, so an edge that crosses several
//   fragments misses those between its ends (a shattered cube drawn with 12 triangles left 33 %
//   of it covered by no fragment, with 48 triangles 86 %). Once any edge of the body is broken,
//   the render mesh is replaced (once, kept) by a copy whose edges are split at their
//   midpoints, conforming (a midpoint per edge, shared by its two triangles), until none is
//   longer than the tets' mean edge, each new point bound like a render vertex with its edge's
//   mean normal and UV. Chosen over clipping each render triangle by the tets it crosses: it
//   reuses the cut, the rim walk and the caps unchanged, and a render mesh already that fine
//   (the 50 690-vertex benchmark mesh) is not touched. The length was measured: half the mean
//   edge fills a coarse mesh's pieces worse (more chips own render triangles and their cycles
//   meet more junctions: 1.4 % of the cube uncovered against 0.9 %) and refines meshes that
//   were fine enough (a 15 x 15 x 15 box over 10 x 10 x 10 cells: 2.0 % against 1.1 %). Its
//   price: a coarse mesh's broken body is drawn with more triangles (a 12-triangle box over
//   10 x 10 x 10 cells: 3 370), the split triangles' shading interpolates the artist's normals
//   linearly, and the length is global, so a strongly graded tet mesh is refined to its mean
//   edge everywhere. A body that never breaks is drawn as given, with no extra vertex.
// - Fracture: cutting the render triangles. A cut render edge is cut at one point, computed
//   once for the edge (lower vertex first) where the boundary w_a = w_b between the two ends'
//   cells crosses it in the lower end's tet (b: among that tet's nodes in the other fragment,
//   or, within a fragment, outside the lower end's group; the edge midpoint when there is
//   none), kept at least 5 % of the edge from its ends. The point gets one copy per side, each
//   bound like a vertex of that side (the tet of the edge's end on that side, extrapolated
//   barycentric coordinates, its group), with rest normal and UV interpolated along the edge.
//   A triangle with two cut edges is split along the segment between their cut points (a
//   triangle and a quad); one with three also gets a point at its centroid (one copy per
//   corner) and splits into three quads. For fragment labels this is marching triangles; the
//   local rule adds the crack front: a triangle with one cut edge ij is where a crack ends, and
//   splits into (i, p_i, k) and (p_j, j, k), so the two sides open from the edge and meet at
//   the third corner k, a whole render vertex that follows its own group.
// - Fracture: closing. Each piece's side along a cut, in the piece's orientation, is a rim
//   segment (p_i -> k -> p_j through a front corner). On a 2-manifold render mesh every vertex
//   has as many incoming as outgoing segments (each render edge has two triangles and each
//   piece one segment per cut point), so the segments split into cycles; a walk that comes back
//   to a vertex already on it closes a cycle there, so a front corner on two cycles gets a cap
//   in each. Each cycle is closed by a cap, a fan of crack triangles (centre, c_k+1, c_k) around
//   a centre vertex placed every frame, which uses the rim copies themselves, so each edge of
//   the surface is used once in each direction: closed and 2-manifold. Where two fragments meet
//   along a cycle, their caps are the same fan reversed and their enclosed volumes add up to the
//   render mesh's; where three meet (a triangle with three labels on the way), each fragment's
//   cycle passes that triangle's centroid (a junction point) and is split there into runs, each
//   capped on its own around the mean of the run's cut points, which the neighbour across the
//   run shares. Junctions: a run is closed through the body along the triple lines of the labels
//   in the tets (where all four nodes are drawn, three fragments' cells meet on segments from
//   the centroid of a face with nodes in three fragments to the tet centroid; with chips, on
//   segments to a chip's node or along an edge between two chips): the shortest such path that
//   bounds both its fragments, from the line point nearest one junction point to the one
//   nearest the other, searched from the lower point so the neighbour gets the same one
//   reversed; each path point gets a copy per cycle, bound in a tet that holds a node of the
//   cycle's fragment and following that node's group, with the rest normal of the cycle's first
//   junction point (the shading there is approximate). What the paths leave of the cycle (each path
//   walked back, split into loops where it returns to a point; a path there and back encloses
//   nothing) is capped loop by loop: where a fourth fragment touches the cycle's fragment inside,
//   those loops are the faces between them, which the fourth caps the same way. A path along one
//   triple line between junctions of the same three fragments is replaced by the chord, as the
//   three fragments' chords then all lie on it and cancel. A run closes by its path only when the
//   neighbour's cycle holds the same run (same fragments and junction triangles) and both cycles
//   have a path for every run; other runs close by their chords, and the cycle's loops then hold
//   the polygon of its junction points, which its neighbours need not share, closed by a cone to a
//   node of its own fragment (so it moves with it): the node beyond the loop, within its radius r
//   of its centroid c, nearest to c + r/2 along the cap's normal (flat where there is none). A
//   cycle whose caps would not close falls back to chords for every run. Before, a cycle with a
//   run without a path sent its neighbours to chords too, and theirs (iterated), and the polygons
//   were flat: the shattered bunny 0.915 of its volume covered, now 0.973 (0.85 % twice against
//   0.066 %); four blades through a cube 31.7 % uncovered, now 6.7 %
//   (RenderMesh.PolygonsOfJunctionPointsAreClosedByConesToTheirPiece). Eight octants cut by three
//   blades through one point: 18.8 % of the cube covered by no fragment with the flat polygons,
//   5e-18 with the paths (RenderMesh.PiecesMeetingAtOnePointInsideFillTheBody). Not resolved: a
//   render mesh whose triangles span several tets at a junction (the shattered bunny's surface
//   vertices are its boundary nodes), where a junction triangle's three fragments meet in no tet: 6
//   of its 183 cycles with junctions close by paths, and the rest left cores covered by no
//   fragment (the bunny's pieces held 0.84 of its volume, before chips were given whole and the
//   polygons got cones). Refining the render mesh to a third of
//   the mean edge does not change that (still 6; docs/validation.md): most failing runs are between
//   fragments whose cells touch only at a chip's node or edge, which no triple line bounds.
//   Tried and dropped: sharing each core out as cones from the mean of its junction points (one
//   apex for all its pieces, not a node of each), carried by each fragment. At
//   rest that fills the body (the bunny's pieces: 0.998 of its volume, 0.25 % covered twice),
//   but a core spans much of a shattered body, so each piece carries a cone to a far point that
//   is not its own volume (pieces drawn with 0.8 to 1.6 of their cells' volume), its apex
//   extrapolated from a surface tet far from it; limited to cores within two tet edges it
//   applied to none. The centre is the mean of the rim's cut
//   points between two fragments when it has any: where an unseparated crack in one fragment runs
//   into its cut with another, the two cycles differ, and a centre on the crack's front would make
//   a cone over the separation that the neighbour's cap does not cancel (16.7 % of a notched, cut
//   bar left uncovered; RenderMesh.PartialCrackMeetingAFragmentCutIsClosed), while on those cut
//   points, the same rest points for both, the caps cancel and the crack's detour encloses nothing
//   at rest. Else the centre is the mean of the rim, or, when the rim has front corners (a crack
//   that has not separated the body), the mean of those: such a cycle runs along one side of the
//   crack from front to front and back along the other, so its fan is two crack faces, one per
//   side, that fold along the crack front (through the front corners and the centre between them)
//   like the faces of the real crack, and at rest, with both sides in the same place, it encloses
//   no volume. This was chosen over stopping the cut at the last broken edge (which leaves the
//   pieces' boundary open where the crack ends inside a render triangle) and over tracing the front
//   through the tets (the exact front, at the cost of clipping cells): it needs no data beyond the
//   cut, is closed by construction, and for a straight front the fold lies on it
//   (RenderMesh.PartlyCrackedBarShowsItsOpeningCrack: within a render edge and a cell). Its price:
//   a front that curves strongly is drawn as the fan's fold through the mean of its ends, and the
//   centre's one normal is shared by both faces (the fan's area vector, which for an opening crack
//   points out of the gap), so the crack faces' shading there is approximate. The caps are not the
//   tets' crack faces: they are a simple surface that closes the cut, flat for a planar cycle, and
//   a fan over a strongly non-convex cycle folds over itself (still closed, with the right signed
//   volume). Clipping the tets' crack facets to the inside of the render surface would put the caps
//   on the cells' facets exactly, but needs a planar arrangement per facet (render triangles
//   crossing it, shared points with the neighbouring facets) and is not done. Cap triangles are
//   crack faces (crackFlags 1: the interior material; UV 0 at the centre); their rim vertices keep
//   the render mesh's normal and UV, the centre takes the fan's normal.
// - What cannot be closed. An open artist's mesh stays open at its own holes: a cut that runs
//   into a hole is a chain, not a cycle, from one cut point on the hole's rim to another. It is
//   walked from its start (a copy with more rim segments leaving than entering) and capped like
//   a cycle, so the fan's closing edge spans the hole and each piece is open only where the
//   artist's mesh is (RenderMesh.OpenRenderMeshIsOpenOnlyAtItsHoles; before, chains were left
//   uncapped and each piece was open along its whole cut). A fragment that owns no
//   render vertex and is not a chip is drawn with its CrackSurface faces (closed, CrackSurface's
//   design note) if one of its nodes is inside the render mesh at rest (generalised winding number
//   >= 1/2), else not at all; such an interior fragment is also enclosed by its neighbours' caps,
//   which do not know it is missing. The cut follows the render mesh's resolution: a fragment
//   thinner than a render edge may own no render vertex.
// - Cost: nothing until World::surface asks; then O(render vertices + caps) per rendered frame
//   plus the tet surface's own update (its local maps and the faces of fragments drawn with
//   them). rebuild() runs once per fracture step, O(render triangles + tets): a look at each
//   tet (which fragments are chips), a side test per triangle edge (a few table reads; it looks
//   further, at the two cell nodes' graph edges, only where both touch broken edges and neither
//   end's tet holds the other's), one hash lookup per cut edge, a counting sort and a walk over the
//   rim segments, plus a winding number (O(render triangles)) for each node first asked about;
//   where a cycle has two junctions or more, the triple lines (a look at each tet, a map entry
//   for each tet with three fragments or with chips) and a shortest path per run along them
//   (scenes/bunny_render.json: the surface stage 15.0 to 15.9 ms a frame against 13.2 to 14.4
//   before, `graphfrac bench stages`, 1 thread); and,
//   on the first break, the refinement (one pass per halving of the longest edge, and a binding of
//   its vertices). Measured in RenderMesh.PerFrameCostAgainstTheStep: the unseparated-crack rule
//   adds about 0.5 ms to a 1.4 ms rebuild of a 24k-vertex render mesh on a shattered bar
//   (docs/design.md).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "graphfrac/jobs.h"
#include "graphfrac/mesh.h"
#include "graphfrac/status.h"
#include "kernels/math.h"
#include "mesh/edge_graph.h"
#include "surface/crack_surface.h"

namespace gf::detail {

/// A render mesh bound to the rest tets: read-only rest data, made by World::createBody.
struct EmbeddedBinding {
  std::vector<double> rest;        ///< 3 per vertex
  std::vector<double> restNormal;  ///< 3 per vertex, unit
  std::vector<float> uv;           ///< 2 per vertex, or empty
  std::vector<uint32_t> indices;   ///< 3 per triangle
  std::vector<uint16_t> material;  ///< per triangle, or empty (RenderMesh::materials)
  std::vector<int32_t> tet;        ///< per vertex: the tet it is bound to
  std::vector<double> weight;      ///< 4 per vertex: its barycentric coordinates there
  int32_t outsideCount = 0;        ///< vertices outside every tet
  double maxOutside = 0;           ///< the largest distance of such a vertex to its tet [m]

  /// Binds `mesh` (RenderMesh::check passed) to the validated mesh `rest`. Error naming `field`
  /// ("BodyDef.renderMesh") for a vertex farther than twice the longest tet edge from every tet.
  static Result<EmbeddedBinding> bind(const TetMesh& rest, const RenderMesh& mesh,
                                      const std::string& field);
  /// The same surface with its triangles split at edge midpoints (shared by an edge's two
  /// triangles, so it stays conforming) until no edge is longer than `maxEdge`, bound to `tets`
  /// like bind()'s vertices. Its first vertices are this binding's, in order; the new ones take
  /// the mean normal and UV of their edge's ends. When no edge is that long, the copy is
  /// returned unbound (tet and weight empty).
  EmbeddedBinding refined(const TetMesh& tets, double maxEdge) const;

 private:
  // Finds each vertex's tet and weights; with `limitDistance`, an error for one farther than
  // twice the longest tet edge from every tet.
  static Result<void> locate(const TetMesh& rest, EmbeddedBinding& b, const std::string& field,
                             bool limitDistance);
};

/// The drawn surface of a body with a render mesh: its triangles deformed with the tets, cut
/// where a crack splits tets (between fragments, or within one where a crack has not yet
/// separated the body), and closed by caps over the cuts (see the design note).
class EmbeddedSurface {
 public:
  /// All four must outlive this object. `restInverse` is Dm^-1 per tet of `rest`.
  void init(const EmbeddedBinding& binding, const TetMesh& rest, const EdgeGraph& graph,
            const Mat3* restInverse);
  /// Recomputes the vertex copies, the cut render triangles and the caps from the broken flags
  /// (1 per edge) and node fragments. Then frameNodes() lists the nodes whose local maps the
  /// copies need: hand them to CrackSurface::setExtraFrameNodes before its rebuild().
  void rebuild(const uint8_t* broken, const int32_t* nodeFragment);
  /// Whether rebuild() draws chips' cells with their neighbours (design note: chips); on for
  /// bodies that release severed edges after every batch (FractureSettings::releaseEveryBatch),
  /// off by default: every fragment is then drawn as its own.
  void setChipsDrawnByNeighbours(bool on) { m_chipsByNeighbours = on; }
  /// Nodes whose local maps the last rebuild() needs.
  std::span<const int32_t> frameNodes() const { return m_frameNodes; }
  /// Per fragment: 1 where the last rebuild() draws it with the crack surface's faces, the only
  /// ones update() takes (hand them to CrackSurface::setDrawnFragments before its rebuild()).
  std::span<const uint8_t> crackDrawn() const { return m_crackDrawn; }
  /// Places the vertices for node positions `x` (3 per node), with the local maps of `crack`,
  /// which must be up to date for `x` (its updatePositions or rebuild ran), and takes its
  /// crack faces. Every vertex is dirty afterwards.
  void update(const double* x, const CrackSurface& crack, JobSystem* jobs = nullptr);

  /// Positions, 3 floats per vertex.
  std::span<const float> positions() const { return m_positionsF; }
  /// Positions in double, 3 per vertex.
  std::span<const double> positionsDouble() const { return m_positions; }
  /// Unit normals, 3 floats per vertex.
  std::span<const float> normals() const { return m_normalsF; }
  /// Unit normals in double, 3 per vertex.
  std::span<const double> normalsDouble() const { return m_normals; }
  /// 2 per vertex when the render mesh has UVs (0, 0 on crack faces), else empty.
  std::span<const float> uvs() const { return m_uv; }
  /// Render triangles (cut pieces included) first, then the caps, then the faces of fragments
  /// drawn with their CrackSurface faces; 3 vertex indices each.
  std::span<const uint32_t> indices() const { return m_indices; }
  /// Per triangle: 1 for a crack face (caps included), 0 for a render-mesh triangle.
  std::span<const uint8_t> crackFlags() const { return m_triCrack; }
  /// Per triangle when the render mesh has materials: the source triangle's, kInteriorMaterial
  /// on crack faces; else empty.
  std::span<const uint16_t> materials() const { return m_triMaterial; }
  /// Per vertex: the node of its group with the largest weight (crack vertices: CrackSurface's).
  std::span<const int32_t> vertexNode() const { return m_vertexNode; }
  /// Per vertex: its fragment (every triangle's vertices share it).
  std::span<const int32_t> vertexFragment() const { return m_vertexFragment; }
  /// Vertices bound to the tets: render-vertex copies and cut points (they come first; then
  /// the caps' centres, then vertices taken from CrackSurface).
  uint32_t embeddedVertexCount() const { return uint32_t(m_vTet.size()); }
  /// Number of caps closing the cuts.
  uint32_t capCount() const { return uint32_t(m_capStart.size() - 1); }
  /// Cuts that run into a hole of an open render mesh: chains between two cut points on the
  /// hole's rim, each capped across the hole (those of one segment are left open).
  uint32_t openCutCount() const { return m_openCuts; }
  /// Per bound vertex: the render-mesh vertex it shows, or -1 for a cut point. After fracture,
  /// an index at or past the render mesh's vertex count is a point the refinement added (an
  /// edge midpoint, design note).
  std::span<const int32_t> vertexSource() const { return m_vSource; }
  /// Incremented whenever the triangles change.
  uint64_t topologyVersion() const { return m_topologyVersion; }

 private:
  uint32_t addCopy(int32_t source, int32_t tet, const double* w, unsigned group, int32_t fragment,
                   Vec3 rest, Vec3 restNormal, const float* uv);
  uint32_t homeCopy(uint32_t v);
  uint32_t pointCopy(Vec3 P, Vec3 N, const float* uv, uint32_t side);
  uint32_t cutCopy(uint32_t u, uint32_t v, uint32_t side);
  bool apart(uint32_t u, uint32_t v) const;
  unsigned joinedMask(int32_t t) const;
  unsigned drawnNodes(int32_t t) const;
  void compose(const CrackSurface& crack);
  void splitAtJunctions();
  bool nodeInside(int32_t node);
  void giveChipsToNeighbours(const int32_t* nodeFragment);
  void makeNodeTets();  // m_nodeTet, once
  /// The node of `fragment`, not a chip, joined by a graph edge to a node of the tet `n`
  /// (4 nodes), nearest to P at rest; -1 if none.
  int32_t nearestNode(const int32_t* n, int32_t fragment, Vec3 P) const;

  // The artist's mesh; after the first break, that mesh refined to about a corner cell (null
  // when no edge needed it); m_binding is the one the last rebuild() cut.
  const EmbeddedBinding* m_original = nullptr;
  std::unique_ptr<EmbeddedBinding> m_refined;
  bool m_refineChecked = false;
  double m_meanEdge = 0;  // the tets' mean edge length [m]
  const EmbeddedBinding* m_binding = nullptr;
  const TetMesh* m_rest = nullptr;
  const EdgeGraph* m_graph = nullptr;
  const Mat3* m_restInverse = nullptr;

  // Per render vertex, from rebuild(): its fragment, its group and its copy in that fragment.
  std::vector<int32_t> m_home, m_homeCopy, m_homeNode;
  std::vector<uint8_t> m_homeGroup;
  // Cut render edges (lower vertex << 32 | upper) -> the copies of the cut point on the lower
  // and the upper end's side.
  std::unordered_map<uint64_t, std::pair<uint32_t, uint32_t>> m_cut;
  // Rim segments (from, to copy): each piece's side along a cut, in the piece's orientation.
  std::vector<std::pair<uint32_t, uint32_t>> m_segments;
  std::vector<int32_t> m_outStart, m_out, m_nextOut, m_onPath, m_path,
      m_surplus;  // their walk, rebuild()
  // Caps: rim copies (CSR), in the order the cut runs for the fragment.
  std::vector<int32_t> m_capStart{0}, m_capRim;
  uint32_t m_openCuts = 0;
  // Fragments drawn with their CrackSurface faces (1 per fragment id), and per node whether it
  // is inside the render mesh at rest (-1: not asked yet).
  std::vector<uint8_t> m_crackDrawn;
  std::vector<int8_t> m_nodeInside;
  const int32_t* m_nodeFragment = nullptr;  // during rebuild()
  const uint8_t* m_broken = nullptr;        // during rebuild()
  std::vector<uint8_t> m_nodeCracked;       // per node: 1 when one of its edges is broken
  std::vector<uint8_t> m_wholeTet;  // per fragment: 1 when it holds a whole tet (not a chip)
  bool m_chipsByNeighbours = false;
  // Per node the fragment that draws it (a chip's: the neighbour it is given to) and whether it
  // is a chip given away; per edge whether it is a crack as drawn (not between a chip and the
  // fragment it is given to); a tet holding each node (made when first needed).
  std::vector<int32_t> m_drawLabel, m_nodeTet;
  std::vector<uint8_t> m_chipNode, m_drawBroken;
  const uint8_t* m_realBroken = nullptr;  // during rebuild(): the broken edges
  std::vector<uint8_t> m_frameMark;
  std::vector<int32_t> m_frameNodes;

  // Copies: the tet, weights and group mask that move them, and the render vertex they show.
  std::vector<int32_t> m_vTet, m_vSource;
  std::vector<uint8_t> m_vSeparated;  // 1 for a cut point between two fragments
  std::vector<int32_t> m_vJunction;   // a junction point's render triangle, else -1
  std::vector<int32_t> m_vAcross;     // a cut point's other fragment (between two), else -1
  std::vector<double> m_vWeight, m_vRest, m_vRestNormal;
  std::vector<float> m_vUv;
  std::vector<uint8_t> m_vGroup;
  std::vector<int32_t> m_vNode, m_vFragment;
  std::vector<uint32_t> m_renderIndices;
  std::vector<uint16_t> m_renderMaterial;  // per m_renderIndices triangle, when materials

  // The faces taken from CrackSurface: its vertex for each of ours after the caps' centres.
  std::vector<int32_t> m_crackFrom, m_crackMap;
  uint64_t m_crackVersion = ~uint64_t(0);
  bool m_composed = false;

  // Output.
  std::vector<double> m_positions, m_normals;
  std::vector<float> m_positionsF, m_normalsF, m_uv;
  std::vector<uint32_t> m_indices;
  std::vector<uint8_t> m_triCrack;
  std::vector<uint16_t> m_triMaterial;
  std::vector<int32_t> m_vertexNode, m_vertexFragment;
  uint64_t m_topologyVersion = 0;
};

}  // namespace gf::detail
