// Rest data of graph-based fracture (thesis sec 4.2.3, SPEC §2), built once per body and
// read-only afterwards, MuJoCo style: flat arrays a CUDA backend can copy unchanged.
//
// Design: the criterion needs, per tet, the unit REST direction of each of its 6 edges (the
// edge matrix T of eq 4.9 is built from them, so the normal stress is evaluated in the
// material frame and is rotation invariant), per-edge strengths, and for the non-local
// criterion (eq 4.10-4.12) the list of tets whose rest centroids lie within R_d. Those lists
// are found with a uniform hash grid of cell size >= R_d (27 cells per query), never O(n^2),
// and stored CSR with float weights: at R_d = 5 mean edge lengths a tet has thousands of
// neighbours, so the lists dominate the memory and float halves it at no visible cost.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "fracture/edge_break.h"
#include "graphfrac/defs.h"
#include "graphfrac/jobs.h"
#include "graphfrac/mesh.h"
#include "graphfrac/status.h"
#include "kernels/math.h"
#include "mesh/edge_graph.h"

namespace gf::detail {

/// Non-owning view of a body's rest mesh (positions 3 per node, 4 node indices per tet).
struct RestMeshView {
  const double* positions = nullptr;
  const int32_t* tets = nullptr;
  int32_t nodeCount = 0;
  int32_t tetCount = 0;
};

/// View of a TetMesh (valid while the mesh lives).
inline RestMeshView restView(const TetMesh& m) {
  return {m.positions.data(), m.tets.data(), int32_t(m.nodeCount()), int32_t(m.tetCount())};
}

/// Fibre directions that make the edge strength anisotropic (FractureSettings::
/// fibreStrengthRatio): one unit vector per tet, or `constant` for the whole body when perTet
/// is null. `present` false: the body has no fibres.
struct FibreView {
  const Vec3* perTet = nullptr;
  Vec3 constant{1, 0, 0};
  bool present = false;
};

/// Strength of an edge whose rest direction makes angle theta with the fibre, cos2 =
/// cos^2 theta, `across` the across-fibre strength and `ratio` along / across: Hankinson's
/// law (1921) with exponent 2, the standard fit for wood loaded at an angle to its grain: the
/// compliance 1 / sigma interpolated linearly in cos^2 theta. An edge breaks under tension
/// along itself, opening a crack normal to it, so edges across the fibres (cos2 = 0) split
/// the body between its fibres and edges along them (cos2 = 1) must tear the fibres.
inline double fibreEdgeStrength(double across, double ratio, double cos2) {
  return across * ratio / (ratio * (1.0 - cos2) + cos2);
}

/// Uniform grid over rest centroids with cells no smaller than R: every tet within R of a
/// point lies in the 27 cells around the point's cell.
struct CentroidGrid {
  double lo[3] = {0, 0, 0};
  double cell = 1;
  int32_t dims[3] = {0, 0, 0};
  std::vector<int32_t> start, items;  ///< CSR: tets per cell, in id order.
  std::vector<int32_t> tetCell;       ///< Cell of each tet.

