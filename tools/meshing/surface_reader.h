// Reading the triangle surface `graphfrac mesh from-surface` tetrahedralises. Wavefront OBJ (.obj)
// and PLY (ASCII and both binary byte orders) are read here, in double precision and with the
// line or element of every vertex and face, so that errors point into the file; every other
// format (STL, glTF 2.0, FBX, Collada, 3DS, ...) goes through assimp (surface_reader_assimp.cpp),
// which also reads OBJ and PLY on request. All meshes of the scene graph are merged with their
// node transforms applied and converted to metres and Y-up.
#pragma once

#include <graphfrac/status.h>

#include <cstdint>
#include <string>
#include <vector>

namespace gf::meshing {

/// "%.9g": enough digits to tell coordinates apart in messages.
std::string formatDouble(double v);

/// Why a number token is unusable ("'1e400' is out of the range of a double", "... is not
/// finite", "... is not a number"), or "" when it is a finite double, stored in v.
std::string numberProblem(const std::string& s, double& v);

/// Which reader produced a SurfaceFile; it decides how vertices and faces are named.
enum class SurfaceSource {
  kObj,     // vertices and faces by line, vertices numbered from 1
  kPly,     // elements numbered from 0
  kAssimp,  // by mesh (one per node that instances it), vertices and triangles from 0
};

/// Vertices and triangles as the file numbers them, and where each came from, so that every
/// later message can point into the file. Positions are in metres, Y up (after any unit and
/// axis conversion).
struct SurfaceFile {
  std::string path;
  SurfaceSource source = SurfaceSource::kObj;
  std::vector<double> positions;    // 3 per vertex
  std::vector<int64_t> triangles;   // 3 per triangle, 0-based, in range
  std::vector<int64_t> vertexLine;  // OBJ: the line of each vertex; assimp: index in its mesh
  std::vector<int64_t> faceTag;     // per triangle: OBJ line, PLY face index (fans share it),
                                    // assimp: triangle index in its mesh
  // assimp only: the mesh of each vertex and triangle, an index into meshNames.
  std::vector<int32_t> vertexMesh, faceMesh;
  std::vector<std::string> meshNames;  // "mesh 'Cube'" or "mesh 'Wheel' in node 'Wheel.L'"
  // 2 per vertex (u right, v up from the image's bottom left, assimp's and OBJ's convention):
  // assimp, the first texture coordinate set when every mesh read has one; OBJ, read with
  // SurfaceReadOptions::uvs, when every face corner has one (a vertex with several becomes
  // one vertex per UV); PLY, the vertices' u and v (or s and t, texture_u and texture_v,
  // texture_s and texture_t) properties; else empty.
  std::vector<float> uvs;
  // Per triangle an index into `materials` (the file's materials that some triangle uses, in
  // the order first used): assimp, and OBJ read with SurfaceReadOptions::uvs (usemtl, with
  // newmtl, Kd and map_Kd from its mtllib); empty otherwise.
  std::vector<uint16_t> faceMaterial;
  struct Material {
    std::string name;             // the file's name for it, or "material N"
    float colour[3] = {1, 1, 1};  // base colour (glTF baseColorFactor) or diffuse colour
    std::string texture;          // its base colour or diffuse texture as the file names it
                                  // (relative to the file's folder), or empty; "*N" = embedded
  };
  std::vector<Material> materials;
  // What was read and converted, for the summary: "FBX (Autodesk FBX Importer), 2 meshes";
  // "unit 0.01 m (FBX UnitScaleFactor 1), up +Y (FBX axis system)".
  std::string format, conversion;
  size_t skippedPoints = 0, skippedLines = 0;  // assimp: primitives that are not triangles

  size_t vertexCount() const { return positions.size() / 3; }
  /// "vertex 7 (1, 0, 2)", numbered as the file's faces refer to it; assimp: "vertex 7 of
  /// mesh 'Cube' (1, 0, 2)".
  std::string vertex(size_t i) const;
  /// Where vertex i is defined: "cube.obj:12: vertex 7", "cube.ply: vertex 7",
  /// "model.glb: mesh 'Cube': vertex 7".
  std::string vertexAt(size_t i) const;
  /// "face on line 12" / "face 5" / "triangle 5 of mesh 'Cube'", with its vertices:
  /// "(vertices 1 2 3)".
  std::string face(size_t t) const;
};

/// How a file is read: the unit and up axis that replace what the file declares (or says
/// nothing of), and whether OBJ and PLY go through assimp too.
struct SurfaceReadOptions {
  double scale = 0;     // metres per file unit; 0: the file's unit (FBX, Collada), else 1
  char up = 0;          // 'x', 'y' or 'z': the model's up axis; 0: the file's, else y
  bool assimp = false;  // read OBJ and PLY through assimp as well
  bool uvs = false;     // OBJ: read texture coordinates, splitting vertices at UV seams
};

/// Reads a triangle surface; polygons become triangles, points and lines are skipped (and
/// counted). Errors name the file, the line, element or mesh, and the reason.
Result<SurfaceFile> readSurfaceFile(const std::string& path,
                                    const SurfaceReadOptions& options = {});

/// True when this build reads through assimp (found at configure time).
bool haveAssimp();

namespace detail {
/// The assimp reader (surface_reader_assimp.cpp): positions converted to metres and Y up, by
/// what the file declares or by the options' overrides.
Result<SurfaceFile> readWithAssimp(const std::string& path, const SurfaceReadOptions& options);
/// Applies the row-major 3x3 matrix m to every position; a mirror (det < 0) also reverses every
/// triangle so that outward faces stay outward.
void transformSurface(SurfaceFile& s, const double m[9]);
/// The rotation taking the up axis ('x', 'y', 'z') to +Y: row-major 3x3.
void upToY(char up, double m[9]);
}  // namespace detail

}  // namespace gf::meshing
