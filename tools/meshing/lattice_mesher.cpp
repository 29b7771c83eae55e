// Design note. The mesh is a subset of a fixed lattice, so it conforms by construction and its
// tets start with known shapes (Kuhn tets: dihedral angles 45, 60 and 90 degrees, radius ratio
// 0.72); everything after that only selects tets and moves boundary nodes a bounded distance.
//  1. Grid: cubic cells of side h over the soup's box, padded by kPad cells on every side, each
//     split into the 6 tets that share the cell's main diagonal (the same in every cell, so
//     neighbours conform). A tet is (cell, permutation of the axes); none is stored until kept.
//  2. Inside: the winding number w at every grid node (the BVH's far field makes this
//     O(nodes log triangles)). A tet with all four corners at w >= 1/2 is kept, with none is
//     dropped, and a mixed one is decided by w at its centroid.
//  3. Manifold boundary: gf::validate() wants every boundary edge on exactly two boundary faces.
//     Where kept tets touch only along an edge the fan around it has gaps; the fan is filled
//     (all lattice tets around the edge kept) and the check repeated until none is left. Filling
//     only adds tets, so it ends; it adds a few tets along thin junctions.
//  4. Snap: each boundary node moves towards the closest point of the soup, at most maxSnap
//     cells from its lattice point (below half a cell no two nodes can meet, so no duplicate
//     nodes), and only as far (full, half, quarter) as keeps every incident tet positive and
//     its smallest dihedral angle above minDihedralDeg (or no worse than before). Nodes with no
//     triangle within a cell (on the surface the winding number spans across a hole) stay.
//     Two sweeps in node order: deterministic.
#include "meshing/lattice_mesher.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <vector>

