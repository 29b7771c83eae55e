// Triangle surfaces through assimp (Debian's libassimp-dev): STL, glTF 2.0, FBX, Collada, 3DS,
// OFF and the other formats it reads, and OBJ and PLY on request. Built only where CMake found
// assimp; the runtime never links it.
//
// The scene graph is walked here rather than by aiProcess_PreTransformVertices so that every
// triangle keeps its mesh and node for messages, and so that the root transform assimp builds
// for Collada's <unit> can be replaced by --scale. Units and axes:
//   glTF 2.0  metres, Y up by definition: nothing to do.
//   Collada   assimp applies <unit meter> and <up_axis> in the root transform; --up switches
//             assimp's turn off (IMPORT_COLLADA_IGNORE_UP_DIRECTION), --scale replaces the unit.
//   FBX       assimp passes the file's GlobalSettings on as scene metadata and applies neither:
//             UnitScaleFactor (centimetres per unit) and the axis system (UpAxis, FrontAxis,
//             CoordAxis, each with a sign) are applied here.
//   others    no unit or axis: metres, Y up, unless --scale and --up say otherwise.
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "meshing/surface_reader.h"

namespace gf::meshing {

bool haveAssimp() { return true; }

namespace detail {
namespace {

// A row-major 3x4 affine transform in double (assimp's are float).
struct Affine {
  double m[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};

  static Affine from(const aiMatrix4x4& a) {
    Affine r;
    const float* rows[3] = {&a.a1, &a.b1, &a.c1};
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 4; ++j) r.m[4 * i + j] = rows[i][j];
    }
    return r;
  }
  static Affine linear(const double l[9]) {
    Affine r;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) r.m[4 * i + j] = l[3 * i + j];
      r.m[4 * i + 3] = 0;
    }
    return r;
  }
  Affine operator*(const Affine& b) const {
    Affine r;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 4; ++j) {
        double v = j == 3 ? m[4 * i + 3] : 0;
        for (int k = 0; k < 3; ++k) v += m[4 * i + k] * b.m[4 * k + j];
        r.m[4 * i + j] = v;
      }
    }
    return r;
  }
  double det() const {
    return m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) +
           m[2] * (m[4] * m[9] - m[5] * m[8]);
  }
};

template <class T>
bool metadata(const aiScene* scene, const char* key, T& value) {
  return scene->mMetaData && scene->mMetaData->Get(key, value);
}

std::string formatName(const aiScene* scene) {
  aiString name;
  if (scene->mMetaData && scene->mMetaData->Get("SourceAsset_Format", name)) return name.C_Str();
  return "";
}

// FBX's axis system as a rotation to X right, Y up, Z front (FBX's own default, identity):
// the rows pick the file's CoordAxis, UpAxis and FrontAxis with their signs. Empty when the
// metadata is missing or not a permutation.
bool fbxAxes(const aiScene* scene, double l[9], std::string& says) {
  int32_t axis[3], sign[3];
  const char* keys[3][2] = {
      {"CoordAxis", "CoordAxisSign"}, {"UpAxis", "UpAxisSign"}, {"FrontAxis", "FrontAxisSign"}};
  for (int r = 0; r < 3; ++r) {
    if (!metadata(scene, keys[r][0], axis[r]) || !metadata(scene, keys[r][1], sign[r]))
      return false;
    if (axis[r] < 0 || axis[r] > 2) return false;
  }
  if (axis[0] == axis[1] || axis[1] == axis[2] || axis[0] == axis[2]) return false;
  std::fill(l, l + 9, 0.0);
  for (int r = 0; r < 3; ++r) l[3 * r + axis[r]] = sign[r] < 0 ? -1 : 1;
  says = std::string("up ") + (sign[1] < 0 ? "-" : "+") + static_cast<char>('X' + axis[1]) +
         " (FBX UpAxis)";
  return true;
}

// The name a mesh instance goes by in messages.
std::string meshName(const aiScene* scene, unsigned mesh, const aiNode* node, bool instanced) {
  const std::string name = scene->mMeshes[mesh]->mName.C_Str();
  std::string s = name.empty() ? "mesh " + std::to_string(mesh) : "mesh '" + name + "'";
  if (instanced || name.empty()) s += std::string(" in node '") + node->mName.C_Str() + "'";
  return s;
}

struct Walk {
  const aiScene* scene;
  std::vector<unsigned> uses;  // how many nodes instance each mesh
  SurfaceFile* out;
  bool allHaveUvs = true;     // every mesh so far had texture coordinates (set 0)
  std::vector<int32_t> used;  // per file material: its index in SurfaceFile::materials, or -1
};

