// `graphfrac bench fracture`: the cost of fracture at run time, per stage. The same body is
// stepped as plain FEM, with fracture on but nothing broken, with about a thousand broken
// edges, and with nearly every edge broken (a connected strip left), all in one process. The
// linear solver runs a fixed number of PCG iterations so the configurations do equal solver
// work and the differences are fracture's. Prints per-stage ms per step and the ratios.
// `graphfrac bench multigrid`: per-stage ms and fps of the default multigrid and PCG
// settings on the thesis's chapter-6 bodies at 4k, 28k, 35k and 160k tets; --mg adds other
// multigrid settings to the same run. Beside the wall clock it prints the process's CPU time
// per frame (on a loaded machine the fairer figure), each multigrid setting's residual
// reduction per V-cycle and the frames whose solve stopped short of its tolerance.
// `graphfrac bench overhead`: what the World API costs on top of the solver: World::step of a
// pure-deformation body against the raw integrator step it wraps, in alternating rounds on
// one thread.
// `graphfrac bench options`: the per-step cost of the step's options (the turning frame,
// numerical damping, the fracture averaging in edge lengths or metres) against the default, in
// alternating rounds.
// `graphfrac bench stages`: per-stage ms per frame (fracture, elements, assembly,
// solve, contact, surface, Bullet) of whole scenes run through the Bullet bridge, the glass bunny
// hit by a Bullet ball and the Charpy bar by default. `graphfrac bench debris`: 200 small boxes
// falling onto the ground against one box of the same tet count, at 1 and 2 threads in one run, and
// the OS threads the process holds. `graphfrac bench contact`: body-body contact's cost. Boxes
// falling side by side onto the ground, never touching, with BodyDef::contact on and off in
// alternating rounds (the ratio is what a scene without contact pairs pays); then columns of boxes
// stacked on each other, where the contact stage's ms over its pairs is the cost per pair.
// `graphfrac bench xfem`: Is-XFEM against graph cuts on the same box and blades (bench_xfem.cpp).
// `graphfrac bench haptic`: the cost of a haptic sample against the surface size
// (bench_haptic.cpp).
// `graphfrac bench peer`: graphfrac beside Bullet's deformable FEM (bench_peer.cpp).
// `graphfrac bench fragments`: fragment labelling on recorded break steps (bench_fragments.cpp).
// `graphfrac bench scenes`: the fixed 4k-680k scene list with fracture off and on
// (bench_scenes.cpp).
#include <dirent.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "cli/args.h"
#include "cli/bench_args.h"
#include "cli/bench_cases.h"
#include "cli/commands.h"
#include "cli/progress.h"
#include "fem/fem_body.h"
#include "fem/integrator.h"
#include "graphfrac/jobs.h"
#include "graphfrac/world.h"
#include "scene/scene.h"
#include "world/backend.h"
#ifdef GF_CLI_HAS_BULLET
#include "scene/bullet_scene.h"
#endif

