// Per-frame boundary surfaces of a body as OBJ or PLY. The boundary of a rest mesh is computed
// once (TetMesh::boundaryFaces) and only the boundary nodes are written, renumbered, each frame.
#pragma once

#include <graphfrac/mesh.h>
#include <graphfrac/status.h>

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

/// Writes the surface at the given node positions (3 doubles per mesh node).
Result<void> writeSurfaceFrame(const std::string& path, const SurfaceTopology& topo,
                               std::span<const double> positions, SurfaceFormat format);

}  // namespace gf::cli
