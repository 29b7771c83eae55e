#include "xfem/cut_body.h"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <string>

#include "kernels/xfem_enrichment.h"
#include "xfem/cut_surface.h"
#include "xfem/union_find.h"

namespace gf::detail {

namespace {

Vec3 nodePosition(const TetMesh& mesh, int32_t n) {
  return {mesh.positions[3 * size_t(n)], mesh.positions[3 * size_t(n) + 1],
          mesh.positions[3 * size_t(n) + 2]};
}

// One cut through one tet: its local plane, and whether the cut crosses the tet fully.
struct TetCut {
  int32_t cut = 0;
  CutPlane plane;
  bool full = true;
};

// Point p in the convex polygon g (in g's plane), up to tol times each edge's length outside it.
bool polygonContains(const CutPolygon& g, Vec3 p, double tol) {
  Vec3 n;
  for (int i = 1; i + 1 < g.count; ++i) n += cross(g.v[i] - g.v[0], g.v[i + 1] - g.v[0]);
  for (int i = 0; i < g.count; ++i) {
    const Vec3 e = g.v[(i + 1) % g.count] - g.v[i];
    if (dot(cross(e, p - g.v[i]), n) < -tol * dot(e, e) * norm(n)) return false;
  }
  return true;
}

Vec3 polygonCentre(const CutPolygon& g) {
  Vec3 c;
  for (int i = 0; i < g.count; ++i) c += g.v[i];
  return (1.0 / g.count) * c;
}

// Two cells' polygons on a shared tet face overlap (with area): one's centre lies in the other.
bool polygonsOverlap(const CutPolygon& a, const CutPolygon& b) {
  return polygonContains(b, polygonCentre(a), 1e-9) || polygonContains(a, polygonCentre(b), 1e-9);
}

// The face of tet X (0..3, opposite that node) a polygon lies in, to `tol`; -1 if none.
int tetFaceHolding(const Vec3 X[4], const CutPolygon& g, double tol) {
  for (int a = 0; a < 4; ++a) {
    const Vec3 p = X[(a + 1) % 4], q = X[(a + 2) % 4], r = X[(a + 3) % 4];
    Vec3 n = cross(q - p, r - p);
    n = (1.0 / norm(n)) * n;
    bool on = true;
    for (int i = 0; i < g.count && on; ++i) on = std::abs(dot(n, g.v[i] - p)) <= tol;
    if (on) return a;
  }
  return -1;
}

// Side of x against a cut that does not cross its tet: the plane's, or for a blade (its cut
// surface, bladeSurface) the sign of eq 3.1 to its nearest triangle.
bool positiveSide(const XfemBodyDef& def, const std::vector<Blade>& surfaces, int32_t cut, Vec3 x) {
  const int32_t planes = int32_t(def.planes.size());
  if (cut < planes) return planeDistance(def.planes[size_t(cut)], x) >= 0;
  const Blade& b = surfaces[size_t(cut - planes)];
  double best = INFINITY, sign = 1;
  for (size_t t = 0; 3 * t < b.triangles.size(); ++t) {
    Vec3 p[3];
    for (int k = 0; k < 3; ++k) {
      const size_t i = size_t(b.triangles[3 * t + size_t(k)]);
      p[k] = {b.vertices[3 * i], b.vertices[3 * i + 1], b.vertices[3 * i + 2]};
    }
    if (norm(cross(p[1] - p[0], p[2] - p[0])) == 0) continue;
    const double d = signedDistanceToTriangle(x, p[0], p[1], p[2]);  // eq 3.1
    if (std::abs(d) < best) best = std::abs(d), sign = d;
  }
  return sign >= 0;
}

}  // namespace

Result<std::unique_ptr<XfemBody>> XfemBody::create(const XfemBodyDef& def) {
  const TetMesh& mesh = def.mesh;
  const int32_t nodes = int32_t(mesh.nodeCount()), tets = int32_t(mesh.tetCount());
  const int32_t planeCount = int32_t(def.planes.size());
  const int32_t cutCount = planeCount + int32_t(def.blades.size());
  if (tets == 0) return fail("XfemBody: mesh: no tets");
  if (cutCount > 32)
    return fail("XfemBody: planes and blades: ", std::to_string(cutCount), " > 32");
  for (int32_t j = 0; j < planeCount; ++j)
    if (std::abs(norm(def.planes[size_t(j)].normal) - 1.0) > 1e-12)
      return fail("XfemBody: planes[", std::to_string(j), "]: normal is not a unit vector");
  if (!(def.constraint.minRatio >= 0 && def.constraint.minRatio < 1))
    return fail("XfemBody: constraint.minRatio: ", std::to_string(def.constraint.minRatio),
                " is not in [0, 1)");
  if (!(def.constraint.relative >= 0 && std::isfinite(def.constraint.relative)))
    return fail("XfemBody: constraint.relative: ", std::to_string(def.constraint.relative),
                " is not finite and >= 0");
  for (int32_t n : def.fixedNodes)
    if (n < 0 || n >= nodes)
      return fail("XfemBody: fixedNodes: node ", std::to_string(n), " out of range");

  std::unique_ptr<XfemBody> body(new XfemBody());
  XfemBody& b = *body;
  b.m_def = def;
  b.m_cutReports.assign(size_t(cutCount), {});

  // Every cut's crossings per tet. Node sides against a plane as for blades (blade_path.h): a
  // node within its snap distance counts as on the plane, and on it as positive. A plane cuts a
  // tet when its nodes have both sides (a tet whose only positive nodes are on the plane is cut
  // with an empty positive cell, so those nodes' enriched functions stay conforming; one with
  // no negative node is whole, on the positive side) and always crosses it fully. In the tet,
  // the plane is lowered onto a positive node that rounding leaves just below it. A blade's
  // crossings come from its path.
  std::vector<std::vector<TetCut>> crossings(static_cast<size_t>(tets));
  std::vector<Vec3> X(4 * static_cast<size_t>(tets));
  const std::vector<double> snap = nodeSnapDistances(mesh);
  for (int32_t t = 0; t < tets; ++t) {
    for (int a = 0; a < 4; ++a)
      X[4 * size_t(t) + a] = nodePosition(mesh, mesh.tets[4 * size_t(t) + a]);
    for (int32_t j = 0; j < planeCount; ++j) {
      CutPlane local = def.planes[size_t(j)];
      bool pos = false, neg = false;
      for (int a = 0; a < 4; ++a) {
        const Vec3 x = X[4 * size_t(t) + a];
        const double d = planeDistance(def.planes[size_t(j)], x);
        if (d >= -snap[size_t(mesh.tets[4 * size_t(t) + a])]) {
          pos = true;
          if (d < 0) local.offset = std::min(local.offset, dot(local.normal, x));
        } else {
          neg = true;
        }
      }
      // Lowering the plane must not lift a negative node onto it (two nodes of one tet within
      // rounding of the plane on opposite sides: their sides are not decidable).
      for (int a = 0; a < 4 && pos && neg; ++a) {
        const Vec3 x = X[4 * size_t(t) + a];
        const bool wasNegative =
            planeDistance(def.planes[size_t(j)], x) < -snap[size_t(mesh.tets[4 * size_t(t) + a])];
        if (wasNegative && planeDistance(local, x) >= 0)
          return fail("XfemBody: planes[", std::to_string(j), "]: tet ", std::to_string(t),
                      " has nodes on both sides within rounding of the plane");
      }
      if (pos && neg) {
        crossings[size_t(t)].push_back({j, local, true});
        ++b.m_cutReports[size_t(j)].fullTets;
      }
    }
  }
  std::vector<Blade> bladeSurfaces;
  for (size_t k = 0; k < def.blades.size(); ++k) {
    const int32_t j = planeCount + int32_t(k);
    auto surface = bladeSurface(def.blades[k]);
    if (!surface.ok())
      return fail("XfemBody: blades[", std::to_string(k), "]: ", surface.error().message);
    bladeSurfaces.push_back(std::move(surface.value()));
    auto path = traceBlade(mesh, def.blades[k]);
    if (!path.ok())
      return fail("XfemBody: blades[", std::to_string(k), "]: ", path.error().message);
    XfemCutReport& r = b.m_cutReports[size_t(j)];
    r.fullTets = path.value().fullCount;
    r.partialTets = path.value().partialCount;
    r.maxDeviation = path.value().maxDeviation;
    for (const BladeTetCrossing& c : path.value().crossings)
      crossings[size_t(c.tet)].push_back({j, c.plane, c.full});
  }

  // Eq 3.4, restricted where a blade ends: node i gets an enriched function for cut j when
  // cut j crosses some tet around i fully and none partially (see the design note).
  std::vector<uint8_t> nodeFull(size_t(nodes) * size_t(cutCount), 0);
  std::vector<uint8_t> nodePartial(size_t(nodes) * size_t(cutCount), 0);
  for (int32_t t = 0; t < tets; ++t)
    for (const TetCut& c : crossings[size_t(t)])
      for (int a = 0; a < 4; ++a) {
        const size_t i = size_t(mesh.tets[4 * size_t(t) + a]) * size_t(cutCount) + size_t(c.cut);
        (c.full ? nodeFull : nodePartial)[i] = 1;
      }
  const auto enrichable = [&](int32_t node, int32_t cut) {
    const size_t i = size_t(node) * size_t(cutCount) + size_t(cut);
    return nodeFull[i] && !nodePartial[i];
  };
  // The cuts each tet carries: fully crossed, with at least one enriched node.
  std::vector<std::vector<TetCut>> tetCuts(static_cast<size_t>(tets));
  for (int32_t t = 0; t < tets; ++t) {
    for (const TetCut& c : crossings[size_t(t)]) {
      if (!c.full) continue;
      bool any = false;
      for (int a = 0; a < 4; ++a) any = any || enrichable(mesh.tets[4 * size_t(t) + a], c.cut);
      if (any) tetCuts[size_t(t)].push_back(c);
    }
    // More cuts than a cell's fixed capacity: refused, rather than dropping a cut (a wrong
    // volume and a piece that does not separate).
    if (tetCuts[size_t(t)].size() > size_t(kMaxCutPlanes)) {
      std::string list;
      for (const TetCut& c : tetCuts[size_t(t)])
        list += (list.empty() ? "" : ", ") + std::to_string(c.cut);
      return fail("XfemBody: planes and blades: tet ", std::to_string(t), " is crossed by ",
                  std::to_string(tetCuts[size_t(t)].size()), " cuts (", list, "; planes first),",
                  " at most ", std::to_string(kMaxCutPlanes),
                  " per tet: space the cuts further apart or refine the mesh");
    }
    if (!tetCuts[size_t(t)].empty()) ++b.m_cutTets;
  }
  b.m_enriched.assign(size_t(nodes) * size_t(cutCount), -1);
  b.m_functionCount = nodes;
  for (int32_t t = 0; t < tets; ++t)
    for (const TetCut& c : tetCuts[size_t(t)]) {
      ++b.m_cutReports[size_t(c.cut)].enrichedTets;
      for (int a = 0; a < 4; ++a) {
        const int32_t node = mesh.tets[4 * size_t(t) + a];
        int32_t& f = b.m_enriched[size_t(node) * size_t(cutCount) + size_t(c.cut)];
        if (f < 0 && enrichable(node, c.cut)) f = b.m_functionCount++;
      }
    }
  const int32_t F = b.m_functionCount;

  // Cells of every tet, for the pieces: volume, load, and (cut tets) their polygons on the
  // tet's faces; an uncut tet's face is its whole triangle, which overlaps any neighbour cell.
  struct Cell {
    int32_t tet = 0;
    Vec3 centroid;
    unsigned cutBits = 0, sides = 0;  // The tet's cuts (bit j: cut j) and the cell's sides.
    double volume = 0;
    bool dropped = false;
    std::vector<std::pair<int32_t, double>> load;
    std::vector<Eigen::Triplet<double>> mass;  // the cell's own, by function
  };
  std::vector<Cell> cells;
  std::vector<int32_t> firstCell(size_t(tets) + 1, 0);
  std::vector<std::array<std::vector<std::pair<int32_t, CutPolygon>>, 4>> facePolygons(
      static_cast<size_t>(tets));
  std::vector<int32_t> parent;
  std::vector<unsigned> openCuts(static_cast<size_t>(tets), 0);  // per tet: bit j, cut j opens
  // Per tet and face (opposite node a): bit j set when the face's three nodes lie on one side of
  // the tet's cut j (faceFixed), and that side is positive (facePositive).
  std::vector<std::array<unsigned, 4>> faceFixed(static_cast<size_t>(tets), {0, 0, 0, 0});
  std::vector<std::array<unsigned, 4>> facePositive(static_cast<size_t>(tets), {0, 0, 0, 0});

  // Elements, assembled; eq 3.16's volumes on the way.
  std::vector<Eigen::Triplet<double>> mass, stiffness;
  {
    // Reserved up front: growing tens of millions of triplets (20 cuts) cost more than the
    // elements themselves in copies and page faults.
    size_t pairs = 0;
    for (int32_t t = 0; t < tets; ++t)
      pairs += size_t(16) * (1 + tetCuts[size_t(t)].size()) * (1 + tetCuts[size_t(t)].size());
    mass.reserve(3 * pairs);
    stiffness.reserve(9 * pairs);
  }
  b.m_force = Eigen::VectorXd::Zero(3 * F);
  std::vector<double> support(static_cast<size_t>(nodes), 0.0);
  std::vector<double> enrichedVolume(static_cast<size_t>(F - nodes), 0.0);
  XfemSurfaceBuilder surface(mesh, cutCount, b.m_enriched, def.k);
  std::vector<std::vector<XfemDroppedCell>> droppedIn(def.dropped.empty() ? 0 : size_t(tets));
  for (const XfemDroppedCell& d : def.dropped) {
    if (d.tet < 0 || d.tet >= tets)
      return fail("XfemBody: dropped: tet ", std::to_string(d.tet), " out of range");
    droppedIn[size_t(d.tet)].push_back(d);
  }
  for (int32_t t = 0; t < tets; ++t) {
    firstCell[size_t(t)] = int32_t(cells.size());
    const std::vector<TetCut>& cuts = tetCuts[size_t(t)];
    const int m = int(cuts.size());
    CutPlane local[kMaxCutPlanes];
    int32_t localCut[kMaxCutPlanes];
    for (int j = 0; j < m; ++j) {
      local[j] = cuts[size_t(j)].plane;
      localCut[j] = cuts[size_t(j)].cut;
    }
    surface.beginTet(t, localCut, local, m);
    const Vec3* x = &X[4 * size_t(t)];
    // Nodes on a cut (to their snap distance) lie within twice the largest snap of the tet's
    // local plane: the cells treat them as on it, so no sliver of rounding noise is made.
    double onPlane = 0;
    for (int a = 0; a < 4; ++a)
      onPlane = std::max(onPlane, 4 * snap[size_t(mesh.tets[4 * size_t(t) + a])]);
    uint32_t dropCells = 0;  // bit mask: the cell of that side mask is dropped
    if (!droppedIn.empty())
      for (unsigned mask = 0; mask < (1u << m); ++mask) {
        unsigned sides = 0;
        for (int j = 0; j < m; ++j)
          if ((mask >> j) & 1u) sides |= 1u << localCut[j];
        for (const XfemDroppedCell& d : droppedIn[size_t(t)])
          if ((sides & d.cutBits) == d.sides) dropCells |= 1u << mask;
      }
    const CutElement e = buildCutElement(x, local, m, def.k, def.material, onPlane, dropCells);
    const int n = 4 * (1 + m);
    // Functions of nodes without the cut's enrichment are dropped (-1).
    std::vector<int32_t> map(static_cast<size_t>(n));
    unsigned opens = 0;  // bit j: cut j of this tet has all four nodes enriched
    for (int j = 0; j < m; ++j) opens |= 1u << j;
    for (int a = 0; a < 4; ++a) {
      const int32_t node = mesh.tets[4 * size_t(t) + a];
      map[size_t(a)] = node;
      for (int j = 0; j < m; ++j) {
        const int32_t f =
            b.m_enriched[size_t(node) * size_t(cutCount) + size_t(cuts[size_t(j)].cut)];
        map[size_t(4 + 4 * j + a)] = f;
        if (f < 0) opens &= ~(1u << j);
      }
    }
    for (int A = 0; A < n; ++A) {
      if (map[size_t(A)] < 0) continue;
      for (int B = 0; B < n; ++B) {
        if (map[size_t(B)] < 0) continue;
        for (int i = 0; i < 3; ++i) {
          if (e.mass(A, B) != 0)
            mass.emplace_back(3 * map[size_t(A)] + i, 3 * map[size_t(B)] + i, e.mass(A, B));
          for (int j = 0; j < 3; ++j)
            if (e.stiffness(3 * A + i, 3 * B + j) != 0)
              stiffness.emplace_back(3 * map[size_t(A)] + i, 3 * map[size_t(B)] + j,
                                     e.stiffness(3 * A + i, 3 * B + j));
        }
      }
      // Eq 3.6 with b = rho g.
      for (int i = 0; i < 3; ++i) b.m_force[3 * map[size_t(A)] + i] += e.load[A] * def.gravity[i];
    }

    double tetVolume = 0;
    for (const CutCell& c : e.cells) tetVolume += c.volume;
    for (int a = 0; a < 4; ++a) support[size_t(mesh.tets[4 * size_t(t) + a])] += tetVolume;
    for (const CutCell& c : e.cells) {
      Cell cell;
      cell.tet = t;
      cell.volume = c.volume;
      Vec3 centroid;
      for (int q = 0; q < c.rule.count; ++q) centroid += c.rule.weights[q] * c.rule.points[q];
      centroid = (1.0 / c.volume) * centroid;
      cell.centroid = centroid;
      for (int j = 0; j < m; ++j) {
        cell.cutBits |= 1u << cuts[size_t(j)].cut;
        if ((c.sideMask >> j) & 1u) cell.sides |= 1u << cuts[size_t(j)].cut;
      }
      cell.dropped = c.dropped;
      if (c.dropped) {
        b.m_held.resize(size_t(F), 0);
        for (int A = 4; A < n; ++A)
          if (map[size_t(A)] >= 0 && c.mass(A, A) > 0) b.m_held[size_t(map[size_t(A)])] = 1;
      }
      for (int A = 0; A < n; ++A)
        if (map[size_t(A)] >= 0) {
          cell.load.emplace_back(map[size_t(A)], c.load[A]);
          for (int B = 0; B < n; ++B)
            if (map[size_t(B)] >= 0 && c.mass(A, B) != 0)
              cell.mass.emplace_back(map[size_t(A)], map[size_t(B)], c.mass(A, B));
        }
      // Cells of one tet stay joined across a cut that does not open there.
      const int32_t id = int32_t(cells.size());
      parent.push_back(id);
      for (int32_t o = firstCell[size_t(t)]; o < id; ++o) {
        unsigned differ = 0;
        for (int j = 0; j < m; ++j)
          if (((c.sideMask ^ e.cells[size_t(o - firstCell[size_t(t)])].sideMask) >> j) & 1u)
            differ |= 1u << j;
        if ((differ & opens) == 0) unite(parent, id, o);
      }
      // A cut through a node layer makes a tet face the cap of the cells below it (clipTet
      // relabels a face lying in the plane): it is still that tet face for the pieces.
      int capOnFace[kCutPolytopeMaxFaces];
      for (int f = 0; f < c.polytope.faceCount; ++f) {
        const CutPolygon& g = c.polytope.faces[f];
        capOnFace[f] = g.label < kCutFaceLabel ? g.label : tetFaceHolding(x, g, onPlane);
        if (m > 0 && capOnFace[f] >= 0)
          facePolygons[size_t(t)][size_t(capOnFace[f])].emplace_back(id, g);
      }
      const auto surfaceStart = std::chrono::steady_clock::now();
      surface.addCell(id, c.sideMask, c.polytope, capOnFace);
      b.m_surfaceBuildMs +=
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - surfaceStart)
              .count();
      cells.push_back(std::move(cell));
      for (int j = 0; j < m; ++j) {
        const bool cellPositive = (c.sideMask >> j) & 1u;
        // Eq 3.16's enriched support: where classic XFEM's psi_i^j is non-zero, the cells
        // on the other side of cut j from node i.
        for (int a = 0; a < 4; ++a)
          if ((e.sides.side[j][a] > 0.5) != cellPositive && map[size_t(4 + 4 * j + a)] >= 0)
            enrichedVolume[size_t(map[size_t(4 + 4 * j + a)] - nodes)] += c.volume;
        // The cut face along a tet face (node layer) has only the negative cell: record it
        // from there, turned to face the positive side.
        if (!cellPositive)
          for (int f = 0; f < c.polytope.faceCount; ++f)
            if (c.polytope.faces[f].label == kCutFaceLabel + j && capOnFace[f] >= 0) {
              CutPolygon g = c.polytope.faces[f];
              std::reverse(g.v, g.v + g.count);
              b.m_cutFaces.push_back({t, cuts[size_t(j)].cut, ((opens >> j) & 1u) != 0, g});
            }
        if (cellPositive)
          for (int f = 0; f < c.polytope.faceCount; ++f)
            if (c.polytope.faces[f].label == kCutFaceLabel + j)
              b.m_cutFaces.push_back(
                  {t, cuts[size_t(j)].cut, ((opens >> j) & 1u) != 0, c.polytope.faces[f]});
      }
    }
    for (int j = 0; j < m; ++j)
      for (int a = 0; a < 4; ++a) {
        const double s0 = e.sides.side[j][(a + 1) % 4];
        bool same = true;
        for (int k = 2; k < 4; ++k) same = same && e.sides.side[j][(a + k) % 4] == s0;
        if (!same) continue;
        faceFixed[size_t(t)][size_t(a)] |= 1u << cuts[size_t(j)].cut;
        if (s0 > 0.5) facePositive[size_t(t)][size_t(a)] |= 1u << cuts[size_t(j)].cut;
      }
    for (int j = 0; j < m; ++j)
      if ((opens >> j) & 1u) {
        ++b.m_cutReports[size_t(cuts[size_t(j)].cut)].openTets;
        openCuts[size_t(t)] |= 1u << cuts[size_t(j)].cut;
      }
  }
  firstCell[size_t(tets)] = int32_t(cells.size());

