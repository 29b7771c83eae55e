// `graphfrac mesh`: from-surface runs the tetgen program as a subprocess (it is AGPL and never
// linked), on a .smesh written from the OBJ, and reads its .node/.ele back through the
// runtime's validated reader. info and convert are thin wrappers over gf::TetMesh.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "graphfrac/mesh.h"

extern char** environ;

namespace gf::cli {
namespace {

namespace fs = std::filesystem;

constexpr const char* kUsage =
    "usage: graphfrac mesh from-surface IN.obj OUT.msh [--max-volume V] [--quality Q]\n"
    "                                  [--tetgen PATH] [--keep-temp]\n"
    "       graphfrac mesh info FILE            (.msh, .node or .ele)\n"
    "       graphfrac mesh convert IN OUT       (IN .msh/.node/.ele; OUT .msh/.obj/.ply)\n";

int usage(const std::string& why) {
  std::fprintf(stderr, "graphfrac mesh: %s\n%s", why.c_str(), kUsage);
  return kExitUsage;
}

int failure(const std::string& why) {
  std::fflush(stdout);  // keep the order of what was printed before the error
  std::fprintf(stderr, "graphfrac mesh: error: %s\n", why.c_str());
  return kExitScene;
}

// ---- OBJ reading -------------------------------------------------------------------------

struct Surface {
  std::vector<double> positions;   // 3 per vertex
  std::vector<int32_t> triangles;  // 3 per triangle, 0-based
  int mergedVertices = 0, droppedFaces = 0, unusedVertices = 0;
};

bool parseNumber(const std::string& s, double& v) {
  const char* b = s.data();
  const char* e = b + s.size();
  if (b != e && *b == '+') ++b;
  auto [p, ec] = std::from_chars(b, e, v);
  return ec == std::errc() && p == e && b != e && std::isfinite(v);
}

bool parseIndex(const std::string& s, int64_t& v) {
  const std::string head = s.substr(0, s.find('/'));  // "i/t/n": the vertex index comes first
  const char* b = head.data();
  const char* e = b + head.size();
  auto [p, ec] = std::from_chars(b, e, v);
  return ec == std::errc() && p == e && b != e;
}

// Reads v and f lines; polygons become fans; vt, vn, groups and materials are ignored.
// Then merges vertices with identical coordinates, drops faces that become degenerate and
// vertices no face uses, so tetgen gets a clean closed surface.
Result<Surface> readObj(const std::string& path) {
  std::ifstream in(path);
  if (!in) return fail(path, ": cannot open");
  Surface s;
  std::vector<int> faceLine;  // line of each triangle, for index errors found at the end
  std::vector<int64_t> faceIdx;
  std::string line, tok;
  int ln = 0;
  while (std::getline(in, line)) {
    ++ln;
    const std::string where = path + ":" + std::to_string(ln) + ": ";
    std::istringstream ss(line);
    if (!(ss >> tok) || tok[0] == '#') continue;
    if (tok == "v") {
      double x[3];
      for (double& c : x) {
        if (!(ss >> tok) || !parseNumber(tok, c)) {
          return fail(where, "vertex needs 3 finite coordinates");
        }
      }
      s.positions.insert(s.positions.end(), x, x + 3);
    } else if (tok == "f") {
      std::vector<int64_t> poly;
      const int64_t nv = static_cast<int64_t>(s.positions.size() / 3);
      while (ss >> tok) {
        int64_t i = 0;
        if (!parseIndex(tok, i) || i == 0) return fail(where, "bad face index '", tok, "'");
        if (i < 0) {
          i += nv;  // relative to the vertices so far
          if (i < 0) return fail(where, "relative face index '", tok, "' points before vertex 1");
        } else {
          i -= 1;
        }
        poly.push_back(i);
      }
      if (poly.size() < 3) return fail(where, "face needs at least 3 vertices");
      for (size_t k = 1; k + 1 < poly.size(); ++k) {
        faceIdx.insert(faceIdx.end(), {poly[0], poly[k], poly[k + 1]});
        faceLine.push_back(ln);
      }
    }
  }
  if (in.bad()) return fail(path, ": read error");
  const int64_t nv = static_cast<int64_t>(s.positions.size() / 3);
  if (nv == 0) return fail(path, ": no vertices ('v' lines)");
  if (faceIdx.empty()) return fail(path, ": no faces ('f' lines)");
  for (size_t i = 0; i < faceIdx.size(); ++i) {
    if (faceIdx[i] >= nv) {
      return fail(path, ":", std::to_string(faceLine[i / 3]), ": face index ",
                  std::to_string(faceIdx[i] + 1), " exceeds the ", std::to_string(nv),
                  " vertices of the file");
    }
  }

  // Merge exact duplicates (OBJ exporters split vertices at UV seams).
  std::map<std::array<double, 3>, int32_t> unique;
  std::vector<int32_t> remap(static_cast<size_t>(nv));
  std::vector<double> merged;
  for (int64_t i = 0; i < nv; ++i) {
    const std::array<double, 3> p = {s.positions[3 * i], s.positions[3 * i + 1],
                                     s.positions[3 * i + 2]};
    auto [it, inserted] = unique.emplace(p, static_cast<int32_t>(merged.size() / 3));
    if (inserted) merged.insert(merged.end(), p.begin(), p.end());
    remap[static_cast<size_t>(i)] = it->second;
  }
  s.mergedVertices = static_cast<int>(nv - static_cast<int64_t>(merged.size() / 3));
  std::vector<int32_t> used(merged.size() / 3, -1);
  std::vector<double> compact;
  std::vector<int> keptLine;  // source line of each kept triangle
  for (size_t f = 0; f < faceIdx.size(); f += 3) {
    int32_t t[3];
    for (int k = 0; k < 3; ++k)
      t[k] = remap[static_cast<size_t>(faceIdx[f + static_cast<size_t>(k)])];
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
      ++s.droppedFaces;
      continue;
    }
    for (int32_t& v : t) {
      if (used[static_cast<size_t>(v)] < 0) {
        used[static_cast<size_t>(v)] = static_cast<int32_t>(compact.size() / 3);
        compact.insert(compact.end(), &merged[3 * static_cast<size_t>(v)],
                       &merged[3 * static_cast<size_t>(v)] + 3);
      }
      v = used[static_cast<size_t>(v)];
    }
    s.triangles.insert(s.triangles.end(), t, t + 3);
    keptLine.push_back(faceLine[f / 3]);
  }
  s.unusedVertices = static_cast<int>(merged.size() / 3 - compact.size() / 3);
  s.positions = std::move(compact);
  if (s.triangles.empty()) return fail(path, ": all faces are degenerate");

