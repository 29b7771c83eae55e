// The render surface of an Is-XFEM body (issue 21 item 4): per piece, a closed triangle mesh
// made of the body's boundary faces as clipped into the piece's cells and of the exact cut
// polygons (the blade's section of each tet), moving with the enriched field of eq 3.4.
//
// Design: the topology is built once, when the body is made (the cells never change), and a frame
// only evaluates the field at the vertices (a short list of shape-function weights per vertex).
// Vertices are welded by what they are, never by where they round to: clipTet tags every polygon
// vertex with the planes it lies on (tet faces and cuts), which names it as a mesh node, a mesh
// edge and one cut, a mesh face and two cuts, or a tet and three cuts. One such point is one
// vertex per side of the field: two cells holding it share the vertex when the enriched field is
// continuous between them there, i.e. unless they lie on different sides of a cut whose enriched
// functions do not vanish at the point (some node of its smallest simplex is enriched for the
// cut). A cell face is emitted when the field can jump across it: a cut polygon always (its tet
// carries an enriched node, eq 3.4), a face on the body's boundary always, an interior tet face
// when the cells on its two sides differ in the side of a cut enriched on that face (a cut along
// a node layer). Each opened cut face so appears twice, once per side, with outward normals.
// A cut that does not open (a blade ending inside the body: its front tets have nodes without the
// enrichment) makes no hole: the cut polygons of every tet carrying the enrichment are emitted on
// both sides as a pocket inside the piece, whose two sides share their vertices where the jump
// vanishes (on the faces, edges and nodes of nodes without the enrichment, the pocket's rim), so
// the pocket opens exactly as the field does (fading to zero towards the front) and closes along
// the front; at rest its two sides coincide and add no volume. Where a tet without a cut meets
// one with it on a face or edge (the front again), the cut's vertices on the shared edge are also
// inserted into the uncut side's polygons (no T-junctions), which is where welding by name needs
// no tolerance either. Polygons of more than three vertices are fanned from their centroid.
#pragma once

#include <graphfrac/mesh.h>

#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "kernels/cut_polytope.h"

namespace gf::detail {

/// A vertex of a piece's surface.
struct XfemSurfaceVertex {
  Vec3 rest;  ///< Rest position.
  /// Mesh nodes spanning the smallest mesh simplex that holds the vertex (one: a node; two: an
  /// edge; three: a face; four: inside a tet), ascending, padded with -1; for a polygon's centre
  /// vertex, the simplex of its polygon.
  std::array<int32_t, 4> simplex{-1, -1, -1, -1};
  unsigned cuts = 0;   ///< Bit j: the vertex lies on cut j (planes first, then blades).
  unsigned sides = 0;  ///< Bit j: the field is that of the positive side of cut j (when carried).
};

/// One piece's closed surface.
struct XfemPieceSurface {
  std::vector<XfemSurfaceVertex> vertices;
  std::vector<int32_t> triangles;    ///< 3 vertex indices each, counter-clockwise from outside.
  std::vector<int32_t> triangleCut;  ///< Per triangle: the cut it lies on, -1 on the boundary.
  std::vector<Vec3> positions;       ///< Deformed positions (XfemBody::updateSurface).
  /// The field at vertex i is sum over w in [weightStart[i], weightStart[i+1]) of
  /// weightValue[w] times the displacement of shape function weightFunction[w] (eq 3.4).
  std::vector<int32_t> weightStart, weightFunction;
  std::vector<double> weightValue;
};

/// Collects a cut body's cells and builds its pieces' surfaces.
class XfemSurfaceBuilder {
 public:
  /// `enriched[node * cutCount + j]` is the enriched function of node for cut j, or -1.
  XfemSurfaceBuilder(const TetMesh& mesh, int32_t cutCount, const std::vector<int32_t>& enriched,
                     double k);
  /// Tet t's cuts (global ids, local planes); called once per tet before its cells, ascending.
  void beginTet(int32_t t, const int32_t* cuts, const CutPlane* planes, int count);
  /// A cell of the current tet: its local side mask, its polytope, and per polytope face the tet
  /// face it lies on (0..3) or -1 for a cut polygon inside the tet.
  void addCell(int32_t cell, unsigned sideMask, const CutPolytope& polytope, const int* onFace);
  /// Builds the surfaces; piece[cell] is each cell's piece.
  std::vector<XfemPieceSurface> build(const std::vector<int32_t>& piece, int32_t pieceCount);

 private:
  struct Key {
    std::array<int32_t, 4> nodes;  // ascending, -1 padded
    unsigned cuts;                 // empty for a node
    bool operator==(const Key& o) const { return nodes == o.nodes && cuts == o.cuts; }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const;
  };
  struct TetData {
    int32_t cutFirst = 0, cutCount = 0;  // into m_cutIds / m_planes
  };
  struct Polygon {
    int32_t cell = 0, face = -1, cut = -1;  // face: tet face it lies on; cut: -1 off the cuts
    int32_t first = 0, count = 0;           // into m_polygonKeys
  };
  struct CellData {
    int32_t tet = 0;
    unsigned sideMask = 0;  // local
    int32_t polygonFirst = 0, polygonCount = 0;
    int32_t keyFirst = 0, keyCount = 0;  // sorted unique keys, into m_cellKeys
  };
  int32_t keyOf(int32_t t, Vec3 x, unsigned on);
  int localCut(int32_t tet, int32_t cut) const;
  unsigned cutBits(int32_t tet) const;
  int nodesSide(int32_t tet, int j, const std::array<int32_t, 4>& nodes) const;
  bool jumps(int32_t a, int32_t b, const std::array<int32_t, 4>& nodes) const;

  const TetMesh& m_mesh;
  int32_t m_cutTotal;
  const std::vector<int32_t>& m_enriched;
  double m_k;
  std::vector<TetData> m_tets;
  std::vector<int32_t> m_cutIds;
  std::vector<CutPlane> m_planes;
  std::vector<CellData> m_cells;
  std::vector<Polygon> m_polygons;
  std::vector<int32_t> m_polygonKeys, m_cellKeys;
  std::vector<Key> m_keys;
  std::vector<Vec3> m_keyPosition;
  std::vector<unsigned> m_keyOnCuts;  // every cut a key was seen on (nodes included)
  std::unordered_map<Key, int32_t, KeyHash> m_keyIndex;
  int32_t m_currentTet = -1;
};

}  // namespace gf::detail
