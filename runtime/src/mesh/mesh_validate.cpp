// Mesh validation. Checks run cheapest first, and each stops at the first problem so the
// message can name one element or node precisely. Tolerances are relative to the bounding-box
// diagonal L so that a mesh in millimetres and one in kilometres behave the same.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <unordered_map>

#include "mesh/mesh_internal.h"

namespace gf {
namespace detail {
namespace {

constexpr double kZeroVolumeRel = 1e-12;  // |6V| below this * L^3 is a degenerate tet
constexpr double kDuplicateRel = 1e-10;   // nodes closer than this * L are the same point

// Formats "file:line: element T: " or "source: element e: " for messages.
class Namer {
 public:
  Namer(const std::string& source, const MeshSourceMap* map) : m_source(source), m_map(map) {}

  std::string tet(size_t e) const {
    if (m_map && e < m_map->tetTags.size()) {
      return m_map->tetFile + ":" + std::to_string(m_map->tetLines[e]) + ": element " +
             std::to_string(m_map->tetTags[e]) + ": ";
    }
    return m_source + ": element " + std::to_string(e) + ": ";
  }
  std::string nodeAt(size_t i) const {
    if (m_map && i < m_map->nodeTags.size()) {
      return m_map->nodeFile + ":" + std::to_string(m_map->nodeLines[i]) + ": node " +
             std::to_string(m_map->nodeTags[i]) + ": ";
    }
    return m_source + ": node " + std::to_string(i) + ": ";
  }
  // A node as the user numbers it (file number when loaded from a file).
  std::string node(int64_t i) const {
    if (m_map && i >= 0 && static_cast<size_t>(i) < m_map->nodeTags.size()) {
      return std::to_string(m_map->nodeTags[static_cast<size_t>(i)]);
    }
    return std::to_string(i);
  }

 private:
  const std::string& m_source;
  const MeshSourceMap* m_map;
};

std::string num(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

// Duplicate nodes through a hash grid: cells much larger than the tolerance, so nearly every
// query touches one cell; hash collisions only cost time since distances are compared exactly.
Result<void> checkDuplicates(const TetMesh& mesh, double tol, const Namer& name) {
  const size_t n = mesh.nodeCount();
  const double* p = mesh.positions.data();
  const double cell = 1000.0 * tol;
  double lo[3] = {p[0], p[1], p[2]};
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], p[3 * i + static_cast<size_t>(k)]);
  }
  auto cellOf = [&](double x, int k) {
    return static_cast<int64_t>(std::floor((x - lo[k]) / cell));
  };
  auto hash = [](int64_t a, int64_t b, int64_t c) {
    uint64_t h = static_cast<uint64_t>(a) * 0x9E3779B97F4A7C15ull;
    h ^= static_cast<uint64_t>(b) * 0xC2B2AE3D27D4EB4Full + (h << 6) + (h >> 2);
    h ^= static_cast<uint64_t>(c) * 0x165667B19E3779F9ull + (h << 6) + (h >> 2);
    return h;
  };
  std::unordered_map<uint64_t, int32_t> head;
  head.reserve(n);
  std::vector<int32_t> next(n, -1);
  for (size_t i = 0; i < n; ++i) {
    const double* x = p + 3 * i;
    int64_t a[3], b[3];
    for (int k = 0; k < 3; ++k) {
      a[k] = cellOf(x[k] - tol, k);
      b[k] = cellOf(x[k] + tol, k);
    }
    for (int64_t cx = a[0]; cx <= b[0]; ++cx) {
      for (int64_t cy = a[1]; cy <= b[1]; ++cy) {
        for (int64_t cz = a[2]; cz <= b[2]; ++cz) {
          auto it = head.find(hash(cx, cy, cz));
          if (it == head.end()) continue;
          for (int32_t j = it->second; j >= 0; j = next[static_cast<size_t>(j)]) {
            const double* y = p + 3 * static_cast<size_t>(j);
            const double d =
                std::sqrt((x[0] - y[0]) * (x[0] - y[0]) + (x[1] - y[1]) * (x[1] - y[1]) +
                          (x[2] - y[2]) * (x[2] - y[2]));
            if (d <= tol) {
              return fail(name.nodeAt(i), "duplicate node: same position as node ", name.node(j),
                          " (distance ", num(d), ", tolerance ", num(tol), ")");
            }
          }
        }
      }
    }
    const uint64_t h = hash(cellOf(x[0], 0), cellOf(x[1], 1), cellOf(x[2], 2));
    auto [it, inserted] = head.emplace(h, static_cast<int32_t>(i));
    if (!inserted) {
      next[i] = it->second;
      it->second = static_cast<int32_t>(i);
    }
  }
  return {};
}

// A face of more than two tets, or a boundary edge not on exactly two boundary faces, makes
// the boundary non-manifold (the surface code and fracture assume a 2-manifold boundary).
Result<void> checkManifold(const TetMesh& mesh, const Namer& name) {
  const std::vector<FaceRecord> faces = sortedFaces(mesh);
  struct EdgeRecord {
    int32_t a, b, tet;
  };
  std::vector<EdgeRecord> edges;
  for (size_t i = 0; i < faces.size();) {
    size_t j = i + 1;
    while (j < faces.size() && std::equal(faces[j].key, faces[j].key + 3, faces[i].key)) ++j;
    if (j - i > 2) {
      return fail(name.tet(static_cast<size_t>(faces[i].tet)), "non-manifold: face (",
                  name.node(faces[i].key[0]), ", ", name.node(faces[i].key[1]), ", ",
                  name.node(faces[i].key[2]), ") is shared by ", std::to_string(j - i), " tets");
    }
    if (j - i == 1) {
      const int32_t* k = faces[i].key;
      edges.push_back({k[0], k[1], faces[i].tet});
      edges.push_back({k[0], k[2], faces[i].tet});
      edges.push_back({k[1], k[2], faces[i].tet});
    }
    i = j;
  }
  std::sort(edges.begin(), edges.end(), [](const EdgeRecord& x, const EdgeRecord& y) {
    if (x.a != y.a) return x.a < y.a;
    if (x.b != y.b) return x.b < y.b;
    return x.tet < y.tet;
  });
  for (size_t i = 0; i < edges.size();) {
    size_t j = i + 1;
    while (j < edges.size() && edges[j].a == edges[i].a && edges[j].b == edges[i].b) ++j;
    if (j - i != 2) {
      return fail(name.tet(static_cast<size_t>(edges[i].tet)), "non-manifold boundary: edge (",
                  name.node(edges[i].a), ", ", name.node(edges[i].b), ") is on ",
                  std::to_string(j - i), " boundary faces (expected 2)");
    }
    i = j;
  }
  return {};
}

}  // namespace