  // Pieces: join cells of neighbouring tets on the same side of every cut that opens in both
  // (their enriched fields separate there even where a bent blade's local planes meet the
  // shared face along different lines), and whose polygons on the face overlap unless those
  // common cuts are all the two tets carry. A cut that opens in one tet only, with the shared
  // face's nodes all on one side of it, lets only that side's cells through the face: the face
  // lies on the cut (a cut through a node layer) and the other tet is wholly beyond it.
  {
    const int opposite[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
    std::map<std::array<int32_t, 3>, std::pair<int32_t, int>> unmatched;  // face -> (tet, a)
    for (int32_t t = 0; t < tets; ++t)
      for (int a = 0; a < 4; ++a) {
        std::array<int32_t, 3> f;
        for (int k = 0; k < 3; ++k) f[size_t(k)] = mesh.tets[4 * size_t(t) + opposite[a][k]];
        std::sort(f.begin(), f.end());
        const auto it = unmatched.find(f);
        if (it == unmatched.end()) {
          unmatched.emplace(f, std::make_pair(t, a));
          continue;
        }
        const int32_t u = it->second.first;
        const int au = it->second.second;
        const auto& pu = facePolygons[size_t(u)][size_t(au)];
        const auto& pt = facePolygons[size_t(t)][size_t(a)];
        unmatched.erase(it);
        const unsigned common = openCuts[size_t(u)] & openCuts[size_t(t)];
        const unsigned onlyU = openCuts[size_t(u)] & ~common & faceFixed[size_t(u)][size_t(au)];
        const unsigned onlyT = openCuts[size_t(t)] & ~common & faceFixed[size_t(t)][size_t(a)];
        const auto through = [&](int32_t cell, unsigned only, unsigned positive) {
          return ((cells[size_t(cell)].sides ^ positive) & only) == 0;
        };
        const unsigned posU = facePositive[size_t(u)][size_t(au)];
        const unsigned posT = facePositive[size_t(t)][size_t(a)];
        if (pu.empty() && pt.empty()) {
          unite(parent, firstCell[size_t(u)], firstCell[size_t(t)]);
        } else if (pu.empty() || pt.empty()) {
          // An uncut tet's face is its whole triangle: it overlaps every cell on the other side.
          const int32_t whole = pu.empty() ? firstCell[size_t(u)] : firstCell[size_t(t)];
          const unsigned only = pu.empty() ? onlyT : onlyU, positive = pu.empty() ? posT : posU;
          for (const auto& [cell, polygon] : pu.empty() ? pt : pu)
            if (through(cell, only, positive)) unite(parent, whole, cell);
        } else {
          const bool sidesDecide = cells[size_t(pu[0].first)].cutBits == common &&
                                   cells[size_t(pt[0].first)].cutBits == common;
          for (const auto& [cu, gu] : pu)
            for (const auto& [ct, gt] : pt)
              if (((cells[size_t(cu)].sides ^ cells[size_t(ct)].sides) & common) == 0 &&
                  through(cu, onlyU, posU) && through(ct, onlyT, posT) &&
                  (sidesDecide || polygonsOverlap(gu, gt)))
                unite(parent, cu, ct);
        }
      }
  }
  std::vector<int32_t> pieceOf(cells.size(), -1);
  std::vector<int32_t> roots;
  for (size_t c = 0; c < cells.size(); ++c) {
    const int32_t r = findRoot(parent, int32_t(c));
    if (pieceOf[size_t(r)] < 0) {
      pieceOf[size_t(r)] = int32_t(roots.size());
      roots.push_back(r);
      // The mask: the cell's own sides of its tet's cuts, the sides of its centroid otherwise.
      XfemPiece p;
      p.mask = cells[c].sides;
      for (int32_t j = 0; j < cutCount; ++j)
        if (!((cells[c].cutBits >> j) & 1u) &&
            positiveSide(def, bladeSurfaces, j, cells[c].centroid))
          p.mask |= 1u << j;
      p.load = Eigen::VectorXd::Zero(F);
      b.m_pieces.push_back(std::move(p));
    }
    XfemPiece& p = b.m_pieces[size_t(pieceOf[size_t(r)])];
    p.volume += cells[c].volume;
    ++p.cells;
    for (const auto& [f, w] : cells[c].load) p.load[f] += w;
    p.cellIds.push_back({cells[c].tet, cells[c].cutBits, cells[c].sides});
    p.dropped = p.dropped || cells[c].dropped;
  }
  {
    std::vector<std::vector<Eigen::Triplet<double>>> pieceMass(b.m_pieces.size());
    for (size_t c = 0; c < cells.size(); ++c) {
      auto& to = pieceMass[size_t(pieceOf[size_t(findRoot(parent, int32_t(c)))])];
      to.insert(to.end(), cells[c].mass.begin(), cells[c].mass.end());
    }
    for (size_t p = 0; p < b.m_pieces.size(); ++p) {
      b.m_pieces[p].mass.resize(F, F);
      b.m_pieces[p].mass.setFromTriplets(pieceMass[p].begin(), pieceMass[p].end());
    }
  }
  // Roots are first cells, so pieces come in order of their first tet; then by mask.
  {
    std::vector<int32_t> order(b.m_pieces.size()), rank(b.m_pieces.size());
    for (size_t p = 0; p < order.size(); ++p) order[p] = int32_t(p);
    std::stable_sort(order.begin(), order.end(), [&](int32_t l, int32_t r) {
      return b.m_pieces[size_t(l)].mask < b.m_pieces[size_t(r)].mask;
    });
    std::vector<XfemPiece> sorted;
    for (size_t p = 0; p < order.size(); ++p) {
      rank[size_t(order[p])] = int32_t(p);
      sorted.push_back(std::move(b.m_pieces[size_t(order[p])]));
    }
    b.m_pieces = std::move(sorted);
    std::vector<int32_t> cellPiece(cells.size());
    for (size_t c = 0; c < cells.size(); ++c)
      cellPiece[c] = rank[size_t(pieceOf[size_t(findRoot(parent, int32_t(c)))])];
    const auto surfaceStart = std::chrono::steady_clock::now();
    b.m_surface = surface.build(cellPiece, int32_t(b.m_pieces.size()));
    b.m_surfaceBuildMs +=
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - surfaceStart)
            .count();
  }

