// Tetrahedral meshes: the computational mesh of a body, loaded, validated and generated here.
// Positions are double: rest shapes of stiff bodies need the precision (docs/design.md).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "status.h"

namespace gf {

/// What loading a mesh repaired; filled by the loaders when a pointer is passed.
struct MeshLoadInfo {
  int flippedFixed = 0;  ///< Tets with negative volume that were reoriented (two nodes swapped).
};

/// A tetrahedral mesh as flat arrays (copies straight to a device).
/// Tets are positively oriented: det[x1-x0, x2-x0, x3-x0] > 0.
struct TetMesh {
  std::vector<double> positions;  ///< 3 per node: x0 y0 z0 x1 ...
  std::vector<int32_t> tets;      ///< 4 node indices per tet.

  size_t nodeCount() const { return positions.size() / 3; }
  size_t tetCount() const { return tets.size() / 4; }

  /// Loads by extension: `.msh` (Gmsh 2.2 or 4.1 ASCII), `.node`/`.ele` (TetGen; either name,
  /// the other is found beside it). Validates (see validate()) and fixes flipped tets.
  /// Errors name the file, the line, the element or node and the reason.
  static Result<TetMesh> fromFile(const std::string& path, MeshLoadInfo* info = nullptr);
  /// TetGen pair; index base (0 or 1) is read from the files (node numbers are looked up, so
  /// any numbering works). Attributes and boundary markers are read and ignored; of 10-node
  /// tets the 4 corners are kept.
  static Result<TetMesh> fromTetGen(const std::string& nodePath, const std::string& elePath,
                                    MeshLoadInfo* info = nullptr);
  /// Gmsh ASCII 2.2 or 4.1; only 4-node tetrahedra (type 4) are kept, other elements ignored.
  /// Node tags may be non-contiguous; nodes keep their file order.
  static Result<TetMesh> fromGmsh(const std::string& path, MeshLoadInfo* info = nullptr);

  /// Writes Gmsh 2.2 ASCII (node and element tags 1-based, coordinates round-trip exactly).
  Result<void> writeMsh(const std::string& path) const;
  /// Writes the boundary surface (faces of exactly one tet), outward oriented, as OBJ or PLY
  /// (by extension).
  Result<void> writeSurface(const std::string& path) const;

  /// Boundary triangles (3 node indices each), outward oriented; assumes positively oriented
  /// tets (as after validate()).
  std::vector<int32_t> boundaryFaces() const;
  /// Total rest volume (sum of signed tet volumes).
  double volume() const;
};

/// The material id of crack faces (SurfaceView::materials); not valid in RenderMesh::materials.
inline constexpr uint16_t kInteriorMaterial = 0xFFFF;

/// An artist's triangle mesh drawn in place of a body's tet boundary (BodyDef::renderMesh;
/// thesis sec 7.3.2, the multi-resolution framework): each vertex is bound at body creation to
/// the tet that contains it (or the nearest one, for vertices slightly outside) by barycentric
/// coordinates and follows it every frame. Given in the same rest frame as the tet mesh.
struct RenderMesh {
  std::vector<double> positions;  ///< 3 per vertex, rest frame of BodyDef::mesh
  std::vector<float> normals;     ///< 3 per vertex, or empty: area-weighted from the triangles
  std::vector<float> uvs;         ///< 2 per vertex, or empty
  std::vector<uint32_t> indices;  ///< 3 per triangle, counter-clockwise seen from outside
  /// Per triangle: its material's id (the importer's table, kept on the tools' side), or empty:
  /// every triangle material 0. Kept through refinement and crack cutting (SurfaceView::
  /// materials); kInteriorMaterial is reserved for crack faces.
  std::vector<uint16_t> materials;

  size_t vertexCount() const { return positions.size() / 3; }
  size_t triangleCount() const { return indices.size() / 3; }
  /// Sizes, finite values, non-zero normals and indices in range. Empty when valid; otherwise
  /// names the field ("normals[4]: ...") and the reason.
  Result<void> check() const;
};

/// Checks a mesh and repairs what is safe to repair. Errors name `source` (a file name or a
/// description), the element or node, and the reason: non-finite coordinates, out-of-range
/// indices, repeated node in a tet, zero volume (|6V| < 1e-12 L^3, L the bounding-box
/// diagonal), duplicate nodes (closer than 1e-10 L), unreferenced nodes, non-manifold boundary
/// (a face of more than two tets, or a boundary edge not on exactly two boundary faces). Tets that
/// are only flipped are reoriented and counted in `flippedFixed` when non-null.
Result<void> validate(TetMesh& mesh, const std::string& source, int* flippedFixed = nullptr);

/// Mesh generators at a requested resolution. Every output passes validate(); counts below
/// 1 are raised to 1 (2 for sphere cells).
namespace gen {
/// Options of box(). A notch, when depth > 0, carves a V of the given depth and opening angle
/// (degrees) across the full width (z) at x = notchX on the top face (y = sy): the nodes of
/// each x-column are scaled down in y to the V profile, and the columns nearest the V's tip
/// and shoulders are moved onto them, so the V is exact when the cells are finer than it.
/// Depth is clamped to [0, 0.95 sy] and the angle to [1, 179] degrees.
struct BoxOptions {
  double notchDepth = 0;      ///< Depth of the V below the top face (0: no notch).
  double notchAngleDeg = 45;  ///< Opening angle of the V in degrees.
  double notchX = -1;         ///< x of the V's tip; < 0: centre (sx / 2).
};
/// Axis-aligned box [0,sx]x[0,sy]x[0,sz] of nx*ny*nz cells, 6 tets each (Kuhn/Freudenthal
/// split along the cell diagonal: identical in every cell, so neighbours conform).
TetMesh box(double sx, double sy, double sz, int nx, int ny, int nz, const BoxOptions& o = {});
/// Cylinder (or disc, with layers = 1) along y: axis x = z = 0, y in [0, h], radius r;
/// `segments` nodes around the outer ring (at least 3), `layers` along y, `rings` radial
/// (ring k has about segments*k/rings nodes so triangles stay well shaped). Prisms are split
/// into 3 tets with the smallest-index diagonal rule, which conforms between neighbours.
TetMesh cylinder(double r, double h, int segments, int layers, int rings);
/// Tube: the cylinder above with a coaxial hole of radius rInner (0 <= rInner < r; 0 gives
/// cylinder()); `rings` + 1 circles of `segments` nodes from rInner to r.
TetMesh tube(double r, double rInner, double h, int segments, int layers, int rings);
/// Sphere of radius r centred at the origin, about `n` cells across the diameter (rounded up
/// to even): a Kuhn-split cube grid mirrored per octant, mapped shell by shell onto the ball.
TetMesh sphere(double r, int n);
/// Thin slab in x-z, thickness t along y: a box with ny = max(1, round(t / cell)),
/// cell = min(sx / nx, sz / nz).
TetMesh slab(double sx, double sz, double t, int nx, int nz);
}  // namespace gen

}  // namespace gf
