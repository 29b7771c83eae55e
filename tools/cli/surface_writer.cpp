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

void writeObj(std::FILE* f, const SurfaceTopology& t, std::span<const double> x) {
  std::fputs("# graphfrac surface frame\n", f);
  for (int32_t n : t.nodes) {
    std::fprintf(f, "v %.9g %.9g %.9g\n", x[3 * n], x[3 * n + 1], x[3 * n + 2]);
  }
  for (size_t i = 0; i + 2 < t.faces.size(); i += 3) {
    std::fprintf(f, "f %d %d %d\n", t.faces[i] + 1, t.faces[i + 1] + 1, t.faces[i + 2] + 1);
  }
}

// Binary PLY in the host's byte order (the header says which), float positions.
void writePly(std::FILE* f, const SurfaceTopology& t, std::span<const double> x) {
  const char* order =
      std::endian::native == std::endian::little ? "binary_little_endian" : "binary_big_endian";
  std::fprintf(f,
               "ply\nformat %s 1.0\ncomment graphfrac surface frame\nelement vertex %zu\n"
               "property float x\nproperty float y\nproperty float z\nelement face %zu\n"
               "property list uchar int vertex_indices\nend_header\n",
               order, t.nodes.size(), t.faces.size() / 3);
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

}  // namespace

Result<void> writeSurfaceFrame(const std::string& path, const SurfaceTopology& topo,
                               std::span<const double> positions, SurfaceFormat format) {
  for (int32_t n : topo.nodes) {
    if (3 * static_cast<size_t>(n) + 2 >= positions.size()) {
      return fail(path, ": positions hold ", std::to_string(positions.size() / 3),
                  " nodes but the surface uses node ", std::to_string(n));
    }
  }
  std::unique_ptr<std::FILE, FileCloser> f(
      std::fopen(path.c_str(), format == SurfaceFormat::Obj ? "w" : "wb"));
  if (!f) return fail(path, ": cannot create: ", std::strerror(errno));
  if (format == SurfaceFormat::Obj) {
    writeObj(f.get(), topo, positions);
  } else {
    writePly(f.get(), topo, positions);
  }
  if (std::ferror(f.get()) || std::fclose(f.release()) != 0) {
    return fail(path, ": write error");
  }
  return {};
}

}  // namespace gf::cli
