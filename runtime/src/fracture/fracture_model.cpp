#include "fracture/fracture_model.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "mesh/mesh_internal.h"

namespace gf::detail {

// Counting sort of tets into cells (CSR) keeps each cell's tets in id order, so the build
// and every query are deterministic.
void CentroidGrid::build(const std::vector<double>& centroids, int32_t count, double radius) {
  double hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::numeric_limits<double>::max();
    hi[a] = -std::numeric_limits<double>::max();
  }
  for (int32_t t = 0; t < count; ++t)
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], centroids[3 * size_t(t) + a]);
      hi[a] = std::max(hi[a], centroids[3 * size_t(t) + a]);
    }
  // A radius far below the mesh spacing would ask for more cells than tets; larger cells
  // keep the grid O(T) and stay correct because a query still spans +-1 cell >= R.
  const double maxCells = 4.0 * double(count) + 64.0;
  cell = radius;
  for (;;) {
    double cells = 1;
    for (int a = 0; a < 3; ++a) {
      dims[a] = int32_t(std::floor((hi[a] - lo[a]) / cell)) + 1;
      cells *= double(dims[a]);
    }
    if (cells <= maxCells) break;
    cell *= 1.5;
  }
  const size_t cellCount = size_t(dims[0]) * size_t(dims[1]) * size_t(dims[2]);
  start.assign(cellCount + 1, 0);
  tetCell.resize(size_t(count));
  for (int32_t t = 0; t < count; ++t) {
    const double* c = &centroids[3 * size_t(t)];
    tetCell[size_t(t)] = (coord(c[2], 2) * dims[1] + coord(c[1], 1)) * dims[0] + coord(c[0], 0);
    ++start[size_t(tetCell[size_t(t)]) + 1];
  }
  for (size_t i = 0; i < cellCount; ++i) start[i + 1] += start[i];
  items.resize(size_t(count));
  std::vector<int32_t> fill(start.begin(), start.end() - 1);
  for (int32_t t = 0; t < count; ++t) items[size_t(fill[size_t(tetCell[size_t(t)])]++)] = t;
}

