// Structured tet meshes: box (optionally V-notched), slab, cylinder, tube and sphere. All are built
// from splits that conform between neighbouring cells (Kuhn for cubes, the smallest-index
// diagonal rule for prisms), and every tet is oriented by its computed volume, so the outputs
// pass validate() by construction.
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "mesh/mesh_internal.h"

namespace gf::gen {
namespace {

// Appends tet (a, b, c, d), swapping two nodes if it is negatively oriented.
void addTet(TetMesh& m, int32_t a, int32_t b, int32_t c, int32_t d) {
  int32_t t[4] = {a, b, c, d};
  if (detail::tetSixVolume(m.positions.data(), t) < 0) std::swap(t[2], t[3]);
  m.tets.insert(m.tets.end(), t, t + 4);
}

// Kuhn (Freudenthal) split of a cube into 6 tets around the diagonal from corner 0 to corner 7
// (corner bits: 1 = +x, 2 = +y, 4 = +z). `mirror` flips axes (bit k flips axis k) so the
// diagonal can point another way; the split of each face then depends only on the face, which
// keeps neighbours conforming as long as they use the same mirror or meet on a mirror plane.
void kuhnCube(TetMesh& m, const int32_t corner[8], int mirror) {
  static constexpr int kPerms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                       {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (const auto& p : kPerms) {
    const int v1 = 1 << p[0];
    const int v2 = v1 | (1 << p[1]);
    addTet(m, corner[0 ^ mirror], corner[v1 ^ mirror], corner[v2 ^ mirror], corner[7 ^ mirror]);
  }
}

// Column x positions, with the columns nearest the notch's tip and shoulders moved onto them
// (when that keeps the columns strictly increasing), so the carved V is exact.
std::vector<double> columns(double sx, int nx, const double* kinks, int nk) {
  std::vector<double> x(static_cast<size_t>(nx) + 1);
  for (int i = 0; i <= nx; ++i) x[static_cast<size_t>(i)] = sx * i / nx;
  std::vector<bool> moved(x.size(), false);
  for (int k = 0; k < nk; ++k) {
    const double kx = kinks[k];
    if (kx <= 0 || kx >= sx) continue;
    const int i = static_cast<int>(std::lround(kx / sx * nx));
    if (i <= 0 || i >= nx || moved[static_cast<size_t>(i)]) continue;
    const size_t u = static_cast<size_t>(i);
    if (x[u - 1] < kx && kx < x[u + 1]) {
      x[u] = kx;
      moved[u] = true;
    }
  }
  return x;
}

// Extrudes a triangulated x-z section along y into `layers` prisms of 3 tets each. Prism
// (a,b,c)-(a',b',c') with a < b < c: each quad face takes the diagonal from its smaller bottom
// node to the other top node, a rule both prisms sharing the face agree on.
TetMesh extrude(const std::vector<double>& dx, const std::vector<double>& dz,
                const std::vector<std::array<int32_t, 3>>& tris, double h, int layers) {
  TetMesh m;
  const int32_t perLayer = static_cast<int32_t>(dx.size());
  for (int l = 0; l <= layers; ++l) {
    for (size_t v = 0; v < dx.size(); ++v) {
      m.positions.insert(m.positions.end(), {dx[v], h * l / layers, dz[v]});
    }
  }
  for (int l = 0; l < layers; ++l) {
    for (auto t : tris) {
      std::sort(t.begin(), t.end());
      const int32_t a = t[0] + l * perLayer, b = t[1] + l * perLayer, c = t[2] + l * perLayer;
      const int32_t a1 = a + perLayer, b1 = b + perLayer, c1 = c + perLayer;
      addTet(m, a, b, c, c1);
      addTet(m, a, b, c1, b1);
      addTet(m, a, b1, c1, a1);
    }
  }
  return m;
}

}  // namespace

TetMesh box(double sx, double sy, double sz, int nx, int ny, int nz, const BoxOptions& o) {
  nx = std::max(nx, 1);
  ny = std::max(ny, 1);
  nz = std::max(nz, 1);
  const double depth = std::clamp(o.notchDepth, 0.0, 0.95 * sy);
  const double angle = std::clamp(o.notchAngleDeg, 1.0, 179.0) * std::numbers::pi / 180.0;
  const double tipX = o.notchX < 0 ? 0.5 * sx : o.notchX;
  const double halfWidth = depth * std::tan(0.5 * angle);  // of the V at the top face

  const double kinks[3] = {tipX - halfWidth, tipX, tipX + halfWidth};
  const std::vector<double> xs = columns(sx, nx, kinks, depth > 0 ? 3 : 0);
  // Top of the material over x: sy outside the V, the V's flank inside it.
  auto top = [&](double x) {
    if (depth <= 0) return sy;
    return std::min(sy, sy - depth + std::abs(x - tipX) * depth / halfWidth);
  };

  TetMesh m;
  const int px = nx + 1, py = ny + 1, pz = nz + 1;
  m.positions.reserve(3 * static_cast<size_t>(px) * py * pz);
  for (int k = 0; k < pz; ++k) {
    for (int j = 0; j < py; ++j) {
      for (int i = 0; i < px; ++i) {
        const double x = xs[static_cast<size_t>(i)];
        // Each column is squeezed in y down to the V profile; y -> y * top(x) / sy has a
        // positive Jacobian, so no tet inverts.
        m.positions.push_back(x);
        m.positions.push_back(top(x) * j / ny);
        m.positions.push_back(sz * k / nz);
      }
    }
  }
  auto id = [&](int i, int j, int k) { return static_cast<int32_t>(i + px * (j + py * k)); };
  m.tets.reserve(24 * static_cast<size_t>(nx) * ny * nz);
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        int32_t c[8];
        for (int b = 0; b < 8; ++b) c[b] = id(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1));
        // Mirror by cell parity: neighbours meet on mirror planes (conforming), and the
        // diagonals alternate, so the mesh has no preferred direction. With one diagonal for
        // all cells a beam under a vertical load also bends sideways.
        kuhnCube(m, c, (i & 1) | ((j & 1) << 1) | ((k & 1) << 2));
      }
    }
  }
  return m;
}

