// Scene loader. Design: the JSON is parsed once (comments allowed, duplicate keys rejected) and
// then walked by small readers that each know the JSON path they stand on, so every error can
// say `file: bodies[0].material.E: reason`. Objects are read through ObjReader, which remembers
// the keys it consumed; a key nobody consumed is a typo and is reported with the closest valid
// key. Inside this file errors travel as a SceneError exception (the readers are deeply nested
// and a Result at every level would bury the format's logic); loadScene/parseScene catch it and
// everything else, so nothing crosses the API.
#include "scene/scene.h"

#include <graphfrac/mesh.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/matrix.hpp>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <set>
#include <span>
#include <sstream>
#include <string_view>
#include <utility>
#include <vector>

#include "kernels/svd3.h"
#include "meshing/lattice_mesher.h"
#include "meshing/surface_reader.h"
#include "meshing/triangle_soup.h"
#include "scene/impurity_image.h"
#include "scene/json_reader.h"
#ifdef GF_SCENE_HAS_STB_IMAGE
#include <stb/stb_image.h>
#endif

namespace gf::scene {
namespace {

using namespace detail;  // NOLINT: the readers are this file's vocabulary

// Generous caps that keep a typo (cells: 10000) from exhausting memory.
constexpr long long kMaxCells = 4'000'000;
constexpr int kMaxCellsPerAxis = 2000;
// Surface meshes: about 100 bytes per tet while the lattice mesher works.
constexpr double kMaxSurfaceTets = 5e6;
constexpr int kMaxThreads = 1024;
constexpr int kMaxSubsteps = 10000;

/// Runtime field names ("material.youngsModulus") and the scene keys they are read from ("E").
using FieldName = std::pair<std::string_view, std::string_view>;
using FieldNames = std::span<const FieldName>;

/// Reports what a runtime check() found: the runtime owns the rules (ranges, ordering,
/// combinations) and the loader only the syntax and the JSON types, so a scene is rejected by
/// exactly the rules createBody and setColliders apply. A message "field: reason" whose field
/// is in `names` is reported at that key's JSON path below `path`; any other under `path`
/// itself, with the runtime's field name.
void requireValid(const Result<void>& r, const std::string& path, FieldNames names = {}) {
  if (r) return;
  const std::string& message = r.error().message;
  if (const size_t colon = message.find(": "); colon != std::string::npos) {
    const std::string_view field(message.data(), colon);
    for (const auto& [runtime, key] : names) {
      if (field == runtime) throw SceneError{joinPath(path, key), message.substr(colon + 2)};
    }
  }
  throw SceneError{path, message};
}

constexpr FieldName kMaterialNames[] = {{"material.model", "model"},
                                        {"material.youngsModulus", "E"},
                                        {"material.poissonRatio", "nu"},
                                        {"material.density", "rho"},
                                        {"material.fibreStiffness", "fibre.stiffness"},
                                        {"material.fibreDirection", "fibre.direction"},
                                        {"material.massDamping", "damping.mass"},
                                        {"material.stiffnessDamping", "damping.stiffness"}};
constexpr FieldName kMultigridNames[] = {{"smoother", "smoother"},
                                         {"cycles", "cycles"},
                                         {"coarseRefreshInterval", "refresh_interval"},
                                         {"coarseRefreshSlack", "refresh_slack"}};
constexpr FieldName kSolverNames[] = {
    {"newtonIterations", "newton_iterations"},        {"newtonTolerance", "newton_tolerance"},
    {"numericalDamping", "numerical_damping"},        {"linearSolver", "linear"},
    {"maxLinearIterations", "max_linear_iterations"}, {"linearTolerance", "linear_tolerance"}};
constexpr FieldName kFractureNames[] = {
    {"strength", "strength"},     {"fibreStrengthRatio", "fibre_strength_ratio"},
    {"radius", "radius"},         {"nonlocalLength", "nonlocal_length"},
    {"model", "model"},           {"regions", "regions"},
    {"splitPoint", "split_point"}};
constexpr FieldName kPlasticityNames[] = {
    {"yieldStress", "yield"}, {"flowRate", "flow_rate"}, {"hardening", "hardening"}};
constexpr FieldName kBodyNames[] = {
    {"fracture.fibreStrengthRatio", "fracture.fibre_strength_ratio"},
    {"cutMode", "cut_mode"},
    {"initialVelocity", "initial_velocity"}};
constexpr FieldName kWorldNames[] = {{"WorldDef.substeps", "substeps"},
                                     {"WorldDef.gravity", "gravity"},
                                     {"WorldDef.backend", "backend"},
                                     {"WorldDef.contactSweeps", "contact_sweeps"},
                                     {"WorldDef.coupledContact", "coupled_contact"}};

// ---- scene pieces -------------------------------------------------------------------------

/// Resolves a mesh path against the scene's directory.
std::string resolvePath(const std::string& file, const std::string& baseDir) {
  namespace fs = std::filesystem;
  fs::path p(file);
  if (p.is_relative() && !baseDir.empty()) p = fs::path(baseDir) / p;
  return p.lexically_normal().string();
}

/// Cells along each axis: an array of counts, or one count for the shortest side.
template <size_t N>
std::array<int, N> readCells(const json& v, const std::string& path,
                             const std::array<double, N>& size) {
  std::array<int, N> cells{};
  if (v.is_array()) {
    readArray(v, path, N, "integers");
    for (size_t i = 0; i < N; ++i)
      cells[i] = readInt(v[i], indexPath(path, i), 1, kMaxCellsPerAxis);
  } else if (v.is_number()) {
    const int n = readInt(v, path, 1, kMaxCellsPerAxis);
    const double cell = *std::min_element(size.begin(), size.end()) / n;
    for (size_t i = 0; i < N; ++i) {
      const double c = std::max(1.0, std::round(size[i] / cell));
      if (c > kMaxCellsPerAxis) {
        throw SceneError{path, "gives " + fmt(c) + " cells along axis " + std::to_string(i) +
                                   " (at most " + std::to_string(kMaxCellsPerAxis) + ")"};
      }
      cells[i] = static_cast<int>(c);
    }
  } else {
    throw SceneError{path, "expected an integer or an array of " + std::to_string(N) +
                               " integers, got " + describe(v)};
  }
  long long total = 1;
  for (int c : cells) total *= c;
  if (total > kMaxCells) {
    throw SceneError{path, std::to_string(total) + " cells is too many (at most " +
                               std::to_string(kMaxCells) + ")"};
  }
  return cells;
}

TetMesh readGenerator(ObjReader& o) {
  const std::string kind =
      readChoice(o.require("generator"), o.at("generator"), {"box", "cylinder", "sphere", "slab"});
  if (kind == "box") {
    o.keys({"generator", "size", "cells", "notch"});
    const glm::dvec3 s = readPositiveVec3(o.require("size"), o.at("size"));
    const auto cells = readCells<3>(o.require("cells"), o.at("cells"), {s.x, s.y, s.z});
    gen::BoxOptions opt;
    if (const json* n = o.find("notch")) {
      ObjReader no(*n, o.at("notch"));
      no.keys({"depth", "angle_deg", "x"});
      opt.notchDepth = readPositive(no.require("depth"), no.at("depth"));
      // The generator keeps at least 5 % of the height under the notch's tip.
      if (opt.notchDepth > 0.95 * s.y) {
        throw SceneError{no.at("depth"), "expected at most 0.95 * the box height (" +
                                             fmt(0.95 * s.y) + "), got " + fmt(opt.notchDepth)};
      }
      if (const json* a = no.find("angle_deg")) {
        opt.notchAngleDeg = readInRange(*a, no.at("angle_deg"), 1, 179, false, false);
      }
      opt.notchX = s.x / 2;
      if (const json* x = no.find("x")) opt.notchX = readNumber(*x, no.at("x"));
      const double halfWidth =
          opt.notchDepth * std::tan(0.5 * opt.notchAngleDeg * std::numbers::pi / 180);
      if (opt.notchX - halfWidth < 0 || opt.notchX + halfWidth > s.x) {
        throw SceneError{no.at("x"), "the notch, " + fmt(2 * halfWidth) +
                                         " wide at the top, at x = " + fmt(opt.notchX) +
                                         " does not fit in the box length " + fmt(s.x)};
      }
      // The generator carves the V by moving the columns nearest its tip and shoulders onto
      // them; a V narrower than two cells would lose its tip and silently vanish.
      const double cellX = s.x / cells[0];
      if (2 * halfWidth < 2 * cellX) {
        throw SceneError{no.path(), "the notch is " + fmt(2 * halfWidth) +
                                        " wide at the top, less than two cells (" + fmt(2 * cellX) +
                                        "): use more cells along x or a " + "wider angle"};
      }
      no.finish();
    }
    return gen::box(s.x, s.y, s.z, cells[0], cells[1], cells[2], opt);
  }
  if (kind == "cylinder") {
    o.keys({"generator", "radius", "inner_radius", "height", "segments", "layers", "rings"});
    const double r = readPositive(o.require("radius"), o.at("radius"));
    const double h = readPositive(o.require("height"), o.at("height"));
    double inner = 0;
    if (const json* v = o.find("inner_radius")) {
      inner = readNumber(*v, o.at("inner_radius"));
      if (!(inner > 0 && inner < r)) {
        throw SceneError{o.at("inner_radius"),
                         "expected a number in (0, radius = " + fmt(r) + "), got " + fmt(inner)};
      }
    }
    int segments = 16, rings = 2;
    if (const json* v = o.find("segments")) segments = readInt(*v, o.at("segments"), 3, 1000);
    if (const json* v = o.find("rings")) rings = readInt(*v, o.at("rings"), 1, 1000);
    // Default layers give roughly cubic cells at the rim.
    const double rim = 2 * std::numbers::pi * r / segments;
    int layers = static_cast<int>(std::clamp(std::round(h / rim), 1.0, 1000.0));
    if (const json* v = o.find("layers")) layers = readInt(*v, o.at("layers"), 1, 10000);
    if (static_cast<long long>(segments) * layers * rings > kMaxCells) {
      throw SceneError{o.path(), "segments * layers * rings is too many cells (at most " +
                                     std::to_string(kMaxCells) + ")"};
    }
    return inner > 0 ? gen::tube(r, inner, h, segments, layers, rings)
                     : gen::cylinder(r, h, segments, layers, rings);
  }
  if (kind == "sphere") {
    o.keys({"generator", "radius", "cells"});
    const double r = readPositive(o.require("radius"), o.at("radius"));
    int n = 8;
    if (const json* v = o.find("cells")) n = readInt(*v, o.at("cells"), 2, 150);
    return gen::sphere(r, n);
  }
  // slab: thin in y, size in x and z.
  o.keys({"generator", "size", "thickness", "cells"});
  const json& sizeJ = readArray(o.require("size"), o.at("size"), 2, "positive numbers");
  const double sx = readPositive(sizeJ[0], indexPath(o.at("size"), 0));
  const double sz = readPositive(sizeJ[1], indexPath(o.at("size"), 1));
  const double t = readPositive(o.require("thickness"), o.at("thickness"));
  const auto cells = readCells<2>(o.require("cells"), o.at("cells"), {sx, sz});
  // The layers gen::slab will make: about cubic cells of the smaller in-plane cell size. In
  // double, so that a thin-cell typo is caught here rather than narrowed to an int there.
  const double cell = std::min(sx / cells[0], sz / cells[1]);
  const double layers = std::max(1.0, std::round(t / cell));
  if (layers > kMaxCellsPerAxis) {
    throw SceneError{o.at("cells"), "gives " + fmt(layers) + " cells across the thickness " +
                                        fmt(t) + " (at most " + std::to_string(kMaxCellsPerAxis) +
                                        "): use fewer cells in the plane or a thinner slab"};
  }
  if (double(cells[0]) * cells[1] * layers > double(kMaxCells)) {
    throw SceneError{o.at("cells"), fmt(double(cells[0]) * cells[1] * layers) +
                                        " cells is too many (at most " + std::to_string(kMaxCells) +
                                        ")"};
  }
  return gen::slab(sx, sz, t, cells[0], cells[1]);
}

/// "scale": one positive factor or one per axis.
glm::dvec3 readScale(const json& v, const std::string& path) {
  if (v.is_number()) return glm::dvec3(readPositive(v, path));
  if (!v.is_array()) {
    throw SceneError{
        path, "expected a positive number or an array of 3 positive numbers, got " + describe(v)};
  }
  return readPositiveVec3(v, path);
}

// The "surface", "unit" and "up" keys of "mesh" and "render_mesh": the file, read with the
// units and up axis they give (or the file's own).
meshing::SurfaceFile readSurfaceKeys(ObjReader& o, const std::string& baseDir, bool uvs = false) {
  const std::string file = readString(o.require("surface"), o.at("surface"));
  const std::string resolved = resolvePath(file, baseDir);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(resolved, ec)) {
    throw SceneError{o.at("surface"), "no such file \"" + resolved + "\""};
  }
  meshing::SurfaceReadOptions read;
  read.uvs = uvs;
  if (const json* unit = o.find("unit")) read.scale = readPositive(*unit, o.at("unit"));
  if (const json* up = o.find("up")) read.up = readChoice(*up, o.at("up"), {"x", "y", "z"})[0];
  Result<meshing::SurfaceFile> loaded = meshing::readSurfaceFile(resolved, read);
  if (!loaded.ok()) throw SceneError{o.at("surface"), loaded.error().message};
  if (loaded.value().vertexCount() > size_t(std::numeric_limits<int32_t>::max())) {
    throw SceneError{o.at("surface"), resolved + ": too many vertices"};
  }
  return std::move(loaded).value();
}

// A triangle surface in any format graphfrac_meshing reads, tetrahedralised by the lattice
// mesher (open, multi-part and self-intersecting surfaces too): "cells" along the longest
// axis or about "target_tets" tets; "unit" (metres per file unit) and "up" override what the
// file declares.
TetMesh readSurfaceMesh(ObjReader& o, const std::string& baseDir) {
  o.keys({"surface", "cells", "target_tets", "unit", "up", "scale"});
  meshing::LatticeOptions lattice;
  if (o.has("cells") && o.has("target_tets")) {
    throw SceneError{o.at("cells"), "give \"cells\" or \"target_tets\", not both"};
  }
  if (const json* cells = o.find("cells")) {
    lattice.cells = readInt(*cells, o.at("cells"), 1, meshing::kMaxCells);
  }
  if (const json* target = o.find("target_tets")) {
    lattice.targetTets = readPositive(*target, o.at("target_tets"));
    requireAtMost(lattice.targetTets, kMaxSurfaceTets, o.at("target_tets"), *target);
  }
  const meshing::SurfaceFile surface = readSurfaceKeys(o, baseDir);
  const std::vector<int32_t> triangles(surface.triangles.begin(), surface.triangles.end());
  Result<meshing::LatticeResult> meshed =
      meshing::latticeMesh(meshing::TriangleSoup(surface.positions, triangles), lattice);
  if (!meshed.ok()) throw SceneError{o.at("surface"), meshed.error().message};
  return std::move(meshed.value().mesh);
}

// "render_mesh": the artist's surface drawn instead of the tet boundary (BodyDef::renderMesh),
// read like "mesh": {"surface": ...}, scaled about the origin by "scale" and moved by the
// body's "translate" like the tets, so the two stay in register. Normals come from the triangles.
// "texture": the image file, checked here (it exists, opens, and its header is one stb_image
// decodes) so that a typo fails at load rather than in the renderer; the demo decodes it.
// `what` names the file's origin in messages when it came from an asset rather than the scene.
std::string checkTexture(const std::string& resolved, const std::string& at,
                         const std::string& what = "") {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(resolved, ec)) {
    throw SceneError{at, what + "no such file \"" + resolved + "\""};
  }
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(resolved.c_str(), "rb"), &std::fclose);
  if (!f) throw SceneError{at, what + "cannot open \"" + resolved + "\": " + std::strerror(errno)};