namespace gf::cli {

int benchXfem(int argc, char** argv);       // bench_xfem.cpp
int benchHaptic(int argc, char** argv);     // bench_haptic.cpp
int benchPeer(int argc, char** argv);       // bench_peer.cpp
int benchFragments(int argc, char** argv);  // bench_fragments.cpp
int benchScenes(int argc, char** argv);     // bench_scenes.cpp

namespace {

// The backend every benchmark's worlds ask for (--backend; the CPU unless told).
Backend g_backend = Backend::Cpu;

struct Config {
  const char* name;
  bool fracture;
  int cutLevel;             // 0 none, 1 about a thousand edges, 2 all but a connected strip
  bool impurities = false;  // random-graph impurities (sigma 3, degradation)
};

struct ConfigResult {
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

ConfigResult runConfig(const Config& cfg, int nx, int steps) {
  const int ny = nx / 4, nz = nx / 4;
  const double L = 1.0, H = 0.25;
  BodyDef def;
  def.mesh = gen::box(L, H, H, nx, ny, nz);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.solver.linearSolver = LinearSolverKind::PCG;  // equal solver work in every config
  def.solver.maxLinearIterations = 50;
  def.solver.linearTolerance = 1e-30;  // always the full 50 iterations
  def.fracture.enabled = cfg.fracture;
  def.fracture.strength = 1e12;  // only the cuts break edges
  def.fracture.impurities.enabled = cfg.impurities;
  def.fracture.impurities.sigma = 3;
  Grip pin;
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
    if (def.mesh.positions[3 * n] < 1e-9) pin.nodes.push_back(int32_t(n));
  def.grips.push_back(pin);
  World world(WorldDef{glm::vec3(0, -9.81f, 0), g_backend, nullptr, 1, {}});
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
  ConfigResult r;
  const auto t0 = std::chrono::steady_clock::now();
  for (int s = 0; s < steps; ++s) {
    (void)world.step(1.0 / 60);
    const StepTimings& t = world.timings();
    r.fracture += t.fractureMs;
    r.elements += t.elementsMs;
    r.assembly += t.assemblyMs;
    r.solve += t.solveMs;
  }
  r.total = msSince(t0);
  for (double* v : {&r.total, &r.fracture, &r.elements, &r.assembly, &r.solve}) *v /= steps;
  const FractureStats fs = world.fractureStats(id);
  r.broken = fs.brokenEdges;
  r.fragments = fs.fragments;
  r.edges = fs.edgeCount;
  return r;
}

int benchFracture(int argc, char** argv) {
  int nx = 40, steps = 20;
  if (const int e = parseBenchArgs(
          "fracture", argc, argv,
          {{"--cells", &nx, 4, kBenchMaxCells}, {"--steps", &steps, 1, kBenchMaxCount}});
      e != kExitOk)
    return e;
  const Config configs[] = {{"plain FEM", false, 0},
                            {"fracture, 0 broken", true, 0},
                            {"fracture, ~1k broken", true, 1},
                            {"fracture, all but a strip", true, 2},
                            {"fracture + impurities, 0 broken", true, 0, true},
                            {"fracture + impurities, ~1k broken", true, 1, true}};
  std::printf(
      "config,tets,edges,broken,fragments,ms_step,ms_fracture,ms_elements,ms_assembly,"
      "ms_solve\n");
  ConfigResult res[6];
  const int tets = nx * (nx / 4) * (nx / 4) * 6;
  for (int c = 0; c < 6; ++c) {
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
  // Impurities act only through the edge strengths, so a step costs the same with them; only
  // the steps that break edges update the strengths around the breaks.
  std::printf("step time with impurities / without, nothing broken: %.3f\n",
              res[4].total / res[1].total);
  std::printf("step time with impurities / without, ~1k broken: %.3f\n",
              res[5].total / res[2].total);
  return kExitOk;
}

// Residual reduction per V-cycle of a multigrid setting on the case's first step, from two
// fresh worlds that cycle alone ("cycles" mode, no early stop) 1 and kProbeCycles times: the
// first step's system is the same in both, so (r_1 / r_k)^(1 / (k - 1)) is the geometric mean
// factor of the cycles after the first, as in the slow tests' beams. 0 when not a multigrid.
double vcycleReduction(const scene::Scene& sc, const scene::SceneBody& body) {
  constexpr int kProbeCycles = 6;
  if (body.def.solver.linearSolver != LinearSolverKind::Multigrid) return 0;
  double residual[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    scene::SceneBody b = body;
    b.def.solver.multigrid.preconditionCG = false;
    b.def.solver.multigrid.cycles = k == 0 ? 1 : kProbeCycles;
    b.def.solver.linearTolerance = 1e-300;
    WorldDef wdef = sc.world;
    wdef.jobs = nullptr;
    wdef.backend = g_backend;
    World world(wdef);
    if (!scene::addBody(world, b).ok()) return 0;
    residual[k] = world.step(sc.dt).residual;
  }
  return residual[1] > 0 ? std::pow(residual[0] / residual[1], 1.0 / (kProbeCycles - 1)) : 0;
}

int benchMultigrid(int argc, char** argv) {
  int frames = 10;
  std::vector<int> threadCounts = {1, 2};
  std::string only;
  // Extra multigrid settings (--mg JSON, repeatable: a solver.multigrid object) run beside the
  // defaults, so a candidate and the default are timed in one run; --pcg 0 skips PCG.
  std::vector<std::string> extra;
  int pcg = 1;
  if (const int e = parseBenchArgs("multigrid", argc, argv,
                                   {{"--frames", &frames, 1, kBenchMaxCount},
                                    {"--threads", &threadCounts, 0, kBenchMaxThreads},
                                    {"--only", &only},
                                    {"--mg", &extra},
                                    {"--pcg", &pcg, 0, 1}});
      e != kExitOk)
    return e;
  const bool withPcg = pcg != 0;
  if (const std::string e = only.empty() ? "" : unknownBenchCase(only, false); !e.empty()) {
    std::fprintf(stderr, "bench multigrid: %s\n", e.c_str());
    return kExitUsage;
  }
  // Every thread count runs in this process, one after the other per case and solver, so the
  // speed-ups are ratios measured in one run.
  std::vector<std::unique_ptr<JobSystem>> pools;
  std::string counts;
  for (int t : threadCounts) {
    pools.push_back(t == 1 ? nullptr : std::make_unique<ThreadPoolJobSystem>(t));
    counts += (counts.empty() ? "" : ", ") +
              std::to_string(pools.back() ? pools.back()->threadCount() : 1);
  }
  std::printf(
      "# %d frame(s) after one warm-up frame, on %s CPU thread(s); speedup: ms_frame on the "
      "first thread count over this one; thesis fps: one RTX 2060 GPU (table 6.2)\n",
      frames, counts.c_str());
  std::printf(
      "case,solver,tets,threads,ms_frame,fps,speedup,ms_elements,ms_assembly,ms_solve,"
      "ms_fracture,linear_iterations,thesis_gpu_fps,cpu_ms_frame,vcycle_reduction,"
      "unconverged_frames\n");
  std::printf(
      "# cpu_ms_frame: process CPU time per frame (all threads; robust to other jobs on the "
      "machine); vcycle_reduction: residual reduction per V-cycle on the first step (multigrid "
      "only, cycles after the first); unconverged_frames: frames whose linear solve stopped short "
      "of its tolerance (a setting that wins by not converging is no win)\n");
  std::vector<std::array<std::string, 2>> solvers = {
      {"multigrid (default)", R"({"linear": "multigrid"})"}};
  if (withPcg) solvers.push_back({"pcg (default)", R"({"linear": "pcg"})"});
  for (size_t k = 0; k < extra.size(); ++k) {
    solvers.push_back({"multigrid (mg " + std::to_string(k + 1) + ")",
                       R"({"linear": "multigrid", "multigrid": )" + extra[k] + "}"});
    std::printf("# mg %zu: %s\n", k + 1, extra[k].c_str());
  }
  for (const BenchCase& c : benchCases()) {
    if (c.big || (!only.empty() && only != c.name)) continue;
    for (const auto& sv : solvers) {
      const std::string text = benchSceneText(c, sv[1], c.multigridBreaks);
      gf::Result<scene::Scene> sc = scene::parseScene(text, c.name, "");
      if (!sc.ok()) {
        std::fprintf(stderr, "%s\n", sc.error().message.c_str());
        return kExitScene;
      }
      double firstMs = 0;
      const double reduction = vcycleReduction(sc.value(), sc.value().bodies[0]);
      for (const std::unique_ptr<JobSystem>& jobs : pools) {
        WorldDef wdef = sc.value().world;
        wdef.jobs = jobs.get();
        wdef.backend = g_backend;
        World world(wdef);
        const size_t tets = sc.value().bodies[0].def.mesh.tetCount();
        gf::Result<BodyId> id = scene::addBody(world, sc.value().bodies[0]);
        if (!id.ok()) {
          std::fprintf(stderr, "%s: %s\n", c.name, id.error().message.c_str());
          return kExitScene;
        }
        const double dt = sc.value().dt;
        (void)world.step(dt);  // warm-up: first-use allocations
        double elements = 0, assembly = 0, solve = 0, fracture = 0;
        long linear = 0;
        int unconverged = 0;
        const double cpu0 = processCpuMs();
        const auto t0 = std::chrono::steady_clock::now();
        for (int f = 0; f < frames; ++f) {
          const StepStatus st = world.step(dt);
          linear += st.linearIterations;
          unconverged += st.has(kStepNotConverged) ? 1 : 0;
          const StepTimings& t = world.timings();
          elements += t.elementsMs;
          assembly += t.assemblyMs;
          solve += t.solveMs;
          fracture += t.fractureMs;
        }
        const double ms = msSince(t0) / frames;
        const double cpuMs = (processCpuMs() - cpu0) / frames;
        if (firstMs == 0) firstMs = ms;
        std::printf("%s,%s,%zu,%d,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.1f,%s,%.2f,%.2f,%d\n",
                    c.name, sv[0].c_str(), tets, jobs ? jobs->threadCount() : 1, ms, 1000 / ms,
                    firstMs / ms, elements / frames, assembly / frames, solve / frames,
                    fracture / frames, double(linear) / frames, c.thesisFps, cpuMs, reduction,
                    unconverged);
        std::fflush(stdout);
      }
    }
  }
  return kExitOk;
}

// A clamped beam sagging under gravity: no fracture, plasticity, fibres or render surface.
BodyDef overheadBody(int nx) {
  BodyDef def;
  def.mesh = gen::box(1.0, 0.25, 0.25, nx, std::max(1, nx / 4), std::max(1, nx / 4));
  def.material = Material::stableNeoHookean(1e6, 0.4, 1000);
  Grip clamp;
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
    if (def.mesh.positions[3 * n] < 1e-9) clamp.nodes.push_back(int32_t(n));
  def.grips.push_back(clamp);
  return def;
}

int benchOverhead(int argc, char** argv) {
  int nx = 24, steps = 10, rounds = 7;
  if (const int e = parseBenchArgs("overhead", argc, argv,
                                   {{"--cells", &nx, 4, kBenchMaxCells},
                                    {"--steps", &steps, 1, kBenchMaxCount},
                                    {"--rounds", &rounds, 1, kBenchMaxCount}});
      e != kExitOk)
    return e;
  const double dt = 1.0 / 60;
  const BodyDef def = overheadBody(nx);
  const detail::FemModel model = detail::buildFemModel(def);
  detail::FemState state = detail::buildFemState(def, model);
  detail::Integrator integrator(model);
  if (Result<void> r = integrator.setupSolver(model, state); !r.ok()) {
    std::fprintf(stderr, "bench overhead: %s\n", r.error().message.c_str());
    return kExitScene;
  }
  detail::StepContext ctx;
  ctx.dt = dt;
  ctx.gravity = {0, -9.81f, 0};  // as WorldDef's float gravity, so both runs see the same bits

  World world(WorldDef{glm::vec3(0, -9.81f, 0), g_backend, nullptr, 1, {}});
  gf::Result<BodyId> id = world.createBody(def);
  if (!id.ok()) {
    std::fprintf(stderr, "bench overhead: %s\n", id.error().message.c_str());
    return kExitScene;
  }
  // Alternating rounds on the same trajectory; the fastest round of each is the least
  // disturbed by other processes.
  using Clock = std::chrono::steady_clock;
  double rawBest = 1e300, worldBest = 1e300;
  for (int r = 0; r < rounds; ++r) {
    auto t0 = Clock::now();
    for (int s = 0; s < steps; ++s) (void)integrator.step(model, state, ctx, serialJobs());
    rawBest = std::min(rawBest, msSince(t0));
    t0 = Clock::now();
    for (int s = 0; s < steps; ++s) (void)world.step(dt);
    worldBest = std::min(worldBest, msSince(t0));
  }
  const auto wx = world.positions(id.value());
  const bool same = wx.size() == state.x.size() &&
                    std::memcmp(wx.data(), state.x.data(), wx.size() * sizeof(double)) == 0;
  std::printf("# %d rounds of %d steps, best round each, 1 thread, default solver\n", rounds,
              steps);
  std::printf("tets,ms_integrator,ms_world,ratio,identical_positions\n");
  std::printf("%zu,%.3f,%.3f,%.4f,%s\n", def.mesh.tetCount(), rawBest / steps, worldBest / steps,
              worldBest / rawBest, same ? "yes" : "no");
  return kExitOk;
}

// A free 0.2 m cube spinning at 20 rad/s about a tilted axis, default settings: the body of
// tests/physics/test_rigid_motion.cpp, where the step's options matter.
BodyDef spinningCube(int n) {
  BodyDef def;
  def.mesh = gen::box(0.2, 0.2, 0.2, n, n, n);
  for (double& x : def.mesh.positions) x -= 0.1;
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  return def;
}

std::vector<double> spinVelocities(const BodyDef& def) {
  const glm::dvec3 w = 20.0 * glm::normalize(glm::dvec3(0.3, 1, 0.2));
  std::vector<double> v(def.mesh.positions.size());
  for (size_t n = 0; n < v.size() / 3; ++n) {
    const glm::dvec3 r(def.mesh.positions[3 * n], def.mesh.positions[3 * n + 1],
                       def.mesh.positions[3 * n + 2]);
    const glm::dvec3 u = glm::cross(w, r);
    for (int i = 0; i < 3; ++i) v[3 * n + i] = u[i];
  }
  return v;
}

// The largest edge stress the criterion sees at the start of a step of the spinning cube with
// these fracture settings: every edge given strength 1e-6 Pa breaks and reports its stress.
double largestEdgeStress(const BodyDef& def, const std::vector<double>& v) {
  World world(WorldDef{glm::vec3(0), g_backend, nullptr, 1, {}});
  const BodyId id = world.createBody(def).value();
  (void)world.setVelocities(id, v);
  for (int s = 0; s < 3; ++s) (void)world.step(1.0 / 60);  // settle into the spin's stretch
  (void)world.setEdgeStrengths(id, std::vector<double>(world.edges(id).size() / 2, 1e-6));
  (void)world.step(1.0 / 60);
  double largest = 0;
  for (const FractureEvent& e : world.fractureEvents())
    largest = std::max(largest, double(e.stress));
  return largest;
}

int benchOptions(int argc, char** argv) {
  int n = 16, steps = 5, rounds = 5;
  if (const int e = parseBenchArgs("options", argc, argv,
                                   {{"--cells", &n, 2, kBenchMaxCells},
                                    {"--steps", &steps, 1, kBenchMaxCount},
                                    {"--rounds", &rounds, 1, kBenchMaxCount}});
      e != kExitOk)
    return e;
  const BodyDef base = spinningCube(n);
  const std::vector<double> v = spinVelocities(base);
  const double h = 0.2 / n;
  struct Option {
    std::string name;
    BodyDef def;
  };
  std::vector<Option> options;
  options.push_back({"default (turning frame, backward Euler, no fracture)", base});
  options.push_back({"corotatedInertia off (plain backward Euler)", base});
  options.back().def.solver.corotatedInertia = false;
  options.push_back({"numericalDamping 0 (implicit midpoint)", base});
  options.back().def.solver.numericalDamping = 0;
  // Fracture with every edge's strength 5 % over the largest stress the criterion will see:
  // nothing breaks, but the Gershgorin bound lets few tets near the top skip the average (a
  // body about to break; far from its strength the criterion costs next to nothing).
  const auto fracture = [&](const char* name, double radius, double length) {
    Option o{name, base};
    o.def.fracture.enabled = true;
    o.def.fracture.radius = radius;
    o.def.fracture.nonlocalLength = length;
    o.def.fracture.strength = 1e30;
    o.def.fracture.strength = 1.05 * largestEdgeStress(o.def, v);
    options.push_back(o);
  };
  fracture("fracture, local, near strength", 0, 0);
  fracture("fracture, R_d = 2 edge lengths, near strength", 2, 0);
  fracture("fracture, nonlocalLength = 2 cells, near strength", 0, 2 * h);
  fracture("fracture, nonlocalLength = 4 cells, near strength", 0, 4 * h);

  std::vector<std::unique_ptr<World>> worlds;
  std::vector<BodyId> ids;
  for (const Option& o : options) {
    worlds.push_back(std::make_unique<World>(WorldDef{glm::vec3(0), g_backend, nullptr, 1, {}}));
    Result<BodyId> id = worlds.back()->createBody(o.def);
    if (!id.ok()) {
      std::fprintf(stderr, "bench options: %s: %s\n", o.name.c_str(), id.error().message.c_str());
      return kExitScene;
    }
    ids.push_back(id.value());
    (void)worlds.back()->setVelocities(id.value(), v);
    (void)worlds.back()->step(1.0 / 60);  // warm-up: solver set-up, first allocation
  }
  // Alternating rounds; the fastest round of each option is the least disturbed by others.
  std::vector<double> best(options.size(), 1e300), iterations(options.size(), 0);
  std::vector<StepTimings> stages(options.size());
  for (int r = 0; r < rounds; ++r)
    for (size_t o = 0; o < options.size(); ++o) {
      StepTimings sum;
      double linear = 0;
      const auto t0 = std::chrono::steady_clock::now();
      for (int s = 0; s < steps; ++s) {
        linear += double(worlds[o]->step(1.0 / 60).linearIterations) / steps;
        const StepTimings& t = worlds[o]->timings();
        sum.fractureMs += t.fractureMs / steps;
        sum.elementsMs += t.elementsMs / steps;
        sum.solveMs += t.solveMs / steps;
      }
      if (msSince(t0) / steps < best[o]) {
        best[o] = msSince(t0) / steps;
        stages[o] = sum;
        iterations[o] = linear;
      }
    }
  std::printf("# spinning cube, %zu tets, dt 1/60, 1 thread; best of %d rounds of %d steps\n",
              base.mesh.tetCount(), rounds, steps);
  std::printf(
      "option,ms_step,ratio_to_default,ms_fracture,ms_elements,ms_solve,linear_iterations,"
      "broken_edges\n");
  for (size_t o = 0; o < options.size(); ++o)
    std::printf("%s,%.3f,%.3f,%.3f,%.3f,%.3f,%.1f,%d\n", options[o].name.c_str(), best[o],
                best[o] / best[0], stages[o].fractureMs, stages[o].elementsMs, stages[o].solveMs,
                iterations[o], worlds[o]->fractureStats(ids[o]).brokenEdges);
  return kExitOk;
}

int benchStages(int argc, char** argv) {
  int frames = 0;  // 0: all of each scene's frames
  std::vector<int> threadCounts = {1};
  std::vector<std::string> scenes;
  if (const int e = parseBenchArgs("stages", argc, argv,
                                   {{"--frames", &frames, 1, kBenchMaxCount},
                                    {"--threads", &threadCounts, 0, kBenchMaxThreads},
                                    {"--scene", &scenes}});
      e != kExitOk)
    return e;
  if (scenes.empty()) scenes = {"scenes/bunny_bullet.json", "scenes/charpy.json"};
#ifndef GF_CLI_HAS_BULLET
  std::fprintf(stderr,
               "graphfrac bench stages: this graphfrac was built without Bullet "
               "(GF_WITH_BULLET); the stages include the Bullet step\n");
  return kExitScene;
#else
  std::printf(
      "# per frame, mean over the frames after one warm-up frame; every body's render surface "
      "is requested once per frame, as a renderer would; bullet = the bridge outside World::step "
      "(colliders, "
      "impulses, hand-off, Bullet steps, fragment transforms)\n");
  std::printf(
      "scene,tets,threads,frames,substeps,ms_frame,ms_fracture,ms_elements,ms_assembly,"
      "ms_solve,ms_contact,ms_surface,ms_bullet,ms_other,broken_edges,fragments,in_bullet,"
      "contact_pairs\n");
  for (const std::string& path : scenes) {
    gf::Result<scene::Scene> sc = scene::loadScene(path);
    if (!sc.ok()) {
      std::fprintf(stderr, "%s\n", sc.error().message.c_str());
      return kExitScene;
    }
    sc.value().world.backend = g_backend;
    size_t tets = 0;
    for (const scene::SceneBody& b : sc.value().bodies) tets += b.def.mesh.tetCount();
    // Each thread count runs in this process, one after the other, so their ratios are measured
    // in one run.
    for (const int threads : threadCounts) {
      gf::Result<std::unique_ptr<scene::BulletScene>> run =
          scene::BulletScene::create(sc.value(), threads);
      if (!run.ok()) {
        std::fprintf(stderr, "%s\n", run.error().message.c_str());
        return kExitScene;
      }
      scene::BulletScene& bs = *run.value();
      const int n = frames > 0 ? frames : std::max(1, sc.value().frames - 1);
      for (size_t b = 0; b < bs.bodyCount(); ++b) (void)bs.world().surface(bs.body(b));
      (void)bs.step();  // warm-up: first-use allocations, the surfaces' first build
      StepTimings sum;
      double bullet = 0, total = 0;
      for (int f = 0; f < n; ++f) {
        const StepStatus st = bs.step();
        if (st.has(kStepInvalidInput) || st.has(kStepNanContained)) {
          std::fprintf(stderr, "%s: frame %d: %s\n", path.c_str(), bs.frame(), st.message.c_str());
          return kExitFlagged;
        }
        // A renderer asks for each surface once per frame; World::surface() updates it then.
        const auto ts = std::chrono::steady_clock::now();
        for (size_t b = 0; b < bs.bodyCount(); ++b) (void)bs.world().surface(bs.body(b));
        const double surfaceMs = msSince(ts);
        const scene::FrameTimings& t = bs.timings();
        sum.fractureMs += t.world.fractureMs;
        sum.elementsMs += t.world.elementsMs;
        sum.assemblyMs += t.world.assemblyMs;
        sum.solveMs += t.world.solveMs;
        sum.contactMs += t.world.contactMs;
        sum.contactPairs += t.world.contactPairs;
        sum.surfaceMs += surfaceMs;
        bullet += t.bulletMs;
        total += t.totalMs + surfaceMs;
      }
      int32_t broken = 0, fragments = 0;
      for (size_t b = 0; b < bs.bodyCount(); ++b) {
        broken += bs.world().fractureStats(bs.body(b)).brokenEdges;
        fragments += bs.world().fractureStats(bs.body(b)).fragments;
      }
      const double other = total - sum.fractureMs - sum.elementsMs - sum.assemblyMs - sum.solveMs -
                           sum.contactMs - sum.surfaceMs - bullet;
      std::printf("%s,%zu,%d,%d,%d,%.2f,%.2f,%.2f,%.2f,%.2f,%.3f,%.2f,%.2f,%.2f,%d,%d,%zu,%lld\n",
                  sc.value().name.c_str(), tets, threads, n, sc.value().world.substeps, total / n,
                  sum.fractureMs / n, sum.elementsMs / n, sum.assemblyMs / n, sum.solveMs / n,
                  sum.contactMs / n, sum.surfaceMs / n, bullet / n, other / n, broken, fragments,
                  bs.handedOff(), (long long)sum.contactPairs);
      std::fflush(stdout);
    }
  }
  return kExitOk;
#endif
}

// Entries of /proc/self/task: every OS thread of the process, whoever started it (-1 where
// procfs is missing).
int processThreads() {
  DIR* d = opendir("/proc/self/task");
  if (!d) return -1;
  int n = 0;
  while (const dirent* e = readdir(d))
    if (e->d_name[0] != '.') ++n;
  closedir(d);
  return n;
}

// Debris: `count` boxes of 0.1 m and cells^3 cells on a grid, 2 cm above a ground plane, or
// (count == 0) one 1 m x 0.4 m x 0.5 m box with the same number of cells of the same size on
// it. Default solver settings unless `solver` names one.
std::unique_ptr<World> debrisWorld(int cells, int count, JobSystem* jobs,
                                   const std::string& solver) {
  Collider ground;  // the plane y = 0
  auto world =
      std::make_unique<World>(WorldDef{glm::vec3(0, -9.81f, 0), g_backend, jobs, 1, {ground}});
  BodyDef def;
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  if (solver == "pcg") def.solver.linearSolver = LinearSolverKind::PCG;
  if (solver == "direct") def.solver.linearSolver = LinearSolverKind::Direct;
  if (solver == "multigrid") def.solver.multigrid.directBelowNodes = 0;
  const double side = 0.1, lift = 0.02;
  if (count == 0) {
    // 10c x 4c x 5c = 200 c^3 cells of the debris boxes' size.
    def.mesh = gen::box(1.0, 0.4, 0.5, 10 * cells, 4 * cells, 5 * cells);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) def.mesh.positions[3 * n + 1] += lift;
    if (!world->createBody(def).ok()) return nullptr;
    return world;
  }
  const TetMesh cube = gen::box(side, side, side, cells, cells, cells);
  for (int b = 0; b < count; ++b) {
    def.mesh = cube;
    const double x = 0.25 * (b % 20), z = 0.25 * (b / 20);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
      def.mesh.positions[3 * n] += x;
      def.mesh.positions[3 * n + 1] += lift + 0.01 * (b % 7);  // they land on different steps
      def.mesh.positions[3 * n + 2] += z;
    }
    if (!world->createBody(def).ok()) return nullptr;
  }
  return world;
}

int benchDebris(int argc, char** argv) {
  int frames = 10, rounds = 3;
  std::string solver = "default";
  if (const int e = parseBenchArgs("debris", argc, argv,
                                   {{"--frames", &frames, 1, kBenchMaxCount},
                                    {"--rounds", &rounds, 1, kBenchMaxCount},
                                    {"--solver", &solver}});
      e != kExitOk)
    return e;
  if (solver != "default" && solver != "pcg" && solver != "direct" && solver != "multigrid") {
    std::fprintf(stderr, "bench debris: --solver is default, pcg, direct or multigrid\n");
    return kExitUsage;
  }
  constexpr int kBodies = 200;
  const double dt = 1.0 / 60;
  const int threadsAtStart = processThreads();
  int threadsAfter[2] = {0, 0};
  struct Row {
    int threads = 0, bodies = 0, tets = 0;
    double ms = 1e300, elements = 0, assembly = 0, solve = 0, linear = 0;
  };
  std::vector<Row> rows;
  for (int threads : {1, 2}) {
    ThreadPoolJobSystem jobs(threads);
    for (int cells : {2, 3}) {
      std::unique_ptr<World> worlds[2] = {debrisWorld(cells, kBodies, &jobs, solver),
                                          debrisWorld(cells, 0, &jobs, solver)};
      if (!worlds[0] || !worlds[1]) {
        std::fprintf(stderr, "bench debris: a body could not be created\n");
        return kExitScene;
      }
      Row r[2];
      for (int w = 0; w < 2; ++w) {
        r[w].threads = jobs.threadCount();
        r[w].bodies = w == 0 ? kBodies : 1;
        r[w].tets = kBodies * 6 * cells * cells * cells;
        (void)worlds[w]->step(dt);  // warm-up: solver set-up, first-use allocations
      }
      // Alternating rounds; the fastest round of each world is the least disturbed.
      for (int round = 0; round < rounds; ++round)
        for (int w = 0; w < 2; ++w) {
          Row sum = r[w];
          sum.elements = sum.assembly = sum.solve = sum.linear = 0;
          const auto t0 = std::chrono::steady_clock::now();
          for (int f = 0; f < frames; ++f) {
            sum.linear += double(worlds[w]->step(dt).linearIterations) / frames;
            const StepTimings& t = worlds[w]->timings();
            sum.elements += t.elementsMs / frames;
            sum.assembly += t.assemblyMs / frames;
            sum.solve += t.solveMs / frames;
          }
          sum.ms = msSince(t0) / frames;
          if (sum.ms < r[w].ms) r[w] = sum;
        }
      rows.push_back(r[0]);
      rows.push_back(r[1]);
    }
    threadsAfter[threads - 1] = processThreads();  // the pool is still alive here
  }
  std::printf(
      "# debris: %d free boxes of 0.1 m falling onto a ground plane against one box of the "
      "same tets; solver %s, dt 1/60; best of %d rounds of %d frames\n",
      kBodies, solver.c_str(), rounds, frames);
  std::printf("threads,bodies,tets,ms_frame,ms_elements,ms_assembly,ms_solve,linear_iterations\n");
  for (const Row& r : rows)
    std::printf("%d,%d,%d,%.3f,%.3f,%.3f,%.3f,%.1f\n", r.threads, r.bodies, r.tets, r.ms,
                r.elements, r.assembly, r.solve, r.linear);
  std::printf("threads,tets_per_body,ms_many,ms_one,ratio_many_to_one\n");
  for (size_t i = 0; i + 1 < rows.size(); i += 2)
    std::printf("%d,%d,%.3f,%.3f,%.3f\n", rows[i].threads, rows[i].tets / kBodies, rows[i].ms,
                rows[i + 1].ms, rows[i].ms / rows[i + 1].ms);
  std::printf(
      "# OS threads of the process (/proc/self/task): %d at start, %d after the 1-thread runs, "
      "%d while the 2-thread pool runs (the JobSystem's: 1 and 2)\n",
      threadsAtStart, threadsAfter[0], threadsAfter[1]);
  return kExitOk;
}

// 16 bodies on the ground, 0.3 m apart on a 4 x 4 grid: boxes of 0.1 m and `cells`^3 cells
// (stacked false: apart, never touching), or the two blocks of BodyContact.TwoBlocksComeToRest-
// Stacked (20 cm of 4^3 cells with 15 cm of 3^3 cells dropped on it) at each place.
std::unique_ptr<World> contactWorld(int cells, bool stacked, bool contact, JobSystem* jobs) {
  Collider ground;  // the plane y = 0
  ground.friction = 0.5;
  auto world =
      std::make_unique<World>(WorldDef{glm::vec3(0, -9.81f, 0), g_backend, jobs, 1, {ground}});
  BodyDef def;
  def.material = Material::stableNeoHookean(stacked ? 2e5 : 1e6, 0.3, 1000);
  def.material.stiffnessDamping = 0.02;
  def.contact = contact;
  for (int b = 0; b < 16 * (stacked ? 2 : 1); ++b) {
    const int place = stacked ? b / 2 : b;
    const bool top = stacked && b % 2 == 1;
    def.mesh = !stacked ? gen::box(0.1, 0.1, 0.1, cells, cells, cells)
               : top    ? gen::box(0.15, 0.15, 0.15, 3, 3, 3)
                        : gen::box(0.2, 0.2, 0.2, 4, 4, 4);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
      def.mesh.positions[3 * n] += 0.3 * (place % 4) + (top ? 0.025 : 0.0);
      def.mesh.positions[3 * n + 1] += top ? 0.25 : 0.01;
      def.mesh.positions[3 * n + 2] += 0.3 * (place / 4) + (top ? 0.025 : 0.0);
    }
    if (!world->createBody(def).ok()) return nullptr;
  }
  return world;
}

int benchContact(int argc, char** argv) {
  int frames = 60, rounds = 5, cells = 4, threads = 1;
  if (const int e = parseBenchArgs("contact", argc, argv,
                                   {{"--frames", &frames, 1, kBenchMaxCount},
                                    {"--rounds", &rounds, 1, kBenchMaxCount},
                                    {"--cells", &cells, 1, kBenchMaxCells},
                                    {"--threads", &threads, 1, kBenchMaxThreads}});
      e != kExitOk)
    return e;
  // One thread: the World's own serial jobs, as a game without a pool runs it.
  std::unique_ptr<JobSystem> pool =
      threads > 1 ? std::make_unique<ThreadPoolJobSystem>(threads) : nullptr;
  const double dt = 1.0 / 60;
  // No pairs: the same falling boxes with contact on and off, the best of `rounds` alternating
  // runs each (the same fall in both, so the solver work is equal).
  double best[2] = {1e300, 1e300}, contactMs = 0;
  int64_t pairsApart = 0;
  for (int r = 0; r < rounds; ++r)
    for (int on = 1; on >= 0; --on) {
      std::unique_ptr<World> w = contactWorld(cells, false, on != 0, pool.get());
      if (!w) return kExitScene;
      (void)w->step(dt);  // warm-up: first-use allocations, the contact surfaces
      double contact = 0;
      int64_t pairs = 0;
      const auto t0 = std::chrono::steady_clock::now();
      for (int f = 0; f < frames; ++f) {
        (void)w->step(dt);
        contact += w->timings().contactMs;
        pairs += w->timings().contactPairs;
      }
      const double ms = msSince(t0) / frames;
      if (ms < best[on]) {
        best[on] = ms;
        if (on) {
          contactMs = contact / frames;
          pairsApart = pairs;
        }
      }
    }
  std::printf(
      "# 16 boxes of %d tets falling apart onto the ground, %d frames, best of %d, %d thread(s)\n",
      6 * cells * cells * cells, frames, rounds, threads);
  std::printf("case,ms_frame_contact_on,ms_frame_contact_off,ratio,ms_contact_stage,pairs\n");
  std::printf("apart,%.3f,%.3f,%.4f,%.4f,%lld\n", best[1], best[0], best[1] / best[0], contactMs,
              (long long)pairsApart);
  // Pairs: 16 stacks of two blocks at rest.
  std::unique_ptr<World> w = contactWorld(cells, true, true, pool.get());
  if (!w) return kExitScene;
  for (int f = 0; f < 120; ++f) (void)w->step(dt);  // they land and settle
  double contact = 0, total = 0;
  int64_t pairs = 0;
  for (int f = 0; f < frames; ++f) {
    const auto t0 = std::chrono::steady_clock::now();
    (void)w->step(dt);
    total += msSince(t0);
    contact += w->timings().contactMs;
    pairs += w->timings().contactPairs;
  }
  std::printf("# 16 stacks of two blocks (BodyContact.TwoBlocks...) at rest, %d frames after 120\n",
              frames);
  std::printf("case,ms_frame,ms_contact_stage,pairs_per_frame,us_per_pair\n");
  std::printf("stacked,%.3f,%.4f,%.1f,%.3f\n", total / frames, contact / frames,
              double(pairs) / frames, pairs > 0 ? 1e3 * contact / double(pairs) : 0.0);
  return kExitOk;
}

}  // namespace