  /// Buckets `count` centroids (3 each) into cells of size >= radius (larger when the mesh
  /// would need more than 4 cells per tet).
  void build(const std::vector<double>& centroids, int32_t count, double radius);
  /// Cell coordinate along `axis`, clamped to the grid.
  int32_t coord(double v, int axis) const {
    const double c = std::floor((v - lo[axis]) / cell);
    if (!(c > 0)) return 0;
    return c >= double(dims[axis] - 1) ? dims[axis] - 1 : int32_t(c);
  }
  /// Calls fn(cell) for the (up to) 27 cells around cell `id`.
  template <class Fn>
  void forEachCellAround(int32_t id, Fn&& fn) const {
    const int32_t ix = id % dims[0], iy = (id / dims[0]) % dims[1], iz = id / (dims[0] * dims[1]);
    for (int32_t z = iz > 0 ? iz - 1 : 0; z <= iz + 1 && z < dims[2]; ++z)
      for (int32_t y = iy > 0 ? iy - 1 : 0; y <= iy + 1 && y < dims[1]; ++y)
        for (int32_t x = ix > 0 ? ix - 1 : 0; x <= ix + 1 && x < dims[0]; ++x)
          fn((z * dims[1] + y) * dims[0] + x);
  }
  /// Calls fn(tet) for every tet in the 27 cells around point c.
  template <class Fn>
  void forEachNear(const double* c, Fn&& fn) const {
    const int32_t id = (coord(c[2], 2) * dims[1] + coord(c[1], 1)) * dims[0] + coord(c[0], 0);
    forEachCellAround(id, [&](int32_t cellId) {
      for (int32_t s = start[size_t(cellId)]; s < start[size_t(cellId) + 1]; ++s)
        fn(items[size_t(s)]);
    });
  }
};

/// Read-only fracture data of one body.
struct FractureModel {
  FractureSettings settings;
  int32_t tetCount = 0;
  int32_t edgeCount = 0;
  /// Unit rest direction of local edge k of tet t (from node kTetEdgeNodes[k][0] to [1]) at
  /// [18 t + 3 k]; the sign is irrelevant to N^T S N.
  std::vector<double> edgeDirections;
  /// sigma_th per edge [Pa] a body starts with: settings.strength, or fibreEdgeStrength of the
  /// mean cos^2 over the edge's tets when fibreStrengthRatio != 1. Commands and impurities
  /// change a copy in the body's data (FractureData::strength), never this.
  std::vector<double> strength;
  std::vector<double> centroids;  ///< Rest centroid, 3 per tet.
  double meanEdgeLength = 0;      ///< Mean rest length over unique edges.
  /// R: settings.nonlocalLength, else settings.radius * meanEdgeLength (eq 4.10).
  double radiusAbs = 0;
  /// Non-local neighbours (eq 4.10): tets with |c_j - c_i| < R, self included, sorted by id,
  /// weight w = 1 - d / R, times the neighbour's rest volume when R is nonlocalLength. Empty
  /// when R = 0 (local criterion).
  std::vector<int32_t> neighbourStart, neighbourIndex;
  std::vector<float> neighbourWeight;
  /// The grid the lists were built with (non-local only); the criterion also uses it to
  /// bound each tet's averaged stress by the largest stress in the cells around it.
  CentroidGrid grid;
  /// Face-adjacent tet across the face opposite local node f at [4 t + f], -1 on the
  /// boundary. Built only for brittle bodies (or by buildFaceAdjacency).
  std::vector<int32_t> faceNeighbours;

  /// Builds the model. `jobs` parallelises the neighbour search (null = serial). Errors name
  /// the field: a non-positive or non-finite strength, radius or fibre strength ratio, a
  /// ratio != 1 without fibres, mismatched graph and mesh, a degenerate edge, or neighbour
  /// lists over 2^31 entries (R_d too large for the mesh).
  static Result<FractureModel> build(const RestMeshView& rest, const EdgeGraph& graph,
                                     const FractureSettings& settings, JobSystem* jobs = nullptr,
                                     const FibreView& fibres = {});
  /// Fills faceNeighbours (brittle mode needs it); O(T log T).
  void buildFaceAdjacency(const RestMeshView& rest);
  /// True when the criterion averages over neighbours (R_d > 0).
  bool nonLocal() const { return radiusAbs > 0; }
};

/// Squared-distance rule of the neighbour lists, shared with the tests' brute-force check.
inline bool withinRadius(const double* ci, const double* cj, double radius2, double& d2) {
  const double dx = ci[0] - cj[0], dy = ci[1] - cj[1], dz = ci[2] - cj[2];
  d2 = dx * dx + dy * dy + dz * dz;
  return d2 < radius2;
}

}  // namespace gf::detail
