#include "xfem/cut_surface.h"

#include <algorithm>
#include <map>

#include "kernels/element.h"
#include "kernels/xfem_enrichment.h"
#include "xfem/union_find.h"

namespace gf::detail {

namespace {

Vec3 meshNode(const TetMesh& mesh, int32_t n) {
  return {mesh.positions[3 * size_t(n)], mesh.positions[3 * size_t(n) + 1],
          mesh.positions[3 * size_t(n) + 2]};
}

// Point p inside the convex polygon (in its plane), for matching polygons whose vertices differ.
bool convexContains(const std::vector<Vec3>& g, Vec3 p) {
  Vec3 n;
  for (size_t i = 1; i + 1 < g.size(); ++i) n += cross(g[i] - g[0], g[i + 1] - g[0]);
  for (size_t i = 0; i < g.size(); ++i) {
    const Vec3 e = g[(i + 1) % g.size()] - g[i];
    if (dot(cross(e, p - g[i]), n) < -1e-9 * dot(e, e) * norm(n)) return false;
  }
  return true;
}

}  // namespace

size_t XfemSurfaceBuilder::KeyHash::operator()(const Key& k) const {
  size_t h = k.cuts;
  for (int32_t n : k.nodes) h = h * 1000003u ^ size_t(uint32_t(n));
  return h;
}

XfemSurfaceBuilder::XfemSurfaceBuilder(const TetMesh& mesh, int32_t cutCount,
                                       const std::vector<int32_t>& enriched, double k)
    : m_mesh(mesh), m_cutTotal(cutCount), m_enriched(enriched), m_k(k) {
  m_tets.resize(mesh.tetCount());
}

void XfemSurfaceBuilder::beginTet(int32_t t, const int32_t* cuts, const CutPlane* planes,
                                  int count) {
  m_currentTet = t;
  m_tets[size_t(t)].cutFirst = int32_t(m_cutIds.size());
  m_tets[size_t(t)].cutCount = count;
  for (int j = 0; j < count; ++j) {
    m_cutIds.push_back(cuts[j]);
    m_planes.push_back(planes[j]);
  }
}

int32_t XfemSurfaceBuilder::keyOf(int32_t t, Vec3 x, unsigned on) {
  const TetData& td = m_tets[size_t(t)];
  Key key{{-1, -1, -1, -1}, 0};
  int n = 0;
  for (int a = 0; a < 4; ++a)
    if (!((on >> a) & 1u)) key.nodes[size_t(n++)] = m_mesh.tets[4 * size_t(t) + size_t(a)];
  for (int i = 1; i < n; ++i)  // ascending (std::sort on a prefix trips -Warray-bounds)
    for (int j = i; j > 0 && key.nodes[size_t(j)] < key.nodes[size_t(j - 1)]; --j)
      std::swap(key.nodes[size_t(j)], key.nodes[size_t(j - 1)]);
  unsigned cuts = 0;
  for (int j = 0; j < td.cutCount; ++j)
    if ((on >> (kCutFaceLabel + j)) & 1u) cuts |= 1u << m_cutIds[size_t(td.cutFirst + j)];
  // A node is a node, whatever cut passes through it.
  key.cuts = n == 1 ? 0u : cuts;
  const auto [it, added] = m_keyIndex.emplace(key, int32_t(m_keys.size()));
  if (added) {
    m_keys.push_back(key);
    m_keyPosition.push_back(n == 1 ? meshNode(m_mesh, key.nodes[0]) : x);
    m_keyOnCuts.push_back(0);
  }
  m_keyOnCuts[size_t(it->second)] |= cuts;
  return it->second;
}

void XfemSurfaceBuilder::addCell(int32_t cell, unsigned sideMask, const CutPolytope& polytope,
                                 const int* onFace) {
  if (m_cells.size() <= size_t(cell)) m_cells.resize(size_t(cell) + 1);
  CellData& c = m_cells[size_t(cell)];
  const int32_t t = m_currentTet;
  c.tet = t;
  c.sideMask = sideMask;
  c.polygonFirst = int32_t(m_polygons.size());
  std::vector<int32_t> keys;
  for (int f = 0; f < polytope.faceCount; ++f) {
    const CutPolygon& g = polytope.faces[f];
    Polygon p;
    p.cell = cell;
    p.face = onFace[f];
    p.cut = g.label >= kCutFaceLabel
                ? m_cutIds[size_t(m_tets[size_t(t)].cutFirst + g.label - kCutFaceLabel)]
                : -1;
    p.first = int32_t(m_polygonKeys.size());
    for (int i = 0; i < g.count; ++i) {
      const int32_t k = keyOf(t, g.v[i], g.on[i]);
      if (p.count > 0 && m_polygonKeys.back() == k) continue;
      m_polygonKeys.push_back(k);
      ++p.count;
    }
    while (p.count > 1 && m_polygonKeys.back() == m_polygonKeys[size_t(p.first)]) {
      m_polygonKeys.pop_back();
      --p.count;
    }
    if (p.count < 3) {
      m_polygonKeys.resize(size_t(p.first));
      continue;
    }
    keys.insert(keys.end(), m_polygonKeys.begin() + p.first, m_polygonKeys.end());
    m_polygons.push_back(p);
  }
  c.polygonCount = int32_t(m_polygons.size()) - c.polygonFirst;
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  c.keyFirst = int32_t(m_cellKeys.size());
  c.keyCount = int32_t(keys.size());
  m_cellKeys.insert(m_cellKeys.end(), keys.begin(), keys.end());
}

int XfemSurfaceBuilder::localCut(int32_t tet, int32_t cut) const {
  const TetData& td = m_tets[size_t(tet)];
  for (int j = 0; j < td.cutCount; ++j)
    if (m_cutIds[size_t(td.cutFirst + j)] == cut) return j;
  return -1;
}

unsigned XfemSurfaceBuilder::cutBits(int32_t tet) const {
  const TetData& td = m_tets[size_t(tet)];
  unsigned bits = 0;
  for (int j = 0; j < td.cutCount; ++j) bits |= 1u << m_cutIds[size_t(td.cutFirst + j)];
  return bits;
}

// The common side (eq 3.2's H) of these nodes of tet `tet` against its local cut j, or -1.
int XfemSurfaceBuilder::nodesSide(int32_t tet, int j, const std::array<int32_t, 4>& nodes) const {
  const CutPlane& plane = m_planes[size_t(m_tets[size_t(tet)].cutFirst + j)];
  int side = -1;
  for (int32_t n : nodes) {
    if (n < 0) continue;
    const int h = int(xfemHeaviside(planeDistance(plane, meshNode(m_mesh, n))));
    if (side >= 0 && h != side) return -1;
    side = h;
  }
  return side;
}

// Whether the field of cells a and b can differ on the simplex of `nodes` (a face or a point's
// simplex, shared by both): psi_i^j N_i (eq 3.7) differs between the two by
// (H_a - H_b) N_i for every node i enriched for cut j, so the field jumps exactly when the
// cells are on different sides of a cut with an enriched node on the simplex. A tet without cut
// j is on the side of the simplex's nodes (its cell's eq 3.2 value is that side).
bool XfemSurfaceBuilder::jumps(int32_t a, int32_t b, const std::array<int32_t, 4>& nodes) const {
  const CellData &ca = m_cells[size_t(a)], &cb = m_cells[size_t(b)];
  unsigned cuts = cutBits(ca.tet) | cutBits(cb.tet);
  while (cuts) {
    const int32_t c = __builtin_ctz(cuts);
    cuts &= cuts - 1;
    bool enriched = false;
    for (int32_t n : nodes)
      enriched =
          enriched || (n >= 0 && m_enriched[size_t(n) * size_t(m_cutTotal) + size_t(c)] >= 0);
    if (!enriched) continue;
    const int ja = localCut(ca.tet, c), jb = localCut(cb.tet, c);
    const int sa = ja >= 0 ? int((ca.sideMask >> ja) & 1u) : nodesSide(cb.tet, jb, nodes);
    const int sb = jb >= 0 ? int((cb.sideMask >> jb) & 1u) : nodesSide(ca.tet, ja, nodes);
    if (sa >= 0 && sb >= 0 && sa != sb) return true;
  }
  return false;
}

std::vector<XfemPieceSurface> XfemSurfaceBuilder::build(const std::vector<int32_t>& piece,
                                                        int32_t pieceCount) {
  const int32_t tets = int32_t(m_mesh.tetCount());
  const int32_t cells = int32_t(m_cells.size());
  // Polygons on each tet face, and each face's neighbour across it.
  std::vector<std::vector<int32_t>> onFace(4 * size_t(tets));
  for (int32_t p = 0; p < int32_t(m_polygons.size()); ++p)
    if (m_polygons[size_t(p)].face >= 0)
      onFace[4 * size_t(m_cells[size_t(m_polygons[size_t(p)].cell)].tet) +
             size_t(m_polygons[size_t(p)].face)]
          .push_back(p);
  std::vector<int32_t> neighbour(4 * size_t(tets), -1);  // 4 u + b
  {
    std::map<std::array<int32_t, 3>, int32_t> open;
    for (int32_t t = 0; t < tets; ++t)
      for (int a = 0; a < 4; ++a) {
        std::array<int32_t, 3> f;
        for (int k = 0, i = 0; k < 4; ++k)
          if (k != a) f[size_t(i++)] = m_mesh.tets[4 * size_t(t) + size_t(k)];
        std::sort(f.begin(), f.end());
        const auto it = open.find(f);
        if (it == open.end()) {
          open.emplace(f, 4 * t + a);
        } else {
          neighbour[size_t(4 * t + a)] = it->second;
          neighbour[size_t(it->second)] = 4 * t + a;
          open.erase(it);
        }
      }
  }
  const auto faceNodes = [&](int32_t t, int a) {
    std::array<int32_t, 4> f{-1, -1, -1, -1};
    for (int k = 0, i = 0; k < 4; ++k)
      if (k != a) f[size_t(i++)] = m_mesh.tets[4 * size_t(t) + size_t(k)];
    return f;
  };
  const auto sortedKeys = [&](const Polygon& p) {
    std::vector<int32_t> k(m_polygonKeys.begin() + p.first,
                           m_polygonKeys.begin() + p.first + p.count);
    std::sort(k.begin(), k.end());
    return k;
  };
  const auto occurrence = [&](int32_t cell, int32_t key) {
    const CellData& c = m_cells[size_t(cell)];
    const auto begin = m_cellKeys.begin() + c.keyFirst, end = begin + c.keyCount;
    const auto it = std::lower_bound(begin, end, key);
    return it != end && *it == key ? int32_t(it - m_cellKeys.begin()) : -1;
  };

  // Which polygons bound their piece (see the design note).
  std::vector<uint8_t> emit(m_polygons.size(), 0);
  for (size_t p = 0; p < m_polygons.size(); ++p) {
    const Polygon& g = m_polygons[p];
    const int32_t t = m_cells[size_t(g.cell)].tet;
    const int32_t across = g.face >= 0 ? neighbour[4 * size_t(t) + size_t(g.face)] : -1;
    if (g.face < 0 || across < 0) {
      emit[p] = 1;
      continue;
    }
    const std::vector<int32_t> mine = sortedKeys(g);
    int32_t other = -1;
    for (int32_t q : onFace[size_t(across)])
      if (sortedKeys(m_polygons[size_t(q)]) == mine) other = q;
    if (other < 0) {
      // Subdivided differently (a cut carried on one side only): the cell across that holds
      // this polygon's centre.
      Vec3 centre;
      for (int32_t k : mine) centre += m_keyPosition[size_t(k)];
      centre = (1.0 / double(mine.size())) * centre;
      for (int32_t q : onFace[size_t(across)]) {
        const Polygon& h = m_polygons[size_t(q)];
        std::vector<Vec3> ring;
        for (int i = 0; i < h.count; ++i)
          ring.push_back(m_keyPosition[size_t(m_polygonKeys[size_t(h.first + i)])]);
        if (convexContains(ring, centre)) other = q;
      }
    }
    emit[p] = other >= 0 && jumps(g.cell, m_polygons[size_t(other)].cell, faceNodes(t, g.face));
  }

  // Vertices: a point per side of the field. Occurrences (cell, key) are joined where two cells
  // of one piece that both hold the point see the same field there.
  std::vector<int32_t> parent(m_cellKeys.size());
  for (size_t i = 0; i < parent.size(); ++i) parent[i] = int32_t(i);
  const auto join = [&](int32_t a, int32_t b, int32_t key) {
    if (piece[size_t(a)] != piece[size_t(b)] || jumps(a, b, m_keys[size_t(key)].nodes)) return;
    unite(parent, occurrence(a, key), occurrence(b, key));
  };
  for (int32_t a = 0; a < cells; ++a)
    for (int32_t b = a + 1; b < cells && m_cells[size_t(b)].tet == m_cells[size_t(a)].tet; ++b)
      for (int32_t i = 0; i < m_cells[size_t(a)].keyCount; ++i) {
        const int32_t key = m_cellKeys[size_t(m_cells[size_t(a)].keyFirst + i)];
        if (occurrence(b, key) >= 0) join(a, b, key);
      }
  for (int32_t f = 0; f < 4 * tets; ++f) {
    const int32_t g = neighbour[size_t(f)];
    if (g < f) continue;
    for (int32_t p : onFace[size_t(f)])
      for (int32_t q : onFace[size_t(g)]) {
        const Polygon &P = m_polygons[size_t(p)], &Q = m_polygons[size_t(q)];
        for (int i = 0; i < P.count; ++i)
          for (int j = 0; j < Q.count; ++j)
            if (m_polygonKeys[size_t(P.first + i)] == m_polygonKeys[size_t(Q.first + j)])
              join(P.cell, Q.cell, m_polygonKeys[size_t(P.first + i)]);
      }
  }

  std::vector<XfemPieceSurface> out(static_cast<size_t>(pieceCount));
  for (XfemPieceSurface& s : out) s.weightStart.push_back(0);
  // The field at rest point x of cell c (eq 3.4): its shape functions' values, by function.
  const auto addVertex = [&](XfemPieceSurface& s, int32_t cell, Vec3 x,
                             const std::array<int32_t, 4>& simplex, unsigned cuts) {
    const CellData& c = m_cells[size_t(cell)];
    const TetData& td = m_tets[size_t(c.tet)];
    Vec3 X[4];
    for (int a = 0; a < 4; ++a) X[a] = meshNode(m_mesh, m_mesh.tets[4 * size_t(c.tet) + size_t(a)]);
    double volume = 0;
    const Mat<4, 3> B = shapeGradients(restShapeInverse(X, volume));
    CutElementSides sides;
    sides.cutCount = td.cutCount;
    for (int j = 0; j < td.cutCount; ++j)
      for (int a = 0; a < 4; ++a)
        sides.side[j][a] = xfemHeaviside(planeDistance(m_planes[size_t(td.cutFirst + j)], X[a]));
    double value[4 * (1 + kMaxCutPlanes)];
    Vec3 gradient[4 * (1 + kMaxCutPlanes)];
    enrichedShapeFunctions(X[0], B, sides, c.sideMask, m_k, x, value, gradient);
    XfemSurfaceVertex v;
    v.rest = x;
    v.simplex = simplex;
    v.cuts = cuts;
    for (int j = 0; j < td.cutCount; ++j)
      if ((c.sideMask >> j) & 1u) v.sides |= 1u << m_cutIds[size_t(td.cutFirst + j)];
    for (int A = 0; A < 4 * (1 + td.cutCount); ++A) {
      const int32_t node = m_mesh.tets[4 * size_t(c.tet) + size_t(A % 4)];
      const int32_t f = A < 4 ? node
                              : m_enriched[size_t(node) * size_t(m_cutTotal) +
                                           size_t(m_cutIds[size_t(td.cutFirst + A / 4 - 1)])];
      if (f < 0 || value[A] == 0) continue;
      s.weightFunction.push_back(f);
      s.weightValue.push_back(value[A]);
    }
    s.weightStart.push_back(int32_t(s.weightFunction.size()));
    s.vertices.push_back(v);
    return int32_t(s.vertices.size()) - 1;
  };

  std::vector<int32_t> vertexOf(m_cellKeys.size(), -1);  // root occurrence -> vertex
  std::vector<std::vector<std::vector<int32_t>>> polygonsOf(static_cast<size_t>(pieceCount));
  std::vector<std::vector<int32_t>> polygonIds(static_cast<size_t>(pieceCount));
  std::vector<std::vector<int32_t>> keyOfVertex(static_cast<size_t>(pieceCount));
  for (size_t p = 0; p < m_polygons.size(); ++p) {
    if (!emit[p]) continue;
    const Polygon& g = m_polygons[p];
    const int32_t pc = piece[size_t(g.cell)];
    XfemPieceSurface& s = out[size_t(pc)];
    std::vector<int32_t> ring;
    for (int i = 0; i < g.count; ++i) {
      const int32_t key = m_polygonKeys[size_t(g.first + i)];
      const int32_t root = findRoot(parent, occurrence(g.cell, key));
      if (vertexOf[size_t(root)] < 0) {
        vertexOf[size_t(root)] = addVertex(s, g.cell, m_keyPosition[size_t(key)],
                                           m_keys[size_t(key)].nodes, m_keyOnCuts[size_t(key)]);
        keyOfVertex[size_t(pc)].push_back(key);
      }
      ring.push_back(vertexOf[size_t(root)]);
    }
    polygonsOf[size_t(pc)].push_back(std::move(ring));
    polygonIds[size_t(pc)].push_back(int32_t(p));
  }

  for (int32_t pc = 0; pc < pieceCount; ++pc) {
    XfemPieceSurface& s = out[size_t(pc)];
    const std::vector<int32_t>& keys = keyOfVertex[size_t(pc)];
    // Vertices by their simplex, and how many sides each point has in this piece.
    std::map<std::array<int32_t, 4>, std::vector<int32_t>> bySimplex;
    std::map<int32_t, int> copies;
    for (int32_t v = 0; v < int32_t(keys.size()); ++v) {
      bySimplex[s.vertices[size_t(v)].simplex].push_back(v);
      ++copies[keys[size_t(v)]];
    }
    for (size_t k = 0; k < polygonsOf[size_t(pc)].size(); ++k) {
      const std::vector<int32_t>& ring = polygonsOf[size_t(pc)][k];
      const Polygon& g = m_polygons[size_t(polygonIds[size_t(pc)][k])];
      // A vertex of a neighbouring polygon on this polygon's edge (a cut carried on the other
      // side only): inserted, so the edge is shared whole (no T-junction).
      std::vector<int32_t> full;
      bool inserted = false;
      for (size_t i = 0; i < ring.size(); ++i) {
        const int32_t u = ring[i], w = ring[(i + 1) % ring.size()];
        full.push_back(u);
        std::array<int32_t, 8> both;
        std::copy(s.vertices[size_t(u)].simplex.begin(), s.vertices[size_t(u)].simplex.end(),
                  both.begin());
        std::copy(s.vertices[size_t(w)].simplex.begin(), s.vertices[size_t(w)].simplex.end(),
                  both.begin() + 4);
        std::sort(both.begin(), both.end());
        const auto last = std::unique(both.begin(), both.end());
        std::array<int32_t, 4> line{-1, -1, -1, -1};
        int n = 0;
        for (auto it = both.begin(); it != last; ++it)
          if (*it >= 0 && n < 5) {
            if (n < 4) line[size_t(n)] = *it;
            ++n;
          }
        if (n > 4) continue;
        const auto found = bySimplex.find(line);
        if (found == bySimplex.end()) continue;
        const unsigned common = s.vertices[size_t(u)].cuts & s.vertices[size_t(w)].cuts;
        const Vec3 a = s.vertices[size_t(u)].rest, d = s.vertices[size_t(w)].rest - a;
        std::vector<std::pair<double, int32_t>> between;
        for (int32_t c : found->second) {
          if (c == u || c == w || (s.vertices[size_t(c)].cuts & common) != common ||
              s.vertices[size_t(c)].cuts == common || copies[keys[size_t(c)]] != 1)
            continue;
          const double t = dot(s.vertices[size_t(c)].rest - a, d) / dot(d, d);
          if (t > 0 && t < 1) between.emplace_back(t, c);
        }
        std::sort(between.begin(), between.end());
        for (const auto& [t, c] : between) full.push_back(c);
        inserted = inserted || !between.empty();
      }
      if (full.size() == 3 && !inserted) {
        s.triangles.insert(s.triangles.end(), full.begin(), full.end());
        s.triangleCut.push_back(g.cut);
        continue;
      }
      Vec3 centre;
      for (int32_t v : full) centre += s.vertices[size_t(v)].rest;
      centre = (1.0 / double(full.size())) * centre;
      std::array<int32_t, 4> simplex{-1, -1, -1, -1};
      const int32_t t = m_cells[size_t(g.cell)].tet;
      for (int a = 0, i = 0; a < 4; ++a)
        if (a != g.face) simplex[size_t(i++)] = m_mesh.tets[4 * size_t(t) + size_t(a)];
      std::sort(simplex.begin(), simplex.begin() + (g.face >= 0 ? 3 : 4));
      const int32_t c = addVertex(s, g.cell, centre, simplex, g.cut >= 0 ? 1u << g.cut : 0u);
      for (size_t i = 0; i < full.size(); ++i) {
        s.triangles.insert(s.triangles.end(), {c, full[i], full[(i + 1) % full.size()]});
        s.triangleCut.push_back(g.cut);
      }
    }
    s.positions.resize(s.vertices.size());
    for (size_t v = 0; v < s.vertices.size(); ++v) s.positions[v] = s.vertices[v].rest;
  }
  return out;
}

}  // namespace gf::detail