#ifdef GF_SCENE_HAS_STB_IMAGE
  int w = 0, h = 0, channels = 0;
  if (!stbi_info_from_file(f.get(), &w, &h, &channels)) {
    throw SceneError{at, what + "\"" + resolved +
                             "\" is not an image stb_image reads (PNG, JPEG, TGA, "
                             "BMP, PSD, GIF, HDR, PIC, PNM): " +
                             stbi_failure_reason()};
  }
#else
  throw SceneError{at,
                   "this build reads no images (stb_image from libstb-dev was not found at "
                   "configure: tools/setup tools)"};
#endif
  return resolved;
}

std::string readTexture(ObjReader& o, const std::string& baseDir) {
  const std::string at = o.at("texture");
  return checkTexture(resolvePath(readString(o.require("texture"), at), baseDir), at);
}

// The asset's materials, when its triangles use two or more: ids into the table, each material's
// texture resolved against the asset's folder and checked like "texture".
void readAssetMaterials(const meshing::SurfaceFile& surface, const std::string& at, RenderMesh& m,
                        std::vector<SceneBody::Material>& materials) {
  if (surface.materials.size() < 2 || surface.faceMaterial.size() != m.triangleCount()) return;
  const std::string folder = std::filesystem::path(surface.path).parent_path().string();
  for (const meshing::SurfaceFile::Material& f : surface.materials) {
    SceneBody::Material s;
    s.name = f.name;
    s.colour = glm::vec3(f.colour[0], f.colour[1], f.colour[2]);
    const std::string what = "material '" + f.name + "' of \"" + surface.path + "\": texture ";
    if (!f.texture.empty() && f.texture[0] == '*')
      throw SceneError{at, what + "\"" + f.texture +
                               "\" is embedded in the file; graphfrac reads texture files only "
                               "(export the images beside the asset)"};
    if (!f.texture.empty()) {
      if (m.uvs.empty())
        throw SceneError{at, what + "\"" + f.texture +
                                 "\" has no texture coordinates (UVs) in the mesh to map it with"};
      s.texture = checkTexture(resolvePath(f.texture, folder), at, what);
    }
    materials.push_back(std::move(s));
  }
  m.materials = surface.faceMaterial;
}

RenderMesh readRenderMesh(const json& v, const std::string& path, const std::string& baseDir,
                          const glm::dvec3& translate, std::string& texture,
                          std::vector<SceneBody::Material>& materials) {
  ObjReader o(v, path);
  o.keys({"surface", "unit", "up", "scale", "texture", "materials"});
  glm::dvec3 k(1);
  if (const json* scale = o.find("scale")) k = readScale(*scale, o.at("scale"));
  const meshing::SurfaceFile surface = readSurfaceKeys(o, baseDir, true);
  RenderMesh m;
  m.positions = surface.positions;
  for (size_t i = 0; i < surface.vertexCount(); ++i) {
    for (int a = 0; a < 3; ++a)
      m.positions[3 * i + a] = m.positions[3 * i + a] * k[a] + translate[a];
  }
  m.indices.assign(surface.triangles.begin(), surface.triangles.end());
  m.uvs = surface.uvs;
  // The asset's own materials unless "texture" paints the whole mesh or "materials" is false.
  const bool own = o.has("materials") ? readBool(*o.find("materials"), o.at("materials")) : true;
  if (own && !o.has("texture")) readAssetMaterials(surface, o.at("surface"), m, materials);
  if (Result<void> r = m.check(); !r.ok()) throw SceneError{o.at("surface"), r.error().message};
  if (o.has("texture")) {
    texture = readTexture(o, baseDir);
    if (m.uvs.empty()) {
      throw SceneError{o.at("texture"),
                       "the render mesh \"" + surface.path +
                           "\" has no texture coordinates (UVs) to map it with (UVs are read "
                           "from OBJ when every face corner has one, from PLY's per-vertex u "
                           "and v, and through assimp, e.g. from glTF, Collada or FBX, when "
                           "every mesh in the file has them)"};
    }
  }
  return m;
}

TetMesh readMesh(const json& v, const std::string& path, const std::string& baseDir) {
  ObjReader o(v, path);
  TetMesh mesh;
  // Read first so that every branch below accepts it.
  const json* scaleJ = o.find("scale");
  const bool hasFile = o.has("file"), hasGen = o.has("generator"), hasSurface = o.has("surface");
  if (!hasFile && !hasGen && !hasSurface) {
    // Catches a misspelt "file"/"generator"/"surface" as the typo it is.
    o.keys({"file", "generator", "surface", "size", "cells", "notch", "radius", "height",
            "segments", "layers", "rings", "thickness", "scale", "target_tets", "unit", "up"});
  }
  if (int(hasFile) + int(hasGen) + int(hasSurface) != 1) {
    throw SceneError{path, "needs exactly one of \"file\", \"generator\" or \"surface\""};
  }
  if (hasSurface) {
    mesh = readSurfaceMesh(o, baseDir);
  } else if (hasFile) {
    o.keys({"file"});
    const std::string file = readString(o.require("file"), o.at("file"));
    const std::string resolved = resolvePath(file, baseDir);
    std::error_code ec;
    if (!std::filesystem::is_regular_file(resolved, ec)) {
      throw SceneError{o.at("file"), "no such file \"" + resolved + "\""};
    }
    Result<TetMesh> r = TetMesh::fromFile(resolved);
    if (!r.ok()) throw SceneError{o.at("file"), r.error().message};
    mesh = std::move(r).value();
  } else {
    mesh = readGenerator(o);
    if (mesh.tetCount() == 0) throw SceneError{path, "the generator produced an empty mesh"};
  }
  if (scaleJ != nullptr) {
    // About the origin, before "translate"; positive factors keep every tet positively oriented.
    const glm::dvec3 k = readScale(*scaleJ, o.at("scale"));
    for (size_t i = 0; i < mesh.nodeCount(); ++i) {
      for (int a = 0; a < 3; ++a) mesh.positions[3 * i + a] *= k[a];
    }
  }
  o.finish();
  return mesh;
}