  // tetgen needs a closed surface; an edge on one face only is a hole, found here with a
  // line number instead of as an empty tetgen output.
  std::map<std::pair<int32_t, int32_t>, std::pair<int, size_t>> edges;  // uses, first face
  for (size_t f = 0; f < s.triangles.size(); f += 3) {
    for (int k = 0; k < 3; ++k) {
      int32_t a = s.triangles[f + static_cast<size_t>(k)],
              b = s.triangles[f + static_cast<size_t>(k + 1) % 3];
      if (a > b) std::swap(a, b);
      auto [it, inserted] = edges.emplace(std::make_pair(a, b), std::make_pair(0, f / 3));
      ++it->second.first;
    }
  }
  for (const auto& [edge, use] : edges) {
    if (use.first == 1) {
      return fail(path, ": surface is not closed: an edge of the face on line ",
                  std::to_string(keptLine[use.second]), " belongs to no other face");
    }
  }
  return s;
}

// ---- tetgen subprocess -------------------------------------------------------------------

Result<void> writeSmesh(const Surface& s, const std::string& path) {
  std::ofstream out(path);
  if (!out) return fail(path, ": cannot write the temporary surface");
  char buf[128];
  out << "# part 1: nodes\n" << s.positions.size() / 3 << " 3 0 0\n";
  for (size_t i = 0; i < s.positions.size() / 3; ++i) {
    std::snprintf(buf, sizeof buf, "%zu %.17g %.17g %.17g\n", i + 1, s.positions[3 * i],
                  s.positions[3 * i + 1], s.positions[3 * i + 2]);
    out << buf;
  }
  out << "# part 2: facets\n" << s.triangles.size() / 3 << " 0\n";
  for (size_t f = 0; f < s.triangles.size(); f += 3) {
    out << "3 " << s.triangles[f] + 1 << ' ' << s.triangles[f + 1] + 1 << ' '
        << s.triangles[f + 2] + 1 << '\n';
  }
  out << "# part 3: holes\n0\n# part 4: regions\n0\n";
  out.flush();
  if (!out) return fail(path, ": write failed");
  return {};
}

std::string tail(const std::string& path, size_t lines) {
  std::ifstream in(path);
  std::vector<std::string> all;
  std::string l;
  while (std::getline(in, l)) all.push_back(l);
  std::string out;
  for (size_t i = all.size() > lines ? all.size() - lines : 0; i < all.size(); ++i)
    out += "    " + all[i] + "\n";
  return out;
}

// Runs `tetgen switches input` with stdout and stderr going to `log`.
Result<void> runTetgen(const std::string& tetgen, const std::string& switches,
                       const std::string& input, const std::string& log) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  std::vector<std::string> args = {tetgen, switches, input};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, tetgen.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    if (rc == ENOENT) {
      return fail("tetgen program '", tetgen,
                  "' not found (install the Debian package 'tetgen', or pass --tetgen PATH)");
    }
    return fail("cannot run '", tetgen, "': ", std::strerror(rc));
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return fail("waiting for tetgen failed: ", std::strerror(errno));
  }
  if (WIFSIGNALED(status)) {
    return fail("tetgen ", switches, " crashed (signal ", std::to_string(WTERMSIG(status)),
                "); its last output:\n", tail(log, 12));
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    return fail("tetgen ", switches, " failed (exit ", std::to_string(WEXITSTATUS(status)),
                "; is the surface closed and free of self-intersections?); its last output:\n",
                tail(log, 12));
  }
  return {};
}

