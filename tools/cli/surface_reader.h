// Reading the triangle surface `graphfrac mesh from-surface` tetrahedralises: Wavefront OBJ and
// PLY (ASCII and both binary byte orders), detected by content, then extension; other formats
// (STL, glTF, FBX, ...) are named in the error instead of failing as a broken OBJ.
#pragma once

#include <graphfrac/status.h>

#include <cstdint>
#include <string>
#include <vector>

namespace gf::cli {

/// "%.9g": enough digits to tell coordinates apart in messages.
std::string formatDouble(double v);

/// Why a number token is unusable ("'1e400' is out of the range of a double", "... is not
/// finite", "... is not a number"), or "" when it is a finite double, stored in v.
std::string numberProblem(const std::string& s, double& v);

/// Vertices and triangles as the file numbers them, and where each came from, so that every
/// later message can point into the file.
struct SurfaceFile {
  std::string path;
  bool ply = false;                 // PLY: elements numbered from 0; OBJ: lines, vertices from 1
  std::vector<double> positions;    // 3 per vertex
  std::vector<int64_t> triangles;   // 3 per triangle, 0-based, in range
  std::vector<int64_t> vertexLine;  // OBJ: the line of each vertex
  std::vector<int64_t> faceTag;     // per triangle: OBJ line, PLY face index (fans share it)

  size_t vertexCount() const { return positions.size() / 3; }
  // "vertex 7 (1, 0, 2)", numbered as the file's faces refer to it.
  std::string vertex(size_t i) const {
    return "vertex " + std::to_string(ply ? i : i + 1) + " (" + formatDouble(positions[3 * i]) +
           ", " + formatDouble(positions[3 * i + 1]) + ", " + formatDouble(positions[3 * i + 2]) +
           ")";
  }
  // Where vertex i is defined: "cube.obj:12: vertex 7" or "cube.ply: vertex 7".
  std::string vertexAt(size_t i) const {
    if (ply) return path + ": vertex " + std::to_string(i);
    return path + ":" + std::to_string(vertexLine[i]) + ": vertex " + std::to_string(i + 1);
  }
  // "face on line 12" / "face 5", with its vertices: "(vertices 1 2 3)".
  std::string face(size_t t) const {
    std::string s = ply ? "face " : "face on line ";
    s += std::to_string(faceTag[t]);
    s += " (vertices";
    for (size_t k = 0; k < 3; ++k) {
      s += ' ';
      s += std::to_string(triangles[3 * t + k] + (ply ? 0 : 1));
    }
    s += ')';
    return s;
  }
};

/// Reads an OBJ or PLY surface; polygons become fans. Errors name the file, the line or
/// element and the reason.
Result<SurfaceFile> readSurfaceFile(const std::string& path);

}  // namespace gf::cli
