// TetMesh basics: loading by extension, node-number resolution shared by the readers, volume,
// boundary faces and the Gmsh 2.2 writer.
#include <algorithm>
#include <charconv>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <unordered_map>

#include "mesh/mesh_internal.h"

namespace gf {

namespace detail {

double tetSixVolume(const double* p, const int32_t* t) {
  const double* a = p + 3 * static_cast<size_t>(t[0]);
  const double* b = p + 3 * static_cast<size_t>(t[1]);
  const double* c = p + 3 * static_cast<size_t>(t[2]);
  const double* d = p + 3 * static_cast<size_t>(t[3]);
  const double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double e3[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
  return e1[0] * (e2[1] * e3[2] - e2[2] * e3[1]) - e1[1] * (e2[0] * e3[2] - e2[2] * e3[0]) +
         e1[2] * (e2[0] * e3[1] - e2[1] * e3[0]);
}

std::vector<FaceRecord> sortedFaces(const int32_t* tets, size_t tetCount) {
  const size_t nt = tetCount;
  std::vector<FaceRecord> faces(4 * nt);
  for (size_t e = 0; e < nt; ++e) {
    const int32_t* t = &tets[4 * e];
    for (int f = 0; f < 4; ++f) {
      FaceRecord& r = faces[4 * e + static_cast<size_t>(f)];
      r.key[0] = t[kTetFaces[f][0]];
      r.key[1] = t[kTetFaces[f][1]];
      r.key[2] = t[kTetFaces[f][2]];
      std::sort(r.key, r.key + 3);
      r.tet = static_cast<int32_t>(e);
      r.local = f;
    }
  }
  // Ties broken by tet so the order (and hence boundaryFaces()) is deterministic.
  std::sort(faces.begin(), faces.end(), [](const FaceRecord& x, const FaceRecord& y) {
    if (x.key[0] != y.key[0]) return x.key[0] < y.key[0];
    if (x.key[1] != y.key[1]) return x.key[1] < y.key[1];
    if (x.key[2] != y.key[2]) return x.key[2] < y.key[2];
    return x.tet < y.tet;
  });
  return faces;
}

std::vector<int32_t> boundaryFaces(const int32_t* tets, size_t tetCount) {
  std::vector<int32_t> out;
  const std::vector<FaceRecord> faces = sortedFaces(tets, tetCount);
  for (size_t i = 0; i < faces.size();) {
    size_t j = i + 1;
    while (j < faces.size() && std::equal(faces[j].key, faces[j].key + 3, faces[i].key)) ++j;
    if (j - i == 1) {
      const int32_t* t = &tets[4 * static_cast<size_t>(faces[i].tet)];
      for (int k = 0; k < 3; ++k) out.push_back(t[kTetFaces[faces[i].local][k]]);
    }
    i = j;
  }
  return out;
}

Result<TetMesh> finishRawMesh(RawMesh&& raw, MeshLoadInfo* info) {
  const size_t nn = raw.nodeTags.size();
  const size_t nt = raw.tetTags.size();

  // Node numbers -> indices. Most files number 0..n-1 or 1..n; anything else goes through a
  // hash map, which also catches numbers defined twice.
  bool contiguous = true;
  for (size_t i = 0; i < nn && contiguous; ++i) {
    contiguous = raw.nodeTags[i] == raw.nodeTags[0] + static_cast<int64_t>(i);
  }
  const int64_t base = nn > 0 ? raw.nodeTags[0] : 0;
  std::unordered_map<int64_t, int32_t> index;
  if (!contiguous) {
    index.reserve(nn);
    for (size_t i = 0; i < nn; ++i) {
      const auto [it, inserted] = index.emplace(raw.nodeTags[i], static_cast<int32_t>(i));
      if (!inserted) {
        return fail(raw.nodeFile, ":", std::to_string(raw.nodeLines[i]), ": node ",
                    std::to_string(raw.nodeTags[i]), ": number already used on line ",
                    std::to_string(raw.nodeLines[static_cast<size_t>(it->second)]));
      }
    }
  }

  TetMesh mesh;
  mesh.positions = std::move(raw.positions);
  mesh.tets.resize(4 * nt);
  for (size_t e = 0; e < nt; ++e) {
    for (size_t k = 0; k < 4; ++k) {
      const int64_t tag = raw.tetNodeTags[4 * e + k];
      int64_t idx = -1;
      if (contiguous) {
        if (tag >= base && tag - base < static_cast<int64_t>(nn)) idx = tag - base;
      } else if (auto it = index.find(tag); it != index.end()) {
        idx = it->second;
      }
      if (idx < 0) {
        const std::string where =
            raw.nodeFile == raw.tetFile ? std::string() : " in " + raw.nodeFile;
        return fail(raw.tetFile, ":", std::to_string(raw.tetLines[e]), ": element ",
                    std::to_string(raw.tetTags[e]), ": node ", std::to_string(tag),
                    " is not defined", where);
      }
      mesh.tets[4 * e + k] = static_cast<int32_t>(idx);
    }
  }

  MeshSourceMap map;
  map.nodeFile = std::move(raw.nodeFile);
  map.tetFile = std::move(raw.tetFile);
  map.nodeTags = std::move(raw.nodeTags);
  map.tetTags = std::move(raw.tetTags);
  map.nodeLines = std::move(raw.nodeLines);
  map.tetLines = std::move(raw.tetLines);
  int flipped = 0;
  Result<void> v = validateMesh(mesh, map.tetFile, &map, &flipped);
  if (!v.ok()) return v.error();
  if (info) info->flippedFixed = flipped;
  return mesh;
}

}  // namespace detail

Result<TetMesh> TetMesh::fromFile(const std::string& path, MeshLoadInfo* info) {
  const std::string ext = detail::lowerExtension(path);
  if (ext == ".msh") return fromGmsh(path, info);
  if (ext == ".node" || ext == ".ele") {
    std::filesystem::path p(path);
    const std::string stem = (p.parent_path() / p.stem()).string();
    const std::string nodeExt = ext == ".node" ? p.extension().string() : ".node";
    const std::string eleExt = ext == ".ele" ? p.extension().string() : ".ele";
    return fromTetGen(stem + nodeExt, stem + eleExt, info);
  }
  return fail(path, ": unknown mesh format '", ext, "' (expected .msh, .node or .ele)");
}

double TetMesh::volume() const {
  double v = 0;
  for (size_t e = 0; e < tetCount(); ++e) v += detail::tetSixVolume(positions.data(), &tets[4 * e]);
  return v / 6.0;
}

std::vector<int32_t> TetMesh::boundaryFaces() const {
  std::vector<int32_t> out;
  const int32_t n = static_cast<int32_t>(nodeCount());
  for (int32_t t : tets) {
    if (t < 0 || t >= n) return out;  // unvalidated garbage: no boundary rather than a crash
  }
  return detail::boundaryFaces(tets.data(), tetCount());
}

namespace {

// Appends shortest round-trip text of x (to_chars), so a written mesh reads back bit-exact.
void appendNumber(std::string& s, double x) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  s.append(buf, r.ptr);
}

void appendNumber(std::string& s, int64_t x) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  s.append(buf, r.ptr);
}

}  // namespace