  b.m_enrichedRatio.assign(size_t(F - nodes), 0.0);
  for (int32_t n = 0; n < nodes; ++n)
    for (int32_t j = 0; j < cutCount; ++j) {
      const int32_t f = b.m_enriched[size_t(n) * size_t(cutCount) + size_t(j)];
      if (f >= 0)
        b.m_enrichedRatio[size_t(f - nodes)] =
            enrichedVolume[size_t(f - nodes)] / support[size_t(n)];
    }

  b.m_mass.resize(3 * F, 3 * F);
  b.m_mass.setFromTriplets(mass.begin(), mass.end());
  b.m_stiffness.resize(3 * F, 3 * F);
  b.m_stiffness.setFromTriplets(stiffness.begin(), stiffness.end());

  if (auto r = b.buildStepMatrix(); !r) return r.error();
  b.m_u = Eigen::VectorXd::Zero(3 * F);
  b.m_v = Eigen::VectorXd::Zero(3 * F);
  return body;
}

Result<void> XfemBody::buildStepMatrix() {
  const int32_t nodes = int32_t(m_def.mesh.nodeCount()), F = m_functionCount;
  const int32_t cutCount = int32_t(m_def.planes.size() + m_def.blades.size());
  m_freeDof.clear();
  m_constrained = 0;
  // Fixed nodes hold their standard and enriched DOFs; the step matrix is over the rest.
  std::vector<uint8_t> fixed(static_cast<size_t>(F), 0);
  for (int32_t n : m_def.fixedNodes) {
    fixed[size_t(n)] = 1;
    for (int32_t j = 0; j < cutCount; ++j) {
      const int32_t f = m_enriched[size_t(n) * size_t(cutCount) + size_t(j)];
      if (f >= 0) fixed[size_t(f)] = 1;
    }
  }
  if (!m_def.dropped.empty()) {
    const Eigen::VectorXd diagonal = m_mass.diagonal();
    for (int32_t f = 0; f < F; ++f)
      if (!(diagonal[3 * f] > 0) || (size_t(f) < m_held.size() && m_held[size_t(f)]))
        fixed[size_t(f)] = 1;
  }
  for (int32_t f = 0; f < F; ++f)
    if (!fixed[size_t(f)])
      for (int i = 0; i < 3; ++i) m_freeDof.push_back(3 * f + i);
  // The free rows and columns of A, renumbered: the free DOFs ascend, so each column's rows
  // stay sorted (a selection-matrix product did the same at twice the assembly's cost).
  const int32_t free = int32_t(m_freeDof.size());
  std::vector<int32_t> freeIndex(3 * size_t(F), -1);
  for (int32_t r = 0; r < free; ++r) freeIndex[size_t(m_freeDof[size_t(r)])] = r;
  const Eigen::SparseMatrix<double> A = m_mass + (m_def.dt * m_def.dt) * m_stiffness;
  m_stepMatrix.resize(free, free);
  m_stepMatrix.reserve(A.nonZeros());
  for (Eigen::Index c = 0; c < A.outerSize(); ++c) {
    const int32_t fc = freeIndex[size_t(c)];
    if (fc < 0) continue;
    m_stepMatrix.startVec(fc);
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, c); it; ++it)
      if (const int32_t fr = freeIndex[size_t(it.row())]; fr >= 0)
        m_stepMatrix.insertBack(fr, fc) = it.value();
  }
  m_stepMatrix.finalize();
  m_stepMatrix.makeCompressed();
  // Sec 3.2.2.2: (A + lambda I) on the enriched DOFs of too small a volume ratio (eq 3.16).
  for (int32_t r = 0; r < free; ++r) {
    const int32_t f = m_freeDof[size_t(r)] / 3;
    if (f < nodes || !(m_enrichedRatio[size_t(f - nodes)] < m_def.constraint.minRatio)) continue;
    m_stepMatrix.coeffRef(r, r) *= 1.0 + m_def.constraint.relative;
    ++m_constrained;
  }
  const SymmetricCsc csc{int32_t(m_stepMatrix.rows()), m_stepMatrix.outerIndexPtr(),
                         m_stepMatrix.innerIndexPtr(), m_stepMatrix.valuePtr()};
  if (auto factored = m_solver.factorize(csc); !factored.ok())
    return fail("XfemBody: step matrix M + dt^2 K: ", factored.error().message);
  return {};
}