namespace gf::meshing {
namespace {

constexpr int kPad = 2;                  // empty cells around the box: fans never reach the edge
constexpr int kRepairRounds = 64;        // manifold repair passes before giving up
constexpr size_t kMaxTets = 20'000'000;  // ~2 GB while the boundary faces are sorted
constexpr int kSubsamples = 3;           // per axis, in cut cells, for the reference volume
constexpr double kPi = 3.14159265358979323846;

double seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The 6 Kuhn tets of a cell as corner numbers (bit 0: +x, bit 1: +y, bit 2: +z), positively
// oriented.
struct KuhnTable {
  int corner[6][4];
  KuhnTable() {
    const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (int p = 0; p < 6; ++p) {
      const int a = 1 << perms[p][0], b = 1 << perms[p][1];
      int* c = corner[p];
      c[0] = 0;
      c[1] = a;
      c[2] = a | b;
      c[3] = 7;
      // Orientation of the unit-cube tet: det of the three corner offsets.
      auto off = [](int k) { return Vec3{double(k & 1), double((k >> 1) & 1), double(k >> 2)}; };
      if (dot(off(c[1]), cross(off(c[2]), off(c[3]))) < 0) std::swap(c[2], c[3]);
    }
  }
};
const KuhnTable kKuhn;

// The lattice: node and cell numbering, node positions.
struct Grid {
  Vec3 origin;
  double h = 0;
  int n[3] = {0, 0, 0};  // cells per axis
  size_t nodeId(int i, int j, int k) const {
    return static_cast<size_t>(i) +
           static_cast<size_t>(n[0] + 1) *
               (static_cast<size_t>(j) + static_cast<size_t>(n[1] + 1) * static_cast<size_t>(k));
  }
  size_t cellId(int i, int j, int k) const {
    return static_cast<size_t>(i) +
           static_cast<size_t>(n[0]) *
               (static_cast<size_t>(j) + static_cast<size_t>(n[1]) * static_cast<size_t>(k));
  }
  size_t nodeCount() const {
    return static_cast<size_t>(n[0] + 1) * static_cast<size_t>(n[1] + 1) *
           static_cast<size_t>(n[2] + 1);
  }
  size_t cellCount() const {
    return static_cast<size_t>(n[0]) * static_cast<size_t>(n[1]) * static_cast<size_t>(n[2]);
  }
  void nodeIndex(size_t id, int ijk[3]) const {
    ijk[0] = static_cast<int>(id % static_cast<size_t>(n[0] + 1));
    id /= static_cast<size_t>(n[0] + 1);
    ijk[1] = static_cast<int>(id % static_cast<size_t>(n[1] + 1));
    ijk[2] = static_cast<int>(id / static_cast<size_t>(n[1] + 1));
  }
  void cellIndex(size_t id, int ijk[3]) const {
    ijk[0] = static_cast<int>(id % static_cast<size_t>(n[0]));
    id /= static_cast<size_t>(n[0]);
    ijk[1] = static_cast<int>(id % static_cast<size_t>(n[1]));
    ijk[2] = static_cast<int>(id / static_cast<size_t>(n[1]));
  }
  Vec3 position(int i, int j, int k) const {
    return origin + h * Vec3{double(i), double(j), double(k)};
  }
  // Global node of corner c (bits as in KuhnTable) of cell ijk.
  size_t cornerNode(const int ijk[3], int c) const {
    return nodeId(ijk[0] + (c & 1), ijk[1] + ((c >> 1) & 1), ijk[2] + (c >> 2));
  }
};

Grid makeGrid(const TriangleSoup& soup, int cells) {
  Grid g;
  const Vec3 ext = soup.hi() - soup.lo();
  const double longest = std::max({ext.x, ext.y, ext.z});
  g.h = longest / cells;
  for (int k = 0; k < 3; ++k) {
    const int inner = std::max(1, static_cast<int>(std::ceil(ext[k] / g.h - 1e-9)));
    g.n[k] = inner + 2 * kPad;
    // Centre the soup in the padded grid.
    g.origin[k] = soup.lo()[k] - 0.5 * (g.n[k] * g.h - ext[k]);
  }
  return g;
}

// Sorted node triple of a face, with the tet it came from.
struct FaceKey {
  std::array<size_t, 3> v;
  bool operator<(const FaceKey& o) const { return v < o.v; }
  bool operator==(const FaceKey& o) const { return v == o.v; }
};

// Tet corners (lattice nodes) of tet t = 6 * cell + perm.
std::array<size_t, 4> tetNodes(const Grid& g, size_t t) {
  int ijk[3];
  g.cellIndex(t / 6, ijk);
  const int* c = kKuhn.corner[t % 6];
  return {g.cornerNode(ijk, c[0]), g.cornerNode(ijk, c[1]), g.cornerNode(ijk, c[2]),
          g.cornerNode(ijk, c[3])};
}

// Boundary faces of the kept tets (faces of exactly one), as sorted node triples.
std::vector<FaceKey> boundaryFaces(const Grid& g, const std::vector<size_t>& kept) {
  std::vector<FaceKey> faces;
  faces.reserve(4 * kept.size());
  for (size_t t : kept) {
    const std::array<size_t, 4> v = tetNodes(g, t);
    for (int skip = 0; skip < 4; ++skip) {
      FaceKey f;
      int m = 0;
      for (int k = 0; k < 4; ++k) {
        if (k != skip) f.v[static_cast<size_t>(m++)] = v[static_cast<size_t>(k)];
      }
      std::sort(f.v.begin(), f.v.end());
      faces.push_back(f);
    }
  }
  std::sort(faces.begin(), faces.end());
  std::vector<FaceKey> boundary;
  for (size_t i = 0; i < faces.size();) {
    size_t j = i + 1;
    while (j < faces.size() && faces[j] == faces[i]) ++j;
    if (j - i == 1) boundary.push_back(faces[i]);
    i = j;
  }
  return boundary;
}

// Boundary edges that are not on exactly two boundary faces.
std::vector<std::pair<size_t, size_t>> badEdges(const std::vector<FaceKey>& boundary) {
  std::vector<std::pair<size_t, size_t>> edges;
  edges.reserve(3 * boundary.size());
  for (const FaceKey& f : boundary) {
    edges.push_back({f.v[0], f.v[1]});
    edges.push_back({f.v[0], f.v[2]});
    edges.push_back({f.v[1], f.v[2]});
  }
  std::sort(edges.begin(), edges.end());
  std::vector<std::pair<size_t, size_t>> bad;
  for (size_t i = 0; i < edges.size();) {
    size_t j = i + 1;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i != 2) bad.push_back(edges[i]);
    i = j;
  }
  return bad;
}

// Keeps every lattice tet around edge (a, b); returns how many were not kept before.
size_t fillFan(const Grid& g, size_t a, size_t b, std::vector<uint8_t>& keep,
               std::vector<size_t>& kept) {
  int pa[3], pb[3];
  g.nodeIndex(a, pa);
  g.nodeIndex(b, pb);
  int lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = std::max(std::max(pa[k], pb[k]) - 1, 0);
    hi[k] = std::min(std::min(pa[k], pb[k]), g.n[k] - 1);
  }
  size_t added = 0;
  for (int k = lo[2]; k <= hi[2]; ++k) {
    for (int j = lo[1]; j <= hi[1]; ++j) {
      for (int i = lo[0]; i <= hi[0]; ++i) {
        const size_t cell = g.cellId(i, j, k);
        for (size_t p = 0; p < 6; ++p) {
          const size_t t = 6 * cell + p;
          if (keep[t]) continue;
          const std::array<size_t, 4> v = tetNodes(g, t);
          if (std::find(v.begin(), v.end(), a) == v.end()) continue;
          if (std::find(v.begin(), v.end(), b) == v.end()) continue;
          keep[t] = 1;
          kept.push_back(t);
          ++added;
        }
      }
    }
  }
  return added;
}

