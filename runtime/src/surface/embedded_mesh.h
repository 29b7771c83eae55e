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
// - Fracture. A vertex belongs to the corner cell of its tet's node with the largest weight
//   (with midpoint splits that cell is exactly {w_a = max_k w_k}, crack_surface.h) and so to
//   that node's fragment and to its group (the nodes of the tet joined to it over unbroken
//   edges). A vertex whose group is the whole tet moves as above; one in a partial group moves
//   like a partial CrackSurface vertex, through the group nodes' local maps, so it follows its
//   side of the crack and not the mean of both. A triangle goes whole to the fragment of most
//   of its vertices (ties: its first vertex's); a vertex of another fragment is duplicated for
//   it and follows the triangle's fragment: the nodes of its tet in that fragment, or, when
//   its tet has none, the tet of a vertex of the triangle that is in that fragment, by
//   extrapolated barycentric coordinates. Triangles are not cut along the crack.
// - Closing. The crack faces of the body's CrackSurface (the inner quads of unjoined edges) are
//   appended as they are. They end at the tet boundary, not at the render mesh, so a fragment
//   that has render triangles is not watertight at the crack's rim: the render triangles' open
//   edges and the crack faces' open edges do not meet (tests/physics/test_render_mesh.cpp
//   measures how many fragments are closed). Fragments made only of crack faces are closed.
// - Cost: nothing until World::surface asks; then O(render vertices) per rendered frame plus the
//   tet surface's own update (its crack faces are borrowed). rebuild() runs once per fracture.
#pragma once

#include <cstdint>
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
  std::vector<int32_t> tet;        ///< per vertex: the tet it is bound to
  std::vector<double> weight;      ///< 4 per vertex: its barycentric coordinates there
  int32_t outsideCount = 0;        ///< vertices outside every tet
  double maxOutside = 0;           ///< the largest distance of such a vertex to its tet [m]

  /// Binds `mesh` (RenderMesh::check passed) to the validated mesh `rest`. Error naming `field`
  /// ("BodyDef.renderMesh") for a vertex farther than twice the longest tet edge from every tet.
  static Result<EmbeddedBinding> bind(const TetMesh& rest, const RenderMesh& mesh,
                                      const std::string& field);
};

/// The drawn surface of a body with a render mesh: its triangles deformed with the tets, split
/// by fragment, plus the crack faces of the body's CrackSurface.
class EmbeddedSurface {
 public:
  /// All four must outlive this object. `restInverse` is Dm^-1 per tet of `rest`.
  void init(const EmbeddedBinding& binding, const TetMesh& rest, const EdgeGraph& graph,
            const Mat3* restInverse);
  /// Recomputes the vertex copies and the render triangles' fragments from the broken flags
  /// (1 per edge) and node fragments. Then frameNodes() lists the nodes whose local maps the
  /// copies need: hand them to CrackSurface::setExtraFrameNodes before its rebuild().
  void rebuild(const uint8_t* broken, const int32_t* nodeFragment);
  /// Nodes whose local maps the last rebuild() needs.
  std::span<const int32_t> frameNodes() const { return m_frameNodes; }
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
  /// Render triangles first, then the crack faces; 3 vertex indices each.
  std::span<const uint32_t> indices() const { return m_indices; }
  /// Per triangle: 1 for a crack face, 0 for a render-mesh triangle.
  std::span<const uint8_t> crackFlags() const { return m_triCrack; }
  /// Per vertex: the node of its group with the largest weight (crack vertices: CrackSurface's).
  std::span<const int32_t> vertexNode() const { return m_vertexNode; }
  /// Per vertex: its fragment (every triangle's vertices share it).
  std::span<const int32_t> vertexFragment() const { return m_vertexFragment; }
  /// Vertices that are render-mesh copies (they come first; the rest are crack vertices).
  uint32_t embeddedVertexCount() const { return uint32_t(m_vTet.size()); }
  /// Per render-mesh copy: the render-mesh vertex it shows.
  std::span<const int32_t> vertexSource() const { return m_vSource; }
  /// Incremented whenever the triangles change.
  uint64_t topologyVersion() const { return m_topologyVersion; }

 private:
  uint32_t addCopy(int32_t source, int32_t tet, const double* w, unsigned group, int32_t fragment);
  void compose(const CrackSurface& crack);

  const EmbeddedBinding* m_binding = nullptr;
  const TetMesh* m_rest = nullptr;
  const EdgeGraph* m_graph = nullptr;
  const Mat3* m_restInverse = nullptr;

  // Per render vertex, from rebuild(): its fragment, its group and its copy in that fragment.
  std::vector<int32_t> m_home, m_homeCopy;
  std::vector<uint8_t> m_homeGroup;
  std::unordered_map<uint64_t, uint32_t> m_otherCopy;  // (vertex, fragment) -> copy
  std::vector<uint8_t> m_frameMark;
  std::vector<int32_t> m_frameNodes;

  // Copies: the tet, weights and group mask that move them, and the render vertex they show.
  std::vector<int32_t> m_vTet, m_vSource;
  std::vector<double> m_vWeight;
  std::vector<uint8_t> m_vGroup;
  std::vector<int32_t> m_vNode, m_vFragment;
  std::vector<uint32_t> m_renderIndices;

  // The crack faces taken from CrackSurface: its vertex for each of ours after the copies.
  std::vector<int32_t> m_crackFrom, m_crackMap;
  uint64_t m_crackVersion = ~uint64_t(0);
  bool m_composed = false;

  // Output.
  std::vector<double> m_positions, m_normals;
  std::vector<float> m_positionsF, m_normalsF, m_uv;
  std::vector<uint32_t> m_indices;
  std::vector<uint8_t> m_triCrack;
  std::vector<int32_t> m_vertexNode, m_vertexFragment;
  uint64_t m_topologyVersion = 0;
};

}  // namespace gf::detail
