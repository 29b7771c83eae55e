// Internals shared by the mesh readers, validation and export: text scanning with line numbers,
// the raw (tagged) mesh a reader fills, and the sorted face list used for boundaries.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "graphfrac/mesh.h"
#include "graphfrac/status.h"

namespace gf::detail {

/// A whole text file held in memory and walked line by line, so parsers can say `file:line:`.
class TextFile {
 public:
  /// Reads `path`; errors for a missing, unreadable or non-regular file.
  static Result<TextFile> read(const std::string& path);
  /// Next line without its end-of-line characters; false at end of file.
  bool next(std::string_view& line);
  /// 1-based number of the line last returned by next() (0 before the first).
  int line() const { return m_line; }
  /// The path as given to read().
  const std::string& path() const { return m_path; }
  /// "path:line: " for the line last returned.
  std::string where() const { return m_path + ":" + std::to_string(m_line) + ": "; }
  /// True when the file holds only whitespace.
  bool blank() const;

 private:
  std::string m_path;
  std::string m_text;
  size_t m_pos = 0;
  int m_line = 0;
};

/// Splits `line` at whitespace into `out` (cleared first); text from `comment` on is dropped
/// when `comment` is not '\0'.
void splitTokens(std::string_view line, std::vector<std::string_view>& out, char comment = '\0');
/// Whole-token integer parse; false on garbage, trailing characters or overflow.
bool parseInt(std::string_view token, int64_t& value);
/// Whole-token floating-point parse ("nan" and "inf" parse; callers check finiteness).
bool parseDouble(std::string_view token, double& value);
/// A token quoted for an error message, shortened if long.
std::string quote(std::string_view token);

/// A mesh as a reader found it: node and element numbers as written, with their lines, so
/// tags can be resolved and validation errors can point into the file.
struct RawMesh {
  std::string nodeFile, tetFile;  ///< Paths for messages (the same file for Gmsh).
  std::vector<double> positions;  ///< 3 per node, file order.
  std::vector<int64_t> nodeTags;  ///< Node number as written, per node.
  std::vector<int32_t> nodeLines;
  std::vector<int64_t> tetNodeTags;  ///< 4 node numbers per tet, as written.
  std::vector<int64_t> tetTags;      ///< Element number as written, per tet.
  std::vector<int32_t> tetLines;
};

/// Where each node and tet of a loaded mesh came from, for validation messages.
struct MeshSourceMap {
  std::string nodeFile, tetFile;
  std::vector<int64_t> nodeTags, tetTags;
  std::vector<int32_t> nodeLines, tetLines;
};

/// Resolves node numbers to indices (errors for undefined or repeated numbers), then validates
/// with messages that point at file lines.
Result<TetMesh> finishRawMesh(RawMesh&& raw, MeshLoadInfo* info);

/// validate() with an optional map back to the source files.
Result<void> validateMesh(TetMesh& mesh, const std::string& source, const MeshSourceMap* map,
                          int* flippedFixed);

/// Six times the signed volume of tet `t` (nodes t[0..3]); > 0 for positive orientation.
double tetSixVolume(const double* positions, const int32_t* t);

/// Local node triples of the four faces, ordered so that they face outward for a positively
/// oriented tet (face i is opposite node i).
inline constexpr int kTetFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

/// One tet face with its nodes sorted (the key) and where it came from.
struct FaceRecord {
  int32_t key[3];
  int32_t tet;
  int32_t local;  ///< 0..3, index into kTetFaces.
};

/// All 4 * tetCount faces sorted by key (ties by tet), so that faces shared by tets are
/// adjacent. Indices must be in range.
std::vector<FaceRecord> sortedFaces(const int32_t* tets, size_t tetCount);
inline std::vector<FaceRecord> sortedFaces(const TetMesh& mesh) {
  return sortedFaces(mesh.tets.data(), mesh.tetCount());
}

/// Faces of exactly one tet (3 node indices each), oriented as kTetFaces gives them: outward
/// for positively oriented tets. Indices must be in range.
std::vector<int32_t> boundaryFaces(const int32_t* tets, size_t tetCount);

/// Lower-case extension with the dot (".msh"), or "" when there is none.
std::string lowerExtension(const std::string& path);

}  // namespace gf::detail
