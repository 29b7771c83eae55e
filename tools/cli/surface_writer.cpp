#include "cli/surface_writer.h"

#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>

namespace gf::cli {

SurfaceTopology surfaceTopology(const TetMesh& mesh) {
  SurfaceTopology t;
  t.faces = mesh.boundaryFaces();
  std::vector<int32_t> local(mesh.nodeCount(), -1);
  for (int32_t& n : t.faces) {
    if (local[n] < 0) {
      local[n] = static_cast<int32_t>(t.nodes.size());
      t.nodes.push_back(n);
    }
    n = local[n];
  }
  return t;
}

namespace {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

const char* plyByteOrder() {
  return std::endian::native == std::endian::little ? "binary_little_endian" : "binary_big_endian";
}

void writeObj(std::FILE* f, const SurfaceTopology& t, std::span<const double> x) {
  std::fputs("# graphfrac surface frame\n", f);
  for (int32_t n : t.nodes) {
    std::fprintf(f, "v %.9g %.9g %.9g\n", x[3 * n], x[3 * n + 1], x[3 * n + 2]);
  }
  std::fputs("g surface\n", f);
  for (size_t i = 0; i + 2 < t.faces.size(); i += 3) {
    std::fprintf(f, "f %d %d %d\n", t.faces[i] + 1, t.faces[i + 1] + 1, t.faces[i + 2] + 1);
  }
}

// Binary PLY in the host's byte order (the header says which), float positions.
void writePly(std::FILE* f, const SurfaceTopology& t, std::span<const double> x) {
  std::fprintf(f,
               "ply\nformat %s 1.0\ncomment graphfrac surface frame\nelement vertex %zu\n"
               "property float x\nproperty float y\nproperty float z\nelement face %zu\n"
               "property list uchar int vertex_indices\nend_header\n",
               plyByteOrder(), t.nodes.size(), t.faces.size() / 3);
  for (int32_t n : t.nodes) {
    const float p[3] = {static_cast<float>(x[3 * n]), static_cast<float>(x[3 * n + 1]),
                        static_cast<float>(x[3 * n + 2])};
    std::fwrite(p, sizeof(float), 3, f);
  }
  for (size_t i = 0; i + 2 < t.faces.size(); i += 3) {
    const unsigned char three = 3;
    std::fwrite(&three, 1, 1, f);
    std::fwrite(&t.faces[i], sizeof(int32_t), 3, f);
  }
}

/// Opens `path`, runs `body` and reports open, write and close errors against the file.
template <class Body>
Result<void> writeFile(const std::string& path, SurfaceFormat format, Body&& body) {
  File f(std::fopen(path.c_str(), format == SurfaceFormat::Obj ? "w" : "wb"));
  if (!f) return fail(path, ": cannot create: ", std::strerror(errno));
  body(f.get());
  if (std::ferror(f.get()) || std::fclose(f.release()) != 0) {
    return fail(path, ": write error");
  }
  return {};
}

void writeRenderObj(std::FILE* f, const SurfaceView& v) {
  const size_t nv = v.positions.size() / 3, nt = v.indices.size() / 3;
  size_t cracks = 0;
  for (uint8_t m : v.crackMask) cracks += m != 0;
  std::fprintf(f, "# graphfrac render surface: %zu vertices, %zu triangles (%zu crack)\n", nv, nt,
               cracks);
  for (size_t i = 0; i < nv; ++i) {
    std::fprintf(f, "v %.9g %.9g %.9g\n", v.positions[3 * i], v.positions[3 * i + 1],
                 v.positions[3 * i + 2]);
  }
  for (size_t i = 0; i < nv; ++i) {
    std::fprintf(f, "vn %.6g %.6g %.6g\n", v.normals[3 * i], v.normals[3 * i + 1],
                 v.normals[3 * i + 2]);
  }
  // Boundary first, then the crack faces, each as one group.
  for (uint8_t group = 0; group < 2; ++group) {
    if (group == 1 && cracks == 0) break;
    std::fputs(group == 0 ? "g surface\n" : "g crack\n", f);
    for (size_t t = 0; t < nt; ++t) {
      if ((v.crackMask[t] != 0) != (group == 1)) continue;
      const uint32_t a = v.indices[3 * t] + 1, b = v.indices[3 * t + 1] + 1,
                     c = v.indices[3 * t + 2] + 1;
      std::fprintf(f, "f %u//%u %u//%u %u//%u\n", a, a, b, b, c, c);
    }
  }
}

void writeRenderPly(std::FILE* f, const SurfaceView& v) {
  const size_t nv = v.positions.size() / 3, nt = v.indices.size() / 3;
  std::fprintf(f,
               "ply\nformat %s 1.0\ncomment graphfrac render surface; red faces are crack "
               "faces\nelement vertex %zu\nproperty float x\nproperty float y\nproperty float z\n"
               "property float nx\nproperty float ny\nproperty float nz\nproperty int fragment\n"
               "element face %zu\nproperty list uchar int vertex_indices\nproperty uchar red\n"
               "property uchar green\nproperty uchar blue\nend_header\n",
               plyByteOrder(), nv, nt);
  for (size_t i = 0; i < nv; ++i) {
    std::fwrite(&v.positions[3 * i], sizeof(float), 3, f);
    std::fwrite(&v.normals[3 * i], sizeof(float), 3, f);
    const int32_t fragment = v.vertexFragment.empty() ? 0 : v.vertexFragment[i];
    std::fwrite(&fragment, sizeof(int32_t), 1, f);
  }
  for (size_t t = 0; t < nt; ++t) {
    const unsigned char three = 3;
    std::fwrite(&three, 1, 1, f);
    const int32_t idx[3] = {static_cast<int32_t>(v.indices[3 * t]),
                            static_cast<int32_t>(v.indices[3 * t + 1]),
                            static_cast<int32_t>(v.indices[3 * t + 2])};
    std::fwrite(idx, sizeof(int32_t), 3, f);
    std::fwrite(v.crackMask[t] != 0 ? kCrackColour : kBoundaryColour, 1, 3, f);
  }
}

}  // namespace

Result<void> writeSurfaceFrame(const std::string& path, const SurfaceTopology& topo,
                               std::span<const double> positions, SurfaceFormat format) {
  for (int32_t n : topo.nodes) {
    if (3 * static_cast<size_t>(n) + 2 >= positions.size()) {
      return fail(path, ": positions hold ", std::to_string(positions.size() / 3),
                  " nodes but the surface uses node ", std::to_string(n));
    }
  }
  return writeFile(path, format, [&](std::FILE* f) {
    if (format == SurfaceFormat::Obj) {
      writeObj(f, topo, positions);
    } else {
      writePly(f, topo, positions);
    }
  });
}

Result<void> writeRenderSurface(const std::string& path, const SurfaceView& view,
                                SurfaceFormat format) {
  // A view that disagrees with itself would write a file that no viewer can read.
  const size_t nv = view.positions.size() / 3, nt = view.indices.size() / 3;
  if (view.positions.size() % 3 != 0 || view.indices.size() % 3 != 0 ||
      view.normals.size() != view.positions.size() || view.crackMask.size() != nt ||
      (!view.vertexFragment.empty() && view.vertexFragment.size() != nv)) {
    return fail(path, ": inconsistent render surface (", std::to_string(view.positions.size()),
                " position, ", std::to_string(view.normals.size()), " normal, ",
                std::to_string(view.indices.size()), " index, ",
                std::to_string(view.crackMask.size()), " crack-mask values)");
  }
  for (uint32_t i : view.indices) {
    if (i >= nv) {
      return fail(path, ": render surface index ", std::to_string(i), " out of range (",
                  std::to_string(nv), " vertices)");
    }
  }
  return writeFile(path, format, [&](std::FILE* f) {
    if (format == SurfaceFormat::Obj) {
      writeRenderObj(f, view);
    } else {
      writeRenderPly(f, view);
    }
  });
}

}  // namespace gf::cli