bool XfemBody::step() {
  const double dt = m_def.dt;
  // Eq 3.13 for linear elasticity (K x^k is the elastic force K u of the displacement).
  const Eigen::VectorXd full = m_mass * m_v - dt * (m_stiffness * m_u - m_force);
  Eigen::VectorXd rhs(Eigen::Index(m_freeDof.size()));
  for (size_t r = 0; r < m_freeDof.size(); ++r) rhs[Eigen::Index(r)] = full[m_freeDof[r]];
  Eigen::VectorXd v(rhs.size());
  if (!m_solver.solveFactored(rhs.data(), v.data())) return false;  // non-finite: no NaN step
  m_v.setZero();
  for (size_t r = 0; r < m_freeDof.size(); ++r) m_v[m_freeDof[r]] = v[Eigen::Index(r)];
  m_u += dt * m_v;
  return true;
}

bool XfemBody::step(const std::vector<XfemContactPlane>& planes, XfemContactReport* report) {
  if (report) {
    *report = {};
    report->impulse.assign(6 * planes.size(), 0.0);
  }
  if (planes.empty()) return step();
  const double dt = m_def.dt;
  const Eigen::Index free = Eigen::Index(m_freeDof.size());
  // Eq 3.13 without contact: v0 = A^-1 b.
  const Eigen::VectorXd full = m_mass * m_v - dt * (m_stiffness * m_u - m_force);
  Eigen::VectorXd rhs(free);
  for (Eigen::Index r = 0; r < free; ++r) rhs[r] = full[m_freeDof[size_t(r)]];
  Eigen::VectorXd v0(free);
  if (!m_solver.solveFactored(rhs.data(), v0.data())) return false;
  std::vector<int32_t> freeIndex(size_t(m_u.size()), -1);
  for (Eigen::Index r = 0; r < free; ++r) freeIndex[size_t(m_freeDof[size_t(r)])] = int32_t(r);

  // A contact row: vertex i of piece p against plane c, its current gap and G_k over the free
  // DOFs (n times the vertex's weights, eq 3.4), sparse.
  struct Row {
    int32_t piece, vertex, plane;
    double gap;
    std::vector<std::pair<int32_t, double>> g;
  };
  const auto gapOf = [&](const XfemPieceSurface& s, size_t i, const XfemContactPlane& c,
                         const Eigen::VectorXd* v) {
    Vec3 x = s.vertices[i].rest;
    for (int32_t w = s.weightStart[i]; w < s.weightStart[i + 1]; ++w)
      for (int d = 0; d < 3; ++d) {
        const int32_t dof = 3 * s.weightFunction[size_t(w)] + d;
        double u = m_u[dof];
        if (v && freeIndex[size_t(dof)] >= 0) u += dt * (*v)[freeIndex[size_t(dof)]];
        x[d] += s.weightValue[size_t(w)] * u;
      }
    return dot(c.normal, x) - c.offset;
  };
  double size = 0;  // the body's largest extent at rest
  {
    Vec3 lo{INFINITY, INFINITY, INFINITY}, hi = -lo;
    for (size_t n = 0; 3 * n < m_def.mesh.positions.size(); ++n)
      for (int d = 0; d < 3; ++d) {
        lo[d] = std::min(lo[d], m_def.mesh.positions[3 * n + size_t(d)]);
        hi[d] = std::max(hi[d], m_def.mesh.positions[3 * n + size_t(d)]);
      }
    for (int d = 0; d < 3; ++d) size = std::max(size, hi[d] - lo[d]);
  }
  std::vector<Row> rows;
  std::vector<uint8_t> active;  // per (piece, vertex, plane), flattened below
  std::vector<size_t> vertexBase(m_surface.size() + 1, 0);
  for (size_t p = 0; p < m_surface.size(); ++p)
    vertexBase[p + 1] = vertexBase[p] + m_surface[p].vertices.size();
  active.assign(vertexBase.back() * planes.size(), 0);
  std::vector<Eigen::VectorXd> Y;  // A^-1 G_k^T
  std::vector<double> lambda, start;
  std::vector<size_t> keys;
  Eigen::VectorXd v = v0;
  Eigen::MatrixXd S;  // G A^-1 G^T, grown by rows
  int rounds = 0, sweeps = 0, pivots = 0;
  double worst = 0;
  bool converged = true;
  for (; rounds < 16; ++rounds) {
    // The vertices that v leaves beyond a plane join the active set.
    const size_t before = rows.size();
    for (size_t p = 0; p < m_surface.size(); ++p)
      for (size_t i = 0; i < m_surface[p].vertices.size() && !m_pieces[p].dropped; ++i)
        for (size_t c = 0; c < planes.size(); ++c) {
          const size_t key = (vertexBase[p] + i) * planes.size() + c;
          uint8_t& a = active[key];
          // Last step's contacts join at once with their impulses (warm start): a resting body
          // then needs a few sweeps, not thousands.
          const auto warm = rounds == 0 ? m_warm.find(key) : m_warm.end();
          if (a || (warm == m_warm.end() && gapOf(m_surface[p], i, planes[c], &v) >= 0)) continue;
          Row row{
              int32_t(p), int32_t(i), int32_t(c), gapOf(m_surface[p], i, planes[c], nullptr), {}};
          const XfemPieceSurface& s = m_surface[p];
          for (int32_t w = s.weightStart[i]; w < s.weightStart[i + 1]; ++w)
            for (int d = 0; d < 3; ++d) {
              const int32_t r = freeIndex[size_t(3 * s.weightFunction[size_t(w)] + d)];
              const double value = s.weightValue[size_t(w)] * planes[c].normal[d];
              if (r >= 0 && value != 0) row.g.emplace_back(r, value);
            }
          a = 1;
          if (row.g.empty()) continue;  // held by fixed DOFs only: nothing can move it
          rows.push_back(std::move(row));
          keys.push_back(key);
          start.push_back(warm == m_warm.end() ? 0.0 : warm->second);
        }
    if (rows.size() == before) break;
    for (size_t k = before; k < rows.size(); ++k) {
      Eigen::VectorXd gk = Eigen::VectorXd::Zero(free), yk(free);
      for (const auto& [r, value] : rows[k].g) gk[r] += value;
      if (!m_solver.solveFactored(gk.data(), yk.data())) return false;
      Y.push_back(std::move(yk));
      lambda.push_back(start[k]);
    }
    const Eigen::Index m = Eigen::Index(rows.size());
    Eigen::MatrixXd grown(m, m);
    grown.topLeftCorner(Eigen::Index(before), Eigen::Index(before)) =
        S.topLeftCorner(Eigen::Index(before), Eigen::Index(before));
    for (Eigen::Index k = 0; k < m; ++k)
      for (Eigen::Index l = std::max<Eigen::Index>(k, Eigen::Index(before)); l < m; ++l) {
        double sum = 0;
        for (const auto& [r, value] : rows[size_t(k)].g) sum += value * Y[size_t(l)][r];
        grown(k, l) = grown(l, k) = sum;
      }
    S = std::move(grown);
    // q_k = G_k v0 + g_k / dt: the end gap over dt without contact impulses.
    Eigen::VectorXd q(m);
    for (Eigen::Index k = 0; k < m; ++k) {
      double gv = 0;
      for (const auto& [r, value] : rows[size_t(k)].g) gv += value * v0[r];
      q[k] = gv + rows[size_t(k)].gap / dt;
    }
    // lambda >= 0, w = S lambda + q >= 0, complementary. The contacts of one piece are
    // coupled through its near-rigid motion, so S is nearly singular (its elastic directions
    // are dt^2 E times softer than the rigid ones) and exactly so where more vertices than
    // DOFs touch: projected Gauss-Seidel alone crawls there. So first principal pivoting: the
    // pushing set P solved exactly (S_PP lambda_P = -q_P, least squares of minimum norm where
    // S_PP is singular), vertices switched in or out by sign, all at once for 10 rounds and
    // then the first one only (Murty's least-index rule, which terminates on a P-matrix); then
    // projected Gauss-Seidel from there for what rounding leaves. It stops when every vertex's
    // complementarity residual (w where it pushes, a negative w where it does not) moves it by
    // under 1e-9 of the body's size in the step.
    const double tolerance = 1e-9 * size / dt;
    const auto residualOf = [&](const Eigen::VectorXd& w) {
      double r = 0;
      for (Eigen::Index k = 0; k < m; ++k)
        r = std::max(r, lambda[size_t(k)] > 0 ? std::abs(w[k]) : -w[k]);
      return r;
    };
    Eigen::VectorXd w(m);
    std::vector<uint8_t> pushing(static_cast<size_t>(m));
    for (Eigen::Index k = 0; k < m; ++k) pushing[size_t(k)] = lambda[size_t(k)] > 0 || q[k] < 0;
    // S + eps I with eps 1e-10 of S's largest diagonal is positive definite, a P-matrix, for
    // which Murty's rule cannot cycle (on the singular S it did); eps lambda is far below the
    // tolerance, which is checked on S itself.
    const double eps = 1e-10 * S.diagonal().maxCoeff();
    for (int pivot = 0; pivot < 10 * m + 50; ++pivot) {
      ++pivots;
      std::vector<Eigen::Index> P;
      for (Eigen::Index k = 0; k < m; ++k)
        if (pushing[size_t(k)]) P.push_back(k);
      std::fill(lambda.begin(), lambda.end(), 0.0);
      if (!P.empty()) {
        Eigen::MatrixXd SP(Eigen::Index(P.size()), Eigen::Index(P.size()));
        Eigen::VectorXd qP(Eigen::Index(P.size()));
        for (size_t i = 0; i < P.size(); ++i) {
          qP[Eigen::Index(i)] = -q[P[i]];
          for (size_t j = 0; j < P.size(); ++j)
            SP(Eigen::Index(i), Eigen::Index(j)) = S(P[i], P[j]) + (i == j ? eps : 0.0);
        }
        const Eigen::VectorXd x = SP.completeOrthogonalDecomposition().solve(qP);
        for (size_t i = 0; i < P.size(); ++i) lambda[size_t(P[i])] = x[Eigen::Index(i)];
      }
      w = q;
      for (Eigen::Index k = 0; k < m; ++k)
        if (lambda[size_t(k)] != 0) w += lambda[size_t(k)] * S.col(k);
      // Violations: a pushing vertex that pulls, a free one that penetrates.
      Eigen::Index first = -1;
      int switched = 0;
      for (Eigen::Index k = 0; k < m; ++k) {
        const double violation =
            pushing[size_t(k)] ? -lambda[size_t(k)] * S(k, k) : -w[k];  // both velocities
        if (violation <= tolerance) continue;
        ++switched;
        if (first < 0) first = k;  // Murty: the least index
      }
      if (switched == 0) break;
      if (pivot < 10) {
        for (Eigen::Index k = 0; k < m; ++k) {
          const double violation = pushing[size_t(k)] ? -lambda[size_t(k)] * S(k, k) : -w[k];
          if (violation > tolerance) pushing[size_t(k)] ^= 1;
        }
      } else {
        pushing[size_t(first)] ^= 1;
      }
    }
    for (double& l : lambda) l = std::max(l, 0.0);
    w = q;
    for (Eigen::Index k = 0; k < m; ++k)
      if (lambda[size_t(k)] != 0) w += lambda[size_t(k)] * S.col(k);
    worst = residualOf(w);
    for (int sweep = 0; sweep < 5000 && worst > tolerance; ++sweep) {
      ++sweeps;
      for (Eigen::Index k = 0; k < m; ++k) {
        if (!(S(k, k) > 0)) continue;
        const double next = std::max(0.0, lambda[size_t(k)] - w[k] / S(k, k));
        const double d = next - lambda[size_t(k)];
        if (d != 0) {
          w += d * S.col(k);
          lambda[size_t(k)] = next;
        }
      }
      worst = residualOf(w);
    }
    converged = worst <= tolerance;
    v = v0;
    for (size_t k = 0; k < rows.size(); ++k)
      if (lambda[k] != 0) v += lambda[k] * Y[k];
  }
  if (!v.allFinite()) return false;
  m_warm.clear();
  for (size_t k = 0; k < rows.size(); ++k)
    if (lambda[k] > 0) m_warm.emplace(keys[k], lambda[k]);
  m_v.setZero();
  for (Eigen::Index r = 0; r < free; ++r) m_v[m_freeDof[size_t(r)]] = v[r];
  m_u += dt * m_v;
  if (report) {
    report->contacts = int32_t(rows.size());
    report->rounds = rounds;
    report->sweeps = sweeps;
    report->pivots = pivots;
    report->converged = converged;
    report->residual = worst;
    for (size_t k = 0; k < rows.size(); ++k) {
      const Row& row = rows[k];
      const XfemPieceSurface& s = m_surface[size_t(row.piece)];
      const XfemContactPlane& c = planes[size_t(row.plane)];
      report->minGap = std::min(report->minGap, gapOf(s, size_t(row.vertex), c, nullptr));
      Vec3 x = s.vertices[size_t(row.vertex)].rest;
      for (int32_t w = s.weightStart[size_t(row.vertex)]; w < s.weightStart[size_t(row.vertex) + 1];
           ++w)
        for (int d = 0; d < 3; ++d)
          x[d] += s.weightValue[size_t(w)] * m_u[3 * s.weightFunction[size_t(w)] + d];
      const Vec3 J = lambda[k] * c.normal, L = cross(x, J);
      for (int d = 0; d < 3; ++d) {
        report->impulse[6 * size_t(row.plane) + size_t(d)] += J[d];
        report->impulse[6 * size_t(row.plane) + 3 + size_t(d)] += L[d];
      }
    }
  }
  return true;
}