/// Nodes inside an axis-aligned box (inclusive, with a tolerance relative to the mesh size so
/// that a face at exactly x = 0 is caught despite rounding in the generator).
std::vector<int32_t> selectRegion(const json& v, const std::string& path, const TetMesh& mesh) {
  ObjReader o(v, path);
  o.keys({"min", "max"});
  const glm::dvec3 lo = readVec3(o.require("min"), o.at("min"));
  const glm::dvec3 hi = readVec3(o.require("max"), o.at("max"));
  o.finish();
  for (int i = 0; i < 3; ++i) {
    if (lo[i] > hi[i]) {
      throw SceneError{path, "min[" + std::to_string(i) + "] = " + fmt(lo[i]) +
                                 " is greater than max[" + std::to_string(i) + "] = " + fmt(hi[i])};
    }
  }
  glm::dvec3 bmin(std::numeric_limits<double>::max()), bmax(-std::numeric_limits<double>::max());
  const size_t n = mesh.nodeCount();
  for (size_t i = 0; i < n; ++i) {
    const glm::dvec3 p(mesh.positions[3 * i], mesh.positions[3 * i + 1], mesh.positions[3 * i + 2]);
    bmin = glm::min(bmin, p);
    bmax = glm::max(bmax, p);
  }
  const glm::dvec3 ext = bmax - bmin;
  const double tol = 1e-9 * std::max({ext.x, ext.y, ext.z, 1e-30});
  std::vector<int32_t> nodes;
  for (size_t i = 0; i < n; ++i) {
    bool inside = true;
    for (int k = 0; k < 3; ++k) {
      const double x = mesh.positions[3 * i + k];
      inside = inside && x >= lo[k] - tol && x <= hi[k] + tol;
    }
    if (inside) nodes.push_back(static_cast<int32_t>(i));
  }
  if (nodes.empty()) {
    char buf[256];
    std::snprintf(buf, sizeof buf, "selects no node (mesh bounds [%g, %g, %g] to [%g, %g, %g])",
                  bmin.x, bmin.y, bmin.z, bmax.x, bmax.y, bmax.z);
    throw SceneError{path, buf};
  }
  return nodes;
}

std::vector<int32_t> readNodeList(const json& v, const std::string& path, const TetMesh& mesh) {
  readArray(v, path, 0, "node indices");
  if (v.empty()) throw SceneError{path, "expected at least one node index, got []"};
  std::vector<int32_t> nodes;
  const long long count = static_cast<long long>(mesh.nodeCount());
  for (size_t i = 0; i < v.size(); ++i) {
    const std::string p = indexPath(path, i);
    if (!v[i].is_number_integer() || v[i].get<long long>() < 0 || v[i].get<long long>() >= count) {
      throw SceneError{p, "expected a node index in [0, " + std::to_string(count - 1) +
                              "] (the mesh has " + std::to_string(count) + " nodes), got " +
                              describe(v[i])};
    }
    nodes.push_back(static_cast<int32_t>(v[i].get<long long>()));
  }
  return nodes;
}

/// A node set given by exactly one of "region" or "nodes" (or "node" when allowed).
std::vector<int32_t> readSelection(ObjReader& o, const TetMesh& mesh) {
  const int given = int(o.has("region")) + int(o.has("nodes"));
  if (given != 1) throw SceneError{o.path(), "needs exactly one of \"region\" or \"nodes\""};
  if (const json* r = o.find("region")) return selectRegion(*r, o.at("region"), mesh);
  return readNodeList(o.require("nodes"), o.at("nodes"), mesh);
}

Material readMaterial(const json& v, const std::string& path) {
  ObjReader o(v, path);
  o.keys({"model", "E", "nu", "rho", "fibre", "damping"});
  Material m;
  if (const json* model = o.find("model")) {
    const std::string s = readChoice(*model, o.at("model"),
                                     {"stable_neo_hookean", "neo_hookean", "stvk", "corotated"});
    m.model = s == "stable_neo_hookean" ? MaterialModel::StableNeoHookean
              : s == "neo_hookean"      ? MaterialModel::NeoHookean
              : s == "stvk"             ? MaterialModel::StVK
                                        : MaterialModel::Corotated;
  }
  m.youngsModulus = readNumber(o.require("E"), o.at("E"));
  m.poissonRatio = readNumber(o.require("nu"), o.at("nu"));
  m.density = readNumber(o.require("rho"), o.at("rho"));
  if (const json* f = o.find("fibre")) {
    ObjReader fo(*f, o.at("fibre"));
    fo.keys({"stiffness", "direction"});
    m.fibreStiffness = readNumber(fo.require("stiffness"), fo.at("stiffness"));
    if (const json* d = fo.find("direction")) {
      // Normalised for the runtime; a zero vector stays zero for Material::check to report.
      const glm::dvec3 dir = readVec3(*d, fo.at("direction"));
      const double len = glm::length(dir);
      m.fibreDirection = glm::vec3(len > 0 ? dir / len : dir);
    }
    fo.finish();
  }
  if (const json* d = o.find("damping")) {
    ObjReader dobj(*d, o.at("damping"));
    dobj.keys({"mass", "stiffness"});
    if (const json* r1 = dobj.find("mass")) m.massDamping = readNumber(*r1, dobj.at("mass"));
    if (const json* r2 = dobj.find("stiffness")) {
      m.stiffnessDamping = readNumber(*r2, dobj.at("stiffness"));
    }
    dobj.finish();
  }
  o.finish();
  requireValid(m.check(), path, kMaterialNames);
  return m;
}

/// A multigrid setup "50/1000/all": handle counts of the coarse levels, coarsest first, ending
/// with the mesh itself ("all"); "auto" (empty): chosen from the body's size. Only the syntax
/// is read here; MultigridSettings::check owns the rules (positive, increasing).
std::vector<int32_t> readLevels(const json& v, const std::string& path) {
  const std::string text = readString(v, path);
  if (text == "auto") return {};
  const std::string want =
      "expected \"auto\" or coarse handle counts separated by '/', coarsest first, ending with "
      "\"all\" (e.g. \"50/1000/all\"), got " +
      describe(v);
  std::vector<int32_t> levels;
  size_t pos = 0;
  while (true) {
    const size_t slash = text.find('/', pos);
    const std::string part = text.substr(pos, slash == std::string::npos ? slash : slash - pos);
    if (slash == std::string::npos) {
      if (part != "all" || levels.empty()) throw SceneError{path, want};
      return levels;
    }
    if (part.empty() || part.size() > 9 ||
        part.find_first_not_of("0123456789") != std::string::npos) {
      throw SceneError{path, want};
    }
    levels.push_back(static_cast<int32_t>(std::stol(part)));
    pos = slash + 1;
  }
}

MultigridSettings readMultigrid(const json& v, const std::string& path) {
  ObjReader o(v, path);
  o.keys({"levels", "smoother", "pre_sweeps", "post_sweeps", "coarse_pre_sweeps",
          "coarse_post_sweeps", "mode", "cycles", "refresh_interval", "refresh_slack",
          "crack_rebinding", "smoothed_prolongation", "prolongation_filter"});
  MultigridSettings m;
  if (const json* x = o.find("levels")) m.levels = readLevels(*x, o.at("levels"));
  if (const json* x = o.find("smoother")) {
    const std::string s = readChoice(*x, o.at("smoother"), {"jacobi", "gauss_seidel", "chebyshev"});
    m.smoother = s == "jacobi"         ? Smoother::Jacobi
                 : s == "gauss_seidel" ? Smoother::GaussSeidel
                                       : Smoother::Chebyshev;
  }
  if (const json* x = o.find("pre_sweeps")) m.preSweeps = readInteger(*x, o.at("pre_sweeps"));
  if (const json* x = o.find("post_sweeps")) m.postSweeps = readInteger(*x, o.at("post_sweeps"));
  if (const json* x = o.find("coarse_pre_sweeps")) {
    m.coarsePreSweeps = readInteger(*x, o.at("coarse_pre_sweeps"));
  }
  if (const json* x = o.find("coarse_post_sweeps")) {
    m.coarsePostSweeps = readInteger(*x, o.at("coarse_post_sweeps"));
  }
  if (const json* x = o.find("mode")) {
    m.preconditionCG = readChoice(*x, o.at("mode"), {"cg", "cycles"}) == "cg";
  }
  if (const json* x = o.find("cycles")) m.cycles = readInteger(*x, o.at("cycles"));
  if (const json* x = o.find("refresh_interval")) {
    m.coarseRefreshInterval = readInteger(*x, o.at("refresh_interval"));
  }
  if (const json* x = o.find("refresh_slack")) {
    m.coarseRefreshSlack = readInteger(*x, o.at("refresh_slack"));
  }
  if (const json* x = o.find("crack_rebinding")) {
    m.crackRebinding = readBool(*x, o.at("crack_rebinding"));
  }
  if (const json* x = o.find("smoothed_prolongation")) {
    m.smoothedProlongation = readBool(*x, o.at("smoothed_prolongation"));
  }
  if (const json* x = o.find("prolongation_filter")) {
    m.prolongationFilter = readNumber(*x, o.at("prolongation_filter"));
  }
  o.finish();
  requireValid(m.check(), path, kMultigridNames);
  return m;
}