struct TempDir {
  std::string path;
  bool keep = false;
  ~TempDir() {
    if (!path.empty() && !keep) {
      std::error_code ec;
      fs::remove_all(path, ec);
    }
  }
};

double seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

int fromSurface(const std::vector<std::string>& args) {
  std::string in, out, tetgen = "tetgen";
  double maxVolume = 0, quality = 1.414;
  bool keep = false;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&](double& v) {
      if (i + 1 >= args.size() || !parseNumber(args[i + 1], v) || v <= 0) return false;
      ++i;
      return true;
    };
    if (a == "--max-volume") {
      if (!value(maxVolume)) return usage("--max-volume needs a positive number");
    } else if (a == "--quality") {
      if (!value(quality)) return usage("--quality needs a positive number (radius-edge ratio)");
    } else if (a == "--tetgen") {
      if (i + 1 >= args.size()) return usage("--tetgen needs a path");
      tetgen = args[++i];
    } else if (a == "--keep-temp") {
      keep = true;
    } else if (a.rfind("--", 0) == 0) {
      return usage("unknown option " + a);
    } else if (in.empty()) {
      in = a;
    } else if (out.empty()) {
      out = a;
    } else {
      return usage("unexpected argument " + a);
    }
  }
  if (in.empty() || out.empty()) return usage("from-surface needs IN.obj and OUT.msh");
  const auto t0 = std::chrono::steady_clock::now();

  Result<Surface> surface = readObj(in);
  if (!surface) return failure(surface.error().message);
  const Surface& s = surface.value();
  std::printf("surface %s: %zu vertices, %zu triangles", in.c_str(), s.positions.size() / 3,
              s.triangles.size() / 3);
  if (s.mergedVertices || s.droppedFaces || s.unusedVertices) {
    std::printf(" (merged %d duplicate vertices, dropped %d degenerate faces, %d unused vertices)",
                s.mergedVertices, s.droppedFaces, s.unusedVertices);
  }
  std::printf("\n");

  TempDir tmp;
  tmp.keep = keep;
  std::string pattern = (fs::temp_directory_path() / "graphfrac-mesh-XXXXXX").string();
  if (!mkdtemp(pattern.data()))
    return failure(std::string("cannot create a temporary directory: ") + std::strerror(errno));
  tmp.path = pattern;
  const std::string smesh = tmp.path + "/surface.smesh";
  if (Result<void> r = writeSmesh(s, smesh); !r) return failure(r.error().message);

  // p: tetrahedralise a piecewise linear complex; q: radius-edge bound; a: max volume.
  char sw[96];
  if (maxVolume > 0) {
    std::snprintf(sw, sizeof sw, "-pq%ga%g", quality, maxVolume);
  } else {
    std::snprintf(sw, sizeof sw, "-pq%g", quality);
  }
  const auto t1 = std::chrono::steady_clock::now();
  if (Result<void> r = runTetgen(tetgen, sw, smesh, tmp.path + "/tetgen.log"); !r) {
    return failure(r.error().message);
  }
  const double tetgenSeconds = seconds(t1);

  const std::string node = tmp.path + "/surface.1.node", ele = tmp.path + "/surface.1.ele";
  if (!fs::exists(ele)) {
    return failure(
        "tetgen produced no tetrahedra (is the surface closed and free of "
        "self-intersections?); its last output:\n" +
        tail(tmp.path + "/tetgen.log", 12));
  }
  MeshLoadInfo info;
  Result<TetMesh> mesh = TetMesh::fromTetGen(node, ele, &info);
  if (!mesh) return failure("tetgen output is not a valid mesh: " + mesh.error().message);
  if (Result<void> w = mesh.value().writeMsh(out); !w) return failure(w.error().message);
  const TetMesh& m = mesh.value();
  std::printf(
      "tetgen %s: %zu nodes, %zu tets, volume %.6g (%d tets reoriented), %.2f s tetgen, %.2f s "
      "total\n",
      sw, m.nodeCount(), m.tetCount(), m.volume(), info.flippedFixed, tetgenSeconds, seconds(t0));
  std::printf("wrote %s\n", out.c_str());
  if (keep) std::printf("temporary files kept in %s\n", tmp.path.c_str());
  return kExitOk;
}