// Six-volume (signed), extreme dihedral angles (radians) and radius ratio of a tet; the angles
// and the ratio are of the shape whatever the sign of the volume.
struct TetShape {
  double sixVolume = 0, minDihedral = 0, maxDihedral = 0, radiusRatio = 0;
};

TetShape tetShape(const Vec3 p[4]) {
  TetShape s;
  const Vec3 a = p[1] - p[0], b = p[2] - p[0], c = p[3] - p[0];
  s.sixVolume = dot(a, cross(b, c));
  // Outward area vectors of the face opposite each corner.
  Vec3 n[4];
  double area = 0;
  for (int i = 0; i < 4; ++i) {
    const Vec3& q0 = p[(i + 1) % 4];
    const Vec3& q1 = p[(i + 2) % 4];
    const Vec3& q2 = p[(i + 3) % 4];
    n[i] = 0.5 * cross(q1 - q0, q2 - q0);
    if (dot(n[i], p[i] - q0) > 0) n[i] = -n[i];
    area += norm(n[i]);
  }
  s.minDihedral = kPi;
  for (int i = 0; i < 4; ++i) {
    for (int j = i + 1; j < 4; ++j) {
      const double ln = norm(n[i]) * norm(n[j]);
      const double cosine = ln > 0 ? std::clamp(dot(n[i], n[j]) / ln, -1.0, 1.0) : 1.0;
      const double angle = kPi - std::acos(cosine);
      s.minDihedral = std::min(s.minDihedral, angle);
      s.maxDihedral = std::max(s.maxDihedral, angle);
    }
  }
  // r_in = 3V / A = sixVolume / (2A); r_circ = |a^2 (b x c) + b^2 (c x a) + c^2 (a x b)| / 2|6V|.
  const Vec3 m = dot(a, a) * cross(b, c) + dot(b, b) * cross(c, a) + dot(c, c) * cross(a, b);
  const double v6 = std::abs(s.sixVolume);
  if (v6 > 0 && area > 0) s.radiusRatio = 3 * (v6 / (2 * area)) / (norm(m) / (2 * v6));
  return s;
}