TetMesh slab(double sx, double sz, double t, int nx, int nz) {
  nx = std::max(nx, 1);
  nz = std::max(nz, 1);
  const double cell = std::min(sx / nx, sz / nz);
  const int ny = std::max(1, static_cast<int>(std::lround(t / cell)));
  return box(sx, t, sz, nx, ny, nz);
}

TetMesh cylinder(double r, double h, int segments, int layers, int rings) {
  segments = std::max(segments, 3);
  layers = std::max(layers, 1);
  rings = std::max(rings, 1);

  // Disc in x-z: a centre node and concentric rings; ring k has about segments*k/rings nodes.
  std::vector<double> dx{0.0}, dz{0.0};
  std::vector<int32_t> ringStart{0}, ringSize{1};
  for (int k = 1; k <= rings; ++k) {
    const int n = std::max(3, static_cast<int>(std::lround(double(segments) * k / rings)));
    ringStart.push_back(static_cast<int32_t>(dx.size()));
    ringSize.push_back(n);
    for (int s = 0; s < n; ++s) {
      const double a = 2.0 * std::numbers::pi * s / n;
      dx.push_back(r * k / rings * std::cos(a));
      dz.push_back(r * k / rings * std::sin(a));
    }
  }
  std::vector<std::array<int32_t, 3>> tris;
  for (int s = 0; s < ringSize[1]; ++s) {
    tris.push_back({0, ringStart[1] + s, ringStart[1] + (s + 1) % ringSize[1]});
  }
  // Between rings: walk both rings by angle, always advancing the one whose next node comes
  // first, so the strip is triangulated without overlaps whatever the node counts.
  for (int k = 1; k < rings; ++k) {
    const int32_t a0 = ringStart[static_cast<size_t>(k)],
                  b0 = ringStart[static_cast<size_t>(k) + 1];
    const int na = ringSize[static_cast<size_t>(k)], nb = ringSize[static_cast<size_t>(k) + 1];
    int i = 0, j = 0;
    while (i < na || j < nb) {
      const double ai = double(i + 1) / na, bj = double(j + 1) / nb;
      if (j >= nb || (i < na && ai <= bj)) {
        tris.push_back({a0 + i % na, b0 + j % nb, a0 + (i + 1) % na});
        ++i;
      } else {
        tris.push_back({a0 + i % na, b0 + j % nb, b0 + (j + 1) % nb});
        ++j;
      }
    }
  }

  return extrude(dx, dz, tris, h, layers);
}