Result<FractureModel> FractureModel::build(const RestMeshView& rest, const EdgeGraph& graph,
                                           const FractureSettings& settings, JobSystem* jobs,
                                           const FibreView& fibres) {
  // The model is built only for a fracturing body, whatever `enabled` says.
  FractureSettings checked = settings;
  checked.enabled = true;
  if (Result<void> r = checked.check(); !r) return fail("FractureSettings.", r.error().message);
  const double ratio = settings.fibreStrengthRatio;
  if (ratio != 1 && !fibres.present)
    return fail("FractureSettings.fibreStrengthRatio: ", std::to_string(ratio),
                " needs fibres (material.fibreStiffness > 0); use 1 for an isotropic strength");
  if (rest.tetCount < 0 || graph.tetEdges.size() != 6 * size_t(rest.tetCount) ||
      graph.nodeCount != rest.nodeCount)
    return fail("FractureModel: edge graph (", std::to_string(graph.tetEdges.size() / 6), " tets, ",
                std::to_string(graph.nodeCount), " nodes) does not match the mesh (",
                std::to_string(rest.tetCount), " tets, ", std::to_string(rest.nodeCount),
                " nodes)");
  JobSystem& js = jobs ? *jobs : serialJobs();

  FractureModel m;
  m.settings = settings;
  m.tetCount = rest.tetCount;
  m.edgeCount = graph.edgeCount;
  const double* x = rest.positions;
  const auto node = [&](int32_t v) { return Vec3{x[3 * v], x[3 * v + 1], x[3 * v + 2]}; };

  // Rest edge directions N_k of every tet: the rows of T (eq 4.9) follow from them.
  m.edgeDirections.resize(18 * size_t(m.tetCount));
  m.centroids.resize(3 * size_t(m.tetCount));
  for (int32_t t = 0; t < m.tetCount; ++t) {
    const int32_t* tn = rest.tets + 4 * size_t(t);
    for (int k = 0; k < 6; ++k) {
      const Vec3 d = node(tn[kTetEdgeNodes[k][1]]) - node(tn[kTetEdgeNodes[k][0]]);
      const double len = norm(d);
      if (!(len > 0) || !std::isfinite(len))
        return fail("FractureModel: tet ", std::to_string(t), " local edge ", std::to_string(k),
                    ": zero or non-finite rest length");
      for (int a = 0; a < 3; ++a) m.edgeDirections[18 * size_t(t) + 3 * k + a] = d[a] / len;
    }
    const Vec3 c = 0.25 * (node(tn[0]) + node(tn[1]) + node(tn[2]) + node(tn[3]));
    for (int a = 0; a < 3; ++a) m.centroids[3 * size_t(t) + a] = c[a];
  }

  m.strength.assign(size_t(m.edgeCount), settings.strength);
  double lengthSum = 0;
  for (int32_t e = 0; e < m.edgeCount; ++e) {
    const Vec3 d = node(graph.edgeNodes[2 * e + 1]) - node(graph.edgeNodes[2 * e]);
    const double len = norm(d);
    lengthSum += len;
    if (ratio == 1) continue;
    // A fibre field may change across the edge: average cos^2 over the tets that share it,
    // in the graph's fixed order (deterministic).
    double cos2 = 0;
    const int32_t first = graph.edgeTetStart[e], last = graph.edgeTetStart[e + 1];
    for (int32_t s = first; s < last; ++s) {
      const Vec3 a = fibres.perTet ? fibres.perTet[graph.edgeTets[size_t(s)] / 6] : fibres.constant;
      const double c = dot(d, a) / len;
      cos2 += c * c;
    }
    if (last > first) cos2 /= double(last - first);
    m.strength[size_t(e)] = fibreEdgeStrength(settings.strength, ratio, cos2);
  }
  m.meanEdgeLength = m.edgeCount > 0 ? lengthSum / m.edgeCount : 0;
  const bool byLength = settings.nonlocalLength > 0;
  m.radiusAbs = byLength ? settings.nonlocalLength : settings.radius * m.meanEdgeLength;
  // Rest volumes weight the metric average, so that it integrates over the material rather
  // than counting tets (a finer patch of mesh must not pull the mean towards itself).
  std::vector<double> volume;
  if (byLength) {
    volume.resize(size_t(m.tetCount));
    for (int32_t t = 0; t < m.tetCount; ++t) {
      const int32_t* tn = rest.tets + 4 * size_t(t);
      const Vec3 o = node(tn[0]);
      volume[size_t(t)] =
          std::fabs(dot(node(tn[1]) - o, cross(node(tn[2]) - o, node(tn[3]) - o))) / 6.0;
    }
  }

  // Non-local neighbour lists (eq 4.10): count, prefix sum, fill; both passes parallel over
  // tets and each row sorted by id, so the lists never depend on the thread count.
  if (m.radiusAbs > 0 && m.tetCount > 0) {
    const double R = m.radiusAbs, R2 = R * R;
    CentroidGrid& grid = m.grid;
    grid.build(m.centroids, m.tetCount, R);
    std::vector<int32_t> counts(size_t(m.tetCount));
    js.parallelFor(uint32_t(m.tetCount), 256, [&](uint32_t b, uint32_t e) {
      for (uint32_t i = b; i < e; ++i) {
        const double* ci = &m.centroids[3 * size_t(i)];
        int32_t n = 0;
        double d2;
        grid.forEachNear(ci, [&](int32_t j) {
          n += withinRadius(ci, &m.centroids[3 * size_t(j)], R2, d2) ? 1 : 0;
        });
        counts[i] = n;
      }
    });
    int64_t total = 0;
    m.neighbourStart.resize(size_t(m.tetCount) + 1);
    m.neighbourStart[0] = 0;
    for (int32_t i = 0; i < m.tetCount; ++i) {
      total += counts[size_t(i)];
      if (total > int64_t(std::numeric_limits<int32_t>::max()))
        return byLength
                   ? fail("FractureSettings.nonlocalLength: ",
                          std::to_string(settings.nonlocalLength), " m is ",
                          std::to_string(R / m.meanEdgeLength),
                          " mean edge lengths and gives over 2^31 neighbour entries; use a "
                          "shorter length or a coarser mesh")
                   : fail("FractureSettings.radius: ", std::to_string(settings.radius),
                          " mean edge lengths gives over 2^31 neighbour entries; use a smaller "
                          "R_d");
      m.neighbourStart[size_t(i) + 1] = int32_t(total);
    }
    m.neighbourIndex.resize(size_t(total));
    m.neighbourWeight.resize(size_t(total));
    js.parallelFor(uint32_t(m.tetCount), 256, [&](uint32_t b, uint32_t e) {
      for (uint32_t i = b; i < e; ++i) {
        const double* ci = &m.centroids[3 * size_t(i)];
        int32_t* row = m.neighbourIndex.data() + m.neighbourStart[i];
        int32_t n = 0;
        double d2;
        grid.forEachNear(ci, [&](int32_t j) {
          if (withinRadius(ci, &m.centroids[3 * size_t(j)], R2, d2)) row[n++] = j;
        });
        std::sort(row, row + n);
        for (int32_t s = 0; s < n; ++s) {
          withinRadius(ci, &m.centroids[3 * size_t(row[s])], R2, d2);
          // Linear kernel of eq 4.10: 1 at the tet itself, 0 at the support radius.
          const double w = 1.0 - std::sqrt(d2) / R;
          m.neighbourWeight[size_t(m.neighbourStart[i] + s)] =
              float(byLength ? w * volume[size_t(row[s])] : w);
        }
      }
    });
  }

  if (settings.brittle) m.buildFaceAdjacency(rest);
  return m;
}

void FractureModel::buildFaceAdjacency(const RestMeshView& rest) {
  // After sorting, the two records of an interior face are neighbours; record (tet, f) is the
  // face opposite node f, slot 4 tet + f.
  const std::vector<FaceRecord> faces = sortedFaces(rest.tets, size_t(rest.tetCount));
  faceNeighbours.assign(4 * size_t(rest.tetCount), -1);
  auto same = [](const FaceRecord& a, const FaceRecord& b) {
    return a.key[0] == b.key[0] && a.key[1] == b.key[1] && a.key[2] == b.key[2];
  };
  for (size_t i = 0; i + 1 < faces.size(); ++i)
    if (same(faces[i], faces[i + 1])) {
      faceNeighbours[4 * size_t(faces[i].tet) + size_t(faces[i].local)] = faces[i + 1].tet;
      faceNeighbours[4 * size_t(faces[i + 1].tet) + size_t(faces[i + 1].local)] = faces[i].tet;
      ++i;
    }
}

}  // namespace gf::detail