SolverSettings readSolver(const json& v, const std::string& path) {
  ObjReader o(v, path);
  o.keys({"newton_iterations", "newton_tolerance", "line_search", "corotated_inertia",
          "numerical_damping", "linear", "max_linear_iterations", "linear_tolerance", "multigrid"});
  SolverSettings s;
  if (const json* x = o.find("newton_iterations")) {
    s.newtonIterations = readInteger(*x, o.at("newton_iterations"));
  }
  if (const json* x = o.find("newton_tolerance")) {
    s.newtonTolerance = readNumber(*x, o.at("newton_tolerance"));
  }
  if (const json* x = o.find("line_search")) s.lineSearch = readBool(*x, o.at("line_search"));
  if (const json* x = o.find("corotated_inertia")) {
    s.corotatedInertia = readBool(*x, o.at("corotated_inertia"));
  }
  if (const json* x = o.find("numerical_damping")) {
    s.numericalDamping = readNumber(*x, o.at("numerical_damping"));
  }
  if (const json* x = o.find("linear")) {
    const std::string kind = readChoice(*x, o.at("linear"), {"pcg", "direct", "multigrid"});
    s.linearSolver = kind == "pcg"      ? LinearSolverKind::PCG
                     : kind == "direct" ? LinearSolverKind::Direct
                                        : LinearSolverKind::Multigrid;
  }
  if (const json* x = o.find("multigrid")) {
    s.multigrid = readMultigrid(*x, o.at("multigrid"));
    // Settings for a solver that is not selected would be silently ignored.
    if (s.linearSolver != LinearSolverKind::Multigrid) {
      throw SceneError{o.at("multigrid"), "needs \"linear\": \"multigrid\""};
    }
  }
  if (const json* x = o.find("max_linear_iterations")) {
    s.maxLinearIterations = readInteger(*x, o.at("max_linear_iterations"));
  }
  if (const json* x = o.find("linear_tolerance")) {
    s.linearTolerance = readNumber(*x, o.at("linear_tolerance"));
  }
  o.finish();
  requireValid(s.check(), path, kSolverNames);
  return s;
}

/// Records which entry holds each node so that contradictory grips are caught here, with
/// both paths, rather than as a bare node index from createBody.
class HeldNodes {
 public:
  /// Adds the nodes with a velocity; a node already held at the same velocity is skipped.
  std::vector<int32_t> add(const std::vector<int32_t>& nodes, glm::vec3 vel,
                           const std::string& path) {
    std::vector<int32_t> fresh;
    for (int32_t n : nodes) {
      auto [it, inserted] = m_held.try_emplace(n, Entry{vel, path});
      if (inserted) {
        fresh.push_back(n);
      } else if (it->second.velocity != vel) {
        throw SceneError{path, "node " + std::to_string(n) + " is also held by " + it->second.path +
                                   " with a different velocity"};
      }
    }
    return fresh;
  }

 private:
  struct Entry {
    glm::vec3 velocity;
    std::string path;
  };
  std::map<int32_t, Entry> m_held;
};

/// Pins, grips and forces into `def`; `gripNames` gets the JSON entry of each grip made.
void readBoundaryConditions(ObjReader& body, BodyDef& def, std::vector<std::string>& gripNames) {
  HeldNodes held;
  if (const json* pins = body.find("pins")) {
    const std::string path = body.at("pins");
    readArray(*pins, path, 0, "pins");
    for (size_t i = 0; i < pins->size(); ++i) {
      ObjReader o((*pins)[i], indexPath(path, i));
      o.keys({"region", "nodes"});
      Grip g;
      g.nodes = held.add(readSelection(o, def.mesh), g.velocity, o.path());
      o.finish();
      if (g.nodes.empty()) continue;
      def.grips.push_back(std::move(g));
      gripNames.push_back("pins[" + std::to_string(i) + "]");
    }
  }
  if (const json* grips = body.find("grips")) {
    const std::string path = body.at("grips");
    readArray(*grips, path, 0, "grips");
    for (size_t i = 0; i < grips->size(); ++i) {
      ObjReader o((*grips)[i], indexPath(path, i));
      o.keys({"region", "nodes", "velocity"});
      Grip g;
      g.velocity = glm::vec3(readVec3(o.require("velocity"), o.at("velocity")));
      g.nodes = held.add(readSelection(o, def.mesh), g.velocity, o.path());
      o.finish();
      if (g.nodes.empty()) continue;
      def.grips.push_back(std::move(g));
      gripNames.push_back("grips[" + std::to_string(i) + "]");
    }
  }
  if (const json* forces = body.find("forces")) {
    const std::string path = body.at("forces");
    readArray(*forces, path, 0, "forces");
    for (size_t i = 0; i < forces->size(); ++i) {
      ObjReader o((*forces)[i], indexPath(path, i));
      if (o.has("node")) {
        o.keys({"node", "force"});
      } else {
        o.keys({"region", "nodes", "force", "distribute"});
      }
      const glm::dvec3 f = readVec3(o.require("force"), o.at("force"));
      std::vector<int32_t> nodes;
      bool distribute = true;
      if (o.has("node")) {
        if (o.has("region") || o.has("nodes")) {
          throw SceneError{o.path(), "needs exactly one of \"node\", \"nodes\" or \"region\""};
        }
        json one = json::array({*o.find("node")});
        try {
          nodes = readNodeList(one, o.at("node"), def.mesh);
        } catch (SceneError& e) {
          e.path = o.at("node");  // not "node[0]": the file has a single number there
          throw;
        }
      } else {
        nodes = readSelection(o, def.mesh);
        if (const json* d = o.find("distribute")) distribute = readBool(*d, o.at("distribute"));
      }
      o.finish();
      // "distribute": the force is the total, shared equally; otherwise each node gets it.
      const glm::dvec3 per = distribute ? f / static_cast<double>(nodes.size()) : f;
      for (int32_t n : nodes) def.forces.push_back(PointForce{n, glm::vec3(per)});
    }
  }
}

// Caps that catch typos: a radius of thousands of edge lengths would make every neighbour
// list hold the whole body.
constexpr double kMaxFractureRadius = 100;
constexpr int kMaxBrittleRegions = 1'000'000;

FractureSettings readFracture(const json& v, const std::string& path) {
  ObjReader o(v, path);
  o.keys({"strength", "radius", "nonlocal_length", "model", "brittle", "regions",
          "fibre_strength_ratio", "split_point", "release_every_batch"});
  FractureSettings f;
  f.enabled = true;
  f.strength = readNumber(o.require("strength"), o.at("strength"));
  if (const json* r = o.find("radius")) {
    f.radius = readNumber(*r, o.at("radius"));
    requireAtMost(f.radius, kMaxFractureRadius, o.at("radius"), *r);
  }
  if (const json* l = o.find("nonlocal_length"))
    f.nonlocalLength = readNumber(*l, o.at("nonlocal_length"));
  if (const json* m = o.find("model")) {
    f.model = readChoice(*m, o.at("model"), {"projection", "degradation"}) == "projection"
                  ? DamageModel::Projection
                  : DamageModel::Degradation;
  }
  if (const json* b = o.find("brittle")) f.brittle = readBool(*b, o.at("brittle"));
  if (const json* b = o.find("release_every_batch"))
    f.releaseEveryBatch = readBool(*b, o.at("release_every_batch"));
  if (const json* n = o.find("regions")) {
    f.regions = readInteger(*n, o.at("regions"));
    requireAtMost(f.regions, kMaxBrittleRegions, o.at("regions"), *n);
  }
  if (const json* r = o.find("fibre_strength_ratio")) {
    f.fibreStrengthRatio = readNumber(*r, o.at("fibre_strength_ratio"));
  }
  if (const json* p = o.find("split_point")) {
    f.splitPoint = readChoice(*p, o.at("split_point"), {"midpoint", "force_ratio"}) == "force_ratio"
                       ? SplitPoint::ForceRatio
                       : SplitPoint::Midpoint;
  }
  o.finish();
  requireValid(f.check(), path, kFractureNames);
  return f;
}

glm::dquat readOrientation(const json& v, const std::string& path);

ImpuritySettings readImpurities(const json& v, const std::string& path) {
  ObjReader o(v, path);
  o.keys({"noise", "sigma", "mode", "seed", "random_graph"});
  ImpuritySettings s;
  s.enabled = true;
  if (const json* n = o.find("noise"))
    s.noise = readChoice(*n, o.at("noise"), {"gaussian", "uniform"}) == "uniform"
                  ? ImpurityNoise::Uniform
                  : ImpurityNoise::Gaussian;
  if (const json* m = o.find("mode"))
    s.mode = readChoice(*m, o.at("mode"), {"degradation", "upgradation"}) == "upgradation"
                 ? ImpurityMode::Upgradation
                 : ImpurityMode::Degradation;
  if (const json* g = o.find("sigma")) {
    s.sigma = readNumber(*g, o.at("sigma"));
    if (!(s.sigma >= 0 && s.sigma <= 1e9))
      throw SceneError{o.at("sigma"), "must be >= 0 (at most 1e9), got " + describe(*g)};
  }
  if (const json* k = o.find("seed")) {
    const int seed = readInteger(*k, o.at("seed"));
    if (seed < 0) throw SceneError{o.at("seed"), "must be >= 0, got " + describe(*k)};
    s.seed = uint64_t(seed);
  }
  if (const json* r = o.find("random_graph")) s.randomGraph = readBool(*r, o.at("random_graph"));
  o.finish();
  return s;
}

constexpr FieldName kImpurityMapNames[] = {{"potency", "potency"},      {"width", "width"},
                                           {"depth", "depth"},          {"scale", "scale"},
                                           {"rotation", "orientation"}, {"origin", "origin"}};

// Map coordinates are the mesh's own: the body's "translate" moves them with it.
ImpurityMap readImpurityMap(const json& v, const std::string& path, const std::string& baseDir,
                            const glm::dvec3& translate) {
  ObjReader o(v, path);
  o.keys({"polyline", "width", "depth", "image", "threshold", "origin", "orientation", "scale",
          "potency"});
  ImpurityMap m;
  if (o.has("polyline") == o.has("image"))
    throw SceneError{path, "needs exactly one of \"polyline\" and \"image\""};
  if (const json* p = o.find("potency")) m.potency = readNumber(*p, o.at("potency"));
  if (const json* pl = o.find("polyline")) {
    m.kind = ImpurityMap::Kind::Polyline;
    const std::string pp = o.at("polyline");
    if (!pl->is_array()) throw SceneError{pp, "expected an array of [x, y, z] points"};
    for (size_t i = 0; i < pl->size(); ++i)
      m.points.push_back(readVec3((*pl)[i], indexPath(pp, i)) + translate);
    m.width = readNumber(o.require("width"), o.at("width"));
    m.depth = readNumber(o.require("depth"), o.at("depth"));
  } else {
    m.kind = ImpurityMap::Kind::Image;
    const std::string ip = o.at("image");
    const std::string file = resolvePath(readString(*o.find("image"), ip), baseDir);
    double threshold = 0.5;
    if (const json* t = o.find("threshold")) {
      threshold = readNumber(*t, o.at("threshold"));
      if (!(threshold > 0 && threshold <= 1))
        throw SceneError{o.at("threshold"), "must lie in (0, 1], got " + describe(*t)};
    }
    GreyImage img;
    try {
      img = readPngGrey(file);
    } catch (const std::runtime_error& e) {
      throw SceneError{ip, e.what()};
    }
    m.segments = imageSegments(img, threshold);
    if (m.segments.empty())
      throw SceneError{ip, "'" + file +
                               "' has no stroke (no two neighbouring pixels darker than "
                               "the threshold)"};
    m.origin = readVec3(o.require("origin"), o.at("origin")) + translate;
    if (const json* q = o.find("orientation"))
      m.rotation = readOrientation(*q, o.at("orientation"));
    m.scale = readNumber(o.require("scale"), o.at("scale"));
  }
  o.finish();
  requireValid(m.check(), path, kImpurityMapNames);
  return m;
}