bool acceptable(const TetShape& s, double floor, double before) {
  return s.sixVolume > 0 && s.minDihedral >= std::min(floor, before);
}

}  // namespace

TetQuality measureQuality(const TetMesh& mesh) {
  TetQuality q;
  if (mesh.tetCount() == 0) return q;
  q.minDihedralDeg = 180;
  q.minRadiusRatio = 1;
  q.minVolume = INFINITY;
  double sum = 0;
  for (size_t e = 0; e < mesh.tetCount(); ++e) {
    Vec3 p[4];
    for (int k = 0; k < 4; ++k) {
      const size_t v = 3 * static_cast<size_t>(mesh.tets[4 * e + static_cast<size_t>(k)]);
      p[k] = {mesh.positions[v], mesh.positions[v + 1], mesh.positions[v + 2]};
    }
    const TetShape s = tetShape(p);
    q.minDihedralDeg = std::min(q.minDihedralDeg, s.minDihedral * 180 / kPi);
    q.maxDihedralDeg = std::max(q.maxDihedralDeg, s.maxDihedral * 180 / kPi);
    q.minRadiusRatio = std::min(q.minRadiusRatio, s.radiusRatio);
    q.minVolume = std::min(q.minVolume, s.sixVolume / 6);
    sum += s.radiusRatio;
  }
  q.meanRadiusRatio = sum / static_cast<double>(mesh.tetCount());
  return q;
}

