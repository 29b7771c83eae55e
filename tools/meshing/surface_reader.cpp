// Triangle surfaces as files hold them: Wavefront OBJ and PLY (ASCII and both binary byte
// orders) read here, with where each vertex and face came from so that errors point into the
// file; other formats are handed to assimp (surface_reader_assimp.cpp).
#include "meshing/surface_reader.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace gf::meshing {

namespace fs = std::filesystem;

std::string formatDouble(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

std::string numberProblem(const std::string& s, double& v) {
  const char* b = s.data();
  const char* e = b + s.size();
  if (b != e && *b == '+') ++b;
  auto [p, ec] = std::from_chars(b, e, v);
  if (ec == std::errc::result_out_of_range) return "'" + s + "' is out of the range of a double";
  if (ec != std::errc() || p != e || b == e) return "'" + s + "' is not a number";
  if (!std::isfinite(v)) return "'" + s + "' is not finite";
  return "";
}

std::string SurfaceFile::vertex(size_t i) const {
  std::string s = "vertex " + std::to_string(source == SurfaceSource::kObj ? i + 1 : i);
  if (source == SurfaceSource::kAssimp) {
    s = "vertex " + std::to_string(vertexLine[i]) + " of " +
        meshNames[static_cast<size_t>(vertexMesh[i])];
  }
  return s + " (" + formatDouble(positions[3 * i]) + ", " + formatDouble(positions[3 * i + 1]) +
         ", " + formatDouble(positions[3 * i + 2]) + ")";
}

std::string SurfaceFile::vertexAt(size_t i) const {
  switch (source) {
    case SurfaceSource::kObj:
      return path + ":" + std::to_string(vertexLine[i]) + ": vertex " + std::to_string(i + 1);
    case SurfaceSource::kPly:
      return path + ": vertex " + std::to_string(i);
    case SurfaceSource::kAssimp:
      break;
  }
  return path + ": " + meshNames[static_cast<size_t>(vertexMesh[i])] + ": vertex " +
         std::to_string(vertexLine[i]);
}

std::string SurfaceFile::face(size_t t) const {
  std::string s;
  int64_t base = 0;  // how the vertices are numbered
  switch (source) {
    case SurfaceSource::kObj:
      s = "face on line " + std::to_string(faceTag[t]);
      base = 1;
      break;
    case SurfaceSource::kPly:
      s = "face " + std::to_string(faceTag[t]);
      break;
    case SurfaceSource::kAssimp:
      s = "triangle " + std::to_string(faceTag[t]) + " of " +
          meshNames[static_cast<size_t>(faceMesh[t])];
      break;
  }
  s += " (vertices";
  for (size_t k = 0; k < 3; ++k) {
    const size_t v = static_cast<size_t>(triangles[3 * t + k]);
    s += ' ';
    s += std::to_string(source == SurfaceSource::kAssimp ? vertexLine[v]
                                                         : static_cast<int64_t>(v) + base);
  }
  return s + ')';
}

namespace detail {

void transformSurface(SurfaceFile& s, const double m[9]) {
  for (size_t i = 0; i < s.vertexCount(); ++i) {
    double* p = &s.positions[3 * i];
    const double x = p[0], y = p[1], z = p[2];
    for (int r = 0; r < 3; ++r) p[r] = m[3 * r] * x + m[3 * r + 1] * y + m[3 * r + 2] * z;
  }
  const double det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
                     m[2] * (m[3] * m[7] - m[4] * m[6]);
  if (det < 0) {
    for (size_t t = 0; t < s.triangles.size(); t += 3)
      std::swap(s.triangles[t + 1], s.triangles[t + 2]);
  }
}

void upToY(char up, double m[9]) {
  // The turns Collada readers use for X_UP and Z_UP: x' = -y, y' = x; and y' = z, z' = -y.
  static const double kX[9] = {0, -1, 0, 1, 0, 0, 0, 0, 1};
  static const double kY[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  static const double kZ[9] = {1, 0, 0, 0, 0, 1, 0, -1, 0};
  const double* r = up == 'x' ? kX : up == 'z' ? kZ : kY;
  std::copy(r, r + 9, m);
}

}  // namespace detail

namespace {

std::string lowerExtension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// The formats that are read are named by their content; other formats are named so that the
// error says what the file is, instead of failing on the first line as a broken OBJ.
enum class SurfaceFormat { kObj, kPly, kAssimp };

Result<SurfaceFormat> detectFormat(const std::string& path, bool assimp) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(path, ": cannot open");
  char buf[512];
  in.read(buf, sizeof buf);
  const std::string head(buf, static_cast<size_t>(in.gcount()));
  auto starts = [&](const char* magic) { return head.rfind(magic, 0) == 0; };
  if (starts("ply\n") || starts("ply\r\n")) return SurfaceFormat::kPly;
  const std::string ext = lowerExtension(path);
  if (ext == ".ply") return fail(path, ": not a PLY file (it does not start with a 'ply' line)");
  if (ext == ".obj") return SurfaceFormat::kObj;
  // assimp detects the rest by extension, then content, and names what it cannot read.
  if (assimp) return SurfaceFormat::kAssimp;
  std::string other;
  if (starts("solid") || ext == ".stl") {
    other = "an STL";
  } else if (starts("glTF") || ext == ".glb" || ext == ".gltf") {
    other = "a glTF";
  } else if (starts("Kaydara FBX") || ext == ".fbx") {
    other = "an FBX";
  } else if (starts("OFF") || ext == ".off") {
    other = "an OFF";
  } else if (starts("$MeshFormat") || ext == ".msh") {
    other = "a Gmsh .msh";
  } else if (ext == ".node" || ext == ".ele" || ext == ".smesh" || ext == ".poly") {
    other = "a TetGen";
  } else if (ext == ".dae") {
    other = "a COLLADA";
  } else if (ext == ".3ds" || ext == ".blend" || ext == ".vtk" || ext == ".vtu") {
    other = "a " + ext;
  } else if (head.find('\0') != std::string::npos) {
    other = "a binary";
  }
  if (!other.empty()) {
    return fail(path, ": reads Wavefront OBJ and PLY only (got ", other,
                " file): this graphfrac was built without assimp (install libassimp-dev: "
                "tools/setup tools, and configure again)");
  }
  return SurfaceFormat::kObj;
}

// ---- OBJ reading -------------------------------------------------------------------------

bool parseIndex(const std::string& s, int64_t& v) {
  const std::string head = s.substr(0, s.find('/'));  // "i/t/n": the vertex index comes first
  const char* b = head.data();
  const char* e = b + head.size();
  auto [p, ec] = std::from_chars(b, e, v);
  return ec == std::errc() && p == e && b != e;
}

// The texture index of a face corner "i/t" or "i/t/n": true with t (0: none given) when the
// field is absent, empty or a number; false when it is something else.
bool parseTextureIndex(const std::string& s, int64_t& t) {
  t = 0;
  const size_t slash = s.find('/');
  if (slash == std::string::npos) return true;
  const std::string field = s.substr(slash + 1, s.find('/', slash + 1) - slash - 1);
  if (field.empty()) return true;
  auto [p, ec] = std::from_chars(field.data(), field.data() + field.size(), t);
  return ec == std::errc() && p == field.data() + field.size() && t != 0;
}

// The materials of an MTL file (newmtl, Kd, map_Kd), appended to `out`; a file that cannot be
// opened adds none (its materials' faces are then drawn white), as assimp does.
// The rest of a line after its keyword, without surrounding blanks (and a CRLF file's '\r').
std::string restOfLine(std::istringstream& ss) {
  std::string s;
  std::getline(ss >> std::ws, s);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  return s;
}

void readMtl(const std::string& path, std::vector<SurfaceFile::Material>& out) {
  std::ifstream in(path);
  std::string line, tok;
  while (std::getline(in, line)) {
    std::istringstream ss(line);
    if (!(ss >> tok)) continue;
    if (tok == "newmtl") {
      out.emplace_back();
      out.back().name = restOfLine(ss);
    } else if (tok == "Kd" && !out.empty()) {
      for (float& c : out.back().colour) ss >> c;
    } else if (tok == "map_Kd" && !out.empty()) {
      // Options come first; the file name is the last field.
      while (ss >> tok) out.back().texture = tok;
    }
  }
}

// Reads v and f lines, and with `uvs` (render meshes) vt lines and the faces' texture indices,
// and the materials (mtllib, usemtl); polygons become fans; vn and groups are ignored.
Result<SurfaceFile> readObj(const std::string& path, bool uvs) {
  std::ifstream in(path);
  if (!in) return fail(path, ": cannot open");
  SurfaceFile s;
  s.path = path;
  std::string line, tok;
  int64_t ln = 0;
  std::vector<float> textureCoords;   // 2 per vt line
  std::vector<int64_t> cornerUv;      // per triangle corner, 0-based; -1: none
  std::vector<int32_t> faceMaterial;  // per triangle: index in s.materials; -1: before usemtl
  int32_t material = -1;
  bool usemtl = false;
  while (std::getline(in, line)) {
    ++ln;
    const std::string where = path + ":" + std::to_string(ln) + ": ";
    std::istringstream ss(line);
    if (!(ss >> tok) || tok[0] == '#') continue;
    if (tok == "v") {
      double x[3];
      for (int k = 0; k < 3; ++k) {
        const std::string axis(1, static_cast<char>('x' + k));
        if (!(ss >> tok)) return fail(where, "vertex needs 3 coordinates");
        const std::string why = numberProblem(tok, x[k]);
        if (!why.empty()) return fail(where, "vertex coordinate ", axis, ": ", why);
      }
      s.positions.insert(s.positions.end(), x, x + 3);
      s.vertexLine.push_back(ln);
    } else if (tok == "vt" && uvs) {
      double t[2];
      for (int k = 0; k < 2; ++k) {
        if (!(ss >> tok)) return fail(where, "texture coordinate needs u and v");
        const std::string why = numberProblem(tok, t[k]);
        if (!why.empty()) return fail(where, "texture coordinate ", k ? "v" : "u", ": ", why);
      }
      textureCoords.insert(textureCoords.end(), {float(t[0]), float(t[1])});
    } else if (tok == "mtllib" && uvs) {
      const std::string file = restOfLine(ss);
      readMtl((std::filesystem::path(path).parent_path() / file).string(), s.materials);
    } else if (tok == "usemtl" && uvs) {
      const std::string name = restOfLine(ss);
      usemtl = true;
      material = -1;
      for (size_t m = 0; m < s.materials.size() && material < 0; ++m)
        if (s.materials[m].name == name) material = int32_t(m);
      if (material < 0) {
        material = int32_t(s.materials.size());
        s.materials.emplace_back();
        s.materials.back().name = name;
      }
    } else if (tok == "f") {
      std::vector<int64_t> poly, polyUv;
      const int64_t nv = static_cast<int64_t>(s.vertexCount());
      const int64_t nt = static_cast<int64_t>(textureCoords.size() / 2);
      while (ss >> tok) {
        int64_t i = 0, t = 0;
        if (!parseIndex(tok, i) || i == 0) return fail(where, "bad face index '", tok, "'");
        if (i < 0) {
          i += nv;  // relative to the vertices so far
          if (i < 0) return fail(where, "relative face index '", tok, "' points before vertex 1");
        } else {
          i -= 1;
        }
        poly.push_back(i);
        if (!uvs) continue;
        if (!parseTextureIndex(tok, t)) return fail(where, "bad texture index in '", tok, "'");
        if (t < 0) t += nt + 1;  // relative to the vt lines so far
        if (t < 0 || t > nt) {
          return fail(where, "texture index in '", tok, "' is outside the ", std::to_string(nt),
                      " 'vt' lines before it");
        }
        polyUv.push_back(t - 1);
      }
      if (poly.size() < 3) return fail(where, "face needs at least 3 vertices");
      for (size_t k = 1; k + 1 < poly.size(); ++k) {
        s.triangles.insert(s.triangles.end(), {poly[0], poly[k], poly[k + 1]});
        s.faceTag.push_back(ln);
        faceMaterial.push_back(material);
        if (uvs) cornerUv.insert(cornerUv.end(), {polyUv[0], polyUv[k], polyUv[k + 1]});
      }
    }
  }
  if (in.bad()) return fail(path, ": read error");
  const int64_t nv = static_cast<int64_t>(s.vertexCount());
  if (nv == 0) return fail(path, ": no vertices ('v' lines)");
  if (s.triangles.empty()) return fail(path, ": no faces ('f' lines)");
  // Only the materials faces use, in the order first used, as the assimp reader keeps them;
  // faces before any usemtl get a white "default".
  if (usemtl) {
    std::vector<SurfaceFile::Material> defined = std::move(s.materials);
    std::vector<int32_t> used(defined.size() + 1, -1);
    s.materials.clear();
    for (int32_t m : faceMaterial) {
      int32_t& u = used[size_t(m + 1)];
      if (u < 0) {
        u = int32_t(s.materials.size());
        s.materials.push_back(m < 0 ? SurfaceFile::Material{"default", {1, 1, 1}, ""}
                                    : defined[size_t(m)]);
      }
      s.faceMaterial.push_back(uint16_t(u));
    }
    if (s.materials.size() > 0xFFFE) return fail(path, ": more than 65534 materials");
  } else {
    s.materials.clear();
  }
  for (size_t i = 0; i < s.triangles.size(); ++i) {
    if (s.triangles[i] >= nv) {
      return fail(path, ":", std::to_string(s.faceTag[i / 3]), ": face index ",
                  std::to_string(s.triangles[i] + 1), " exceeds the ", std::to_string(nv),
                  " vertices of the file");
    }
  }
  // UVs only when every corner has one (as the assimp reader: some faces without them would
  // leave their texture lookups meaningless). A vertex used with several UVs (a seam) becomes
  // one vertex per UV, as assimp splits them; its line stays the position's.
  if (uvs && std::find(cornerUv.begin(), cornerUv.end(), -1) == cornerUv.end()) {
    std::map<std::pair<int64_t, int64_t>, int64_t> split;
    SurfaceFile out = s;
    out.positions.clear();
    out.vertexLine.clear();
    for (size_t c = 0; c < s.triangles.size(); ++c) {
      const int64_t v = s.triangles[c];
      const auto [it, added] = split.try_emplace({v, cornerUv[c]}, int64_t(split.size()));
      if (added) {
        out.positions.insert(out.positions.end(), &s.positions[3 * size_t(v)],
                             &s.positions[3 * size_t(v)] + 3);
        out.vertexLine.push_back(s.vertexLine[size_t(v)]);
        out.uvs.insert(out.uvs.end(), {textureCoords[2 * size_t(cornerUv[c])],
                                       textureCoords[2 * size_t(cornerUv[c]) + 1]});
      }
      out.triangles[c] = it->second;
    }
    return out;
  }
  return s;
}

// ---- PLY reading -------------------------------------------------------------------------

// A PLY scalar type: its size in bytes and kind ('i' signed, 'u' unsigned, 'f' float).
struct PlyType {
  int size = 0;
  char kind = 0;
};

PlyType plyType(const std::string& name) {
  static const std::map<std::string, PlyType> kTypes = {
      {"char", {1, 'i'}},  {"int8", {1, 'i'}},    {"uchar", {1, 'u'}},  {"uint8", {1, 'u'}},
      {"short", {2, 'i'}}, {"int16", {2, 'i'}},   {"ushort", {2, 'u'}}, {"uint16", {2, 'u'}},
      {"int", {4, 'i'}},   {"int32", {4, 'i'}},   {"uint", {4, 'u'}},   {"uint32", {4, 'u'}},
      {"float", {4, 'f'}}, {"float32", {4, 'f'}}, {"double", {8, 'f'}}, {"float64", {8, 'f'}}};
  auto it = kTypes.find(name);
  return it == kTypes.end() ? PlyType{} : it->second;
}

struct PlyProperty {
  std::string name;
  PlyType type;
  PlyType countType;  // size 0 unless a list
};

struct PlyElement {
  std::string name;
  int64_t count = 0;
  std::vector<PlyProperty> properties;
};

// Reads the values of the body one at a time, as text tokens or as binary of either byte order.
class PlyValues {
 public:
  enum Encoding { kAscii, kLittle, kBig };
  PlyValues(std::istream& in, Encoding encoding) : m_in(in), m_encoding(encoding) {}

  // False with problem() set at the end of the file or on a token that is not a number.
  bool next(PlyType t, double& v) {
    if (m_encoding == kAscii) {
      std::string tok;
      if (!(m_in >> tok)) return setProblem("unexpected end of file");
      if (t.kind != 'f') {
        int64_t i = 0;
        auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), i);
        if (ec != std::errc() || p != tok.data() + tok.size()) {
          return setProblem("'" + tok + "' is not an integer");
        }
        v = static_cast<double>(i);
        return true;
      }
      const std::string why = numberProblem(tok, v);
      return why.empty() || setProblem(why);
    }
    unsigned char b[8];
    if (!m_in.read(reinterpret_cast<char*>(b), t.size)) {
      return setProblem("unexpected end of file");
    }
    const bool little = std::endian::native == std::endian::little;
    if ((m_encoding == kLittle) != little) std::reverse(b, b + t.size);
    v = decode(b, t);
    return true;
  }
  const std::string& problem() const { return m_problem; }

 private:
  static double decode(const unsigned char* b, PlyType t) {
    auto as = [b]<class T>(T) {
      T x;
      std::memcpy(&x, b, sizeof x);
      return static_cast<double>(x);
    };
    if (t.kind == 'f') return t.size == 4 ? as(float{}) : as(double{});
    if (t.size == 1) return t.kind == 'i' ? as(int8_t{}) : as(uint8_t{});
    if (t.size == 2) return t.kind == 'i' ? as(int16_t{}) : as(uint16_t{});
    return t.kind == 'i' ? as(int32_t{}) : as(uint32_t{});
  }
  bool setProblem(std::string why) {
    m_problem = std::move(why);
    return false;
  }

  std::istream& m_in;
  Encoding m_encoding;
  std::string m_problem;
};