PlasticitySettings readPlasticity(const json& v, const std::string& path) {
  ObjReader o(v, path);
  o.keys({"yield", "flow_rate", "hardening"});
  PlasticitySettings p;
  p.enabled = true;
  p.yieldStress = readNumber(o.require("yield"), o.at("yield"));
  if (const json* r = o.find("flow_rate")) p.flowRate = readNumber(*r, o.at("flow_rate"));
  if (const json* k = o.find("hardening")) p.hardening = readNumber(*k, o.at("hardening"));
  o.finish();
  requireValid(p.check(), path, kPlasticityNames);
  return p;
}

/// Rest centroid of tet t.
glm::dvec3 tetCentroid(const TetMesh& mesh, size_t t) {
  glm::dvec3 c(0);
  for (int k = 0; k < 4; ++k) {
    const size_t n = static_cast<size_t>(mesh.tets[4 * t + k]);
    c += glm::dvec3(mesh.positions[3 * n], mesh.positions[3 * n + 1], mesh.positions[3 * n + 2]);
  }
  return c / 4.0;
}

/// Per-tet fibre directions from the rest centroids (after scale and translate).
std::vector<glm::vec3> readFibreField(const json& v, const std::string& path, const TetMesh& mesh) {
  ObjReader o(v, path);
  const std::string type =
      readChoice(o.require("type"), o.at("type"), {"constant", "radial", "rotated"});
  const size_t tets = mesh.tetCount();
  std::vector<glm::vec3> field(tets);
  if (type == "constant") {
    o.keys({"type", "direction"});
    const glm::vec3 d(readDirection(o.require("direction"), o.at("direction")));
    std::fill(field.begin(), field.end(), d);
  } else if (type == "rotated") {
    o.keys({"type", "direction", "rotation_deg"});
    const glm::dvec3 d = readDirection(o.require("direction"), o.at("direction"));
    const double a =
        readNumber(o.require("rotation_deg"), o.at("rotation_deg")) * std::numbers::pi / 180;
    // Right-handed rotation about +y: [1, 0, 0] turned by 90 degrees is [0, 0, -1].
    const glm::dvec3 r(std::cos(a) * d.x + std::sin(a) * d.z, d.y,
                       -std::sin(a) * d.x + std::cos(a) * d.z);
    std::fill(field.begin(), field.end(), glm::vec3(r));
  } else {
    // Radial: from the axis out through the tet's centroid, perpendicular to the axis (muscle
    // fibres around a bone). A tet centred on the axis has no radial direction; it takes a
    // fixed perpendicular so the field stays defined.
    o.keys({"type", "axis_point", "axis"});
    const glm::dvec3 p = readVec3(o.require("axis_point"), o.at("axis_point"));
    const glm::dvec3 a = readDirection(o.require("axis"), o.at("axis"));
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
    for (size_t i = 0; i < mesh.nodeCount(); ++i) {
      const glm::dvec3 x(mesh.positions[3 * i], mesh.positions[3 * i + 1],
                         mesh.positions[3 * i + 2]);
      lo = glm::min(lo, x);
      hi = glm::max(hi, x);
    }
    const double tiny = 1e-9 * glm::length(hi - lo);
    const glm::dvec3 fallback = anyPerpendicular(a);
    for (size_t t = 0; t < tets; ++t) {
      const glm::dvec3 c = tetCentroid(mesh, t) - p;
      const glm::dvec3 r = c - glm::dot(c, a) * a;
      const double len = glm::length(r);
      field[t] = glm::vec3(len > tiny ? r / len : fallback);
    }
  }
  o.finish();
  return field;
}

bool validName(const std::string& s) {
  if (s.empty() || s.size() > 64 || s[0] == '.') return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
  });
}

// ---- demo: colours, hand-off, rigid bodies, camera ----------------------------------------

/// Default surface colours of bodies without "colour", by index: distinct, light enough for
/// crack faces (orange) to stand out, and off the demo's sky blue.
constexpr std::array<glm::vec3, 6> kBodyPalette = {
    glm::vec3(0.72f, 0.8f, 0.62f), glm::vec3(0.55f, 0.75f, 0.9f),  glm::vec3(0.85f, 0.7f, 0.5f),
    glm::vec3(0.8f, 0.55f, 0.65f), glm::vec3(0.75f, 0.75f, 0.55f), glm::vec3(0.6f, 0.6f, 0.85f)};

/// Linear RGB, each channel in [0, 1].
glm::vec3 readColour(const json& v, const std::string& path) {
  readArray(v, path, 3, "numbers in [0, 1] (linear RGB)");
  glm::vec3 c;
  for (int i = 0; i < 3; ++i) {
    c[i] = static_cast<float>(
        readInRange(v[size_t(i)], indexPath(path, size_t(i)), 0, 1, false, false));
  }
  return c;
}

SceneHandoff readHandoff(const json& v, const std::string& path, bool breaks) {
  ObjReader o(v, path);
  o.keys({"policy", "max_volume"});
  const std::string p =
      readChoice(o.require("policy"), o.at("policy"), {"never", "every", "below_volume"});
  SceneHandoff h;
  h.policy = p == "every"          ? SceneHandoff::Policy::Every
             : p == "below_volume" ? SceneHandoff::Policy::BelowVolume
                                   : SceneHandoff::Policy::Never;
  if (h.policy == SceneHandoff::Policy::BelowVolume) {
    h.maxVolume = readPositive(o.require("max_volume"), o.at("max_volume"));
  } else if (o.has("max_volume")) {
    throw SceneError{o.at("max_volume"), "only with \"policy\": \"below_volume\""};
  }
  // Only fragments are handed off; a body that never breaks has none (an Is-XFEM body's pieces
  // are its fragments).
  if (h.policy != SceneHandoff::Policy::Never && !breaks) {
    throw SceneError{o.at("policy"),
                     "needs a \"fracture\" block on the body or \"cut_mode\": \"xfem\" (only "
                     "fragments of a fracturing body or pieces of a cut one are handed to "
                     "Bullet)"};
  }
  o.finish();
  return h;
}

/// {"axis": [..], "angle_deg": a} or {"quaternion": [w, x, y, z]} (normalised).
glm::dquat readOrientation(const json& v, const std::string& path) {
  ObjReader o(v, path);
  o.keys({"axis", "angle_deg", "quaternion"});
  const bool axisForm = o.has("axis") || o.has("angle_deg");
  if (axisForm == o.has("quaternion")) {
    throw SceneError{path, "needs either \"axis\" and \"angle_deg\" or \"quaternion\""};
  }
  glm::dquat q(1, 0, 0, 0);
  if (axisForm) {
    const glm::dvec3 axis = readDirection(o.require("axis"), o.at("axis"));
    const double a = readNumber(o.require("angle_deg"), o.at("angle_deg")) * std::numbers::pi / 180;
    q = glm::angleAxis(a, axis);
  } else {
    const std::string qp = o.at("quaternion");
    const json& qj = readArray(o.require("quaternion"), qp, 4, "numbers [w, x, y, z]");
    for (int i = 0; i < 4; ++i) {
      const double c = readNumber(qj[size_t(i)], indexPath(qp, size_t(i)));
      (i == 0 ? q.w : q[i - 1]) = c;
    }
    const double len = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
    if (!(len > 0)) throw SceneError{qp, "expected a non-zero quaternion, got " + describe(qj)};
    q = q / len;
  }
  o.finish();
  return q;
}

SceneRigidBody readRigidBody(const json& v, const std::string& path, size_t index) {
  ObjReader o(v, path);
  SceneRigidBody r;
  const std::string shape =
      readChoice(o.require("shape"), o.at("shape"), {"sphere", "box", "plane", "capsule"});
  if (shape == "plane") {
    o.keys({"name", "shape", "normal", "offset", "point", "render_size", "mass", "friction",
            "rolling_friction", "restitution", "colour", "touches_bodies"});
    r.shape = SceneRigidBody::Shape::Plane;
    if (const json* n = o.find("normal")) r.normal = readDirection(*n, o.at("normal"));
    if (o.has("offset") && o.has("point")) {
      throw SceneError{path, "give at most one of \"offset\" or \"point\""};
    }
    if (const json* d = o.find("offset")) r.offset = readNumber(*d, o.at("offset"));
    if (const json* p = o.find("point")) {
      r.offset = glm::dot(r.normal, readVec3(*p, o.at("point")));
    }
    if (const json* s = o.find("render_size")) r.renderSize = readPositive(*s, o.at("render_size"));
    // Bullet's btStaticPlaneShape is static only.
    if (const json* m = o.find("mass"); m != nullptr && readNonNegative(*m, o.at("mass")) != 0) {
      throw SceneError{o.at("mass"), "a plane is static: expected 0, got " + describe(*m)};
    }
  } else {
    o.keys({"name", "shape", "radius", "size", "half_length", "mass", "position", "orientation",
            "velocity", "angular_velocity", "friction", "rolling_friction", "restitution", "colour",
            "touches_bodies"});
    if (shape == "sphere") {
      r.shape = SceneRigidBody::Shape::Sphere;
      r.radius = readPositive(o.require("radius"), o.at("radius"));
    } else if (shape == "capsule") {
      // btCapsuleShape: along the body's own y axis.
      r.shape = SceneRigidBody::Shape::Capsule;
      r.radius = readPositive(o.require("radius"), o.at("radius"));
      r.halfLength = readNonNegative(o.require("half_length"), o.at("half_length"));
    } else {
      r.shape = SceneRigidBody::Shape::Box;
      r.halfExtents = 0.5 * readPositiveVec3(o.require("size"), o.at("size"));
    }
    r.mass = readNonNegative(o.require("mass"), o.at("mass"));
    r.position = readVec3(o.require("position"), o.at("position"));
    if (const json* q = o.find("orientation"))
      r.orientation = readOrientation(*q, o.at("orientation"));
    for (const char* key : {"velocity", "angular_velocity"}) {
      const json* vel = o.find(key);
      if (vel == nullptr) continue;
      if (r.mass == 0) {
        throw SceneError{o.at(key), "a static body (mass 0) does not move; give it a mass > 0"};
      }
      (std::string_view(key) == "velocity" ? r.velocity : r.angularVelocity) =
          readVec3(*vel, o.at(key));
    }
  }
  r.name = "rigid" + std::to_string(index);
  if (const json* n = o.find("name")) {
    r.name = readString(*n, o.at("name"));
    if (!validName(r.name)) {
      throw SceneError{o.at("name"),
                       "expected 1-64 letters, digits, '_', '-' or '.', got " + describe(*n)};
    }
  }
  if (const json* f = o.find("friction")) r.friction = readNonNegative(*f, o.at("friction"));
  if (const json* f = o.find("rolling_friction")) {
    r.rollingFriction = readNonNegative(*f, o.at("rolling_friction"));
  }
  if (const json* e = o.find("restitution")) {
    r.restitution = readInRange(*e, o.at("restitution"), 0, 1, false, false);
  }
  if (const json* c = o.find("colour")) r.colour = readColour(*c, o.at("colour"));
  if (const json* t = o.find("touches_bodies"))
    r.touchesBodies = readBool(*t, o.at("touches_bodies"));
  o.finish();
  return r;
}

