// Tetrahedral meshes: the computational mesh of a body, loaded, validated and generated here.
// Positions are double: rest shapes of stiff bodies need the precision (docs/design.md).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "status.h"

namespace gf {

/// A tetrahedral mesh as flat arrays (copies straight to a device).
/// Tets are positively oriented: det[x1-x0, x2-x0, x3-x0] > 0.
struct TetMesh {
  std::vector<double> positions;  ///< 3 per node: x0 y0 z0 x1 ...
  std::vector<int32_t> tets;      ///< 4 node indices per tet.

  size_t nodeCount() const { return positions.size() / 3; }
  size_t tetCount() const { return tets.size() / 4; }

  /// Loads by extension: `.msh` (Gmsh 2.2 or 4.1 ASCII), `.node`/`.ele` (TetGen; either name,
  /// the other is found beside it). Validates (see validate()) and fixes flipped tets.
  static Result<TetMesh> fromFile(const std::string& path);
  /// TetGen pair; index base (0 or 1) is read from the files.
  static Result<TetMesh> fromTetGen(const std::string& nodePath, const std::string& elePath);
  /// Gmsh ASCII 2.2 or 4.1; only 4-node tetrahedra (type 4) are kept, other elements ignored.
  static Result<TetMesh> fromGmsh(const std::string& path);

  /// Writes Gmsh 2.2 ASCII.
  Result<void> writeMsh(const std::string& path) const;
  /// Writes the boundary surface (faces of exactly one tet), outward oriented, as OBJ or PLY
  /// (by extension).
  Result<void> writeSurface(const std::string& path) const;

  /// Boundary triangles (3 node indices each), outward oriented.
  std::vector<int32_t> boundaryFaces() const;
  /// Total rest volume.
  double volume() const;
};

/// Checks a mesh and repairs what is safe to repair. Errors name `source` (a file name or a
/// description), the element or node, and the reason: non-finite coordinates, out-of-range
/// indices, repeated node in a tet, zero volume, duplicate nodes, unreferenced nodes,
/// non-manifold boundary. Tets that are only flipped are reoriented and counted in
/// `flippedFixed` when non-null.
Result<void> validate(TetMesh& mesh, const std::string& source, int* flippedFixed = nullptr);

/// Mesh generators at a requested resolution (cells along the shortest side for boxes).
namespace gen {
/// Axis-aligned box [0,sx]x[0,sy]x[0,sz] of nx*ny*nz cubes, 5 or 6 tets each (6: Kuhn split,
/// conforming). A notch, when depth > 0, removes a V of the given depth and opening angle
/// (degrees) across the full width (z) at x = notchX on the top face (y = sy).
struct BoxOptions {
  double notchDepth = 0, notchAngleDeg = 45, notchX = -1;  // notchX < 0: centre
};
TetMesh box(double sx, double sy, double sz, int nx, int ny, int nz, const BoxOptions& o = {});
/// Cylinder along y, radius r, height h, `segments` around, `layers` along y, `rings` radial.
TetMesh cylinder(double r, double h, int segments, int layers, int rings);
/// Sphere of radius r centred at the origin, about `n` cells across the diameter.
TetMesh sphere(double r, int n);
/// Thin slab in x-z, thickness t along y: a box with ny = max(1, round(t / cell)).
TetMesh slab(double sx, double sz, double t, int nx, int nz);
}  // namespace gen

}  // namespace gf
