// `graphfrac bench xfem`: the comparison of thesis chapters 3 and 6. The same box (2 x 1 x 1 m)
// is cut by the same 1, 5, 10 and 20 slanted planar blades with Is-XFEM (the standalone
// detail::XfemBody: enriched DOFs, linear elasticity, one Cholesky factorisation, CPU) and with
// graph cuts (the World: broken edges, stable neo-Hookean, its default solver). Per count of cuts
// it prints the cut's cost (XFEM: trace, cells, rules, assembly and factorisation; graph: the first
// step, which applies the cut), ms per step afterwards, the cut faces' largest distance from
// their blade plane, the pieces' volumes against the exact split, and (XFEM) the entries of the
// step matrix's Cholesky factor and the fill-reducing ordering chosen, and the render surface's
// cost per frame (XFEM: updateSurface; graph: World::surface after the step) with its triangle
// count (the XFEM surface's topology is built with the cut: surface_build_ms, inside cut_ms).
// The two step times are not
// the same physics (linear vs non-linear elasticity, a factorised vs an iterative solve), so the
// ratio says what each mode costs here, not which algorithm is faster in general.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

#include "cli/bench_args.h"
#include "cli/commands.h"
#include "cli/progress.h"
#include "graphfrac/world.h"
#include "xfem/cut_body.h"