TetMesh tube(double r, double rInner, double h, int segments, int layers, int rings) {
  segments = std::max(segments, 3);
  layers = std::max(layers, 1);
  rings = std::max(rings, 1);
  rInner = std::clamp(rInner, 0.0, r);
  if (rInner <= 0) return cylinder(r, h, segments, layers, rings);
  // Annulus in x-z: rings + 1 circles of `segments` nodes each, every quad between two
  // circles split into two triangles.
  std::vector<double> dx, dz;
  for (int k = 0; k <= rings; ++k) {
    const double rk = rInner + (r - rInner) * k / rings;
    for (int s = 0; s < segments; ++s) {
      const double a = 2.0 * std::numbers::pi * s / segments;
      dx.push_back(rk * std::cos(a));
      dz.push_back(rk * std::sin(a));
    }
  }
  std::vector<std::array<int32_t, 3>> tris;
  for (int k = 0; k < rings; ++k) {
    for (int s = 0; s < segments; ++s) {
      const int32_t a = k * segments + s, b = k * segments + (s + 1) % segments;
      tris.push_back({a, a + segments, b});
      tris.push_back({b, a + segments, b + segments});
    }
  }
  return extrude(dx, dz, tris, h, layers);
}

TetMesh sphere(double r, int n) {
  n = std::max(2, n + (n & 1));  // even, so the octant mirror planes are grid planes
  const int h = n / 2, p = n + 1;
  TetMesh m;
  m.positions.reserve(3 * static_cast<size_t>(p) * p * p);
  for (int k = 0; k <= n; ++k) {
    for (int j = 0; j <= n; ++j) {
      for (int i = 0; i <= n; ++i) {
        // Cube point q on the shell t = |q|_inf, blended towards the sphere as t -> 1: the
        // radius t((1-t)|q̂| + t) grows monotonically with t, so shells never cross.
        const double q[3] = {double(i - h) / h, double(j - h) / h, double(k - h) / h};
        const double t = std::max({std::abs(q[0]), std::abs(q[1]), std::abs(q[2])});
        double x[3] = {0, 0, 0};
        if (t > 0) {
          const double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
          const double scale = (1.0 - t) + t * t / len;
          for (int c = 0; c < 3; ++c) x[c] = r * q[c] * scale;
        }
        m.positions.insert(m.positions.end(), {x[0], x[1], x[2]});
      }
    }
  }
  auto id = [&](int i, int j, int k) { return static_cast<int32_t>(i + p * (j + p * k)); };
  for (int k = 0; k < n; ++k) {
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        int32_t c[8];
        for (int b = 0; b < 8; ++b) c[b] = id(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1));
        // Mirror per octant so every cell's diagonal points away from the centre: the corner
        // cells then split symmetrically and stay well shaped after the mapping.
        const int mirror = (i < h ? 1 : 0) | (j < h ? 2 : 0) | (k < h ? 4 : 0);
        kuhnCube(m, c, mirror);
      }
    }
  }
  return m;
}

}  // namespace gf::gen