SceneCamera readCamera(const json& v, const std::string& path) {
  ObjReader o(v, path);
  o.keys({"eye", "target", "up", "fov", "follow", "smooth_s", "max_turn_deg"});
  SceneCamera c;
  c.eye = readVec3(o.require("eye"), o.at("eye"));
  c.target = readVec3(o.require("target"), o.at("target"));
  if (!(glm::length(c.target - c.eye) > 0)) {
    throw SceneError{o.at("target"), "must differ from \"eye\""};
  }
  if (const json* u = o.find("up")) c.up = readDirection(*u, o.at("up"));
  const glm::dvec3 view = glm::normalize(c.target - c.eye);
  if (!(glm::length(glm::cross(view, glm::normalize(c.up))) > 1e-6)) {
    throw SceneError{o.has("up") ? o.at("up") : path,
                     "the view direction (target - eye) is parallel to \"up\" " +
                         std::string(o.has("up") ? "" : "([0, 1, 0] by default) ") +
                         "so the camera's roll is undefined"};
  }
  if (const json* f = o.find("fov"))
    c.fovDegrees = readInRange(*f, o.at("fov"), 0, 180, true, true);
  if (const json* f = o.find("follow")) c.follow = readBool(*f, o.at("follow"));
  for (const char* key : {"smooth_s", "max_turn_deg"}) {
    if (o.has(key) && !c.follow) throw SceneError{o.at(key), "only with \"follow\": true"};
  }
  if (const json* t = o.find("smooth_s"))
    c.smoothSeconds = readInRange(*t, o.at("smooth_s"), 0, 10, true, false);
  if (const json* a = o.find("max_turn_deg"))
    c.maxTurnDegrees = readInRange(*a, o.at("max_turn_deg"), 0, 45, true, false);
  o.finish();
  return c;
}

/// "initial_deformation": a 3x3 matrix as 3 rows of 3 numbers, applied to the rest shape about
/// its centroid. It must keep every tet the right way out (det > 0).
glm::dmat3 readDeformation(const json& v, const std::string& path) {
  readArray(v, path, 3, "rows [a, b, c] (a 3x3 matrix)");
  glm::dmat3 F(1.0);
  for (int r = 0; r < 3; ++r) {
    const glm::dvec3 row = readVec3(v[size_t(r)], indexPath(path, size_t(r)));
    for (int c = 0; c < 3; ++c) F[c][r] = row[c];  // glm is column-major
  }
  const double det = glm::determinant(F);
  if (!(det > 0)) {
    throw SceneError{path,
                     "expected a matrix with a positive determinant (a negative or zero "
                     "one turns the tets inside out or flat), got det = " +
                         fmt(det)};
  }
  return F;
}

SceneBody readBody(const json& v, const std::string& path, size_t index,
                   const std::string& baseDir) {
  ObjReader o(v, path);
  o.keys({"name",
          "mesh",
          "translate",
          "material",
          "solver",
          "pins",
          "grips",
          "forces",
          "initial_velocity",
          "angular_velocity",
          "initial_deformation",
          "fracture",
          "plasticity",
          "fibre_field",
          "handoff",
          "colour",
          "crack_colour",
          "interior",
          "friction",
          "contact",
          "impurities",
          "impurity_maps",
          "render_mesh",
          "cut_mode"});
  SceneBody body;
  body.name = "body" + std::to_string(index);
  body.colour = kBodyPalette[index % kBodyPalette.size()];
  if (const json* n = o.find("name")) {
    body.name = readString(*n, o.at("name"));
    if (!validName(body.name)) {
      throw SceneError{o.at("name"),
                       "expected 1-64 letters, digits, '_', '-' or '.' (it names output files), "
                       "got " +
                           describe(*n)};
    }
  }
  body.def.mesh = readMesh(o.require("mesh"), o.at("mesh"), baseDir);
  glm::dvec3 translate(0);
  if (const json* t = o.find("translate")) {
    const glm::dvec3 d = readVec3(*t, o.at("translate"));
    translate = d;
    for (size_t i = 0; i < body.def.mesh.nodeCount(); ++i) {
      for (int k = 0; k < 3; ++k) body.def.mesh.positions[3 * i + k] += d[k];
    }
  }
  if (const json* rm = o.find("render_mesh")) {
    body.def.renderMesh =
        readRenderMesh(*rm, o.at("render_mesh"), baseDir, translate, body.texture, body.materials);
    // The texture's own colours unless "colour" tints them.
    if (!body.texture.empty()) body.colour = glm::vec3(1.0f);
  }
  body.def.material = readMaterial(o.require("material"), o.at("material"));
  if (const json* s = o.find("solver")) body.def.solver = readSolver(*s, o.at("solver"));
  readBoundaryConditions(o, body.def, body.gripNames);
  if (const json* iv = o.find("initial_velocity")) {
    body.def.initialVelocity = glm::vec3(readVec3(*iv, o.at("initial_velocity")));
  }
  if (const json* f = o.find("friction")) body.def.friction = readNumber(*f, o.at("friction"));
  if (const json* c = o.find("contact")) body.def.contact = readBool(*c, o.at("contact"));
  if (const json* m = o.find("cut_mode")) {
    body.def.cutMode = readChoice(*m, o.at("cut_mode"), {"graph", "xfem"}) == "xfem"
                           ? CutMode::Xfem
                           : CutMode::Graph;
  }
  if (const json* w = o.find("angular_velocity")) {
    body.angularVelocity = readVec3(*w, o.at("angular_velocity"));
  }
  if (const json* d = o.find("initial_deformation")) {
    body.initialDeformation = readDeformation(*d, o.at("initial_deformation"));
  }
  if (const json* f = o.find("fracture")) body.def.fracture = readFracture(*f, o.at("fracture"));
  if (const json* p = o.find("plasticity")) {
    body.def.plasticity = readPlasticity(*p, o.at("plasticity"));
  }
  if (o.has("impurities") || o.has("impurity_maps")) {
    if (!body.def.fracture.enabled)
      throw SceneError{o.at(o.has("impurities") ? "impurities" : "impurity_maps"),
                       "needs \"fracture\" (impurities change edge strengths)"};
  }
  if (const json* im = o.find("impurities"))
    body.def.fracture.impurities = readImpurities(*im, o.at("impurities"));
  if (const json* maps = o.find("impurity_maps")) {
    const std::string mp = o.at("impurity_maps");
    if (!maps->is_array()) throw SceneError{mp, "expected an array of maps"};
    for (size_t i = 0; i < maps->size(); ++i)
      body.def.fracture.impurityMaps.push_back(
          readImpurityMap((*maps)[i], indexPath(mp, i), baseDir, translate));
  }
  if (const json* h = o.find("handoff")) {
    body.handoff = readHandoff(*h, o.at("handoff"),
                               body.def.fracture.enabled || body.def.cutMode == CutMode::Xfem);
  }
  if (const json* c = o.find("colour")) body.colour = readColour(*c, o.at("colour"));
  if (const json* c = o.find("crack_colour"))
    body.crackColour = readColour(*c, o.at("crack_colour"));
  if (const json* i = o.find("interior"))
    body.interior = readChoice(*i, o.at("interior"), {"plain", "glass", "crumb", "steel"});
  if (const json* ff = o.find("fibre_field")) {
    body.def.fibreField = readFibreField(*ff, o.at("fibre_field"), body.def.mesh);
    // The field only steers the fibre term; without it the field would be silently ignored.
    if (!(body.def.material.fibreStiffness > 0)) {
      throw SceneError{o.at("fibre_field"),
                       "needs \"material.fibre\" with a stiffness > 0 (the field only steers the "
                       "fibre term)"};
    }
  }
  o.finish();
  // The rules that tie settings together (fracture.fibreStrengthRatio needs fibres) and the
  // resolved node indices, exactly as World::createBody will apply them.
  requireValid(body.def.check(), path, kBodyNames);
  return body;
}

// ---- cuts ---------------------------------------------------------------------------------

/// {"translate": [..], "rotate_deg": [rx, ry, rz]}: rotate about x, then y, then z (world
/// axes), then translate, i.e. M = T Rz Ry Rx.
glm::mat4 readPose(const json& v, const std::string& path) {
  ObjReader o(v, path);
  o.keys({"translate", "rotate_deg"});
  glm::dmat4 m(1.0);
  if (const json* t = o.find("translate")) {
    m = glm::translate(m, readVec3(*t, o.at("translate")));
  }
  if (const json* r = o.find("rotate_deg")) {
    const glm::dvec3 deg = readVec3(*r, o.at("rotate_deg"));
    const glm::dvec3 rad = deg * (std::numbers::pi / 180);
    m = glm::rotate(m, rad.z, glm::dvec3(0, 0, 1));
    m = glm::rotate(m, rad.y, glm::dvec3(0, 1, 0));
    m = glm::rotate(m, rad.x, glm::dvec3(1, 0, 0));
  }
  o.finish();
  return glm::mat4(m);
}