int runBenchCommand(int argc, char** argv) {
  const auto isHelp = [](const char* a) {
    return !std::strcmp(a, "--help") || !std::strcmp(a, "-h");
  };
  if (argc < 2 || std::any_of(argv + 1, argv + argc, isHelp)) {
    std::puts(
        "usage: graphfrac bench fracture [--cells NX] [--steps S]\n"
        "  NX cells along a 1 m x 0.25 m x 0.25 m beam (NX/4 across; default 40: 24k tets)\n"
        "       graphfrac bench multigrid [--frames N] [--threads T1,T2,...] [--only CASE]\n"
        "                                 [--mg MULTIGRID_JSON]... [--pcg 0|1]\n"
        "  ms per frame, per stage and 1 -> T speed-up (default threads 1,2, each in this run) of\n"
        "  the default multigrid and PCG settings on 4k, 28k,\n"
        "  35k and 160k tets, next to the thesis's GPU fps (table 6.2); also CPU ms per frame,\n"
        "  each multigrid's residual reduction per V-cycle and the frames left unconverged\n"
        "       graphfrac bench overhead [--cells NX] [--steps S] [--rounds R]\n"
        "  World::step of a pure-deformation beam against the raw integrator step\n"
        "       graphfrac bench options [--cells N] [--steps S] [--rounds R]\n"
        "  per-step cost of the step's options (turning frame, numerical damping, fracture\n"
        "  averaging) against the default, on a spinning cube of N^3 cells (default 16: 24k\n"
        "  tets)\n"
        "       graphfrac bench stages [--scene FILE]... [--frames N] [--threads T1,T2,...]\n"
        "  per-stage ms per frame (fracture, elements, assembly, solve, surface, Bullet) of\n"
        "  scenes run through the Bullet bridge; default scenes/bunny_bullet.json and\n"
        "  scenes/charpy.json, all their frames, 1 thread; a row per scene and thread count (0:\n"
        "  every core)\n"
        "       graphfrac bench debris [--frames N] [--rounds R] [--solver S]\n"
        "  200 boxes of 48 and of 162 tets falling onto the ground against one box of the same\n"
        "  tets, ms per frame at 1 and 2 threads, and the OS threads of the process; S is\n"
        "  default, pcg, direct or multigrid (the multigrid at every size)\n"
        "       graphfrac bench contact [--cells N] [--frames F] [--rounds R] [--threads T]\n"
        "  body-body contact: 16 boxes of N^3 cells (default 4) falling apart with contact on\n"
        "  and off (the ratio is the cost without pairs), then 16 stacks of two blocks at rest\n"
        "  (ms of the contact stage per pair)\n"
        "       graphfrac bench xfem [--cells N] [--steps S]\n"
        "  Is-XFEM against graph cuts (thesis ch 3 vs 6): a 2 x 1 x 1 box of N x N/2 x N/2 cells\n"
        "  (default 40) cut by 1, 5, 10, 20 planar blades; cut and step ms, cut-face distance\n"
        "  from the blades, piece volumes against the exact split\n"
        "       graphfrac bench haptic [--cells N] [--steps S]\n"
        "  microseconds per 1 kHz haptic sample (continuous and discrete penalty) of a cube\n"
        "  pressed into a block of N x N/2 x N cells (default 6, 12 and 24) stepping at 62.5 Hz\n"
        "       graphfrac bench peer [--cells N] [--seconds S] [--no-sweep]\n"
        "                            [--bullet-step-limit S] [--bullet-run-limit S]\n"
        "  graphfrac beside Bullet's deformable FEM on the same mesh, material, dt and load: a\n"
        "  cantilever (1 x 0.1 x 0.1 m, 10N x N x N cells, default N 2) and a dropped cube; ms\n"
        "  per step, error against the static reference, and the stable range over E and dt; a "
        "Bullet\n"
        "  run is stopped after S s for one step (default 2) or for the run (default 120)\n"
        "       graphfrac bench fragments [--cells N] [--rounds R] [--threads T]\n"
        "  ms per break step of keeping the fragments (update, then compute when they split) on\n"
        "  recorded break sequences of a cube of N^3 cells (default 16 and 32: 24k and 192k\n"
        "  tets): a random shatter and a crack plane; a checksum of the final partition\n"
        "       graphfrac bench scenes [--frames N] [--big-frames M] [--only CASE]\n"
        "                              [--reference 0|1] [--csv FILE] [--json FILE]\n"
        "  the fixed scene list, 4k to 680k tets, fracture off and on: ms per stage, fps, peak\n"
        "  resident MB (VmHWM, reset per case) and the solver's error against the same frames\n"
        "  solved by MG-CG to 1e-12; N frames (default 5), M for the 680k box (default 1)\n"
        "Every mode takes --backend auto|cpu|cuda (default cpu) for its worlds. Options are\n"
        "written --name value or --name=value; an unknown option or a bad value is an error.");
    return argc < 2 ? kExitUsage : kExitOk;
  }
  // --backend applies to every mode: taken out here, checked once, and said once.
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    const bool joined = !std::strncmp(argv[i], "--backend=", 10);
    if (!joined && std::strcmp(argv[i], "--backend") != 0) {
      args.push_back(argv[i]);
    } else if (!(joined ? parseBackend(argv[i] + 10, g_backend)
                        : i + 1 < argc && parseBackend(argv[++i], g_backend))) {
      std::fprintf(stderr, "graphfrac bench: --backend needs auto, cpu or cuda\n");
      return kExitUsage;
    }
  }
  const detail::BackendChoice backend = detail::chooseBackend(g_backend);
  if (!backend.error.empty()) {
    std::fprintf(stderr, "graphfrac bench: %s\n", backend.error.c_str());
    return kExitUsage;
  }
  std::printf("# backend: %s\n", backend.description.c_str());
  argc = int(args.size());
  argv = args.data();
  if (!std::strcmp(argv[1], "fracture")) return benchFracture(argc, argv);
  if (!std::strcmp(argv[1], "multigrid")) return benchMultigrid(argc, argv);
  if (!std::strcmp(argv[1], "overhead")) return benchOverhead(argc, argv);
  if (!std::strcmp(argv[1], "stages")) return benchStages(argc, argv);
  if (!std::strcmp(argv[1], "options")) return benchOptions(argc, argv);
  if (!std::strcmp(argv[1], "debris")) return benchDebris(argc, argv);
  if (!std::strcmp(argv[1], "contact")) return benchContact(argc, argv);
  if (!std::strcmp(argv[1], "xfem")) return benchXfem(argc, argv);
  if (!std::strcmp(argv[1], "haptic")) return benchHaptic(argc, argv);
  if (!std::strcmp(argv[1], "peer")) return benchPeer(argc, argv);
  if (!std::strcmp(argv[1], "fragments")) return benchFragments(argc, argv);
  if (!std::strcmp(argv[1], "scenes")) return benchScenes(argc, argv);
  std::fprintf(stderr, "graphfrac bench: unknown benchmark '%s'\n", argv[1]);
  return kExitUsage;
}

}  // namespace gf::cli