// A material's base colour and colour texture: glTF's PBR base colour where the file has one,
// else the classic diffuse.
SurfaceFile::Material readMaterial(const aiMaterial* m, unsigned index) {
  SurfaceFile::Material out;
  aiString name;
  out.name = m->Get(AI_MATKEY_NAME, name) == AI_SUCCESS && name.length > 0
                 ? name.C_Str()
                 : "material " + std::to_string(index);
  aiColor4D c;
  if (m->Get(AI_MATKEY_BASE_COLOR, c) == AI_SUCCESS ||
      m->Get(AI_MATKEY_COLOR_DIFFUSE, c) == AI_SUCCESS) {
    out.colour[0] = c.r;
    out.colour[1] = c.g;
    out.colour[2] = c.b;
  }
  aiString texture;
  for (aiTextureType type : {aiTextureType_BASE_COLOR, aiTextureType_DIFFUSE})
    if (m->GetTextureCount(type) > 0 && m->GetTexture(type, 0, &texture) == AI_SUCCESS) {
      out.texture = texture.C_Str();
      break;
    }
  return out;
}

// Appends the triangles of the node's meshes, placed by t (the node's transform included).
void addMeshes(Walk& w, const aiNode* node, const Affine& t) {
  SurfaceFile& s = *w.out;
  for (unsigned k = 0; k < node->mNumMeshes; ++k) {
    const unsigned mi = node->mMeshes[k];
    if (mi >= w.scene->mNumMeshes) continue;
    const aiMesh* mesh = w.scene->mMeshes[mi];
    const int32_t id = static_cast<int32_t>(s.meshNames.size());
    s.meshNames.push_back(meshName(w.scene, mi, node, w.uses[mi] > 1));
    const int64_t base = static_cast<int64_t>(s.vertexCount());
    const aiVector3D* uv = mesh->mTextureCoords[0];
    w.allHaveUvs = w.allHaveUvs && uv != nullptr;
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      if (w.allHaveUvs) s.uvs.insert(s.uvs.end(), {uv[v].x, uv[v].y});
      const aiVector3D& p = mesh->mVertices[v];
      for (int r = 0; r < 3; ++r) {
        s.positions.push_back(t.m[4 * r] * p.x + t.m[4 * r + 1] * p.y + t.m[4 * r + 2] * p.z +
                              t.m[4 * r + 3]);
      }
      s.vertexLine.push_back(v);
      s.vertexMesh.push_back(id);
    }
    // A mirroring transform turns faces inside out; reversing them keeps them outward.
    const bool mirror = t.det() < 0;
    uint16_t material = 0;
    if (mesh->mMaterialIndex < w.scene->mNumMaterials) {
      int32_t& u = w.used[mesh->mMaterialIndex];
      if (u < 0) {
        u = int32_t(s.materials.size());
        s.materials.push_back(
            readMaterial(w.scene->mMaterials[mesh->mMaterialIndex], mesh->mMaterialIndex));
      }
      material = uint16_t(u);
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices == 1) ++s.skippedPoints;
      if (face.mNumIndices == 2) ++s.skippedLines;
      if (face.mNumIndices != 3) continue;  // aiProcess_Triangulate split the polygons
      const int64_t a = face.mIndices[0], b = face.mIndices[mirror ? 2 : 1],
                    c = face.mIndices[mirror ? 1 : 2];
      s.triangles.insert(s.triangles.end(), {base + a, base + b, base + c});
      s.faceTag.push_back(f);
      s.faceMesh.push_back(id);
      s.faceMaterial.push_back(material);
    }
  }
}

// Depth first, in the file's order; t is the node's world transform.
void collect(Walk& w, const aiNode* node, const Affine& t) {
  addMeshes(w, node, t);
  for (unsigned c = 0; c < node->mNumChildren; ++c) {
    const aiNode* child = node->mChildren[c];
    collect(w, child, t * Affine::from(child->mTransformation));
  }
}

void countUses(const aiNode* node, std::vector<unsigned>& uses) {
  for (unsigned k = 0; k < node->mNumMeshes; ++k) {
    if (node->mMeshes[k] < uses.size()) ++uses[node->mMeshes[k]];
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c) countUses(node->mChildren[c], uses);
}

}  // namespace