Result<void> validateMesh(TetMesh& mesh, const std::string& source, const MeshSourceMap* map,
                          int* flippedFixed) {
  if (flippedFixed) *flippedFixed = 0;
  const Namer name(source, map);
  if (mesh.positions.size() % 3 != 0) {
    return fail(source, ": positions hold ", std::to_string(mesh.positions.size()),
                " values, not a multiple of 3");
  }
  if (mesh.tets.size() % 4 != 0) {
    return fail(source, ": tets hold ", std::to_string(mesh.tets.size()),
                " indices, not a multiple of 4");
  }
  const size_t nn = mesh.nodeCount();
  const size_t nt = mesh.tetCount();
  if (nn == 0) return fail(source, ": mesh has no nodes");
  if (nt == 0) return fail(source, ": mesh has no tetrahedra");
  if (nn > static_cast<size_t>(INT32_MAX))
    return fail(source, ": too many nodes for int32 indices");

  // Coordinates, and the scale for the relative tolerances.
  double lo[3], hi[3];
  for (int k = 0; k < 3; ++k) lo[k] = hi[k] = mesh.positions[static_cast<size_t>(k)];
  for (size_t i = 0; i < nn; ++i) {
    for (int k = 0; k < 3; ++k) {
      const double x = mesh.positions[3 * i + static_cast<size_t>(k)];
      if (!std::isfinite(x)) {
        return fail(name.nodeAt(i), "non-finite coordinate ",
                    std::string(1, static_cast<char>('x' + k)), " = ", num(x));
      }
      lo[k] = std::min(lo[k], x);
      hi[k] = std::max(hi[k], x);
    }
  }

  // Connectivity.
  std::vector<uint8_t> referenced(nn, 0);
  for (size_t e = 0; e < nt; ++e) {
    const int32_t* t = &mesh.tets[4 * e];
    for (int k = 0; k < 4; ++k) {
      if (t[k] < 0 || static_cast<size_t>(t[k]) >= nn) {
        return fail(name.tet(e), "node index ", std::to_string(t[k]), " out of range [0, ",
                    std::to_string(nn), ")");
      }
      for (int m = 0; m < k; ++m) {
        if (t[m] == t[k]) return fail(name.tet(e), "node ", name.node(t[k]), " repeated");
      }
      referenced[static_cast<size_t>(t[k])] = 1;
    }
  }
  for (size_t i = 0; i < nn; ++i) {
    if (!referenced[i]) return fail(name.nodeAt(i), "unreferenced node (in no tetrahedron)");
  }

  const double scale =
      std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                (hi[2] - lo[2]) * (hi[2] - lo[2]));
  const double zeroVolume = kZeroVolumeRel * scale * scale * scale;

  // Volumes: degenerate is an error, merely inverted is an ordering mistake we can repair.
  int flipped = 0;
  for (size_t e = 0; e < nt; ++e) {
    int32_t* t = &mesh.tets[4 * e];
    const double v6 = tetSixVolume(mesh.positions.data(), t);
    if (!(std::abs(v6) >= zeroVolume) || scale == 0) {
      return fail(name.tet(e), "zero volume (6V = ", num(v6), ", threshold ", num(zeroVolume), ")");
    }
    if (v6 < 0) {
      std::swap(t[2], t[3]);
      ++flipped;
    }
  }

  Result<void> dup = checkDuplicates(mesh, kDuplicateRel * scale, name);
  if (!dup.ok()) return dup;
  Result<void> manifold = checkManifold(mesh, name);
  if (!manifold.ok()) return manifold;
  if (flippedFixed) *flippedFixed = flipped;
  return {};
}

}  // namespace detail

Result<void> validate(TetMesh& mesh, const std::string& source, int* flippedFixed) {
  return detail::validateMesh(mesh, source, nullptr, flippedFixed);
}

}  // namespace gf