Result<std::unique_ptr<XfemBody>> XfemBody::withBlade(const XfemBlade& blade) const {
  XfemBodyDef def = m_def;
  def.blades.push_back(blade);
  auto made = create(def);
  if (!made) return made.error();
  XfemBody& b = *made.value();
  const int32_t nodes = int32_t(m_def.mesh.nodeCount());
  const int32_t oldCuts = int32_t(m_def.planes.size() + m_def.blades.size());
  // Planes come first, so a blade appended keeps every old cut's index.
  b.m_u.segment(0, 3 * nodes) = m_u.segment(0, 3 * nodes);
  b.m_v.segment(0, 3 * nodes) = m_v.segment(0, 3 * nodes);
  for (int32_t n = 0; n < nodes; ++n)
    for (int32_t j = 0; j < oldCuts; ++j) {
      const int32_t from = enrichedFunction(n, j), to = b.enrichedFunction(n, j);
      if (from < 0) continue;
      if (to < 0)
        return fail("XfemBody: blades[", std::to_string(def.blades.size() - 1), "]: node ",
                    std::to_string(n), " lost its enrichment for cut ", std::to_string(j));
      b.m_u.segment(3 * to, 3) = m_u.segment(3 * from, 3);
      b.m_v.segment(3 * to, 3) = m_v.segment(3 * from, 3);
    }
  b.updateSurface();
  return made;
}