Result<SurfaceFile> readWithAssimp(const std::string& path, const SurfaceReadOptions& options) {
  Assimp::Importer importer;
  // --up replaces Collada's <up_axis>, which assimp would otherwise apply in the root.
  if (options.up) importer.SetPropertyBool(AI_CONFIG_IMPORT_COLLADA_IGNORE_UP_DIRECTION, true);
  // Validation turns out-of-range indices and the like into an error instead of a crash.
  const aiScene* scene =
      importer.ReadFile(path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                  aiProcess_ValidateDataStructure);
  if (!scene) {
    std::string why = importer.GetErrorString();
    if (why.rfind("No suitable reader found", 0) == 0) {
      return fail(path,
                  ": unsupported format: assimp has no reader for it (by extension or "
                  "content)");
    }
    if (why.rfind("Unable to open file", 0) == 0) return fail(path, ": cannot open");
    return fail(path, ": assimp cannot read it: ", why);
  }
  SurfaceFile s;
  s.path = path;
  s.source = SurfaceSource::kAssimp;
  s.format = formatName(scene);
  if (!scene->mRootNode || scene->mNumMeshes == 0 || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE)) {
    return fail(path, ": the scene is empty: no meshes (", std::to_string(scene->mNumCameras),
                " cameras, ", std::to_string(scene->mNumLights), " lights)");
  }

  // The conversion to metres and Y up, applied before the root's own transform.
  const bool fbx = s.format.find("FBX") != std::string::npos;
  const bool collada = s.format.find("Collada") != std::string::npos;
  double unit = 1;
  std::string unitSays = "unit 1 m (none given)", upSays = "up +Y as assimp gives it";
  double axes[9];
  upToY('y', axes);
  Affine root = Affine::from(scene->mRootNode->mTransformation);
  if (fbx) {
    // A float in the files assimp 5.2 writes; a double in some versions.
    float f = 0;
    double cmPerUnit = metadata(scene, "UnitScaleFactor", f) ? f : 0;
    if (cmPerUnit == 0) metadata(scene, "UnitScaleFactor", cmPerUnit);
    {
      if (cmPerUnit > 0 && std::isfinite(cmPerUnit)) {
        unit = cmPerUnit / 100;
        unitSays = "unit " + formatDouble(unit) + " m (FBX UnitScaleFactor " +
                   formatDouble(cmPerUnit) + ")";
      }
    }
    std::string says;
    if (!options.up && fbxAxes(scene, axes, says)) upSays = says;
  } else if (collada) {
    // assimp's root holds unit * turn; a uniform scale's cube root of the determinant is the
    // unit.
    const double u = std::cbrt(std::abs(root.det()));
    char digits[32];  // a float's digits: 0.01, not 0.00999999978
    std::snprintf(digits, sizeof digits, "%.6g", u);
    unitSays = std::string("unit ") + digits + " m (Collada <unit>)";
    if (!options.up) upSays = "up by Collada <up_axis>";
    if (options.scale > 0 && u > 0) {
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) root.m[4 * r + c] /= u;
      }
    }
  } else if (s.format.find("glTF") != std::string::npos) {
    unitSays = "unit 1 m (glTF)";
    upSays = "up +Y (glTF)";
  }
  if (options.scale > 0) {
    unit = options.scale;
    unitSays = "unit " + formatDouble(unit) + " m (--scale)";
  }
  if (options.up) {
    upToY(options.up, axes);
    upSays = std::string("up +") + static_cast<char>(std::toupper(options.up)) + " (--up)";
  }
  for (double& x : axes) x *= unit;
  Walk w{scene, std::vector<unsigned>(scene->mNumMeshes, 0), &s, true,
         std::vector<int32_t>(scene->mNumMaterials, -1)};
  countUses(scene->mRootNode, w.uses);
  collect(w, scene->mRootNode, Affine::linear(axes) * root);
  // UVs from some meshes only would leave the others' texture lookups meaningless.
  if (!w.allHaveUvs) s.uvs.clear();
  if (s.materials.size() > 0xFFFE) return fail(path, ": more than 65534 materials");

  s.format +=
      ", " + std::to_string(s.meshNames.size()) + (s.meshNames.size() == 1 ? " mesh" : " meshes");
  s.conversion = unitSays + ", " + upSays;
  if (s.meshNames.empty()) {
    return fail(path, ": the scene is empty: no node uses any of its ",
                std::to_string(scene->mNumMeshes), " meshes");
  }
  if (s.triangles.empty()) {
    return fail(path, ": no triangles to mesh: the file holds only ",
                std::to_string(s.skippedPoints), " points and ", std::to_string(s.skippedLines),
                " lines (a volume needs a closed triangle surface)");
  }
  for (size_t i = 0; i < s.positions.size(); ++i) {
    if (!std::isfinite(s.positions[i])) {
      return fail(s.vertexAt(i / 3), ": coordinate ", std::string(1, char('x' + i % 3)), " = ",
                  formatDouble(s.positions[i]), " is not finite");
    }
  }
  return s;
}

}  // namespace detail
}  // namespace gf::meshing
