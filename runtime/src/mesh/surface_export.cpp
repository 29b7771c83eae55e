// Boundary surface export (OBJ or PLY, ASCII): only the nodes the boundary uses are written,
// renumbered in order of first use, so the file is a clean closed triangle mesh.
#include <charconv>
#include <fstream>

#include "mesh/mesh_internal.h"

namespace gf {

Result<void> TetMesh::writeSurface(const std::string& path) const {
  const std::string ext = detail::lowerExtension(path);
  if (ext != ".obj" && ext != ".ply") {
    return fail(path, ": unknown surface format '", ext, "' (expected .obj or .ply)");
  }
  const std::vector<int32_t> faces = boundaryFaces();
  if (faces.empty()) return fail(path, ": mesh has no boundary faces (empty or invalid mesh)");

  std::vector<int32_t> remap(nodeCount(), -1);
  std::vector<int32_t> used;
  for (int32_t v : faces) {
    if (remap[static_cast<size_t>(v)] < 0) {
      remap[static_cast<size_t>(v)] = static_cast<int32_t>(used.size());
      used.push_back(v);
    }
  }

  std::ofstream out(path, std::ios::binary);
  if (!out) return fail(path, ": cannot open for writing");
  std::string s;
  const bool obj = ext == ".obj";
  if (obj) {
    s += "# boundary of a tet mesh: " + std::to_string(used.size()) + " vertices, " +
         std::to_string(faces.size() / 3) + " triangles\n";
  } else {
    s += "ply\nformat ascii 1.0\nelement vertex " + std::to_string(used.size()) +
         "\nproperty double x\nproperty double y\nproperty double z\nelement face " +
         std::to_string(faces.size() / 3) +
         "\nproperty list uchar int vertex_indices\nend_header\n";
  }
  char buf[32];
  for (int32_t v : used) {
    if (obj) s += "v";
    for (int k = 0; k < 3; ++k) {
      if (obj || k > 0) s += ' ';
      const auto r = std::to_chars(buf, buf + sizeof buf,
                                   positions[3 * static_cast<size_t>(v) + static_cast<size_t>(k)]);
      s.append(buf, r.ptr);
    }
    s += '\n';
  }
  for (size_t f = 0; f < faces.size(); f += 3) {
    s += obj ? "f" : "3";
    for (int k = 0; k < 3; ++k) {
      // OBJ indices are 1-based, PLY 0-based.
      const int32_t idx =
          remap[static_cast<size_t>(faces[f + static_cast<size_t>(k)])] + (obj ? 1 : 0);
      s += ' ';
      s += std::to_string(idx);
    }
    s += '\n';
  }
  out << s;
  out.flush();
  if (!out) return fail(path, ": write failed");
  return {};
}

}  // namespace gf