Result<void> XfemBody::setTimeStep(double dt) {
  if (!(std::isfinite(dt) && dt > 0))
    return fail("XfemBody: dt: ", std::to_string(dt), " is not positive and finite");
  if (dt == m_def.dt) return {};
  const double old = m_def.dt;
  m_def.dt = dt;
  if (auto r = buildStepMatrix(); !r) {
    m_def.dt = old;
    (void)buildStepMatrix();  // the old matrix factorised before
    return r;
  }
  return {};
}

Vec3 XfemBody::pieceRestCentre(int piece) const {
  if (piece < 0 || size_t(piece) >= m_pieces.size()) return {};
  const XfemPiece& p = m_pieces[size_t(piece)];
  Vec3 s;
  double m = 0;
  for (int32_t n = 0; n < int32_t(m_def.mesh.nodeCount()); ++n) {
    s += p.load[n] * nodePosition(m_def.mesh, n);
    m += p.load[n];
  }
  return m > 0 ? (1.0 / m) * s : s;
}

void XfemBody::updateSurface() {
  for (XfemPieceSurface& s : m_surface)
    for (size_t v = 0; v < s.vertices.size(); ++v) {
      Vec3 x = s.vertices[v].rest;
      for (int32_t w = s.weightStart[v]; w < s.weightStart[v + 1]; ++w)
        for (int i = 0; i < 3; ++i)
          x[i] += s.weightValue[size_t(w)] * m_u[3 * s.weightFunction[size_t(w)] + i];  // eq 3.4
      s.positions[v] = x;
    }
}