// Reads the x, y, z of the "vertex" element and the vertex_indices list of the "face" element;
// polygons become fans; every other property and element (normals, colours, edges) is skipped.
Result<SurfaceFile> readPly(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(path, ": cannot open");
  SurfaceFile s;
  s.path = path;
  s.source = SurfaceSource::kPly;

  // Header.
  std::vector<PlyElement> elements;
  int encoding = -1;
  std::string line;
  int ln = 0;
  for (;;) {
    if (!std::getline(in, line)) return fail(path, ": PLY header has no 'end_header' line");
    ++ln;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::string where = path + ":" + std::to_string(ln) + ": PLY header: ";
    std::istringstream ss(line);
    std::string key;
    ss >> key;
    if (key == "end_header") break;
    if (key == "format") {
      std::string f;
      ss >> f;
      encoding = f == "ascii"                  ? PlyValues::kAscii
                 : f == "binary_little_endian" ? PlyValues::kLittle
                 : f == "binary_big_endian"    ? PlyValues::kBig
                                               : -1;
      if (encoding < 0) return fail(where, "unknown format '", f, "'");
    } else if (key == "element") {
      PlyElement e;
      if (!(ss >> e.name >> e.count) || e.count < 0) return fail(where, "bad element line");
      elements.push_back(e);
    } else if (key == "property") {
      if (elements.empty()) return fail(where, "property before any element");
      PlyProperty p;
      std::string type;
      ss >> type;
      if (type == "list") {
        std::string countType, itemType;
        ss >> countType >> itemType >> p.name;
        p.countType = plyType(countType);
        p.type = plyType(itemType);
        if (!p.countType.size || p.countType.kind == 'f' || !p.type.size) {
          return fail(where, "bad list types '", countType, " ", itemType, "'");
        }
      } else {
        ss >> p.name;
        p.type = plyType(type);
        if (!p.type.size) return fail(where, "unknown property type '", type, "'");
      }
      elements.back().properties.push_back(p);
    }
    // "ply", "comment" and "obj_info" lines carry nothing that is needed.
  }
  if (encoding < 0) return fail(path, ": PLY header has no 'format' line");
  auto find = [&](const std::string& name) {
    return std::find_if(elements.begin(), elements.end(),
                        [&](const PlyElement& e) { return e.name == name; });
  };
  const auto vertexElement = find("vertex");
  if (vertexElement == elements.end()) return fail(path, ": PLY file has no vertex element");
  for (const char* axis : {"x", "y", "z"}) {
    const auto& props = vertexElement->properties;
    if (std::none_of(props.begin(), props.end(),
                     [&](const PlyProperty& p) { return p.name == axis && !p.countType.size; })) {
      return fail(path, ": PLY vertex element has no '", axis, "' property");
    }
  }
  // Texture coordinates by the names the common writers use (assimp reads the same).
  std::string uName, vName;
  for (const auto& [u, v] :
       {std::pair{"u", "v"}, std::pair{"s", "t"}, std::pair{"texture_u", "texture_v"},
        std::pair{"texture_s", "texture_t"}}) {
    const auto& props = vertexElement->properties;
    const auto has = [&](const char* name) {
      return std::any_of(props.begin(), props.end(),
                         [&](const PlyProperty& p) { return p.name == name && !p.countType.size; });
    };
    if (has(u) && has(v)) {
      uName = u;
      vName = v;
      break;
    }
  }
  const auto faceElement = find("face");
  if (faceElement == elements.end() || faceElement->count == 0) {
    return fail(path, ": PLY file has no faces (a point cloud cannot be meshed)");
  }

  // Body: elements in header order, values in property order.
  PlyValues values(in, static_cast<PlyValues::Encoding>(encoding));
  for (const PlyElement& e : elements) {
    const bool isVertex = &e == &*vertexElement, isFace = &e == &*faceElement;
    for (int64_t i = 0; i < e.count; ++i) {
      auto where = [&] { return path + ": " + e.name + " " + std::to_string(i) + ": "; };
      double xyz[3] = {0, 0, 0};
      float uv[2] = {0, 0};
      std::vector<int64_t> poly;
      for (const PlyProperty& p : e.properties) {
        double v = 0;
        if (!p.countType.size) {
          if (!values.next(p.type, v)) return fail(where(), p.name, ": ", values.problem());
          if (isVertex && p.name.size() == 1 && p.name[0] >= 'x' && p.name[0] <= 'z') {
            xyz[p.name[0] - 'x'] = v;
          }
          if (isVertex && !uName.empty() && (p.name == uName || p.name == vName)) {
            if (!std::isfinite(v))
              return fail(where(), p.name, ": ", formatDouble(v), " is not finite");
            uv[p.name == vName] = float(v);
          }
          continue;
        }
        double n = 0;
        if (!values.next(p.countType, n)) return fail(where(), p.name, ": ", values.problem());
        if (n < 0) return fail(where(), p.name, ": negative list length");
        const bool indices = isFace && (p.name == "vertex_indices" || p.name == "vertex_index");
        for (int64_t k = 0; k < static_cast<int64_t>(n); ++k) {
          if (!values.next(p.type, v)) return fail(where(), p.name, ": ", values.problem());
          if (!indices) continue;
          if (v != std::floor(v) || std::abs(v) > 1e15) {
            return fail(where(), p.name, ": ", formatDouble(v), " is not a vertex index");
          }
          poly.push_back(static_cast<int64_t>(v));
        }
      }
      if (isVertex) {
        s.positions.insert(s.positions.end(), xyz, xyz + 3);
        if (!uName.empty()) s.uvs.insert(s.uvs.end(), uv, uv + 2);
      } else if (isFace) {
        if (poly.size() < 3) return fail(where(), "face needs at least 3 vertices");
        for (size_t k = 1; k + 1 < poly.size(); ++k) {
          s.triangles.insert(s.triangles.end(), {poly[0], poly[k], poly[k + 1]});
          s.faceTag.push_back(i);
        }
      }
    }
  }
  const int64_t nv = static_cast<int64_t>(s.vertexCount());
  if (nv == 0) return fail(path, ": PLY file has no vertices");
  for (size_t i = 0; i < s.triangles.size(); ++i) {
    if (s.triangles[i] < 0 || s.triangles[i] >= nv) {
      return fail(path, ": face ", std::to_string(s.faceTag[i / 3]), ": vertex index ",
                  std::to_string(s.triangles[i]), " is outside the ", std::to_string(nv),
                  " vertices of the file (numbered from 0)");
    }
  }
  for (size_t i = 0; i < s.positions.size(); ++i) {
    if (!std::isfinite(s.positions[i])) {
      return fail(s.vertexAt(i / 3), ": coordinate ", std::string(1, char('x' + i % 3)), " = ",
                  formatDouble(s.positions[i]), " is not finite");
    }
  }
  return s;
}

}  // namespace