namespace gf::cli {

namespace {

// Blade k of `count`: x = at + kB y + kC z, as two triangles well beyond the box.
constexpr double kB = 0.05, kC = 0.03;

double bladeAt(int k, int count) { return 0.013 + 2.0 * (k + 0.5) / count; }

CutPlane bladePlane(double at) {
  const double len = std::sqrt(1 + kB * kB + kC * kC);
  return {{1 / len, -kB / len, -kC / len}, at / len};
}

// Blade corners over y, z in [-1, 2], counter-clockwise in (y, z): normal along +x.
void bladeCorners(double at, double out[4][3]) {
  const double yz[4][2] = {{-1, -1}, {2, -1}, {2, 2}, {-1, 2}};
  for (int i = 0; i < 4; ++i) {
    out[i][0] = at + kB * yz[i][0] + kC * yz[i][1];
    out[i][1] = yz[i][0];
    out[i][2] = yz[i][1];
  }
}

// Volume of {x < a + kB y + kC z} inside the box's 1 x 1 section for x >= 0 and any a:
// integral over y, z in [0, 1] of max(0, a + kB y + kC z), by inclusion-exclusion of
// R(t) = max(t, 0)^3 / 6 at the section's corners (d^2 R / dy dz = kB kC max(t, 0)). A plane
// wholly at x >= 0 gives the mean-x formula without the formula's cancellation.
double beyondZero(double a) {
  if (a >= 0) return a + kB / 2 + kC / 2;
  if (a + kB + kC <= 0) return 0;
  const auto R = [](double t) { return t > 0 ? t * t * t / 6 : 0.0; };
  return (R(a + kB + kC) - R(a + kB) - R(a + kC) + R(a)) / (kB * kC);
}

// Exact pieces in order of x: slabs between consecutive planes, clipped to the box's x in
// [0, 2] (with 20 cuts the last plane leaves the box through its x = 2 face).
std::vector<double> exactPieces(int count) {
  std::vector<double> v;
  double prev = 0;
  for (int k = 0; k <= count; ++k) {
    const double a = bladeAt(k, count);
    const double below = k == count ? 2.0 : beyondZero(a) - beyondZero(a - 2);
    v.push_back(below - prev);
    prev = below;
  }
  return v;
}

double worstRelative(std::vector<double> got, const std::vector<double>& exact) {
  if (got.size() != exact.size()) return INFINITY;
  double worst = 0;
  for (size_t i = 0; i < got.size(); ++i)
    worst = std::max(worst, std::abs(got[i] - exact[i]) / std::abs(exact[i]));
  return worst;
}

struct ModeResult {
  double cutMs = 0, stepMs = 0, flat = 0, volume = 0;
  double surfaceMs = 0;       // per frame: the render surface brought up to the step's state
  double surfaceBuildMs = 0;  // XFEM: the surface's topology, inside cutMs
  int pieces = 0, cutElements = 0, dofs = 0, surfaceTriangles = 0;
  long long factorNonZeros = 0;  // XFEM only
  const char* ordering = "";
};

ModeResult runXfem(const TetMesh& mesh, int count, int steps, double dt) {
  detail::XfemBodyDef def;
  def.mesh = mesh;
  def.material = {1e7, 0.3, 1000};
  def.dt = dt;
  for (int k = 0; k < count; ++k) {
    double c[4][3];
    bladeCorners(bladeAt(k, count), c);
    detail::XfemBlade b;
    for (auto& p : c) b.blade.vertices.insert(b.blade.vertices.end(), {p[0], p[1], p[2]});
    b.blade.triangles = {0, 1, 2, 0, 2, 3};
    def.blades.push_back(b);
  }
  for (int32_t n = 0; n < int32_t(mesh.nodeCount()); ++n)
    if (mesh.positions[3 * size_t(n)] == 0) def.fixedNodes.push_back(n);
  ModeResult r;
  const auto t0 = std::chrono::steady_clock::now();
  auto made = detail::XfemBody::create(def);
  r.cutMs = msSince(t0);
  if (!made.ok()) {
    std::fprintf(stderr, "bench xfem: %s\n", made.error().message.c_str());
    r.pieces = -1;
    return r;
  }
  detail::XfemBody& body = *made.value();
  for (int s = 0; s < steps; ++s) {
    const auto t1 = std::chrono::steady_clock::now();
    body.step();
    r.stepMs += msSince(t1) / steps;
    // The surface's topology is built with the cut; a frame evaluates eq 3.4 at its vertices.
    const auto t2 = std::chrono::steady_clock::now();
    body.updateSurface();
    r.surfaceMs += msSince(t2) / steps;
  }
  for (const detail::XfemPieceSurface& s : body.surface())
    r.surfaceTriangles += int(s.triangles.size() / 3);
  r.surfaceBuildMs = body.surfaceBuildMs();
  for (const detail::XfemCutFace& f : body.cutFaces())
    for (int i = 0; i < f.polygon.count; ++i)
      r.flat = std::max(
          r.flat, std::abs(planeDistance(bladePlane(bladeAt(f.plane, count)), f.polygon.v[i])));
  // Pieces' masks count the planes passed (bits 0..k-1 set): order by that count.
  std::vector<std::pair<int, double>> pieces;
  for (const detail::XfemPiece& p : body.pieces())
    pieces.emplace_back(__builtin_popcount(p.mask), p.volume);
  std::sort(pieces.begin(), pieces.end());
  std::vector<double> volumes;
  for (const auto& p : pieces) volumes.push_back(p.second);
  r.volume = worstRelative(volumes, exactPieces(count));
  r.pieces = int(body.pieces().size());
  r.cutElements = body.cutTetCount();
  r.dofs = body.dofCount();
  r.factorNonZeros = body.factorInfo().factorNonZeros;
  r.ordering = body.factorInfo().ordering;
  return r;
}

ModeResult runGraph(const TetMesh& mesh, int count, int steps, double dt) {
  BodyDef def;
  def.mesh = mesh;
  def.material = Material::stableNeoHookean(1e7, 0.3, 1000);
  def.fracture.enabled = true;
  def.fracture.strength = 1e12;  // only the cuts break edges
  Grip pin;
  for (size_t n = 0; n < mesh.nodeCount(); ++n)
    if (mesh.positions[3 * n] == 0) pin.nodes.push_back(int32_t(n));
  def.grips.push_back(pin);
  Blade blade;
  for (int k = 0; k < count; ++k) {
    double c[4][3];
    bladeCorners(bladeAt(k, count), c);
    const uint32_t base = uint32_t(blade.vertices.size());
    for (auto& p : c) blade.vertices.emplace_back(float(p[0]), float(p[1]), float(p[2]));
    for (uint32_t t : {0u, 1u, 2u, 0u, 2u, 3u}) blade.triangles.push_back(base + t);
  }
  ModeResult r;
  {
    // Crack faces at rest: the same cut without gravity, so nothing has moved when measured.
    World still(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
    auto id = still.createBody(def);
    if (!id.ok() || !still.cut(id.value(), blade).ok()) {
      r.pieces = -1;
      return r;
    }
    (void)still.step(dt);
    const SurfaceView view = still.surface(id.value());
    for (size_t t = 0; t < view.crackMask.size(); ++t) {
      if (!view.crackMask[t]) continue;
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = view.indices[3 * t + size_t(k)];
        const Vec3 x{view.positions[3 * v], view.positions[3 * v + 1], view.positions[3 * v + 2]};
        double nearest = INFINITY;
        for (int j = 0; j < count; ++j)
          nearest = std::min(nearest, std::abs(planeDistance(bladePlane(bladeAt(j, count)), x)));
        r.flat = std::max(r.flat, nearest);
      }
    }
  }
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  if (!id.ok()) {
    r.pieces = -1;
    return r;
  }
  (void)world.surface(id.value());  // the render surface exists before the cut, as in a game
  const auto t0 = std::chrono::steady_clock::now();
  (void)world.cut(id.value(), blade);
  (void)world.step(dt);  // applies the cut
  (void)world.surface(id.value());
  r.cutMs = msSince(t0);
  // Fragments in order of x; volumes are their nodes' corner cells (the graph's split).
  const FractureStats fs = world.fractureStats(id.value());
  std::vector<std::pair<double, double>> frags;
  for (int32_t f = 0; f < fs.fragments; ++f) {
    auto info = world.fragmentInfo(id.value(), f);
    if (info.ok()) frags.emplace_back(info.value().centreOfMass.x, info.value().volume);
  }
  std::sort(frags.begin(), frags.end());
  std::vector<double> volumes;
  for (const auto& f : frags) volumes.push_back(f.second);
  r.volume = worstRelative(volumes, exactPieces(count));
  r.pieces = fs.fragments;
  r.cutElements = fs.brokenEdges;
  r.dofs = 3 * int(mesh.nodeCount());
  for (int s = 0; s < steps; ++s) {
    const auto t1 = std::chrono::steady_clock::now();
    (void)world.step(dt);
    r.stepMs += msSince(t1) / steps;
    const auto t2 = std::chrono::steady_clock::now();
    r.surfaceTriangles = int(world.surface(id.value()).indices.size() / 3);
    r.surfaceMs += msSince(t2) / steps;
  }
  return r;
}

}  // namespace

int benchXfem(int argc, char** argv) {
  int cells = 40, steps = 20;
  if (const int e = parseBenchArgs(
          "xfem", argc, argv,
          {{"--cells", &cells, 4, kBenchMaxCells}, {"--steps", &steps, 1, kBenchMaxCount}});
      e != kExitOk)
    return e;
  const TetMesh mesh = gen::box(2, 1, 1, cells, cells / 2, cells / 2);
  const double dt = 1.0 / 60;
  std::printf("# box 2 x 1 x 1 m, %d x %d x %d cells, %zu tets, %zu nodes; %d steps of %.4f s\n",
              cells, cells / 2, cells / 2, mesh.tetCount(), mesh.nodeCount(), steps, dt);
  std::printf(
      "cuts,mode,cut_ms,ms_per_step,dofs,cut_elements_or_broken_edges,pieces,"
      "cut_face_max_dist_m,piece_volume_max_rel_err,factor_nnz,ordering,surface_ms_per_frame,"
      "surface_triangles,surface_build_ms\n");
  for (int count : {1, 5, 10, 20}) {
    const ModeResult x = runXfem(mesh, count, steps, dt);
    const ModeResult g = runGraph(mesh, count, steps, dt);
    if (x.pieces < 0 || g.pieces < 0) return kExitScene;
    std::printf("%d,xfem,%.2f,%.3f,%d,%d,%d,%.2e,%.2e,%lld,%s,%.3f,%d,%.2f\n", count, x.cutMs,
                x.stepMs, x.dofs, x.cutElements, x.pieces, x.flat, x.volume, x.factorNonZeros,
                x.ordering, x.surfaceMs, x.surfaceTriangles, x.surfaceBuildMs);
    std::printf("%d,graph,%.2f,%.3f,%d,%d,%d,%.2e,%.2e,,,%.3f,%d,\n", count, g.cutMs, g.stepMs,
                g.dofs, g.cutElements, g.pieces, g.flat, g.volume, g.surfaceMs, g.surfaceTriangles);
    std::fflush(stdout);
  }
  return kExitOk;
}

}  // namespace gf::cli