Result<LatticeResult> latticeMesh(const TriangleSoup& soup, const LatticeOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  if (soup.triangleCount() == 0) return fail("the surface has no triangles");
  const Vec3 ext = soup.hi() - soup.lo();
  if (!(std::max({ext.x, ext.y, ext.z}) > 0)) return fail("the surface has no extent");
  LatticeResult r;

  // Resolution: given, or from the target count and a coarse estimate of the inside volume
  // (6 tets per inside cell).
  int cells = o.cells;
  if (cells <= 0 && o.targetTets > 0) {
    const Grid coarse = makeGrid(soup, 24);
    size_t inside = 0;
    for (int k = 0; k < coarse.n[2]; ++k) {
      for (int j = 0; j < coarse.n[1]; ++j) {
        for (int i = 0; i < coarse.n[0]; ++i) {
          const Vec3 c = coarse.position(i, j, k) + 0.5 * Vec3{coarse.h, coarse.h, coarse.h};
          inside += soup.winding(c, o.beta) >= 0.5;
        }
      }
    }
    const double volume = std::max<double>(static_cast<double>(inside), 1) * std::pow(coarse.h, 3);
    const double h = std::cbrt(6 * volume / o.targetTets);
    cells = static_cast<int>(std::ceil(std::max({ext.x, ext.y, ext.z}) / h));
  }
  if (cells <= 0) cells = kDefaultCells;
  cells = std::clamp(cells, 1, kMaxCells);
  const Grid g = makeGrid(soup, cells);
  r.cell = g.h;
  for (int k = 0; k < 3; ++k) r.dims[k] = g.n[k];

  // 2. The winding number at every grid node, then the tets it puts inside.
  std::vector<float> w(g.nodeCount());
  for (int k = 0; k <= g.n[2]; ++k) {
    for (int j = 0; j <= g.n[1]; ++j) {
      for (int i = 0; i <= g.n[0]; ++i) {
        // The padding nodes are outside the soup's box; w there is still computed (it may be
        // non-zero for open input) so that the test is the same everywhere.
        w[g.nodeId(i, j, k)] = static_cast<float>(soup.winding(g.position(i, j, k), o.beta));
      }
    }
  }
  std::vector<uint8_t> keep(6 * g.cellCount(), 0);
  std::vector<size_t> kept;
  for (int k = 0; k < g.n[2]; ++k) {
    for (int j = 0; j < g.n[1]; ++j) {
      for (int i = 0; i < g.n[0]; ++i) {
        const int ijk[3] = {i, j, k};
        const size_t cell = g.cellId(i, j, k);
        for (size_t p = 0; p < 6; ++p) {
          int in = 0;
          Vec3 centroid;
          for (int c : kKuhn.corner[p]) {
            const size_t v = g.cornerNode(ijk, c);
            in += w[v] >= 0.5f;
            centroid += 0.25 * g.position(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2));
          }
          const bool inside = in == 4 || (in > 0 && soup.winding(centroid, o.beta) >= 0.5);
          if (inside) {
            keep[6 * cell + p] = 1;
            kept.push_back(6 * cell + p);
          }
        }
        if (kept.size() > kMaxTets) {
          return fail("the lattice at ", std::to_string(cells), " cells would make more than ",
                      std::to_string(kMaxTets), " tets (use fewer cells)");
        }
      }
    }
  }
  if (kept.empty()) {
    char h[32];
    std::snprintf(h, sizeof h, "%.4g", g.h);
    return fail("no tetrahedron is inside the surface at ", std::to_string(cells),
                " cells along the longest axis (the surface encloses nothing, or only parts "
                "thinner than a cell, ",
                h, " wide: try more cells)");
  }

  // 3. Fill the fans of non-manifold boundary edges until there are none.
  std::vector<FaceKey> boundary;
  for (int round = 0;; ++round) {
    boundary = boundaryFaces(g, kept);
    const std::vector<std::pair<size_t, size_t>> bad = badEdges(boundary);
    if (bad.empty()) break;
    size_t added = 0;
    for (const auto& [a, b] : bad) added += fillFan(g, a, b, keep, kept);
    r.repairTets += added;
    if (added == 0 || round == kRepairRounds) {
      return fail("cannot make the lattice mesh's boundary manifold: ", std::to_string(bad.size()),
                  " edges remain after ", std::to_string(round + 1), " rounds");
    }
  }
  std::sort(kept.begin(), kept.end());

  // Compact: lattice nodes used by kept tets become mesh nodes, in lattice order.
  std::vector<int32_t> nodeOf(g.nodeCount(), -1);
  for (size_t t : kept) {
    for (size_t v : tetNodes(g, t)) nodeOf[v] = 0;
  }
  TetMesh& m = r.mesh;
  std::vector<Vec3> lattice;
  for (size_t v = 0; v < g.nodeCount(); ++v) {
    if (nodeOf[v] < 0) continue;
    nodeOf[v] = static_cast<int32_t>(lattice.size());
    int ijk[3];
    g.nodeIndex(v, ijk);
    lattice.push_back(g.position(ijk[0], ijk[1], ijk[2]));
  }
  for (size_t t : kept) {
    for (size_t v : tetNodes(g, t)) m.tets.push_back(nodeOf[v]);
  }
  std::vector<Vec3> pos = lattice;
  const size_t nn = pos.size(), nt = m.tetCount();

  // Node -> tets (CSR) for the local quality checks.
  std::vector<size_t> start(nn + 1, 0), list(4 * nt);
  for (int32_t v : m.tets) ++start[static_cast<size_t>(v) + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  {
    std::vector<size_t> fill(start.begin(), start.end() - 1);
    for (size_t e = 0; e < nt; ++e) {
      for (size_t k = 0; k < 4; ++k) list[fill[static_cast<size_t>(m.tets[4 * e + k])]++] = e;
    }
  }
  auto shapeOf = [&](size_t e) {
    Vec3 p[4];
    for (size_t k = 0; k < 4; ++k) p[k] = pos[static_cast<size_t>(m.tets[4 * e + k])];
    return tetShape(p);
  };

  // 4. Snap the boundary nodes.
  std::vector<uint8_t> onBoundary(nn, 0);
  for (const FaceKey& f : boundary) {
    for (size_t v : f.v) onBoundary[static_cast<size_t>(nodeOf[v])] = 1;
  }
  r.boundaryNodes = static_cast<size_t>(std::count(onBoundary.begin(), onBoundary.end(), 1));
  const double floor = o.minDihedralDeg * kPi / 180, maxMove = o.maxSnap * g.h;
  std::vector<uint8_t> moved(nn, 0);
  std::vector<double> before;
  for (int sweep = 0; sweep < 2 && maxMove > 0; ++sweep) {
    for (size_t v = 0; v < nn; ++v) {
      if (!onBoundary[v]) continue;
      Vec3 target;
      if (!soup.closestPoint(pos[v], g.h, target)) continue;
      // Bounded displacement from the lattice point.
      Vec3 d = target - lattice[v];
      const double len = norm(d);
      if (len > maxMove) d = (maxMove / len) * d;
      target = lattice[v] + d;
      const Vec3 from = pos[v];
      if (norm(target - from) < 1e-12 * g.h) continue;
      before.clear();
      for (size_t i = start[v]; i < start[v + 1]; ++i) {
        before.push_back(shapeOf(list[i]).minDihedral);
      }
      for (double f : {1.0, 0.5, 0.25}) {
        pos[v] = from + f * (target - from);
        bool ok = true;
        for (size_t i = start[v]; ok && i < start[v + 1]; ++i) {
          ok = acceptable(shapeOf(list[i]), floor, before[i - start[v]]);
        }
        if (ok) {
          moved[v] = 1;
          break;
        }
        pos[v] = from;
      }
    }
  }
  r.snappedNodes = static_cast<size_t>(std::count(moved.begin(), moved.end(), 1));
  m.positions.resize(3 * nn);
  for (size_t v = 0; v < nn; ++v) {
    for (int k = 0; k < 3; ++k) m.positions[3 * v + static_cast<size_t>(k)] = pos[v][k];
  }

  // Parts: connected through shared nodes.
  std::vector<size_t> parent(nn);
  std::iota(parent.begin(), parent.end(), size_t{0});
  auto root = [&](size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (size_t e = 0; e < nt; ++e) {
    for (size_t k = 1; k < 4; ++k) {
      parent[root(static_cast<size_t>(m.tets[4 * e + k]))] =
          root(static_cast<size_t>(m.tets[4 * e]));
    }
  }
  for (size_t i = 0; i < nn; ++i) r.parts += root(i) == i;

  if (Result<void> valid = validate(m, "lattice mesh"); !valid) return valid.error();
  r.meshSeconds = seconds(t0);

  // Reference volume of {w >= 1/2}: whole cells where all corners agree, a finer sample in the
  // cells the surface crosses.
  const auto t1 = std::chrono::steady_clock::now();
  const double cellVolume = g.h * g.h * g.h, step = g.h / kSubsamples;
  double volume = 0;
  for (int k = 0; k < g.n[2]; ++k) {
    for (int j = 0; j < g.n[1]; ++j) {
      for (int i = 0; i < g.n[0]; ++i) {
        const int ijk[3] = {i, j, k};
        int in = 0;
        for (int c = 0; c < 8; ++c) in += w[g.cornerNode(ijk, c)] >= 0.5f;
        if (in == 0) continue;
        if (in == 8) {
          volume += cellVolume;
          continue;
        }
        int count = 0;
        const Vec3 corner = g.position(i, j, k);
        for (int c = 0; c < kSubsamples; ++c) {
          for (int b = 0; b < kSubsamples; ++b) {
            for (int a = 0; a < kSubsamples; ++a) {
              const Vec3 q = corner + step * Vec3{a + 0.5, b + 0.5, c + 0.5};
              count += soup.winding(q, o.beta) >= 0.5;
            }
          }
        }
        volume += cellVolume * count / (kSubsamples * kSubsamples * kSubsamples);
      }
    }
  }
  r.windingVolume = volume;
  r.volumeSeconds = seconds(t1);
  return r;
}

}  // namespace gf::meshing
