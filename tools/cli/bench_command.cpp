// `graphfrac bench fracture`: the cost of fracture at run time (issue 3). The same body is
// stepped as plain FEM, with fracture on but nothing broken, with about a thousand broken
// edges, and with nearly every edge broken (a connected strip left), all in one process. The
// linear solver runs a fixed number of PCG iterations so the configurations do equal solver
// work and the differences are fracture's. Prints per-stage ms per step and the ratios.
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "graphfrac/world.h"

namespace gf::cli {
namespace {

struct Config {
  const char* name;
  bool fracture;
  int cutLevel;  // 0 none, 1 about a thousand edges, 2 all but a connected strip
};

struct Result {
  double total = 0, fracture = 0, elements = 0, assembly = 0, solve = 0;
  int broken = 0, fragments = 1, edges = 0;
};

// Planes normal to `axis` at the given coordinates, limited to y >= yMin.
void addPlanes(Blade& blade, int axis, const std::vector<float>& at, float yMin, float half) {
  for (float c : at) {
    const uint32_t base = uint32_t(blade.vertices.size());
    for (int k = 0; k < 4; ++k) {
      glm::vec3 v(0);
      v[axis] = c;
      const int u = (axis + 1) % 3, w = (axis + 2) % 3;
      v[u] = (k == 1 || k == 2) ? half : -half;
      v[w] = (k >= 2) ? half : -half;
      if (u == 1) v[u] = (k == 1 || k == 2) ? half : yMin;
      if (w == 1) v[w] = (k >= 2) ? half : yMin;
      blade.vertices.push_back(v);
    }
    for (uint32_t t : {0u, 1u, 2u, 0u, 2u, 3u}) blade.triangles.push_back(base + t);
  }
}

Result runConfig(const Config& cfg, int nx, int steps) {
  const int ny = nx / 4, nz = nx / 4;
  const double L = 1.0, H = 0.25;
  BodyDef def;
  def.mesh = gen::box(L, H, H, nx, ny, nz);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.solver.maxLinearIterations = 50;
  def.solver.linearTolerance = 1e-30;  // always the full 50 iterations
  def.fracture.enabled = cfg.fracture;
  def.fracture.strength = 1e12;  // only the cuts break edges
  Grip pin;
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
    if (def.mesh.positions[3 * n] < 1e-9) pin.nodes.push_back(int32_t(n));
  def.grips.push_back(pin);
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def).value();
  const float h = float(L / nx);
  if (cfg.cutLevel > 0) {
    Blade blade;
    std::vector<float> xs;
    if (cfg.cutLevel == 1) {
      // Four half-height planes: about a thousand edges for the default size.
      for (int q = 1; q <= 4; ++q) xs.push_back(float(q) * float(L) / 5 + 0.5f * h);
      addPlanes(blade, 0, xs, float(0.5 * H), 10);
    } else {
      for (int i = 0; i < nx; ++i) xs.push_back((float(i) + 0.5f) * h);
      std::vector<float> ys, zs;
      for (int j = 1; j < ny; ++j) ys.push_back((float(j) + 0.5f) * h);
      for (int k = 0; k < nz; ++k) zs.push_back((float(k) + 0.5f) * h);
      // Everything above the bottom layer of cells shatters; that layer stays connected.
      addPlanes(blade, 0, xs, 1.5f * h, 10);
      addPlanes(blade, 1, ys, 1.5f * h, 10);
      addPlanes(blade, 2, zs, 1.5f * h, 10);
    }
    (void)world.cut(id, blade);
  }
  (void)world.step(1.0 / 60);  // applies the cut; warm-up
  Result r;
  const auto t0 = std::chrono::steady_clock::now();
  for (int s = 0; s < steps; ++s) {
    (void)world.step(1.0 / 60);
    const StepTimings& t = world.timings();
    r.fracture += t.fractureMs;
    r.elements += t.elementsMs;
    r.assembly += t.assemblyMs;
    r.solve += t.solveMs;
  }
  r.total =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  for (double* v : {&r.total, &r.fracture, &r.elements, &r.assembly, &r.solve}) *v /= steps;
  const FractureStats fs = world.fractureStats(id);
  r.broken = fs.brokenEdges;
  r.fragments = fs.fragments;
  r.edges = fs.edgeCount;
  return r;
}

int benchFracture(int argc, char** argv) {
  int nx = 40, steps = 20;
  for (int i = 2; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--cells")) nx = std::max(4, std::atoi(argv[i + 1]));
    if (!std::strcmp(argv[i], "--steps")) steps = std::max(1, std::atoi(argv[i + 1]));
  }
  const Config configs[] = {{"plain FEM", false, 0},
                            {"fracture, 0 broken", true, 0},
                            {"fracture, ~1k broken", true, 1},
                            {"fracture, all but a strip", true, 2}};
  std::printf(
      "config,tets,edges,broken,fragments,ms_step,ms_fracture,ms_elements,ms_assembly,"
      "ms_solve\n");
  Result res[4];
  const int tets = nx * (nx / 4) * (nx / 4) * 6;
  for (int c = 0; c < 4; ++c) {
    res[c] = runConfig(configs[c], nx, steps);
    std::printf("%s,%d,%d,%d,%d,%.3f,%.3f,%.3f,%.3f,%.3f\n", configs[c].name, tets, res[c].edges,
                res[c].broken, res[c].fragments, res[c].total, res[c].fracture, res[c].elements,
                res[c].assembly, res[c].solve);
  }
  std::printf("overhead of fracture over plain FEM (nothing broken): %.1f %%\n",
              100 * (res[1].total / res[0].total - 1));
  std::printf("step time with ~1k broken / nothing broken: %.3f\n", res[2].total / res[1].total);
  std::printf("step time with all but a strip broken / nothing broken: %.3f\n",
              res[3].total / res[1].total);
  return kExitOk;
}

}  // namespace

int runBenchCommand(int argc, char** argv) {
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
    std::puts(
        "usage: graphfrac bench fracture [--cells NX] [--steps S]\n"
        "  NX cells along a 1 m x 0.25 m x 0.25 m beam (NX/4 across; default 40: 24k tets)");
    return argc < 2 ? kExitUsage : kExitOk;
  }
  if (!std::strcmp(argv[1], "fracture")) return benchFracture(argc, argv);
  std::fprintf(stderr, "graphfrac bench: unknown benchmark '%s'\n", argv[1]);
  return kExitUsage;
}

}  // namespace gf::cli
