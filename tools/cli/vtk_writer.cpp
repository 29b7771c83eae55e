#include "cli/vtk_writer.h"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <utility>

namespace gf::cli {
namespace {

/// VTK's cell type id of a linear tetrahedron.
constexpr int kVtkTetra = 10;

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

/// Closes the file and reports a write error that happened at any point, naming the file.
Result<void> finish(File file, const std::string& path) {
  const bool bad = std::ferror(file.get()) != 0;
  const bool closeFailed = std::fclose(file.release()) != 0;
  if (bad || closeFailed) return fail(path, ": write error: ", std::strerror(errno));
  return {};
}

void writeDoubles(std::FILE* f, const char* name, int components, std::span<const double> v) {
  std::fprintf(f,
               "        <DataArray type=\"Float64\" Name=\"%s\" NumberOfComponents=\"%d\" "
               "format=\"ascii\">\n",
               name, components);
  for (size_t i = 0; i < v.size(); ++i) {
    // 12 significant digits: far below what a plot resolves, and a third smaller than 17.
    std::fprintf(f, (i + 1) % size_t(components) == 0 ? "%.12g\n" : "%.12g ", v[i]);
  }
  std::fputs("        </DataArray>\n", f);
}

}  // namespace

std::vector<double> nodeDamage(size_t nodeCount, std::span<const int32_t> edges,
                               std::span<const uint8_t> broken) {
  std::vector<double> damage(nodeCount, 0.0);
  std::vector<int32_t> incident(nodeCount, 0);
  const size_t count = std::min(edges.size() / 2, broken.size());
  for (size_t e = 0; e < count; ++e) {
    for (int k = 0; k < 2; ++k) {
      const int32_t n = edges[2 * e + size_t(k)];
      if (n < 0 || size_t(n) >= nodeCount) continue;
      ++incident[size_t(n)];
      if (broken[e] != 0) damage[size_t(n)] += 1;
    }
  }
  for (size_t n = 0; n < nodeCount; ++n)
    if (incident[n] > 0) damage[n] /= incident[n];
  return damage;
}

Result<void> writeVtu(const std::string& path, const VtuFrame& fr) {
  const size_t nodes = fr.positions.size() / 3;
  const size_t tets = fr.tets.size() / 4;
  if (fr.positions.size() != 3 * nodes || fr.rest.size() != 3 * nodes ||
      fr.velocities.size() != 3 * nodes || fr.tets.size() != 4 * tets ||
      fr.strain.size() != nodes || fr.damage.size() != nodes ||
      (!fr.fragment.empty() && fr.fragment.size() != nodes)) {
    return fail(path, ": the fields of the body disagree in size");
  }
  File file(std::fopen(path.c_str(), "w"));
  if (!file) return fail(path, ": cannot create: ", std::strerror(errno));
  std::FILE* f = file.get();
  std::fputs(
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
      "header_type=\"UInt64\">\n"
      "  <UnstructuredGrid>\n",
      f);
  std::fprintf(f, "    <Piece NumberOfPoints=\"%zu\" NumberOfCells=\"%zu\">\n", nodes, tets);
  std::fputs("      <PointData Vectors=\"displacement\" Scalars=\"damage\">\n", f);
  std::vector<double> u(fr.positions.begin(), fr.positions.end());
  for (size_t i = 0; i < u.size(); ++i) u[i] -= fr.rest[i];
  writeDoubles(f, "displacement", 3, u);
  writeDoubles(f, "velocity", 3, fr.velocities);
  writeDoubles(f, "strain", 1, fr.strain);
  writeDoubles(f, "damage", 1, fr.damage);
  std::fputs(
      "        <DataArray type=\"Int32\" Name=\"fragment\" NumberOfComponents=\"1\" "
      "format=\"ascii\">\n",
      f);
  for (size_t n = 0; n < nodes; ++n)
    std::fprintf(f, "%d\n", fr.fragment.empty() ? 0 : int(fr.fragment[n]));
  std::fputs("        </DataArray>\n      </PointData>\n      <Points>\n", f);
  writeDoubles(f, "points", 3, fr.positions);
  std::fputs("      </Points>\n      <Cells>\n", f);
  std::fputs("        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n", f);
  for (size_t t = 0; t < tets; ++t) {
    std::fprintf(f, "%d %d %d %d\n", int(fr.tets[4 * t]), int(fr.tets[4 * t + 1]),
                 int(fr.tets[4 * t + 2]), int(fr.tets[4 * t + 3]));
  }
  std::fputs("        </DataArray>\n", f);
  std::fputs("        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n", f);
  for (size_t t = 0; t < tets; ++t) std::fprintf(f, "%zu\n", 4 * (t + 1));
  std::fputs("        </DataArray>\n", f);
  std::fputs("        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n", f);
  for (size_t t = 0; t < tets; ++t) std::fprintf(f, "%d\n", kVtkTetra);
  std::fputs(
      "        </DataArray>\n"
      "      </Cells>\n"
      "    </Piece>\n"
      "  </UnstructuredGrid>\n"
      "</VTKFile>\n",
      f);
  return finish(std::move(file), path);
}

void PvdWriter::add(double time, int part, const std::string& file) {
  m_entries.push_back(Entry{time, part, file});
}

Result<void> PvdWriter::write(const std::string& path) const {
  File file(std::fopen(path.c_str(), "w"));
  if (!file) return fail(path, ": cannot create: ", std::strerror(errno));
  std::FILE* f = file.get();
  std::fputs(
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
      "  <Collection>\n",
      f);
  for (const Entry& e : m_entries) {
    std::fprintf(f, "    <DataSet timestep=\"%.17g\" group=\"\" part=\"%d\" file=\"%s\"/>\n",
                 e.time, e.part, e.file.c_str());
  }
  std::fputs("  </Collection>\n</VTKFile>\n", f);
  return finish(std::move(file), path);
}

}  // namespace gf::cli