Result<void> TetMesh::writeMsh(const std::string& path) const {
  std::ofstream out(path, std::ios::binary);
  if (!out) return fail(path, ": cannot open for writing");
  std::string s = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n";
  appendNumber(s, static_cast<int64_t>(nodeCount()));
  s += '\n';
  // Written in chunks: a big mesh does not need its whole text in memory.
  constexpr size_t kFlush = 1 << 20;
  for (size_t i = 0; i < nodeCount(); ++i) {
    appendNumber(s, static_cast<int64_t>(i + 1));
    for (int k = 0; k < 3; ++k) {
      s += ' ';
      appendNumber(s, positions[3 * i + static_cast<size_t>(k)]);
    }
    s += '\n';
    if (s.size() > kFlush) {
      out << s;
      s.clear();
    }
  }
  s += "$EndNodes\n$Elements\n";
  appendNumber(s, static_cast<int64_t>(tetCount()));
  s += '\n';
  for (size_t e = 0; e < tetCount(); ++e) {
    appendNumber(s, static_cast<int64_t>(e + 1));
    s += " 4 2 1 1";  // type 4, two tags: physical group 1, elementary entity 1
    for (int k = 0; k < 4; ++k) {
      s += ' ';
      appendNumber(s, static_cast<int64_t>(tets[4 * e + static_cast<size_t>(k)]) + 1);
    }
    s += '\n';
    if (s.size() > kFlush) {
      out << s;
      s.clear();
    }
  }
  s += "$EndElements\n";
  out << s;
  out.flush();
  if (!out) return fail(path, ": write failed");
  return {};
}

}  // namespace gf
