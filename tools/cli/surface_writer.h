// Per-frame surfaces of a body as OBJ or PLY. Two sources:
// - the render surface of a fracturing body (World::surface: the boundary plus the crack faces,
//   closed per fragment), written with its crack faces marked: an OBJ group `crack` next to the
//   group `surface`, or a per-face colour in PLY;
// - the plain boundary of a body without fracture, computed once from the rest mesh
//   (TetMesh::boundaryFaces), of which only the boundary nodes are written, renumbered.
#pragma once

#include <graphfrac/mesh.h>
#include <graphfrac/status.h>
#include <graphfrac/surface.h>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace gf::cli {

/// Output format of surface frames.
enum class SurfaceFormat { Obj, Ply };

/// The boundary triangles of a mesh over a compact set of vertices.
struct SurfaceTopology {
  std::vector<int32_t> nodes;  ///< Mesh node of each surface vertex.
  std::vector<int32_t> faces;  ///< 3 surface-vertex indices per triangle, outward oriented.
};

/// Extracts the boundary of `mesh` and renumbers its nodes.
SurfaceTopology surfaceTopology(const TetMesh& mesh);

/// Writes the boundary at the given node positions (3 doubles per mesh node), all in the OBJ
/// group `surface`.
Result<void> writeSurfaceFrame(const std::string& path, const SurfaceTopology& topo,
                               std::span<const double> positions, SurfaceFormat format);

/// Colour of crack faces and of the original boundary in PLY files (RGB).
inline constexpr uint8_t kCrackColour[3] = {214, 64, 44};
inline constexpr uint8_t kBoundaryColour[3] = {200, 200, 200};

/// Writes a render surface (World::surface). OBJ: `v` and `vn` per vertex, then the original
/// boundary triangles in group `surface` and the crack triangles in group `crack` (omitted when
/// there are none). PLY (binary): per vertex x y z nx ny nz (float) and its fragment (int), per
/// face its indices and a colour, kCrackColour for crack faces and kBoundaryColour otherwise.
/// Fails, naming the file, on a view whose arrays disagree in size or index out of range.
Result<void> writeRenderSurface(const std::string& path, const SurfaceView& view,
                                SurfaceFormat format);

}  // namespace gf::cli