/// A plane blade is a square of two triangles centred at `point`, both facing `normal`.
void readBladeGeometry(const json& v, const std::string& path, Blade& blade) {
  ObjReader o(v, path);
  const std::string type = readChoice(o.require("type"), o.at("type"), {"plane", "mesh"});
  if (type == "plane") {
    o.keys({"type", "point", "normal", "size"});
    const glm::dvec3 p = readVec3(o.require("point"), o.at("point"));
    const glm::dvec3 n = readDirection(o.require("normal"), o.at("normal"));
    const double h = readPositive(o.require("size"), o.at("size"));
    const glm::dvec3 u = anyPerpendicular(n);
    const glm::dvec3 w = glm::cross(n, u);  // u x w = n: counter-clockwise seen from +n
    blade.vertices = {glm::vec3(p - h * u - h * w), glm::vec3(p + h * u - h * w),
                      glm::vec3(p + h * u + h * w), glm::vec3(p - h * u + h * w)};
    blade.triangles = {0, 1, 2, 0, 2, 3};
  } else {
    o.keys({"type", "vertices", "triangles"});
    const std::string vp = o.at("vertices"), tp = o.at("triangles");
    const json& verts = readArray(o.require("vertices"), vp, 0, "vertices [x, y, z]");
    if (verts.size() < 3) {
      throw SceneError{vp, "expected at least 3 vertices, got " + std::to_string(verts.size())};
    }
    for (size_t i = 0; i < verts.size(); ++i) {
      blade.vertices.push_back(glm::vec3(readVec3(verts[i], indexPath(vp, i))));
    }
    const json& tris = readArray(o.require("triangles"), tp, 0, "triangles [i, j, k]");
    if (tris.empty()) throw SceneError{tp, "expected at least one triangle, got []"};
    const long long count = static_cast<long long>(verts.size());
    for (size_t t = 0; t < tris.size(); ++t) {
      const std::string p = indexPath(tp, t);
      readArray(tris[t], p, 3, "vertex indices");
      for (size_t k = 0; k < 3; ++k) {
        blade.triangles.push_back(
            static_cast<uint32_t>(readInt(tris[t][k], indexPath(p, k), 0, count - 1)));
      }
      const uint32_t* tri = &blade.triangles[3 * t];
      if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
        throw SceneError{p, "a triangle needs 3 different vertices, got " + describe(tris[t])};
      }
    }
  }
  o.finish();
}

SceneCut readCut(const json& v, const std::string& path, const Scene& scene) {
  ObjReader o(v, path);
  o.keys({"frame", "body", "blade", "from", "to"});
  SceneCut cut;
  cut.frame = readInt(o.require("frame"), o.at("frame"), 1, scene.frames);
  cut.body = readString(o.require("body"), o.at("body"));
  bool found = false;
  std::string names;
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    names += (i == 0 ? "\"" : ", \"") + scene.bodies[i].name + "\"";
    if (scene.bodies[i].name == cut.body) cut.bodyIndex = i, found = true;
  }
  if (!found) {
    throw SceneError{o.at("body"), "no body named \"" + cut.body + "\" (bodies: " + names + ")"};
  }
  if (!scene.bodies[cut.bodyIndex].def.fracture.enabled &&
      scene.bodies[cut.bodyIndex].def.cutMode != CutMode::Xfem) {
    throw SceneError{o.at("body"), "body \"" + cut.body +
                                       "\" has no \"fracture\" block; only fracturing bodies "
                                       "or bodies with \"cut_mode\": \"xfem\" can be cut"};
  }
  readBladeGeometry(o.require("blade"), o.at("blade"), cut.blade);
  if (const json* f = o.find("from")) cut.blade.from = readPose(*f, o.at("from"));
  cut.blade.to = cut.blade.from;
  if (const json* t = o.find("to")) cut.blade.to = readPose(*t, o.at("to"));
  o.finish();
  return cut;
}

// ---- strokes ------------------------------------------------------------------------------

SceneStroke readStroke(const json& v, const std::string& path, const Scene& scene) {
  ObjReader o(v, path);
  SceneStroke st;
  const std::string type =
      readChoice(o.require("type"), o.at("type"), {"push", "pull", "cut", "wet", "dry"});
  st.type = type == "push"   ? SceneStroke::Type::Push
            : type == "pull" ? SceneStroke::Type::Pull
            : type == "cut"  ? SceneStroke::Type::Cut
            : type == "wet"  ? SceneStroke::Type::Wet
                             : SceneStroke::Type::Dry;
  if (st.type == SceneStroke::Type::Push) {
    o.keys({"type", "body", "from_frame", "to_frame", "from", "to", "radius", "influence", "k1",
            "k2"});
  } else if (st.type == SceneStroke::Type::Pull) {
    o.keys({"type", "body", "from_frame", "to_frame", "from", "to", "radius", "influence", "k1",
            "k2", "grab", "stiffness"});
  } else if (st.type == SceneStroke::Type::Cut) {
    o.keys({"type", "body", "from_frame", "to_frame", "from", "to", "normal", "size", "threshold",
            "stiffness", "influence", "k1", "k2"});
  } else {
    o.keys({"type", "body", "from_frame", "to_frame", "from", "to", "radius", "rate"});
  }
  st.body = readString(o.require("body"), o.at("body"));
  bool found = false;
  std::string names;
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    names += (i == 0 ? "\"" : ", \"") + scene.bodies[i].name + "\"";
    if (scene.bodies[i].name == st.body) st.bodyIndex = i, found = true;
  }
  if (!found) {
    throw SceneError{o.at("body"), "no body named \"" + st.body + "\" (bodies: " + names + ")"};
  }
  st.fromFrame = readInt(o.require("from_frame"), o.at("from_frame"), 1, scene.frames);
  st.toFrame = readInt(o.require("to_frame"), o.at("to_frame"), st.fromFrame, scene.frames);
  // World::deform, wet and setColliders refuse centres beyond 1e9 m.
  const auto point = [&](const char* key) {
    const glm::dvec3 p = readVec3(o.require(key), o.at(key));
    if (glm::length(p) > 1e9) {
      throw SceneError{
          o.at(key), "expected a point within 1e9 m of the origin, got " + describe(*o.find(key))};
    }
    return p;
  };
  st.from = point("from");
  st.to = point("to");
  if (st.type == SceneStroke::Type::Cut) {
    // The brush's plane holds the path: the normal must be across it (the tool parks meanwhile).
    const glm::dvec3 path = st.to - st.from;
    if (!(glm::length(path) > 0))
      throw SceneError{o.at("to"), "a cut stroke must move: \"to\" equals \"from\""};
    const glm::dvec3 n = readVec3(o.require("normal"), o.at("normal"));
    const glm::dvec3 across = n - glm::dot(n, path) / glm::dot(path, path) * path;
    if (!(glm::length(across) > 0.5 * glm::length(n)))
      throw SceneError{o.at("normal"),
                       "must be a non-zero vector across the path (from -> to), "
                       "within 60 degrees of perpendicular, got " +
                           describe(*o.find("normal"))};
    st.normal = across / glm::length(across);
    st.size = readInRange(o.require("size"), o.at("size"), 0, 1e9, true, false);
    if (const json* x = o.find("threshold"))
      st.threshold = readInRange(*x, o.at("threshold"), 0, 1e9, true, false);
    st.stiffness = 1000;  // HapticContactSettings' default; read below
  } else {
    st.radius = readInRange(o.require("radius"), o.at("radius"), 0, 1e9, true, false);
  }
  if (st.type == SceneStroke::Type::Push || st.type == SceneStroke::Type::Pull ||
      st.type == SceneStroke::Type::Cut) {
    if (const json* x = o.find("influence"))
      st.influence = readInRange(*x, o.at("influence"), 0, 1e9, true, false);
    if (const json* x = o.find("k1")) st.k1 = readInRange(*x, o.at("k1"), 0, 1e9, true, false);
    if (const json* x = o.find("k2")) st.k2 = readInRange(*x, o.at("k2"), 0, 1e9, true, false);
    if (const json* x = o.find("grab"))
      st.grab = readInRange(*x, o.at("grab"), 0, 1e9, false, false);
    if (const json* x = o.find("stiffness"))
      st.stiffness = readInRange(*x, o.at("stiffness"), 0, 1e12, true, false);
  } else if (const json* x = o.find("rate")) {
    st.rate = readInRange(*x, o.at("rate"), 0, 1e9, true, false);
  }
  o.finish();
  return st;
}

/// A collider read for its types only, then held to World::setColliders' rules
/// (Collider::check): what the world would reject, the scene rejects with its JSON path.
Collider readCollider(const json& v, const std::string& path) {
  ObjReader o(v, path);
  Collider c;
  const std::string type =
      readChoice(o.require("type"), o.at("type"), {"plane", "box", "sphere", "capsule"});
  if (type == "plane") {
    o.keys({"type", "point", "normal", "stiffness", "velocity", "angular_velocity", "friction"});
    c.kind = Collider::Kind::Plane;
    if (const json* p = o.find("point")) c.point = glm::vec3(readVec3(*p, o.at("point")));
    if (const json* n = o.find("normal")) {
      // Normalised here; a zero vector stays zero for Collider::check to report.
      const glm::dvec3 d = readVec3(*n, o.at("normal"));
      const double len = glm::length(d);
      c.normal = glm::vec3(len > 0 ? d / len : d);
    }
  } else if (type == "box") {
    o.keys({"type", "center", "half_extents", "stiffness", "velocity", "angular_velocity",
            "friction"});
    c.kind = Collider::Kind::Box;
    c.point = glm::vec3(readVec3(o.require("center"), o.at("center")));
    c.halfExtents = glm::vec3(readVec3(o.require("half_extents"), o.at("half_extents")));
  } else if (type == "capsule") {
    o.keys({"type", "center", "axis", "half_length", "radius", "stiffness", "velocity",
            "angular_velocity", "friction"});
    c.kind = Collider::Kind::Capsule;
    c.point = glm::vec3(readVec3(o.require("center"), o.at("center")));
    c.radius = static_cast<float>(readNumber(o.require("radius"), o.at("radius")));
    c.halfLength = static_cast<float>(readNumber(o.require("half_length"), o.at("half_length")));
    if (const json* a = o.find("axis")) {
      // The segment runs along the collider's own y axis: turn y onto the given axis.
      const glm::dvec3 axis = readVec3(*a, o.at("axis"));
      const double len = glm::length(axis);
      if (!(len > 1e-12)) throw SceneError{o.at("axis"), "must be a non-zero direction"};
      const glm::dvec3 u = axis / len, y{0, 1, 0};
      const double w = 1 + glm::dot(y, u);
      const glm::dvec3 v = glm::cross(y, u);
      // Opposite to y, any half-turn about a perpendicular axis will do.
      const glm::dquat q =
          w > 1e-9 ? glm::normalize(glm::dquat(w, v.x, v.y, v.z)) : glm::dquat(0, 1, 0, 0);
      c.rotation = glm::quat(q);
    }
  } else {
    o.keys({"type", "center", "radius", "stiffness", "velocity", "angular_velocity", "friction"});
    c.kind = Collider::Kind::Sphere;
    c.point = glm::vec3(readVec3(o.require("center"), o.at("center")));
    c.radius = static_cast<float>(readNumber(o.require("radius"), o.at("radius")));
  }
  if (const json* k = o.find("stiffness")) c.stiffness = readNumber(*k, o.at("stiffness"));
  if (const json* u = o.find("velocity")) c.velocity = glm::vec3(readVec3(*u, o.at("velocity")));
  if (const json* w = o.find("angular_velocity"))
    c.angularVelocity = glm::vec3(readVec3(*w, o.at("angular_velocity")));
  if (const json* f = o.find("friction")) c.friction = readNumber(*f, o.at("friction"));
  o.finish();
  // Box, sphere and capsule read their point from "center".
  const std::string_view pointKey = c.kind == Collider::Kind::Plane ? "point" : "center";
  const FieldName names[] = {{"kind", "type"},
                             {"point", pointKey},
                             {"velocity", "velocity"},
                             {"stiffness", "stiffness"},
                             {"normal", "normal"},
                             {"halfExtents", "half_extents"},
                             {"radius", "radius"},
                             {"friction", "friction"},
                             {"halfLength", "half_length"},
                             {"angularVelocity", "angular_velocity"}};
  requireValid(c.check(), path, names);
  return c;
}

