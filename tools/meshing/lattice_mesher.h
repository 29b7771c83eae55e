// Tetrahedralisation of a triangle soup that needs no closed, clean surface: a regular grid over
// the soup's box split into 6 tets per cell (Kuhn / Freudenthal, the split gf::gen::box uses),
// the tets whose inside is decided by the generalised winding number (triangle_soup.h) kept, the
// boundary made 2-manifold, then the boundary nodes pulled towards the soup as far as the
// neighbouring tets' quality allows. Works on open, multi-part and self-intersecting input;
// features thinner than a cell may be lost. Design note at the top of lattice_mesher.cpp.
#pragma once

#include <graphfrac/mesh.h>
#include <graphfrac/status.h>

#include <cstddef>

#include "meshing/triangle_soup.h"

namespace gf::meshing {

/// How a lattice mesh is made.
struct LatticeOptions {
  int cells = 0;          ///< Grid cells along the box's longest axis; 0: from targetTets.
  double targetTets = 0;  ///< About this many tets (when cells is 0); both 0: kDefaultCells.
  double maxSnap = 0.45;  ///< How far a boundary node may move from its lattice point, in cells
                          ///< (below 0.5 no two nodes can meet).
  double minDihedralDeg = 20;  ///< A snap may not leave an incident tet's smallest dihedral angle
                               ///< below this (or below what it was, if already lower).
  double beta = 3;  ///< Winding-number far-field distance in cluster radii (0: exact sum).
};

/// Default grid resolution along the longest axis.
constexpr int kDefaultCells = 32;
/// Largest accepted grid resolution along the longest axis (memory: about 10 bytes per grid
/// cell and 100 per kept tet).
constexpr int kMaxCells = 256;

/// Shape figures of a tet mesh. Radius ratio is 3 r_in / r_circ (1 for the regular tet).
struct TetQuality {
  double minDihedralDeg = 0, maxDihedralDeg = 0;
  double minRadiusRatio = 0, meanRadiusRatio = 0;
  double minVolume = 0;  ///< Smallest signed tet volume.
};

/// A lattice mesh and what making it did.
struct LatticeResult {
  TetMesh mesh;
  double cell = 0;           ///< Grid spacing.
  int dims[3] = {0, 0, 0};   ///< Grid cells along x, y, z (with padding).
  size_t repairTets = 0;     ///< Tets added to make the boundary 2-manifold.
  size_t boundaryNodes = 0;  ///< Nodes on the boundary.
  size_t snappedNodes = 0;   ///< Boundary nodes moved (fully or part way) to the soup.
  size_t parts = 0;          ///< Connected components (through shared nodes).
  double windingVolume = 0;  ///< Volume where the winding number is >= 1/2, sampled on a
                             ///< 3x finer grid in the cells the surface crosses.
  double meshSeconds = 0, volumeSeconds = 0;
};

/// Tetrahedralises the region where the soup's winding number is at least 1/2. Fails when that
/// region holds no tet at this resolution or the boundary cannot be made manifold; the result
/// passes gf::validate().
Result<LatticeResult> latticeMesh(const TriangleSoup& soup, const LatticeOptions& options = {});

/// Dihedral angles, radius ratios and volumes over every tet.
TetQuality measureQuality(const TetMesh& mesh);

}  // namespace gf::meshing
