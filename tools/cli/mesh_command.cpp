// `graphfrac mesh`: from-surface reads a triangle surface (OBJ and PLY by the CLI's own readers;
// STL, glTF, FBX, Collada and the rest through assimp, see surface_reader.h) and tetrahedralises
// it one of two ways. By default a closed surface goes to the tetgen program, and one that is open
// or that tetgen fails on (faces that cross) to the lattice mesher (lattice_mesher.h:
// winding-number inside test, cut grid, snapped boundary). tetgen runs as a subprocess (it is AGPL
// and never linked) on a .smesh written from it, whose .node/.ele are read back through the
// runtime's validated reader. tetgen answers bad input with an abort and no reason, so what it
// would fail on is checked here first and reported in the file's own terms (lines, vertex and face
// numbers): coordinates that overflow, open edges. Finding crossing faces takes a second tetgen
// run, so only a failed run is followed by `tetgen -d`, whose list of crossing facets is translated
// back to the file. info and convert are thin wrappers over gf::TetMesh.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "graphfrac/mesh.h"
#include "meshing/lattice_mesher.h"
#include "meshing/surface_reader.h"
#include "meshing/triangle_soup.h"

extern char** environ;

namespace gf::cli {
namespace {

using namespace gf::meshing;

namespace fs = std::filesystem;

constexpr const char* kUsage =
    "usage: graphfrac mesh from-surface IN OUT.msh [--method auto|tetgen|lattice]\n"
    "                                  [--cells N | --target-tets T]\n"
    "                                  [--max-volume V] [--quality Q]\n"
    "                                  [--scale S] [--up x|y|z] [--assimp]\n"
    "                                  [--tetgen PATH] [--keep-temp]\n"
    "         IN: a triangle surface: Wavefront OBJ (.obj) or PLY (.ply, ASCII or\n"
    "         binary); through assimp: STL, glTF 2.0 (.gltf, .glb), FBX, Collada (.dae),\n"
    "         3DS, OFF and the other formats assimp reads. All meshes of the scene are\n"
    "         merged with their node transforms; polygons are split into triangles,\n"
    "         points and lines skipped. The result is in metres, Y up: glTF is metres and\n"
    "         Y up, FBX's UnitScaleFactor and axis system and Collada's <unit> and\n"
    "         <up_axis> are applied, other formats are taken as metres and Y up.\n"
    "         --method M  tetgen: the tetgen program on a closed surface that does not\n"
    "                     intersect itself (keeps the surface's triangles; --max-volume\n"
    "                     and --quality are its -a and -q). lattice: any triangle soup,\n"
    "                     open, in many parts or self-intersecting: the inside is where\n"
    "                     the generalised winding number is >= 1/2; a grid of 6 tets per\n"
    "                     cube is cut to it and its boundary snapped towards the surface\n"
    "                     (features thinner than a cell may be lost). auto (default):\n"
    "                     tetgen for a closed surface, the lattice when the surface is\n"
    "                     open, when tetgen fails or when --cells/--target-tets is given.\n"
    "         --cells N   lattice cells along the longest axis (default 32, at most 256)\n"
    "         --target-tets T  lattice resolution for about T tets\n"
    "         --scale S   metres per file unit, instead of the file's unit\n"
    "         --up AXIS   the model's up axis (x, y or z), turned to +Y, instead of the\n"
    "                     file's\n"
    "         --assimp    read OBJ and PLY through assimp too (default: the CLI's own\n"
    "                     readers, whose errors name the line or element)\n"
    "         Prints tets, time, dihedral angles, radius ratios and, for the lattice, the\n"
    "         mesh's volume against the winding-number volume of the surface.\n"
    "       graphfrac mesh info FILE            (.msh, .node or .ele)\n"
    "       graphfrac mesh convert IN OUT       (IN .msh/.node/.ele; OUT .msh/.obj/.ply)\n";

// Problems listed in full are cut after this many lines, then "... and N more".
constexpr size_t kListed = 6;

// A tet's six-volume is a triple product of coordinate differences, at most 6 (2M)^3 < 64 M^3
// for coordinates up to M; above this M it overflows and every volume check reads inf.
const double kMaxCoordinate = std::cbrt(std::numeric_limits<double>::max() / 64);

int usage(const std::string& why) {
  std::fprintf(stderr, "graphfrac mesh: %s\n%s", why.c_str(), kUsage);
  return kExitUsage;
}

int failure(const std::string& why) {
  std::fflush(stdout);  // keep the order of what was printed before the error
  std::fprintf(stderr, "graphfrac mesh: error: %s\n", why.c_str());
  return kExitScene;
}

// "7 open edges" / "1 open edge".
std::string plural(size_t n, const std::string& what) {
  return std::to_string(n) + " " + what + (n == 1 ? "" : "s");
}

bool parseNumber(const std::string& s, double& v) { return numberProblem(s, v).empty(); }

// ---- the surface given to tetgen ---------------------------------------------------------

struct Surface {
  std::vector<double> positions;       // 3 per vertex
  std::vector<int32_t> triangles;      // 3 per triangle, 0-based
  std::vector<size_t> vertexSource;    // the file's vertex each one comes from (the first
                                       // of those merged)
  std::vector<size_t> triangleSource;  // the file's triangle each one comes from
  int mergedVertices = 0, droppedFaces = 0, unusedVertices = 0;
  size_t parts = 0;  // connected through shared vertices
  size_t openEdges = 0;
  std::string notClosed;  // why tetgen cannot take it (every open edge), "" when closed
};

size_t findRoot(std::vector<size_t>& parent, size_t i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

// Merges vertices with identical coordinates (OBJ exporters split them at UV seams), drops
// faces that become degenerate and vertices no face uses, then checks what tetgen needs but
// does not explain when missing: finite volumes (an error for every method) and a closed
// surface (noted in notClosed: the lattice method does not need it).
Result<Surface> prepareSurface(const SurfaceFile& f) {
  const size_t nv = f.vertexCount();
  if (nv > static_cast<size_t>(INT32_MAX)) return fail(f.path, ": too many vertices");
  std::vector<char> referenced(nv, 0);
  for (int64_t v : f.triangles) referenced[static_cast<size_t>(v)] = 1;
  for (size_t i = 0; i < nv; ++i) {
    for (size_t k = 0; referenced[i] && k < 3; ++k) {
      const double x = f.positions[3 * i + k];
      if (std::abs(x) > kMaxCoordinate) {
        return fail(f.vertexAt(i), ": coordinate ", std::string(1, char('x' + k)), " = ",
                    formatDouble(x), " is too large: above ", formatDouble(kMaxCoordinate),
                    " the volume of a tetrahedron overflows a double (scale the model down)");
      }
    }
  }

  Surface s;
  std::map<std::array<double, 3>, int32_t> unique;
  std::vector<int32_t> remap(nv);
  std::vector<double> merged;
  std::vector<size_t> mergedSource;
  for (size_t i = 0; i < nv; ++i) {
    const std::array<double, 3> p = {f.positions[3 * i], f.positions[3 * i + 1],
                                     f.positions[3 * i + 2]};
    auto [it, inserted] = unique.emplace(p, static_cast<int32_t>(merged.size() / 3));
    if (inserted) {
      merged.insert(merged.end(), p.begin(), p.end());
      mergedSource.push_back(i);
    }
    remap[i] = it->second;
  }
  s.mergedVertices = static_cast<int>(nv - merged.size() / 3);
  std::vector<int32_t> used(merged.size() / 3, -1);
  for (size_t t = 0; t < f.triangles.size() / 3; ++t) {
    int32_t tri[3];
    for (size_t k = 0; k < 3; ++k) tri[k] = remap[static_cast<size_t>(f.triangles[3 * t + k])];
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
      ++s.droppedFaces;
      continue;
    }
    for (int32_t& v : tri) {
      const size_t m = static_cast<size_t>(v);
      if (used[m] < 0) {
        used[m] = static_cast<int32_t>(s.positions.size() / 3);
        s.positions.insert(s.positions.end(), &merged[3 * m], &merged[3 * m] + 3);
        s.vertexSource.push_back(mergedSource[m]);
      }
      v = used[m];
    }
    s.triangles.insert(s.triangles.end(), tri, tri + 3);
    s.triangleSource.push_back(t);
  }
  s.unusedVertices = static_cast<int>(merged.size() / 3 - s.positions.size() / 3);
  if (s.triangles.empty()) return fail(f.path, ": all faces are degenerate");

  std::vector<size_t> parent(s.positions.size() / 3);
  std::iota(parent.begin(), parent.end(), size_t{0});
  std::map<std::pair<int32_t, int32_t>, std::pair<int, size_t>> edges;  // uses, first triangle
  for (size_t t = 0; t < s.triangles.size() / 3; ++t) {
    for (size_t k = 0; k < 3; ++k) {
      int32_t a = s.triangles[3 * t + k], b = s.triangles[3 * t + (k + 1) % 3];
      parent[findRoot(parent, static_cast<size_t>(a))] = findRoot(parent, static_cast<size_t>(b));
      if (a > b) std::swap(a, b);
      auto [it, inserted] = edges.emplace(std::make_pair(a, b), std::make_pair(0, t));
      ++it->second.first;
    }
  }
  for (size_t i = 0; i < parent.size(); ++i) s.parts += findRoot(parent, i) == i;

  // tetgen needs a closed surface; all the holes are listed at once, so that one round of
  // repair in a modeller is enough.
  std::vector<std::pair<size_t, std::pair<int32_t, int32_t>>> open;  // triangle, edge
  for (const auto& [edge, use] : edges) {
    if (use.first == 1) open.push_back({use.second, edge});
  }
  s.openEdges = open.size();
  if (open.empty()) return s;
  std::sort(open.begin(), open.end());  // in file order
  std::string why = f.path + ": surface is not closed: " + plural(open.size(), "open edge") +
                    " (on one face only), in " + plural(s.parts, "connected part") + ":";
  for (size_t i = 0; i < std::min(open.size(), kListed); ++i) {
    const auto [t, edge] = open[i];
    why += "\n  " + f.vertex(s.vertexSource[static_cast<size_t>(edge.first)]) + " - " +
           f.vertex(s.vertexSource[static_cast<size_t>(edge.second)]) + ", of the " +
           f.face(s.triangleSource[t]);
  }
  if (open.size() > kListed)
    why += "\n  ... and " + std::to_string(open.size() - kListed) + " more";
  s.notClosed = why;
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

// Runs `tetgen switches input` with stdout and stderr going to `log`; returns its wait status.
Result<int> runTetgen(const std::string& tetgen, const std::string& switches,
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
  return status;
}

// tetgen 1.5 aborts on faces that cross ("terminate called after throwing an instance of
// 'int'"); its -d switch lists them instead, as "Facet #A intersects facet #B", counting the
// .smesh facets from 1, each pair usually more than once. Returns the pairs in the file's terms,
// or "" when tetgen -d finds none (or cannot run): then the failure has another cause.
std::string crossingFaces(const std::string& tetgen, const std::string& smesh,
                          const std::string& log, const SurfaceFile& f, const Surface& s) {
  if (!runTetgen(tetgen, "-d", smesh, log)) return "";
  std::ifstream in(log);
  std::vector<std::pair<size_t, size_t>> pairs;
  std::set<std::pair<size_t, size_t>> seen;
  const size_t nt = s.triangles.size() / 3;
  for (std::string line; std::getline(in, line);) {
    size_t a = 0, b = 0;
    if (std::sscanf(line.c_str(), " Facet #%zu intersects facet #%zu", &a, &b) != 2) continue;
    if (a < 1 || b < 1 || a > nt || b > nt || a == b) continue;
    const std::pair<size_t, size_t> p(std::min(a, b) - 1, std::max(a, b) - 1);
    if (seen.insert(p).second) pairs.push_back(p);
  }
  if (pairs.empty()) return "";
  std::string why = f.path + ": surface intersects itself: " + plural(pairs.size(), "pair") +
                    " of faces cross (found by tetgen -d):";
  for (size_t i = 0; i < std::min(pairs.size(), kListed); ++i) {
    why += "\n  " + f.face(s.triangleSource[pairs[i].first]) + " and " +
           f.face(s.triangleSource[pairs[i].second]);
  }
  if (pairs.size() > kListed) {
    why += "\n  ... and " + std::to_string(pairs.size() - kListed) + " more";
  }
  return why;
}

std::string tetgenFailure(const std::string& switches, int status, const std::string& log) {
  std::string why = "tetgen " + switches;
  if (WIFSIGNALED(status)) {
    why += " crashed (signal " + std::to_string(WTERMSIG(status)) + ")";
  } else if (WIFEXITED(status) && WEXITSTATUS(status) != 0) {
    why += " failed (exit " + std::to_string(WEXITSTATUS(status)) + ")";
  } else {
    why += " produced no tetrahedra";
  }
  return why + "; its last output:\n" + tail(log, 12);
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

// What `--method` chooses.
enum class Method { kAuto, kTetgen, kLattice };

// The tetgen run: writes the .smesh, runs tetgen, reads its mesh back. Errors say what tetgen
// (or the surface, for crossing faces) got wrong; with --keep-temp they say where the files are.
struct TetgenRun {
  std::string tetgen = "tetgen";
  double maxVolume = 0, quality = 1.414;
  bool keep = false;
};

Result<TetMesh> tetgenMesh(const TetgenRun& run, const SurfaceFile& f, const Surface& s) {
  TempDir tmp;
  tmp.keep = run.keep;
  std::string pattern = (fs::temp_directory_path() / "graphfrac-mesh-XXXXXX").string();
  if (!mkdtemp(pattern.data()))
    return fail("cannot create a temporary directory: ", std::strerror(errno));
  tmp.path = pattern;
  // Said now and again with an error, so the files can be found however the run ends.
  if (run.keep) std::printf("temporary files in %s (kept: --keep-temp)\n", tmp.path.c_str());
  auto failed = [&](std::string why) {
    if (run.keep) why += "\n(temporary files kept in " + tmp.path + ")";
    return fail(why);
  };
  const std::string smesh = tmp.path + "/surface.smesh";
  if (Result<void> r = writeSmesh(s, smesh); !r) return failed(r.error().message);

  // p: tetrahedralise a piecewise linear complex; q: radius-edge bound; a: max volume.
  char sw[96];
  if (run.maxVolume > 0) {
    std::snprintf(sw, sizeof sw, "-pq%ga%g", run.quality, run.maxVolume);
  } else {
    std::snprintf(sw, sizeof sw, "-pq%g", run.quality);
  }
  const auto t1 = std::chrono::steady_clock::now();
  const std::string log = tmp.path + "/tetgen.log";
  Result<int> status = runTetgen(run.tetgen, sw, smesh, log);
  if (!status) return failed(status.error().message);
  const double tetgenSeconds = seconds(t1);

  const std::string node = tmp.path + "/surface.1.node", ele = tmp.path + "/surface.1.ele";
  const int st = status.value();
  if (!WIFEXITED(st) || WEXITSTATUS(st) != 0 || !fs::exists(ele)) {
    const std::string crossing =
        crossingFaces(run.tetgen, smesh, tmp.path + "/intersections.log", f, s);
    return failed(crossing.empty() ? tetgenFailure(sw, st, log) : crossing);
  }
  MeshLoadInfo info;
  Result<TetMesh> mesh = TetMesh::fromTetGen(node, ele, &info);
  if (!mesh) return failed("tetgen output is not a valid mesh: " + mesh.error().message);
  const TetMesh& m = mesh.value();
  std::printf("tetgen %s: %zu nodes, %zu tets, volume %.6g (%d tets reoriented), %.2f s tetgen\n",
              sw, m.nodeCount(), m.tetCount(), m.volume(), info.flippedFixed, tetgenSeconds);
  if (run.keep) std::printf("temporary files kept in %s\n", tmp.path.c_str());
  return mesh;
}

std::string firstLine(const std::string& s) { return s.substr(0, s.find('\n')); }

void printQuality(const TetMesh& m) {
  const TetQuality q = measureQuality(m);
  std::printf(
      "quality: dihedral angles %.1f .. %.1f deg, radius ratio min %.3f mean %.3f (1 = "
      "regular)\n",
      q.minDihedralDeg, q.maxDihedralDeg, q.minRadiusRatio, q.meanRadiusRatio);
}

Result<TetMesh> latticePath(const LatticeOptions& options, const Surface& s) {
  const TriangleSoup soup(s.positions, s.triangles);
  Result<LatticeResult> lr = latticeMesh(soup, options);
  if (!lr) return lr.error();
  LatticeResult& r = lr.value();
  const TetMesh& m = r.mesh;
  const int cells = std::max({r.dims[0], r.dims[1], r.dims[2]}) - 4;  // less the padding
  std::printf(
      "lattice: %d cells along the longest axis (cell %.4g), %zu nodes, %zu tets in %zu "
      "part%s; %zu tets added for a manifold boundary, %zu of %zu boundary nodes snapped; "
      "%.2f s\n",
      cells, r.cell, m.nodeCount(), m.tetCount(), r.parts, r.parts == 1 ? "" : "s", r.repairTets,
      r.snappedNodes, r.boundaryNodes, r.meshSeconds);
  printQuality(m);
  std::printf("volume: mesh %.6g, winding-number volume %.6g (ratio %.4f; sampled in %.2f s)",
              m.volume(), r.windingVolume, m.volume() / r.windingVolume, r.volumeSeconds);
  if (s.openEdges == 0) {
    std::printf(", closed surface's divergence-theorem volume %.6g", soup.signedVolume());
  }
  std::printf("\n");
  return std::move(r.mesh);
}

int fromSurface(const std::vector<std::string>& args) {
  std::string in, out;
  TetgenRun run;
  LatticeOptions lattice;
  Method method = Method::kAuto;
  SurfaceReadOptions read;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&](double& v) {
      if (i + 1 >= args.size() || !parseNumber(args[i + 1], v) || v <= 0) return false;
      ++i;
      return true;
    };
    if (a == "--max-volume") {
      if (!value(run.maxVolume)) return usage("--max-volume needs a positive number");
    } else if (a == "--quality") {
      if (!value(run.quality))
        return usage("--quality needs a positive number (radius-edge ratio)");
    } else if (a == "--method") {
      const std::string m = i + 1 < args.size() ? args[++i] : "";
      if (m == "auto") {
        method = Method::kAuto;
      } else if (m == "tetgen") {
        method = Method::kTetgen;
      } else if (m == "lattice") {
        method = Method::kLattice;
      } else {
        return usage("--method needs auto, tetgen or lattice");
      }
    } else if (a == "--cells") {
      double c = 0;
      if (!value(c) || c != std::floor(c) || c > kMaxCells) {
        return usage("--cells needs a whole number from 1 to " + std::to_string(kMaxCells));
      }
      lattice.cells = static_cast<int>(c);
    } else if (a == "--target-tets") {
      if (!value(lattice.targetTets)) return usage("--target-tets needs a positive number");
    } else if (a == "--scale") {
      if (!value(read.scale)) return usage("--scale needs a positive number (metres per unit)");
    } else if (a == "--up") {
      const std::string axis = i + 1 < args.size() ? args[i + 1] : "";
      if (axis != "x" && axis != "y" && axis != "z") return usage("--up needs x, y or z");
      read.up = axis[0];
      ++i;
    } else if (a == "--assimp") {
      if (!haveAssimp()) {
        return usage(
            "--assimp: this graphfrac was built without assimp (install libassimp-dev: "
            "tools/setup tools)");
      }
      read.assimp = true;
    } else if (a == "--tetgen") {
      if (i + 1 >= args.size()) return usage("--tetgen needs a path");
      run.tetgen = args[++i];
    } else if (a == "--keep-temp") {
      run.keep = true;
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
  if (in.empty() || out.empty()) return usage("from-surface needs IN (a surface) and OUT.msh");
  const bool latticeAsked = lattice.cells > 0 || lattice.targetTets > 0;
  if (method == Method::kTetgen && latticeAsked) {
    return usage("--cells and --target-tets are options of --method lattice (or auto)");
  }
  const auto t0 = std::chrono::steady_clock::now();

  Result<SurfaceFile> file = readSurfaceFile(in, read);
  if (!file) return failure(file.error().message);
  // What was read and how it was placed, before any complaint about the surface.
  const SurfaceFile& f = file.value();
  std::printf("read %s: %s; %s", in.c_str(), f.format.c_str(), f.conversion.c_str());
  if (f.skippedPoints || f.skippedLines) {
    std::printf("; skipped %zu points and %zu lines", f.skippedPoints, f.skippedLines);
  }
  std::printf("\n");
  Result<Surface> surface = prepareSurface(file.value());
  if (!surface) return failure(surface.error().message);
  const Surface& s = surface.value();
  std::printf("surface %s: %zu vertices, %zu triangles", in.c_str(), s.positions.size() / 3,
              s.triangles.size() / 3);
  if (s.parts > 1) std::printf(", %zu separate parts", s.parts);
  if (s.openEdges) std::printf(", %s", plural(s.openEdges, "open edge").c_str());
  if (s.mergedVertices || s.droppedFaces || s.unusedVertices) {
    std::printf(" (merged %d duplicate vertices, dropped %d degenerate faces, %d unused vertices)",
                s.mergedVertices, s.droppedFaces, s.unusedVertices);
  }
  std::printf("\n");

  // auto: tetgen for a closed surface (it keeps the surface's own triangles) unless a lattice
  // resolution was asked for; the lattice for an open one, or when tetgen fails.
  bool useLattice = method == Method::kLattice || (method == Method::kAuto && latticeAsked);
  if (!useLattice && !s.notClosed.empty()) {
    if (method == Method::kTetgen) return failure(s.notClosed);
    std::printf("surface is not closed (%s): using --method lattice\n",
                plural(s.openEdges, "open edge").c_str());
    useLattice = true;
  }
  Result<TetMesh> mesh = Error{};
  if (!useLattice) {
    mesh = tetgenMesh(run, f, s);
    if (!mesh) {
      if (method == Method::kTetgen) return failure(mesh.error().message);
      std::printf("tetgen cannot mesh it (%s): using --method lattice\n",
                  firstLine(mesh.error().message).c_str());
      useLattice = true;
    } else {
      printQuality(mesh.value());
    }
  }
  if (useLattice) {
    mesh = latticePath(lattice, s);
    if (!mesh) return failure(in + ": " + mesh.error().message);
  }
  if (Result<void> w = mesh.value().writeMsh(out); !w) return failure(w.error().message);
  std::printf("wrote %s (%.2f s in all)\n", out.c_str(), seconds(t0));
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