Scene readScene(const json& root, const std::string& source, const std::string& baseDir) {
  ObjReader o(root, "");
  o.keys({"name", "description", "dt", "frames", "substeps", "threads", "gravity", "backend",
          "contact_sweeps", "coupled_contact", "colliders", "bodies", "cuts", "strokes",
          "rigid_bodies", "camera"});
  Scene scene;
  scene.source = source;
  scene.name = std::filesystem::path(source).stem().string();
  if (const json* v = o.find("name")) scene.name = readString(*v, o.at("name"));
  if (const json* v = o.find("description"))
    scene.description = readString(*v, o.at("description"));
  if (const json* v = o.find("dt")) scene.dt = readPositive(*v, o.at("dt"));
  if (const json* v = o.find("frames")) scene.frames = readInt(*v, o.at("frames"), 1, 100'000'000);
  if (const json* v = o.find("substeps")) {
    scene.world.substeps = readInteger(*v, o.at("substeps"));
    requireAtMost(scene.world.substeps, kMaxSubsteps, o.at("substeps"), *v);
  }
  if (const json* v = o.find("threads"))
    scene.threads = readInt(*v, o.at("threads"), 0, kMaxThreads);
  if (const json* v = o.find("gravity"))
    scene.world.gravity = glm::vec3(readVec3(*v, o.at("gravity")));
  if (const json* v = o.find("backend")) {
    const std::string b = readChoice(*v, o.at("backend"), {"auto", "cpu", "cuda"});
    scene.world.backend = b == "cpu" ? Backend::Cpu : b == "cuda" ? Backend::Cuda : Backend::Auto;
  }
  if (const json* v = o.find("contact_sweeps"))
    scene.world.contactSweeps = readInteger(*v, o.at("contact_sweeps"));
  if (const json* v = o.find("coupled_contact"))
    scene.world.coupledContact = readBool(*v, o.at("coupled_contact"));
  if (const json* v = o.find("colliders")) {
    readArray(*v, o.at("colliders"), 0, "colliders");
    for (size_t i = 0; i < v->size(); ++i) {
      scene.world.colliders.push_back(readCollider((*v)[i], indexPath(o.at("colliders"), i)));
    }
  }
  // The colliders passed Collider::check one by one above.
  requireValid(scene.world.check(), "", kWorldNames);
  const json& bodies = readArray(o.require("bodies"), o.at("bodies"), 0, "bodies");
  if (bodies.empty()) throw SceneError{"bodies", "expected at least one body, got []"};
  for (size_t i = 0; i < bodies.size(); ++i) {
    const std::string path = indexPath("bodies", i);
    SceneBody b = readBody(bodies[i], path, i, baseDir);
    for (size_t j = 0; j < scene.bodies.size(); ++j) {
      if (scene.bodies[j].name == b.name) {
        throw SceneError{path + ".name", "duplicate body name \"" + b.name + "\" (also bodies[" +
                                             std::to_string(j) + "])"};
      }
    }
    scene.bodies.push_back(std::move(b));
  }
  if (const json* v = o.find("rigid_bodies")) {
    readArray(*v, o.at("rigid_bodies"), 0, "rigid bodies");
    for (size_t i = 0; i < v->size(); ++i) {
      const std::string path = indexPath(o.at("rigid_bodies"), i);
      SceneRigidBody r = readRigidBody((*v)[i], path, i);
      for (size_t j = 0; j < scene.rigidBodies.size(); ++j) {
        if (scene.rigidBodies[j].name == r.name) {
          throw SceneError{path + ".name", "duplicate rigid body name \"" + r.name +
                                               "\" (also rigid_bodies[" + std::to_string(j) + "])"};
        }
      }
      scene.rigidBodies.push_back(std::move(r));
    }
  }
  if (const json* v = o.find("camera")) scene.camera = readCamera(*v, o.at("camera"));
  if (const json* v = o.find("cuts")) {
    readArray(*v, o.at("cuts"), 0, "cuts");
    for (size_t i = 0; i < v->size(); ++i) {
      scene.cuts.push_back(readCut((*v)[i], indexPath(o.at("cuts"), i), scene));
    }
    std::stable_sort(scene.cuts.begin(), scene.cuts.end(),
                     [](const SceneCut& a, const SceneCut& b) { return a.frame < b.frame; });
  }
  if (const json* v = o.find("strokes")) {
    readArray(*v, o.at("strokes"), 0, "strokes");
    std::vector<std::pair<SceneStroke, size_t>> read;
    for (size_t i = 0; i < v->size(); ++i) {
      read.emplace_back(readStroke((*v)[i], indexPath(o.at("strokes"), i), scene), i);
    }
    // File order is kept (messages and haptic.csv name strokes by it); the check sorts.
    for (const auto& r : read) scene.strokes.push_back(r.first);
    std::stable_sort(read.begin(), read.end(), [](const auto& a, const auto& b) {
      return a.first.fromFrame < b.first.fromFrame;
    });
    // One tool: a stroke starts after the previous one ended.
    for (size_t k = 1; k < read.size(); ++k) {
      const auto& [prev, pi] = read[k - 1];
      const auto& [cur, ci] = read[k];
      if (cur.fromFrame <= prev.toFrame) {
        throw SceneError{indexPath(o.at("strokes"), ci) + ".from_frame",
                         "frames " + std::to_string(cur.fromFrame) + "-" +
                             std::to_string(cur.toFrame) + " overlap strokes[" +
                             std::to_string(pi) + "] (frames " + std::to_string(prev.fromFrame) +
                             "-" + std::to_string(prev.toFrame) + "); there is one tool"};
      }
    }
  }
  o.finish();
  return scene;
}

}  // namespace

Result<BodyId> addBody(World& world, const SceneBody& body) {
  Result<BodyId> created = world.createBody(body.def);
  if (!created) return created;
  const BodyId id = created.value();
  const bool deform = body.initialDeformation != glm::dmat3(1.0);
  const bool spin = body.angularVelocity != glm::dvec3(0.0);
  if (!deform && !spin) return id;

  // The lumped masses are a quarter of each tet's mass at its corners, so the centre of mass
  // of a uniform body is its volume centroid, and an affine map about it keeps it in place.
  const TetMesh& mesh = body.def.mesh;
  auto node = [&](size_t n) {
    return glm::dvec3(mesh.positions[3 * n], mesh.positions[3 * n + 1], mesh.positions[3 * n + 2]);
  };
  glm::dvec3 centre(0.0);
  double volume = 0;
  for (size_t t = 0; t < mesh.tetCount(); ++t) {
    glm::dvec3 p[4];
    for (int k = 0; k < 4; ++k) p[k] = node(size_t(mesh.tets[4 * t + k]));
    const double v = std::abs(glm::dot(p[1] - p[0], glm::cross(p[2] - p[0], p[3] - p[0]))) / 6;
    centre += v * 0.25 * (p[0] + p[1] + p[2] + p[3]);
    volume += v;
  }
  if (volume > 0) centre /= volume;

  const std::span<const double> x0 = world.positions(id);
  std::vector<double> x(x0.begin(), x0.end());
  if (deform) {
    for (size_t n = 0; 3 * n + 2 < x.size(); ++n) {
      const glm::dvec3 p = centre + body.initialDeformation * (node(n) - centre);
      for (int k = 0; k < 3; ++k) x[3 * n + size_t(k)] = p[k];
    }
    if (Result<void> r = world.setPositions(id, x); !r) {
      (void)world.destroyBody(id);
      return fail("initial_deformation: ", r.error().message);
    }
  }
  if (spin) {
    // A rigid rotation about the centre of mass on top of the initial velocity.
    const std::span<const double> v0 = world.velocities(id);
    std::vector<double> v(v0.begin(), v0.end());
    for (size_t n = 0; 3 * n + 2 < v.size(); ++n) {
      const glm::dvec3 r(x[3 * n] - centre.x, x[3 * n + 1] - centre.y, x[3 * n + 2] - centre.z);
      const glm::dvec3 w = glm::cross(body.angularVelocity, r);
      for (int k = 0; k < 3; ++k) v[3 * n + size_t(k)] += w[k];
    }
    if (Result<void> r = world.setVelocities(id, v); !r) {
      (void)world.destroyBody(id);
      return fail("angular_velocity: ", r.error().message);
    }
  }
  return id;
}

glm::dvec3 anyPerpendicular(const glm::dvec3& unit) {
  const gf::Vec3 u = gf::detail::anyOrthogonal(gf::Vec3{unit.x, unit.y, unit.z});
  return {u.x, u.y, u.z};
}

bool needsBullet(const Scene& scene) {
  if (!scene.rigidBodies.empty()) return true;
  return std::any_of(scene.bodies.begin(), scene.bodies.end(), [](const SceneBody& b) {
    return b.handoff.policy != SceneHandoff::Policy::Never;
  });
}

Result<Scene> parseScene(const std::string& text, const std::string& source,
                         const std::string& baseDir) {
  try {
    json root;
    try {
      root = json::parse(text, DuplicateKeyCheck{}, /*allow_exceptions=*/true,
                         /*ignore_comments=*/true);
    } catch (const json::parse_error& e) {
      return fail(source, ":", syntaxError(e, text));
    }
    return readScene(root, source, baseDir);
  } catch (const SceneError& e) {
    return fail(source, ": ", e.path.empty() ? "(top level)" : e.path, ": ", e.reason);
  } catch (const std::bad_alloc&) {
    return fail(source, ": out of memory while building the scene");
  } catch (const std::exception& e) {
    return fail(source, ": ", e.what());
  } catch (...) {
    return fail(source, ": unexpected error while reading the scene");
  }
}

Result<Scene> loadScene(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(path, ": cannot open the scene file");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return fail(path, ": read error");
  const std::string dir = std::filesystem::path(path).parent_path().string();
  return parseScene(ss.str(), path, dir);
}

}  // namespace gf::scene