int info(const std::vector<std::string>& args) {
  if (args.size() != 1) return usage("info needs exactly one FILE");
  MeshLoadInfo li;
  Result<TetMesh> r = TetMesh::fromFile(args[0], &li);
  if (!r) return failure(r.error().message);
  const TetMesh& m = r.value();
  double lo[3], hi[3];
  for (int k = 0; k < 3; ++k) lo[k] = hi[k] = m.positions[static_cast<size_t>(k)];
  for (size_t i = 0; i < m.nodeCount(); ++i) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], m.positions[3 * i + static_cast<size_t>(k)]);
      hi[k] = std::max(hi[k], m.positions[3 * i + static_cast<size_t>(k)]);
    }
  }
  double vmin = INFINITY, vmax = 0, emin = INFINITY, emax = 0;
  for (size_t e = 0; e < m.tetCount(); ++e) {
    const int32_t* t = &m.tets[4 * e];
    const double* p[4];
    for (int k = 0; k < 4; ++k) p[k] = &m.positions[3 * static_cast<size_t>(t[k])];
    double d[3][3];
    for (int a = 0; a < 3; ++a) {
      for (int k = 0; k < 3; ++k) d[a][k] = p[a + 1][k] - p[0][k];
    }
    const double v = (d[0][0] * (d[1][1] * d[2][2] - d[1][2] * d[2][1]) -
                      d[0][1] * (d[1][0] * d[2][2] - d[1][2] * d[2][0]) +
                      d[0][2] * (d[1][0] * d[2][1] - d[1][1] * d[2][0])) /
                     6.0;
    vmin = std::min(vmin, v);
    vmax = std::max(vmax, v);
    for (int a = 0; a < 4; ++a) {
      for (int b = a + 1; b < 4; ++b) {
        const double l = std::hypot(p[a][0] - p[b][0], p[a][1] - p[b][1], p[a][2] - p[b][2]);
        emin = std::min(emin, l);
        emax = std::max(emax, l);
      }
    }
  }
  std::printf("file          %s\n", args[0].c_str());
  std::printf("nodes         %zu\n", m.nodeCount());
  std::printf("tets          %zu\n", m.tetCount());
  std::printf("boundary      %zu triangles\n", m.boundaryFaces().size() / 3);
  std::printf("volume        %.9g\n", m.volume());
  std::printf("bbox          [%g %g %g] - [%g %g %g] (size %g x %g x %g)\n", lo[0], lo[1], lo[2],
              hi[0], hi[1], hi[2], hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  std::printf("tet volume    %.4g .. %.4g\n", vmin, vmax);
  std::printf("edge length   %.4g .. %.4g\n", emin, emax);
  std::printf("validation    ok (%d flipped tets reoriented on load)\n", li.flippedFixed);
  return kExitOk;
}

int convert(const std::vector<std::string>& args) {
  if (args.size() != 2) return usage("convert needs IN and OUT");
  Result<TetMesh> r = TetMesh::fromFile(args[0]);
  if (!r) return failure(r.error().message);
  std::string ext = fs::path(args[1]).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  Result<void> w = ext == ".msh" ? r.value().writeMsh(args[1]) : r.value().writeSurface(args[1]);
  if (!w) return failure(w.error().message);
  std::printf("wrote %s (%zu nodes, %zu tets)\n", args[1].c_str(), r.value().nodeCount(),
              r.value().tetCount());
  return kExitOk;
}

}  // namespace

int runMeshCommand(int argc, char** argv) {
  if (argc < 2) return usage("missing subcommand");
  const std::string cmd = argv[1];
  const std::vector<std::string> args(argv + 2, argv + argc);
  if (cmd == "from-surface") return fromSurface(args);
  if (cmd == "info") return info(args);
  if (cmd == "convert") return convert(args);
  if (cmd == "help" || cmd == "--help" || cmd == "-h") {
    std::printf("%s", kUsage);
    return kExitOk;
  }
  return usage("unknown subcommand '" + cmd + "'");
}

}  // namespace gf::cli