int XfemBody::pieceWithMask(unsigned mask) const {
  for (size_t p = 0; p < m_pieces.size(); ++p)
    if (m_pieces[p].mask == mask) return int(p);
  return -1;
}

Vec3 XfemBody::pieceMeanDisplacement(int piece) const {
  if (piece < 0 || size_t(piece) >= m_pieces.size()) return {};
  const XfemPiece& p = m_pieces[size_t(piece)];
  Vec3 s;
  for (int32_t f = 0; f < m_functionCount; ++f)
    for (int i = 0; i < 3; ++i) s[i] += p.load[f] * m_u[3 * f + i];
  return (1.0 / (m_def.material.density * p.volume)) * s;
}

Vec3 XfemBody::momentum(int piece) const {
  Vec3 s;
  for (size_t k = 0; k < m_pieces.size(); ++k) {
    if (piece >= 0 && size_t(piece) != k) continue;
    for (int32_t f = 0; f < m_functionCount; ++f)
      for (int i = 0; i < 3; ++i) s[i] += m_pieces[k].load[f] * m_v[3 * f + i];
  }
  return s;
}

Eigen::VectorXd XfemBody::volumeRatioScaling() const {
  const int32_t nodes = int32_t(m_def.mesh.nodeCount());
  Eigen::VectorXd t(Eigen::Index(m_freeDof.size()));
  for (size_t r = 0; r < m_freeDof.size(); ++r) {
    const int32_t f = m_freeDof[r] / 3;
    const double v = f < nodes ? 1.0 : m_enrichedRatio[size_t(f - nodes)];
    t[Eigen::Index(r)] = v > 0 ? 1.0 / std::sqrt(v) : 1.0;  // eq 3.15
  }
  return t;
}

}  // namespace gf::detail