#ifndef GF_MESHING_HAS_ASSIMP
bool haveAssimp() { return false; }

Result<SurfaceFile> detail::readWithAssimp(const std::string& path, const SurfaceReadOptions&) {
  return fail(path,
              ": this graphfrac was built without assimp, which reads formats other than "
              "OBJ and PLY (install libassimp-dev: tools/setup tools, and configure again)");
}
#endif

Result<SurfaceFile> readSurfaceFile(const std::string& path, const SurfaceReadOptions& options) {
  if (options.assimp) return detail::readWithAssimp(path, options);
  Result<SurfaceFormat> format = detectFormat(path, haveAssimp());
  if (!format) return format.error();
  if (format.value() == SurfaceFormat::kAssimp) return detail::readWithAssimp(path, options);
  Result<SurfaceFile> r =
      format.value() == SurfaceFormat::kPly ? readPly(path) : readObj(path, options.uvs);
  if (!r) return r;
  // OBJ and PLY carry no unit or axis: metres and Y up unless told.
  SurfaceFile& s = r.value();
  s.format = format.value() == SurfaceFormat::kPly ? "PLY" : "Wavefront OBJ";
  double m[9];
  detail::upToY(options.up ? options.up : 'y', m);
  const double scale = options.scale > 0 ? options.scale : 1;
  for (double& x : m) x *= scale;
  if (scale != 1 || (options.up && options.up != 'y')) detail::transformSurface(s, m);
  s.conversion = "unit " + formatDouble(scale) + " m" +
                 (options.scale > 0 ? " (--scale)" : " (none given)") + ", up +" +
                 static_cast<char>(std::toupper(options.up ? options.up : 'y')) +
                 (options.up ? " (--up)" : " (none given)");
  return r;
}

}  // namespace gf::meshing
