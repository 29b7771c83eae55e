// `graphfrac mesh from-surface` on good and bad surfaces: it reads OBJ and PLY (ASCII and both
// binary byte orders) to the same tet mesh, reads STL, glTF, FBX and Collada through assimp in
// metres, and when the input cannot be read or meshed says why in the file's terms (line,
// vertex and face numbers, or meshes) with every open edge and every pair of crossing faces, not
// the first problem alone or tetgen's abort. Cases that run tetgen are skipped where the program
// is not installed, and cases that read assimp's test models where assimp or the models are
// missing (tools/setup tools installs all three).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "graphfrac/mesh.h"
#include "meshing/surface_reader.h"

namespace fs = std::filesystem;

namespace {

struct Outcome {
  int code = -1;
  std::string out, err;
};

Outcome mesh(std::vector<std::string> args) {
  args.insert(args.begin(), "mesh");
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  Outcome o;
  o.code = gf::cli::runMeshCommand(static_cast<int>(argv.size()), argv.data());
  o.out = testing::internal::GetCapturedStdout();
  o.err = testing::internal::GetCapturedStderr();
  return o;
}

bool haveTetgen() {
  std::stringstream path(std::getenv("PATH") ? std::getenv("PATH") : "");
  for (std::string dir; std::getline(path, dir, ':');) {
    if (access((fs::path(dir) / "tetgen").c_str(), X_OK) == 0) return true;
  }
  return false;
}

#define REQUIRE_TETGEN() \
  if (!haveTetgen()) GTEST_SKIP() << "the tetgen program is not installed (tools/setup tools)"

// Debian's assimp-testmodels.
const fs::path kModels = "/usr/share/assimp/models";

#define REQUIRE_ASSIMP()                                                                 \
  if (!gf::meshing::haveAssimp())                                                        \
  GTEST_SKIP() << "built without assimp (install libassimp-dev: tools/setup tools, and " \
                  "configure again)"

#define REQUIRE_MODELS()                                                           \
  REQUIRE_ASSIMP();                                                                \
  if (!fs::exists(kModels / "STL" / "Wuson.stl"))                                  \
  GTEST_SKIP() << "assimp's test models are not installed in " << kModels.string() \
               << " (Debian package assimp-testmodels: tools/setup tools)"

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("gf_mesh_test_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// The unit cube at `origin`, 8 vertices (index = 4x + 2y + z) and 12 outward triangles.
struct Tris {
  std::vector<std::array<double, 3>> v;
  std::vector<std::array<int, 3>> f;  // 0-based
};

Tris cube(std::array<double, 3> o = {0, 0, 0}, double size = 1) {
  Tris t;
  for (int x = 0; x < 2; ++x) {
    for (int y = 0; y < 2; ++y) {
      for (int z = 0; z < 2; ++z)
        t.v.push_back({o[0] + size * x, o[1] + size * y, o[2] + size * z});
    }
  }
  const int quads[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1},
                           {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
  for (const auto& q : quads) {
    t.f.push_back({q[0], q[1], q[2]});
    t.f.push_back({q[0], q[2], q[3]});
  }
  return t;
}

Tris join(Tris a, const Tris& b) {
  const int n = static_cast<int>(a.v.size());
  a.v.insert(a.v.end(), b.v.begin(), b.v.end());
  for (auto f : b.f) a.f.push_back({f[0] + n, f[1] + n, f[2] + n});
  return a;
}

// Vertices on lines 1..n, faces on lines n+1.. .
void writeObj(const fs::path& path, const Tris& t) {
  std::ofstream out(path);
  out.precision(17);
  for (const auto& p : t.v) out << "v " << p[0] << ' ' << p[1] << ' ' << p[2] << '\n';
  for (const auto& f : t.f) out << "f " << f[0] + 1 << ' ' << f[1] + 1 << ' ' << f[2] + 1 << '\n';
}

template <class T>
void put(std::ofstream& out, T x, bool little) {
  char b[sizeof x];
  std::memcpy(b, &x, sizeof x);
  if (little != (std::endian::native == std::endian::little)) std::reverse(b, b + sizeof x);
  out.write(b, sizeof x);
}

// Binary PLY with an extra per-vertex colour and an extra element, which must be read past.
void writeBinaryPly(const fs::path& path, const Tris& t, bool little) {
  std::ofstream out(path, std::ios::binary);
  out << "ply\nformat binary_" << (little ? "little" : "big") << "_endian 1.0\n"
      << "comment written by test_mesh_command\n"
      << "element vertex " << t.v.size() << "\nproperty float x\nproperty double y\n"
      << "property uchar red\nproperty float z\n"
      << "element face " << t.f.size() << "\nproperty list uchar uint vertex_indices\n"
      << "element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n";
  for (const auto& p : t.v) {
    put(out, static_cast<float>(p[0]), little);
    put(out, p[1], little);
    put(out, uint8_t{200}, little);
    put(out, static_cast<float>(p[2]), little);
  }
  for (const auto& f : t.f) {
    put(out, uint8_t{3}, little);
    for (int i : f) put(out, static_cast<uint32_t>(i), little);
  }
  put(out, int32_t{0}, little);
  put(out, int32_t{1}, little);
}

double meshVolume(const fs::path& msh) {
  gf::Result<gf::TetMesh> m = gf::TetMesh::fromFile(msh.string());
  EXPECT_TRUE(m.ok()) << (m.ok() ? "" : m.error().message);
  return m.ok() ? m.value().volume() : 0;
}

TEST(MeshFromSurface, UsageNamesTheFormats) {
  const Outcome o = mesh({"help"});
  EXPECT_EQ(o.code, gf::cli::kExitOk);
  EXPECT_NE(o.out.find("Wavefront OBJ (.obj) or PLY (.ply, ASCII or"), std::string::npos) << o.out;
}

TEST(MeshFromSurface, ReadsAsciiAndBinaryPly) {
  REQUIRE_TETGEN();
  const fs::path dir = scratch("ply");
  // ASCII with quads (split into fans) and a normal per vertex.
  {
    std::ofstream out(dir / "ascii.ply");
    const Tris c = cube();
    out << "ply\r\nformat ascii 1.0\r\nelement vertex 8\r\nproperty double x\r\n"
        << "property double y\r\nproperty double z\r\nproperty float nx\r\n"
        << "element face 6\r\nproperty list uchar int vertex_index\r\nend_header\r\n";
    for (const auto& p : c.v) out << p[0] << ' ' << p[1] << ' ' << p[2] << " 0.5\n";
    const int quads[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1},
                             {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
    for (const auto& q : quads)
      out << "4 " << q[0] << ' ' << q[1] << ' ' << q[2] << ' ' << q[3] << '\n';
  }
  writeBinaryPly(dir / "le.ply", cube(), true);
  writeBinaryPly(dir / "be.ply", cube(), false);
  for (const char* name : {"ascii", "le", "be"}) {
    const fs::path in = dir / (std::string(name) + ".ply"),
                   out = dir / (std::string(name) + ".msh");
    const Outcome o = mesh({"from-surface", in.string(), out.string()});
    ASSERT_EQ(o.code, gf::cli::kExitOk) << name << "\n" << o.err;
    EXPECT_NE(o.out.find("8 vertices, 12 triangles"), std::string::npos) << o.out;
    EXPECT_NEAR(meshVolume(out), 1.0, 1e-12) << name;
  }
}

// Without assimp the other formats are named; with it, what assimp cannot read is reported with
// the file name and assimp's reason.
TEST(MeshFromSurface, NamesWhatCannotBeRead) {
  const fs::path dir = scratch("formats");
  std::ofstream(dir / "cube.stl") << "solid cube\n  facet normal 0 0 1\n";
  {
    std::ofstream glb(dir / "model.bin", std::ios::binary);
    glb.write("glTF\2\0\0\0", 8);
  }
  {
    std::ofstream fbx(dir / "broken.fbx", std::ios::binary);
    fbx.write("Kaydara FBX Binary  \0\x1a\0", 23);
  }
  const struct {
    const char* file;
    const char* without;  // the error without assimp, then with it
    const char* with;
  } cases[] = {
      {"cube.stl", ": reads Wavefront OBJ and PLY only (got an STL file)",
       ": assimp cannot read it: "},
      {"model.bin", ": reads Wavefront OBJ and PLY only (got a glTF file)",
       ": unsupported format: assimp has no reader for it"},
      {"broken.fbx", ": reads Wavefront OBJ and PLY only (got an FBX file)",
       ": assimp cannot read it: FBX"},
      {"missing.glb", ": cannot open", ": cannot open"},
  };
  for (const auto& c : cases) {
    const Outcome o = mesh({"from-surface", (dir / c.file).string(), (dir / "out.msh").string()});
    EXPECT_EQ(o.code, gf::cli::kExitScene) << c.file;
    const std::string want =
        (dir / c.file).string() + (gf::meshing::haveAssimp() ? c.with : c.without);
    EXPECT_NE(o.err.find(want), std::string::npos) << want << "\n" << o.err;
  }
}

TEST(MeshFromSurface, PlyErrorsNameTheElement) {
  const fs::path dir = scratch("plyerr");
  Tris c = cube();
  c.f[3][1] = 9;  // face 3 points past the 8 vertices
  writeBinaryPly(dir / "range.ply", c, true);
  Outcome o = mesh({"from-surface", (dir / "range.ply").string(), (dir / "o.msh").string()});
  EXPECT_EQ(o.code, gf::cli::kExitScene);
  EXPECT_NE(o.err.find("range.ply: face 3: vertex index 9 is outside the 8 vertices"),
            std::string::npos)
      << o.err;

  // Cut short in the faces.
  writeBinaryPly(dir / "short.ply", cube(), false);
  fs::resize_file(dir / "short.ply", fs::file_size(dir / "short.ply") - 20);
  o = mesh({"from-surface", (dir / "short.ply").string(), (dir / "o.msh").string()});
  EXPECT_EQ(o.code, gf::cli::kExitScene);
  EXPECT_NE(o.err.find("short.ply: face 11: vertex_indices: unexpected end of file"),
            std::string::npos)
      << o.err;
}

TEST(MeshFromSurface, KeepTempSaysWhereTheFilesAre) {
  const fs::path dir = scratch("keep");
  writeObj(dir / "cube.obj", cube());
  // A tetgen that cannot start: the run fails after the temporary files are written.
  const Outcome o =
      mesh({"from-surface", (dir / "cube.obj").string(), (dir / "o.msh").string(), "--keep-temp",
            "--method", "tetgen", "--tetgen", (dir / "no-such-tetgen").string()});
  EXPECT_EQ(o.code, gf::cli::kExitScene);
  const std::string key = "temporary files kept in ";
  const size_t at = o.err.find(key);
  ASSERT_NE(at, std::string::npos) << o.err;
  const std::string kept = o.err.substr(at + key.size(), o.err.find(')', at) - at - key.size());
  EXPECT_NE(o.out.find("temporary files in " + kept), std::string::npos) << o.out;
  EXPECT_TRUE(fs::exists(fs::path(kept) / "surface.smesh")) << kept;
  fs::remove_all(kept);
}

TEST(MeshFromSurface, OpenSurfaceListsEveryOpenEdgeAndThePartCount) {
  const fs::path dir = scratch("open");
  // A cube without its x = 1 side (a square hole: 4 open edges) and a lone triangle apart
  // (3 open edges): 7 in all, in 2 parts.
  Tris t = cube();
  t.f.erase(t.f.begin() + 2, t.f.begin() + 4);  // faces on lines 11 and 12
  t.v.push_back({5, 0, 0});
  t.v.push_back({6, 0, 0});
  t.v.push_back({5, 1, 0});
  t.f.push_back({8, 9, 10});
  writeObj(dir / "open.obj", t);
  const Outcome o = mesh({"from-surface", (dir / "open.obj").string(), (dir / "o.msh").string(),
                          "--method", "tetgen"});
  EXPECT_EQ(o.code, gf::cli::kExitScene);
  EXPECT_NE(o.err.find("open.obj: surface is not closed: 7 open edges (on one face only), in 2 "
                       "connected parts:"),
            std::string::npos)
      << o.err;
  // The hole's rim, in file order, with the file's vertex numbers and positions.
  EXPECT_NE(o.err.find("vertex 5 (1, 0, 0) - vertex 6 (1, 0, 1), of the face on line 14 "
                       "(vertices 1 5 6)"),
            std::string::npos)
      << o.err;
  EXPECT_NE(o.err.find("... and 1 more"), std::string::npos) << o.err;
}

TEST(MeshFromSurface, SelfIntersectionNamesTheCrossingFaces) {
  REQUIRE_TETGEN();
  const fs::path dir = scratch("cross");
  // Two cubes overlapping by half in each direction, written as one surface.
  writeObj(dir / "cross.obj", join(cube(), cube({0.5, 0.5, 0.5})));
  const Outcome o = mesh({"from-surface", (dir / "cross.obj").string(), (dir / "o.msh").string(),
                          "--method", "tetgen"});
  EXPECT_EQ(o.code, gf::cli::kExitScene);
  EXPECT_EQ(o.err.find("crashed"), std::string::npos) << o.err;
  EXPECT_NE(o.err.find("cross.obj: surface intersects itself: 18 pairs of faces cross"),
            std::string::npos)
      << o.err;
  // Each listed pair: a face of the first cube (lines 17..28) and one of the second (29..40).
  std::stringstream lines(o.err);
  int listed = 0;
  for (std::string l; std::getline(lines, l);) {
    int a = 0, b = 0;
    if (std::sscanf(l.c_str(), "  face on line %d (vertices %*d %*d %*d) and face on line %d", &a,
                    &b) != 2) {
      continue;
    }
    ++listed;
    EXPECT_TRUE(a >= 17 && a <= 28 && b >= 29 && b <= 40) << l;
  }
  EXPECT_EQ(listed, 6);
  EXPECT_NE(o.err.find("\n  ... and 12 more"), std::string::npos) << o.err;
}

TEST(MeshFromSurface, HugeOrNonFiniteCoordinatesNameTheLine) {
  const fs::path dir = scratch("huge");
  Tris t = cube();
  t.v[1][2] = 1e300;  // vertex 2, line 2
  writeObj(dir / "huge.obj", t);
  Outcome o = mesh({"from-surface", (dir / "huge.obj").string(), (dir / "o.msh").string()});
  EXPECT_EQ(o.code, gf::cli::kExitScene);
  EXPECT_NE(o.err.find("huge.obj:2: vertex 2: coordinate z = 1e+300 is too large"),
            std::string::npos)
      << o.err;

  std::ofstream(dir / "inf.obj") << "v 0 0 0\nv 1 inf 0\n";
  o = mesh({"from-surface", (dir / "inf.obj").string(), (dir / "o.msh").string()});
  EXPECT_NE(o.err.find("inf.obj:2: vertex coordinate y: 'inf' is not finite"), std::string::npos)
      << o.err;
  std::ofstream(dir / "over.obj") << "# big\nv 0 0 0\nv 1 0 1e400\n";
  o = mesh({"from-surface", (dir / "over.obj").string(), (dir / "o.msh").string()});
  EXPECT_NE(o.err.find("over.obj:3: vertex coordinate z: '1e400' is out of the range of a double"),
            std::string::npos)
      << o.err;
}

// Each triangle corner as (x, y, z, u, v): what a textured surface draws, whatever the
// vertex numbering.
std::vector<std::array<double, 5>> texturedCorners(const gf::meshing::SurfaceFile& f) {
  std::vector<std::array<double, 5>> out;
  for (int64_t v : f.triangles) {
    const size_t i = static_cast<size_t>(v);
    out.push_back({f.positions[3 * i], f.positions[3 * i + 1], f.positions[3 * i + 2],
                   double(f.uvs[2 * i]), double(f.uvs[2 * i + 1])});
  }
  return out;
}

// OBJ texture coordinates, read on request (render meshes): a square of two triangles whose
// diagonal is a UV seam becomes 6 vertices, each corner with the UV its face names (also by a
// relative index); without the request, or when a face names none, the 4 positions and no UVs.
TEST(MeshFromSurface, ObjTextureCoordinatesSplitVerticesAtSeams) {
  const fs::path dir = scratch("objuv");
  const std::string square =
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
      "vt 0 0\nvt 0.5 0\nvt 0.5 1\nvt 0 1\nvt 0.5 0.5\nvt 1 0.5\n";
  std::ofstream(dir / "seam.obj") << square << "f 1/1 2/2 3/3\nf 1/5/1 3/-1 4/-3\n";
  std::ofstream(dir / "mixed.obj") << square << "f 1/1 2/2 3/3\nf 1 3 4\n";
  gf::meshing::SurfaceReadOptions withUvs;
  withUvs.uvs = true;
  gf::Result<gf::meshing::SurfaceFile> r =
      gf::meshing::readSurfaceFile((dir / "seam.obj").string(), withUvs);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r.value().vertexCount(), 6u);
  const std::vector<std::array<double, 5>> corners = texturedCorners(r.value()),
                                           expected = {{0, 0, 0, 0, 0},   {1, 0, 0, 0.5, 0},
                                                       {1, 1, 0, 0.5, 1}, {0, 0, 0, 0.5, 0.5},
                                                       {1, 1, 0, 1, 0.5}, {0, 1, 0, 0, 1}};
  EXPECT_EQ(corners, expected);
  EXPECT_EQ(r.value().vertexLine[3], 1);  // the split vertex keeps its position's line
  for (const char* name : {"seam.obj", "mixed.obj"}) {
    for (const bool uvs : {false, true}) {
      if (uvs && std::string(name) == "seam.obj") continue;
      gf::meshing::SurfaceReadOptions o;
      o.uvs = uvs;
      gf::Result<gf::meshing::SurfaceFile> plain =
          gf::meshing::readSurfaceFile((dir / name).string(), o);
      ASSERT_TRUE(plain.ok()) << plain.error().message;
      EXPECT_EQ(plain.value().vertexCount(), 4u) << name;
      EXPECT_TRUE(plain.value().uvs.empty()) << name;
    }
  }
  // Errors name the line.
  std::ofstream(dir / "short.obj") << square << "vt 0.5\nf 1/1 2/2 3/3\n";
  std::ofstream(dir / "range.obj") << square << "f 1/1 2/2 3/7\n";
  std::ofstream(dir / "word.obj") << square << "f 1/a 2/2 3/3\n";
  const std::pair<const char*, const char*> bad[] = {
      {"short.obj", "short.obj:11: texture coordinate needs u and v"},
      {"range.obj", "range.obj:11: texture index in '3/7' is outside the 6 'vt' lines before it"},
      {"word.obj", "word.obj:11: bad texture index in '1/a'"}};
  for (const auto& [name, message] : bad) {
    gf::Result<gf::meshing::SurfaceFile> e =
        gf::meshing::readSurfaceFile((dir / name).string(), withUvs);
    ASSERT_FALSE(e.ok()) << name;
    EXPECT_NE(e.error().message.find(message), std::string::npos) << e.error().message;
    EXPECT_TRUE(gf::meshing::readSurfaceFile((dir / name).string()).ok()) << name;
  }
}

// ---- through assimp ----------------------------------------------------------------------

struct Shape {
  size_t triangles = 0;
  std::array<double, 3> lo{}, hi{};
  double area = 0;
};

// Read as `mesh from-surface` reads it; the bounding box and area are measured here.
Shape shape(const fs::path& path, gf::meshing::SurfaceReadOptions options = {}) {
  gf::Result<gf::meshing::SurfaceFile> r = gf::meshing::readSurfaceFile(path.string(), options);
  Shape s;
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
  if (!r.ok()) return s;
  const gf::meshing::SurfaceFile& f = r.value();
  s.triangles = f.triangles.size() / 3;
  s.lo = {INFINITY, INFINITY, INFINITY};
  s.hi = {-INFINITY, -INFINITY, -INFINITY};
  for (int64_t v : f.triangles) {
    for (size_t k = 0; k < 3; ++k) {
      s.lo[k] = std::min(s.lo[k], f.positions[3 * static_cast<size_t>(v) + k]);
      s.hi[k] = std::max(s.hi[k], f.positions[3 * static_cast<size_t>(v) + k]);
    }
  }
  for (size_t t = 0; t < f.triangles.size(); t += 3) {
    const double* p[3];
    for (size_t k = 0; k < 3; ++k) p[k] = &f.positions[3 * static_cast<size_t>(f.triangles[t + k])];
    const double a[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
    const double b[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
    s.area += 0.5 * std::hypot(a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                               a[0] * b[1] - a[1] * b[0]);
  }
  return s;
}

// Same triangles, box and area to a relative tolerance (float formats against double ones).
void expectSameShape(const Shape& a, const Shape& b, double tol, const std::string& what) {
  EXPECT_EQ(a.triangles, b.triangles) << what;
  const double size = std::max({a.hi[0] - a.lo[0], a.hi[1] - a.lo[1], a.hi[2] - a.lo[2]});
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_NEAR(a.lo[k], b.lo[k], tol * size) << what << " axis " << k;
    EXPECT_NEAR(a.hi[k], b.hi[k], tol * size) << what << " axis " << k;
  }
  EXPECT_NEAR(a.area, b.area, tol * a.area) << what;
}

// The Wuson model as STL (assimp), PLY and OBJ (the CLI's readers) and OBJ through assimp:
// four readers, one shape.
TEST(MeshFromSurfaceAssimp, OneModelInStlPlyAndObjReadsTheSame) {
  REQUIRE_MODELS();
  const Shape stl = shape(kModels / "STL" / "Wuson.stl");
  EXPECT_EQ(stl.triangles, 3732u);
  EXPECT_NEAR(stl.hi[1] - stl.lo[1], 1.515816, 1e-5);  // its height, Y up as written
  expectSameShape(stl, shape(kModels / "PLY" / "Wuson.ply"), 1e-6, "PLY");
  expectSameShape(stl, shape(kModels / "OBJ" / "WusonOBJ.obj"), 1e-6, "OBJ");
  gf::meshing::SurfaceReadOptions viaAssimp;
  viaAssimp.assimp = true;
  expectSameShape(stl, shape(kModels / "OBJ" / "WusonOBJ.obj", viaAssimp), 1e-6, "OBJ (assimp)");
}

// PLY texture coordinates (per vertex, under each of the names writers use), in ASCII and
// binary: the corners draw the UVs written, and assimp reads the same file alike.
TEST(MeshFromSurfaceAssimp, PlyUvsReadAsWrittenAndAsAssimpReadsThem) {
  REQUIRE_ASSIMP();
  const fs::path dir = scratch("plyuv");
  const double uv[4][2] = {{0, 0}, {0.25, 0}, {0.25, 0.5}, {0, 0.75}};
  for (const auto& [u, v] :
       {std::pair{"u", "v"}, std::pair{"s", "t"}, std::pair{"texture_u", "texture_v"}}) {
    const fs::path path = dir / (std::string(u) + ".ply");
    {
      std::ofstream out(path);
      out << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
             "property float z\nproperty float "
          << u << "\nproperty float " << v
          << "\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
      const double xyz[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
      for (int k = 0; k < 4; ++k)
        out << xyz[k][0] << " " << xyz[k][1] << " " << xyz[k][2] << " " << uv[k][0] << " "
            << uv[k][1] << "\n";
      out << "4 0 1 2 3\n";
    }
    gf::meshing::SurfaceReadOptions viaAssimp;
    viaAssimp.assimp = true;
    gf::Result<gf::meshing::SurfaceFile> a = gf::meshing::readSurfaceFile(path.string()),
                                         b = gf::meshing::readSurfaceFile(path.string(), viaAssimp);
    ASSERT_TRUE(a.ok()) << a.error().message;
    ASSERT_EQ(a.value().uvs.size(), 8u) << u;
    for (int k = 0; k < 4; ++k) {
      EXPECT_EQ(a.value().uvs[2 * k], float(uv[k][0])) << u;
      EXPECT_EQ(a.value().uvs[2 * k + 1], float(uv[k][1])) << u;
    }
    ASSERT_TRUE(b.ok()) << b.error().message;
    ASSERT_FALSE(b.value().uvs.empty()) << u << " (assimp)";
    std::vector<std::array<double, 5>> ca = texturedCorners(a.value()),
                                       cb = texturedCorners(b.value());
    std::sort(ca.begin(), ca.end());
    std::sort(cb.begin(), cb.end());
    EXPECT_EQ(ca, cb) << u;
  }
}

// The spider's OBJ (1368 faces, a UV per corner) read by the OBJ reader and through assimp:
// the same textured corners, whatever order and numbering each gives them.
TEST(MeshFromSurfaceAssimp, ObjUvsReadTheSameAsAssimp) {
  REQUIRE_MODELS();
  gf::meshing::SurfaceReadOptions own, viaAssimp;
  own.uvs = true;
  viaAssimp.assimp = true;
  const fs::path spider = kModels / "OBJ" / "spider.obj";
  gf::Result<gf::meshing::SurfaceFile> a = gf::meshing::readSurfaceFile(spider.string(), own),
                                       b = gf::meshing::readSurfaceFile(spider.string(), viaAssimp);
  ASSERT_TRUE(a.ok()) << a.error().message;
  ASSERT_TRUE(b.ok()) << b.error().message;
  ASSERT_FALSE(a.value().uvs.empty());
  ASSERT_FALSE(b.value().uvs.empty());
  std::vector<std::array<double, 5>> ca = texturedCorners(a.value()),
                                     cb = texturedCorners(b.value());
  EXPECT_EQ(ca.size(), 3u * 1368u);
  ASSERT_EQ(ca.size(), cb.size());
  std::sort(ca.begin(), ca.end());
  std::sort(cb.begin(), cb.end());
  // assimp keeps the file's numbers in floats: 1e-5 of the spider's 200-unit size apart.
  size_t differ = 0;
  for (size_t i = 0; i < ca.size(); ++i)
    for (size_t k = 0; k < 5; ++k) differ += std::abs(ca[i][k] - cb[i][k]) > 1e-4;
  EXPECT_EQ(differ, 0u);
}

// The 1 m cube as binary and text glTF and as Collada written in centimetres (<unit
// meter="0.01">): 12 triangles, [-0.5, 0.5]^3, area 6; tetgen fills it with volume 1.
TEST(MeshFromSurfaceAssimp, UnitCubeInGlbGltfAndCollada) {
  REQUIRE_MODELS();
  const Shape cube = shape(kModels / "glTF2" / "BoxTextured-glTF-Binary" / "BoxTextured.glb");
  EXPECT_EQ(cube.triangles, 12u);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_NEAR(cube.lo[k], -0.5, 1e-6);
    EXPECT_NEAR(cube.hi[k], 0.5, 1e-6);
  }
  EXPECT_NEAR(cube.area, 6.0, 1e-5);
  expectSameShape(cube, shape(kModels / "glTF2" / "BoxTextured-glTF" / "BoxTextured.gltf"), 1e-6,
                  "glTF");
  expectSameShape(cube, shape(kModels / "Collada" / "cube_UTF8BOM.dae"), 1e-6, "Collada");
  if (!haveTetgen()) GTEST_SKIP() << "the tetgen program is not installed (tools/setup tools)";
  const fs::path out = scratch("glb") / "cube.msh";
  const Outcome o = mesh(
      {"from-surface", (kModels / "glTF2" / "BoxTextured-glTF-Binary" / "BoxTextured.glb").string(),
       out.string()});
  ASSERT_EQ(o.code, gf::cli::kExitOk) << o.err;
  EXPECT_NE(o.out.find("unit 1 m (glTF), up +Y (glTF)"), std::string::npos) << o.out;
  EXPECT_NE(o.out.find("8 vertices, 12 triangles"), std::string::npos) << o.out;
  EXPECT_NEAR(meshVolume(out), 1.0, 1e-6);
}

// FBX's UnitScaleFactor (centimetres per unit): a box saved in metres is 1 m, and the spider
// saved in FBX centimetres matches its OBJ (read as metres).
TEST(MeshFromSurfaceAssimp, FbxUnitsBecomeMetres) {
  REQUIRE_MODELS();
  // A 1 m box saved in metres (UnitScaleFactor 100): [-0.5, 0.5] x [0, 1] x [-0.5, 0.5].
  const Shape box = shape(kModels / "FBX" / "box_orphant_embedded_texture.fbx");
  EXPECT_EQ(box.triangles, 12u);
  for (size_t k = 0; k < 3; ++k) EXPECT_NEAR(box.hi[k] - box.lo[k], 1.0, 1e-5) << k;
  EXPECT_NEAR(box.area, 6.0, 1e-4);
  expectSameShape(shape(kModels / "OBJ" / "spider.obj"), shape(kModels / "FBX" / "spider.fbx"),
                  1e-5, "spider in OBJ and in FBX centimetres");

  // --scale replaces the file's unit (UnitScaleFactor 500: 5 m per unit).
  const fs::path five = kModels / "FBX" / "global_settings.fbx";
  gf::meshing::SurfaceReadOptions raw;
  raw.scale = 1;
  const Shape declared = shape(five), unscaled = shape(five, raw);
  EXPECT_NEAR(declared.hi[0] - declared.lo[0], 5 * (unscaled.hi[0] - unscaled.lo[0]), 1e-9);
  gf::Result<gf::meshing::SurfaceFile> r = gf::meshing::readSurfaceFile(five.string());
  ASSERT_TRUE(r.ok());
  EXPECT_NE(r.value().conversion.find("unit 5 m (FBX UnitScaleFactor 500)"), std::string::npos)
      << r.value().conversion;
}

// --up z turns a Z-up model to Y up: (x, y, z) -> (x, z, -y).
TEST(MeshFromSurfaceAssimp, UpAxisTurnsToY) {
  REQUIRE_MODELS();
  const Shape y = shape(kModels / "STL" / "Wuson.stl");
  gf::meshing::SurfaceReadOptions zUp;
  zUp.up = 'z';
  const Shape z = shape(kModels / "STL" / "Wuson.stl", zUp);
  EXPECT_NEAR(z.lo[1], y.lo[2], 1e-9);
  EXPECT_NEAR(z.hi[1], y.hi[2], 1e-9);
  EXPECT_NEAR(z.lo[2], -y.hi[1], 1e-9);
  EXPECT_NEAR(z.hi[0], y.hi[0], 1e-9);
  EXPECT_NEAR(z.area, y.area, 1e-9 * y.area);
}

// A minimal glTF whose one primitive has the given mode (0 points, 1 lines, 4 triangles).
void writeGltf(const fs::path& path, int mode) {
  const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  std::ofstream bin(path.string() + ".bin", std::ios::binary);
  bin.write(reinterpret_cast<const char*>(xyz), sizeof xyz);
  std::ofstream(path) << R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
  "nodes": [{"name": "n", "mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": )"
                      << mode << R"(}]}],
  "buffers": [{"uri": ")"
                      << path.filename().string() << R"(.bin", "byteLength": 36}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]}]})";
}

TEST(MeshFromSurfaceAssimp, PointsLinesAndEmptyScenesAreNamed) {
  REQUIRE_ASSIMP();
  const fs::path dir = scratch("assimp_err");
  writeGltf(dir / "points.gltf", 0);
  Outcome o = mesh({"from-surface", (dir / "points.gltf").string(), (dir / "o.msh").string()});
  EXPECT_EQ(o.code, gf::cli::kExitScene);
  EXPECT_NE(o.err.find("points.gltf: no triangles to mesh: the file holds only 3 points and 0 "
                       "lines"),
            std::string::npos)
      << o.err;
  writeGltf(dir / "lines.gltf", 1);
  o = mesh({"from-surface", (dir / "lines.gltf").string(), (dir / "o.msh").string()});
  EXPECT_NE(o.err.find("lines.gltf: no triangles to mesh: the file holds only 0 points and 1 "
                       "lines"),
            std::string::npos)
      << o.err;
  std::ofstream(dir / "empty.gltf") << R"({"asset": {"version": "2.0"}, "scene": 0,
    "scenes": [{"nodes": [0]}], "nodes": [{"name": "nothing"}]})";
  o = mesh({"from-surface", (dir / "empty.gltf").string(), (dir / "o.msh").string()});
  EXPECT_EQ(o.code, gf::cli::kExitScene);
  EXPECT_NE(o.err.find("empty.gltf: the scene is empty: no meshes"), std::string::npos) << o.err;
}

// What the CLI's readers check holds for assimp's surfaces, named by mesh and vertex.
TEST(MeshFromSurfaceAssimp, OpenAndNonFiniteSurfacesNameTheMesh) {
  REQUIRE_MODELS();
  const fs::path dir = scratch("assimp_open");
  Outcome o = mesh({"from-surface", (kModels / "STL" / "sphereWithHole.stl").string(),
                    (dir / "o.msh").string(), "--method", "tetgen"});
  EXPECT_EQ(o.code, gf::cli::kExitScene);
  EXPECT_NE(o.err.find("sphereWithHole.stl: surface is not closed: "), std::string::npos) << o.err;
  EXPECT_NE(o.err.find(", of the triangle "), std::string::npos) << o.err;
  o = mesh({"from-surface",
            (kModels / "glTF2" / "BoxWithInfinites-glTF-Binary" / "BoxWithInfinites.glb").string(),
            (dir / "o.msh").string()});
  EXPECT_EQ(o.code, gf::cli::kExitScene);
  EXPECT_NE(o.err.find("BoxWithInfinites.glb: mesh "), std::string::npos) << o.err;
  EXPECT_NE(o.err.find("is not finite"), std::string::npos) << o.err;
}

}  // namespace