namespace gf::detail {

XfemPieceMoments XfemBody::pieceMoments(int piece) const {
  XfemPieceMoments r;
  if (piece < 0 || size_t(piece) >= m_pieces.size()) return r;
  const XfemPiece& p = m_pieces[size_t(piece)];
  const int32_t nodes = int32_t(m_def.mesh.nodeCount());
  const auto rest = [&](int32_t f) { return f < nodes ? nodePosition(m_def.mesh, f) : Vec3{}; };
  const auto dof = [](const Eigen::VectorXd& v, int32_t f) {
    return Vec3{v[3 * f], v[3 * f + 1], v[3 * f + 2]};
  };
  r.volume = p.volume;
  // First moments from the loads (the standard functions sum to one on the piece).
  Vec3 restFirst, first;
  for (int32_t f = 0; f < m_functionCount; ++f) {
    const double w = p.load[f];
    if (w == 0) continue;
    if (f < nodes) r.mass += w;
    restFirst += w * rest(f);
    first += w * (rest(f) + dof(m_u, f));
    r.momentum += w * dof(m_v, f);
  }
  if (!(r.mass > 0)) return r;
  r.restCentre = (1.0 / r.mass) * restFirst;
  r.centre = (1.0 / r.mass) * first;
  // Second moments about the centres: the shifts make them exact for a piece far from the origin.
  for (int k = 0; k < p.mass.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(p.mass, k); it; ++it) {
      const int32_t f = int32_t(it.row()), g = int32_t(it.col());
      const double w = it.value();
      // sum_f phi_f = 1 on the piece, so the shift by the centre goes on the standard functions.
      const Vec3 Xf = rest(f) - (f < nodes ? r.restCentre : Vec3{});
      const Vec3 Xg = rest(g) - (g < nodes ? r.restCentre : Vec3{});
      const Vec3 xf = rest(f) + dof(m_u, f) - (f < nodes ? r.centre : Vec3{});
      const Vec3 vg = dof(m_v, g);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          r.restSecond(i, j) += w * Xf[i] * Xg[j];
          r.spread(i, j) += w * xf[i] * Xg[j];
        }
      r.angularMomentum += w * cross(xf, vg);
    }
  return r;
}

Result<std::unique_ptr<XfemBody>> XfemBody::withoutPiece(int piece) const {
  if (piece < 0 || size_t(piece) >= m_pieces.size())
    return fail("XfemBody: piece ", std::to_string(piece), " out of range [0, ",
                std::to_string(m_pieces.size()), ")");
  XfemBodyDef def = m_def;
  const XfemPiece& p = m_pieces[size_t(piece)];
  def.dropped.insert(def.dropped.end(), p.cellIds.begin(), p.cellIds.end());
  auto made = create(def);
  if (!made) return made.error();
  XfemBody& b = *made.value();
  // The same cuts give the same functions in the same order: the state carries over as is.
  if (b.m_functionCount != m_functionCount)
    return fail("XfemBody: dropping piece ", std::to_string(piece), " changed the functions");
  b.m_u = m_u;
  b.m_v = m_v;
  // v on the free functions: M_ff v_f = (M_new v_old)_f, the L2 projection (mass-weighted)
  // of the old field on the cells left (M_new has only those) onto the free functions.
  std::vector<int32_t> freeIndex(size_t(m_functionCount), -1);
  int32_t freeCount = 0;
  for (size_t r = 0; r < b.m_freeDof.size(); r += 3)
    freeIndex[size_t(b.m_freeDof[r] / 3)] = freeCount++;
  Eigen::SparseMatrix<double> scalar(freeCount, freeCount);
  {
    std::vector<Eigen::Triplet<double>> t;
    for (int k = 0; k < b.m_mass.outerSize(); ++k)
      for (Eigen::SparseMatrix<double>::InnerIterator it(b.m_mass, k); it; ++it)
        if (it.row() % 3 == 0 && it.col() % 3 == 0) {
          const int32_t r = freeIndex[size_t(it.row() / 3)], c = freeIndex[size_t(it.col() / 3)];
          if (r >= 0 && c >= 0) t.emplace_back(r, c, it.value());
        }
    scalar.setFromTriplets(t.begin(), t.end());
  }
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> mass(scalar);
  if (mass.info() != Eigen::Success)
    return fail("XfemBody: dropping piece ", std::to_string(piece), ": mass matrix not definite");
  const Eigen::VectorXd Mv = b.m_mass * m_v;
  b.m_v.setZero();
  for (int d = 0; d < 3; ++d) {
    Eigen::VectorXd rhs(freeCount);
    for (int32_t f = 0; f < m_functionCount; ++f)
      if (freeIndex[size_t(f)] >= 0) rhs[freeIndex[size_t(f)]] = Mv[3 * f + d];
    const Eigen::VectorXd x = mass.solve(rhs);
    for (int32_t f = 0; f < m_functionCount; ++f)
      if (freeIndex[size_t(f)] >= 0) b.m_v[3 * f + d] = x[freeIndex[size_t(f)]];
  }
  b.m_warm = m_warm;
  b.updateSurface();
  return made;
}

}  // namespace gf::detail
