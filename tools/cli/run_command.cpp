// `graphfrac run`: loads a scene, steps the world frame by frame (applying the scene's cuts
// before their frames), writes DIR/stats.csv (one row per frame, frame 0 = the initial state),
// the grips' reaction forces and the colliders' impulses per frame, optional surfaces (the
// render surface with crack faces for fracturing bodies), optional ParaView field files and an
// optional fracture-event log, shows progress and ends with a summary. Results are written
// even when a step is flagged (exit code 3) so that a failing run can be inspected.
#include <graphfrac/jobs.h>
#include <graphfrac/world.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <glm/geometric.hpp>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cli/args.h"
#include "cli/commands.h"
#include "cli/csv_writer.h"
#include "cli/progress.h"
#include "cli/surface_writer.h"
#include "cli/svg_plot.h"
#include "cli/vtk_writer.h"
#include "scene/scene.h"
#include "scene/strokes.h"

namespace gf::cli {
namespace {

constexpr const char* kRunUsage =
    "usage: graphfrac run SCENE [options]\n"
    "\n"
    "Simulates a JSON scene (docs/scene_format.md) and writes DIR/stats.csv with one row per\n"
    "frame (frame 0 is the initial state): frame,time,kinetic_energy,elastic_energy,\n"
    "gravity_energy,contact_energy,total_energy,newton_iterations,linear_iterations,residual,\n"
    "flags,ms_elements,ms_assembly,ms_solve,ms_total,broken_edges,fragments,ms_fracture,\n"
    "ms_surface. Energies [J], iterations, broken edges and fragments are summed over\n"
    "bodies. contact_energy is the colliders' penalty energy; total_energy = kinetic +\n"
    "elastic + gravity + contact (the penalty is a spring: its energy is part of the\n"
    "mechanical energy, and a moving collider's work changes the total).\n"
    "newton_iterations sums bodies and substeps: 1 per substep by default (linearly\n"
    "implicit), plus up to 2 more in a substep where a node hits a collider the\n"
    "linearisation did not see; up to solver.newton_iterations with full Newton.\n"
    "Times are per frame [ms].\n"
    "With grips or pins: DIR/grips.csv (frame,body,grip,fx,fy,fz), the force [N] each grip\n"
    "exerts on its body at the end of the frame (World::gripForces; grip = its entry in the\n"
    "scene, e.g. pins[0]). With colliders: DIR/colliders.csv (frame,collider,jx,jy,jz,ax,ay,\n"
    "az), the impulse [N s] each collider gave the bodies during the frame and its moment\n"
    "about the collider's point [N m s] (collider = its index in \"colliders\"; with\n"
    "strokes the sculpting tool is the last). With strokes: DIR/haptic.csv (frame,time,\n"
    "stroke,type,fx,fy,fz,force), the force [N] on the tool over the frame (stroke = its\n"
    "index in the scene's \"strokes\", -1 between strokes), and\n"
    "DIR/haptic.svg, |F| of each push, pull and cut stroke against time.\n"
    "\n"
    "options:\n"
    "  --frames N         frames to run (default: the scene's \"frames\")\n"
    "  --out DIR          output directory (default: out/<scene name>)\n"
    "  --threads T        worker threads, 0 = all cores (default: the scene's \"threads\")\n"
    "  --backend B        auto, cpu or cuda (default: the scene's \"backend\"); the backend\n"
    "                     that runs, and why, is printed before the first frame\n"
    "  --surface obj|ply  also write each body's surface per frame to\n"
    "                     DIR/surface/<body>_<frame:05>.<ext>: the render surface with its\n"
    "                     crack faces (OBJ group \"crack\", red PLY faces) for fracturing\n"
    "                     bodies, the plain boundary for the others\n"
    "  --surface-every K  write surfaces every K-th frame only (default 1)\n"
    "  --vtk              also write ParaView field files: DIR/vtk/<body>_<frame:05>.vtu (the\n"
    "                     tet mesh with point data displacement, velocity, strain, damage =\n"
    "                     the fraction of a node's fracture edges that are broken, fragment)\n"
    "                     and DIR/fields.pvd, which ties them to simulated times\n"
    "  --vtk-every K      write field files every K-th frame only (default 1)\n"
    "  --events FILE      write every fracture event to FILE (CSV: frame,body,edge,nodeA,\n"
    "                     nodeB,x,y,z,stress,cause)\n"
    "  --quiet            no progress and no summary (errors are still printed)\n"
    "  -h, --help         this text\n"
    "\n"
    "exit codes: 0 ok, 1 usage, 2 scene error, 3 a step was flagged (results still written),\n"
    "            4 results could not be written\n";

struct RunOptions {
  std::string scene;
  std::optional<int> frames;
  std::optional<int> threads;
  std::optional<Backend> backend;
  std::string out;
  std::optional<SurfaceFormat> surface;
  int surfaceEvery = 1;
  bool vtk = false;
  int vtkEvery = 1;
  std::string events;
  bool quiet = false;
  bool help = false;
};

/// Parses argv (argv[0] = "run"); returns an error message or empty.
std::string parseArgs(int argc, char** argv, RunOptions& o) {
  ArgParser a(argc, argv);
  while (a.next()) {
    const std::string& arg = a.name();
    if (arg == "-h" || arg == "--help") {
      o.help = true;
    } else if (arg == "--quiet" || arg == "-q") {
      o.quiet = true;
    } else if (arg == "--frames") {
      int n = 0;
      if (!a.intValue(0, 100'000'000, n)) return "--frames needs an integer >= 0";
      o.frames = n;
    } else if (arg == "--threads") {
      int n = 0;
      if (!a.intValue(0, 1024, n)) return "--threads needs an integer >= 0";
      o.threads = n;
    } else if (arg == "--backend") {
      std::string value;
      Backend b{};
      if (!a.value(value) || !parseBackend(value, b)) return "--backend needs auto, cpu or cuda";
      o.backend = b;
    } else if (arg == "--out") {
      if (!a.nonEmptyValue(o.out)) return "--out needs a directory";
    } else if (arg == "--surface") {
      std::string value;
      if (!a.value(value) || (value != "obj" && value != "ply"))
        return "--surface needs obj or ply";
      o.surface = value == "obj" ? SurfaceFormat::Obj : SurfaceFormat::Ply;
    } else if (arg == "--surface-every") {
      if (!a.intValue(1, 100'000'000, o.surfaceEvery)) {
        return "--surface-every needs an integer >= 1";
      }
    } else if (arg == "--vtk") {
      o.vtk = true;
    } else if (arg == "--vtk-every") {
      if (!a.intValue(1, 100'000'000, o.vtkEvery)) return "--vtk-every needs an integer >= 1";
    } else if (arg == "--events") {
      if (!a.nonEmptyValue(o.events)) return "--events needs a file name";
    } else if (a.isOption()) {
      return "unknown option '" + arg + "'";
    } else if (o.scene.empty()) {
      o.scene = arg;
    } else {
      return "more than one scene given ('" + o.scene + "' and '" + arg + "')";
    }
  }
  if (!o.help && o.scene.empty()) return "no scene given";
  return {};
}

/// What the run keeps per body besides the world's state.
struct BodyRecord {
  std::string name;
  BodyId id;
  std::vector<double> rest;  // rest positions, for displacements
  size_t tets = 0;
  // Fracturing and Is-XFEM bodies write World::surface (crack or cut faces), the others
  // `surface`.
  bool fracture = false;
  SurfaceTopology surface;
  std::vector<int32_t> tetNodes;       // --vtk: the cells
  std::vector<std::string> gripNames;  // the scene entry of each BodyDef::grips
};

struct FrameTotals {
  BodyStats stats;  // summed over bodies (momenta unused)
  int64_t brokenEdges = 0;
  int64_t fragments = 0;  // a body without fracture is one piece
  double total() const {
    return stats.kineticEnergy + stats.elasticEnergy + stats.gravityEnergy + stats.contactEnergy;
  }
};

FrameTotals sumStats(const World& world, const std::vector<BodyRecord>& bodies) {
  FrameTotals t;
  for (const BodyRecord& b : bodies) {
    const BodyStats s = world.stats(b.id);
    t.stats.kineticEnergy += s.kineticEnergy;
    t.stats.elasticEnergy += s.elasticEnergy;
    t.stats.gravityEnergy += s.gravityEnergy;
    t.stats.contactEnergy += s.contactEnergy;
    t.stats.mass += s.mass;
    if (b.fracture) {
      const FractureStats f = world.fractureStats(b.id);
      t.brokenEdges += f.brokenEdges;
      t.fragments += f.fragments;
    } else {
      t.fragments += 1;
    }
  }
  return t;
}

const std::vector<std::string> kColumns = {
    "frame",          "time",         "kinetic_energy",    "elastic_energy",    "gravity_energy",
    "contact_energy", "total_energy", "newton_iterations", "linear_iterations", "residual",
    "flags",          "ms_elements",  "ms_assembly",       "ms_solve",          "ms_total",
    "broken_edges",   "fragments",    "ms_fracture",       "ms_surface"};

const char* causeName(FractureEvent::Cause c) {
  switch (c) {
    case FractureEvent::Cause::Stress:
      return "stress";
    case FractureEvent::Cause::BrittlePlane:
      return "brittle";
    case FractureEvent::Cause::Cut:
      return "cut";
    case FractureEvent::Cause::Severed:
      return "severed";
  }
  return "unknown";
}

/// Appends one frame's fracture events to the event log (one row per broken edge).
Result<void> writeEvents(CsvWriter& log, int frame, std::span<const FractureEvent> events,
                         const std::vector<BodyRecord>& bodies) {
  for (const FractureEvent& e : events) {
    std::string name = "?";
    for (const BodyRecord& b : bodies)
      if (b.id == e.body) name = b.name;
    if (Result<void> r =
            log.row({int64_t(frame), name, int64_t(e.edge), int64_t(e.nodeA), int64_t(e.nodeB),
                     double(e.position.x), double(e.position.y), double(e.position.z),
                     double(e.stress), std::string(causeName(e.cause))});
        !r.ok())
      return r;
  }
  return {};
}

/// Flag bits with the names the summary prints.
struct FlagName {
  StepFlag flag;
  const char* name;
};
constexpr FlagName kFlagNames[] = {
    {kStepNotConverged, "not converged"}, {kStepNanContained, "NaN contained"},
    {kStepInvalidInput, "invalid input"}, {kStepLineSearchFailed, "line search failed"},
    {kStepContactSwept, "swept contact"},
};

/// The step's message, or the names of its flags when it gave none.
std::string describeStep(const StepStatus& st) {
  if (!st.message.empty()) return st.message;
  std::string s;
  for (const FlagName& f : kFlagNames) {
    if (st.has(f.flag)) s += (s.empty() ? "" : ", ") + std::string(f.name);
  }
  return s.empty() ? "flags " + std::to_string(st.flags) : s;
}

/// "<body>_<frame:05>.<ext>", the name of a per-frame file.
std::string frameFile(const std::string& body, int frame, const char* ext) {
  char name[64];
  std::snprintf(name, sizeof name, "_%05d.%s", frame, ext);
  return body + name;
}

/// Appends each grip's force on its body (World::gripForces) to grips.csv.
Result<void> writeGripForces(CsvWriter& csv, int frame, World& world,
                             const std::vector<BodyRecord>& bodies) {
  for (const BodyRecord& b : bodies) {
    const std::span<const glm::dvec3> f = world.gripForces(b.id);
    for (size_t g = 0; g < f.size(); ++g) {
      const std::string grip = g < b.gripNames.size() ? b.gripNames[g] : std::to_string(g);
      if (Result<void> r = csv.row({int64_t(frame), b.name, grip, f[g].x, f[g].y, f[g].z}); !r)
        return r;
    }
  }
  return {};
}

/// Appends each collider's impulse and its moment over the last step to colliders.csv.
Result<void> writeColliderImpulses(CsvWriter& csv, int frame, const World& world) {
  const std::span<const glm::dvec3> j = world.colliderImpulses();
  const std::span<const glm::dvec3> a = world.colliderAngularImpulses();
  for (size_t c = 0; c < j.size(); ++c) {
    const glm::dvec3 m = c < a.size() ? a[c] : glm::dvec3(0);
    if (Result<void> r =
            csv.row({int64_t(frame), int64_t(c), j[c].x, j[c].y, j[c].z, m.x, m.y, m.z});
        !r)
      return r;
  }
  return {};
}

/// Prints the largest node displacement of each body (the tip of a cantilever, the lowest
/// point of a dropped block).
void printDisplacements(const World& world, const std::vector<BodyRecord>& bodies) {
  for (const BodyRecord& b : bodies) {
    const std::span<const double> x = world.positions(b.id);
    double best = -1;
    size_t node = 0;
    glm::dvec3 d{0};
    for (size_t i = 0; 3 * i + 2 < x.size() && 3 * i + 2 < b.rest.size(); ++i) {
      const glm::dvec3 di(x[3 * i] - b.rest[3 * i], x[3 * i + 1] - b.rest[3 * i + 1],
                          x[3 * i + 2] - b.rest[3 * i + 2]);
      const double len = glm::length(di);
      if (len > best) best = len, node = i, d = di;
    }
    std::printf("  %-16s max displacement %.6g m at node %zu (%.6g, %.6g, %.6g)\n", b.name.c_str(),
                std::max(best, 0.0), node, d.x, d.y, d.z);
  }
}

}  // namespace

int runCommand(int argc, char** argv) {
  RunOptions opt;
  if (const std::string err = parseArgs(argc, argv, opt); !err.empty()) {
    std::fprintf(stderr, "graphfrac run: %s\n(see graphfrac run --help)\n", err.c_str());
    return kExitUsage;
  }
  if (opt.help) {
    std::fputs(kRunUsage, stdout);
    return kExitOk;
  }

  // ---- scene and world ----------------------------------------------------------------
  Result<scene::Scene> loaded = scene::loadScene(opt.scene);
  if (!loaded.ok()) {
    std::fprintf(stderr, "%s\n", loaded.error().message.c_str());
    return kExitScene;
  }
  scene::Scene sc = std::move(loaded).value();
  // Running such a scene without its rigid bodies would be a different experiment.
  if (scene::needsBullet(sc)) {
    std::fprintf(stderr,
                 "%s: the scene has Bullet rigid bodies or a hand-off policy, which graphfrac "
                 "run does not simulate; run it with graphfrac-demo, or time it with "
                 "`graphfrac bench stages --scene %s`\n",
                 opt.scene.c_str(), opt.scene.c_str());
    return kExitScene;
  }
  const int frames = opt.frames.value_or(sc.frames);
  const int threads = opt.threads.value_or(sc.threads);

  std::unique_ptr<JobSystem> jobs;
  if (threads != 1) jobs = std::make_unique<ThreadPoolJobSystem>(threads);
  WorldDef wdef = sc.world;
  wdef.jobs = jobs.get();
  if (opt.backend) wdef.backend = *opt.backend;
  scene::StrokePlayer strokes(sc, wdef);
  World world(wdef);

  std::vector<BodyRecord> bodies;
  bool anyGrips = false;
  for (size_t i = 0; i < sc.bodies.size(); ++i) {
    scene::SceneBody& sb = sc.bodies[i];
    BodyRecord rec;
    rec.name = sb.name;
    rec.rest = sb.def.mesh.positions;
    rec.tets = sb.def.mesh.tetCount();
    rec.fracture = sb.def.fracture.enabled || sb.def.cutMode == CutMode::Xfem;
    rec.gripNames = sb.gripNames;
    anyGrips = anyGrips || !sb.def.grips.empty();
    if (opt.surface && !rec.fracture) rec.surface = surfaceTopology(sb.def.mesh);
    if (opt.vtk) rec.tetNodes = sb.def.mesh.tets;
    Result<BodyId> id = scene::addBody(world, sb);
    if (!id.ok()) {
      std::fprintf(stderr, "%s: bodies[%zu] (\"%s\"): %s\n", opt.scene.c_str(), i, sb.name.c_str(),
                   id.error().message.c_str());
      return kExitScene;
    }
    rec.id = id.value();
    bodies.push_back(std::move(rec));
  }

  // ---- output -------------------------------------------------------------------------
  namespace fs = std::filesystem;
  const fs::path outDir = opt.out.empty() ? fs::path("out") / sc.name : fs::path(opt.out);
  const fs::path surfDir = outDir / "surface";
  const fs::path vtkDir = outDir / "vtk";
  for (const fs::path& dir : {outDir, opt.surface ? surfDir : outDir, opt.vtk ? vtkDir : outDir}) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) {
      std::fprintf(stderr, "graphfrac run: cannot create %s: %s\n", dir.string().c_str(),
                   ec.message().c_str());
      return kExitOutput;
    }
  }
  CsvWriter csv;
  if (Result<void> r = csv.open((outDir / "stats.csv").string(), kColumns); !r.ok()) {
    std::fprintf(stderr, "graphfrac run: %s\n", r.error().message.c_str());
    return kExitOutput;
  }
  // Reactions: only for scenes that have something to report, so a plain run writes no
  // empty files.
  CsvWriter gripCsv, colliderCsv;
  const bool writeGrips = anyGrips;
  const bool writeColliders = !world.colliders().empty();
  if (writeGrips) {
    if (Result<void> r = gripCsv.open((outDir / "grips.csv").string(),
                                      {"frame", "body", "grip", "fx", "fy", "fz"});
        !r.ok()) {
      std::fprintf(stderr, "graphfrac run: %s\n", r.error().message.c_str());
      return kExitOutput;
    }
  }
  if (writeColliders) {
    if (Result<void> r =
            colliderCsv.open((outDir / "colliders.csv").string(),
                             {"frame", "collider", "jx", "jy", "jz", "ax", "ay", "az"});
        !r.ok()) {
      std::fprintf(stderr, "graphfrac run: %s\n", r.error().message.c_str());
      return kExitOutput;
    }
  }
  // The haptic force of each stroke (thesis fig 7.13): what the tool feels, frame by frame.
  CsvWriter hapticCsv;
  const bool writeHaptic = !sc.strokes.empty();
  std::vector<PlotSeries> hapticSeries;
  if (writeHaptic) {
    if (Result<void> r =
            hapticCsv.open((outDir / "haptic.csv").string(),
                           {"frame", "time", "stroke", "type", "fx", "fy", "fz", "force"});
        !r.ok()) {
      std::fprintf(stderr, "graphfrac run: %s\n", r.error().message.c_str());
      return kExitOutput;
    }
  }
  CsvWriter events;
  if (!opt.events.empty()) {
    if (Result<void> r = events.open(opt.events, {"frame", "body", "edge", "nodeA", "nodeB", "x",
                                                  "y", "z", "stress", "cause"});
        !r.ok()) {
      std::fprintf(stderr, "graphfrac run: %s\n", r.error().message.c_str());
      return kExitOutput;
    }
  }
  auto writeSurfaces = [&](int frame) -> bool {
    if (!opt.surface || frame % opt.surfaceEvery != 0) return true;
    for (const BodyRecord& b : bodies) {
      const std::string path =
          (surfDir / frameFile(b.name, frame, *opt.surface == SurfaceFormat::Obj ? "obj" : "ply"))
              .string();
      const Result<void> r =
          b.fracture ? writeRenderSurface(path, world.surface(b.id), *opt.surface)
                     : writeSurfaceFrame(path, b.surface, world.positions(b.id), *opt.surface);
      if (!r.ok()) {
        std::fprintf(stderr, "\ngraphfrac run: %s\n", r.error().message.c_str());
        return false;
      }
    }
    return true;
  };
  PvdWriter pvd;
  auto writeFields = [&](int frame) -> bool {
    if (!opt.vtk || frame % opt.vtkEvery != 0) return true;
    for (size_t i = 0; i < bodies.size(); ++i) {
      const BodyRecord& b = bodies[i];
      const std::string file = frameFile(b.name, frame, "vtu");
      const std::span<const double> x = world.positions(b.id);
      const std::vector<double> damage =
          nodeDamage(x.size() / 3, world.edges(b.id), world.brokenEdges(b.id));
      VtuFrame f;
      f.positions = x;
      f.rest = b.rest;
      f.velocities = world.velocities(b.id);
      f.tets = b.tetNodes;
      f.strain = world.nodeStrain(b.id);
      f.damage = damage;
      f.fragment = world.nodeFragments(b.id);
      if (Result<void> r = writeVtu((vtkDir / file).string(), f); !r.ok()) {
        std::fprintf(stderr, "\ngraphfrac run: %s\n", r.error().message.c_str());
        return false;
      }
      pvd.add(world.time(), int(i), "vtk/" + file);
    }
    return true;
  };

  if (!opt.quiet) {
    size_t nodes = 0, tets = 0;
    for (const BodyRecord& b : bodies) nodes += b.rest.size() / 3, tets += b.tets;
    const int workers = jobs ? jobs->threadCount() : 1;
    std::printf(
        "graphfrac run: %s: %zu bod%s, %zu nodes, %zu tets; %d frames of %.6g s on %d "
        "thread%s\n",
        sc.name.c_str(), bodies.size(), bodies.size() == 1 ? "y" : "ies", nodes, tets, frames,
        sc.dt, workers, workers == 1 ? "" : "s");
    std::printf("  backend: %s\n  output: %s\n", world.backendDescription().c_str(),
                outDir.string().c_str());
    std::fflush(stdout);
  }

  // ---- frames -------------------------------------------------------------------------
  const FrameTotals initial = sumStats(world, bodies);
  bool outputOk =
      csv.row({int64_t{0}, world.time(), initial.stats.kineticEnergy, initial.stats.elasticEnergy,
               initial.stats.gravityEnergy, initial.stats.contactEnergy, initial.total(),
               int64_t{0}, int64_t{0}, 0.0, int64_t{0}, 0.0, 0.0, 0.0, 0.0, initial.brokenEdges,
               initial.fragments, 0.0, 0.0})
          .ok() &&
      writeSurfaces(0) && writeFields(0);

  Progress progress(frames, Progress::detect(stderr, opt.quiet));
  int flaggedFrames = 0;
  int flagCounts[std::size(kFlagNames)] = {};
  std::string firstFlagMessage;
  int firstFlagFrame = 0;
  long long newtonTotal = 0, linearTotal = 0;
  long long edgeEvents = 0, fragmentEvents = 0;
  double msTotal = 0;
  size_t nextCut = 0;  // scene cuts are sorted by frame
  bool cutFailed = false;
  const auto wallStart = std::chrono::steady_clock::now();

  for (int frame = 1; frame <= frames && outputOk; ++frame) {
    // Cuts break their edges at the start of the next step, so they are given before it.
    for (; nextCut < sc.cuts.size() && sc.cuts[nextCut].frame <= frame; ++nextCut) {
      const scene::SceneCut& c = sc.cuts[nextCut];
      if (Result<void> r = world.cut(bodies[c.bodyIndex].id, c.blade); !r.ok()) {
        std::fprintf(stderr, "\n%s: cuts (frame %d, body \"%s\"): %s\n", opt.scene.c_str(), c.frame,
                     c.body.c_str(), r.error().message.c_str());
        cutFailed = true;
      }
    }
    if (cutFailed) break;
    std::vector<BodyId> ids;
    for (const BodyRecord& b : bodies) ids.push_back(b.id);
    if (Result<void> r = strokes.apply(world, ids, frame); !r.ok()) {
      std::fprintf(stderr, "\n%s: %s\n", opt.scene.c_str(), r.error().message.c_str());
      cutFailed = true;
      break;
    }
    const StepStatus st = world.step(sc.dt);
    const StepTimings& tm = world.timings();
    const FrameTotals t = sumStats(world, bodies);
    newtonTotal += st.newtonIterations;
    linearTotal += st.linearIterations;
    msTotal += tm.totalMs;
    if (!st.ok()) {
      if (flaggedFrames++ == 0) firstFlagMessage = describeStep(st), firstFlagFrame = frame;
      for (size_t k = 0; k < std::size(kFlagNames); ++k) {
        if (st.has(kFlagNames[k].flag)) ++flagCounts[k];
      }
    }
    // World::surface() updates a surface lazily: bring the written ones up to date before the
    // row so that its ms_surface column holds this frame's cost.
    if (opt.surface && frame % opt.surfaceEvery == 0)
      for (const BodyRecord& b : bodies)
        if (b.fracture) (void)world.surface(b.id);
    Result<void> r = csv.row(
        {int64_t{frame}, world.time(), t.stats.kineticEnergy, t.stats.elasticEnergy,
         t.stats.gravityEnergy, t.stats.contactEnergy, t.total(), int64_t{st.newtonIterations},
         int64_t{st.linearIterations}, st.residual, int64_t{st.flags}, tm.elementsMs, tm.assemblyMs,
         tm.solveMs, tm.totalMs, t.brokenEdges, t.fragments, tm.fractureMs, tm.surfaceMs});
    edgeEvents += static_cast<long long>(world.fractureEvents().size());
    fragmentEvents += static_cast<long long>(world.fragmentEvents().size());
    if (r.ok() && !opt.events.empty())
      r = writeEvents(events, frame, world.fractureEvents(), bodies);
    if (r.ok() && writeGrips) r = writeGripForces(gripCsv, frame, world, bodies);
    if (r.ok() && writeColliders) r = writeColliderImpulses(colliderCsv, frame, world);
    if (r.ok() && writeHaptic) {
      const int k = strokes.activeStroke(frame);
      const glm::dvec3 f = strokes.toolForce(world, sc.dt);
      const std::string type = k < 0 ? "none" : scene::strokeTypeName(sc.strokes[size_t(k)].type);
      r = hapticCsv.row(
          {int64_t{frame}, world.time(), int64_t{k}, type, f.x, f.y, f.z, glm::length(f)});
      // The strokes whose tool meets the body: wet and dry only touch its water.
      const bool touches = k >= 0 && sc.strokes[size_t(k)].type != scene::SceneStroke::Type::Wet &&
                           sc.strokes[size_t(k)].type != scene::SceneStroke::Type::Dry;
      if (touches) {
        const std::string name = "strokes[" + std::to_string(k) + "] " + type;
        if (hapticSeries.empty() || hapticSeries.back().name != name) {
          static const char* kColours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e"};
          hapticSeries.push_back({name, kColours[hapticSeries.size() % 5], {}, true});
        }
        hapticSeries.back().points.push_back({world.time(), glm::length(f), ""});
      }
    }
    if (!r.ok()) {
      std::fprintf(stderr, "\ngraphfrac run: %s\n", r.error().message.c_str());
      outputOk = false;
      break;
    }
    outputOk = writeSurfaces(frame) && writeFields(frame);
    char note[96];
    std::snprintf(note, sizeof note, "%.1f ms/frame  E=%.4g J%s", msTotal / frame, t.total(),
                  flaggedFrames > 0 ? "  (flagged steps)" : "");
    progress.update(frame, note);
  }
  progress.finish();
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wallStart).count();
  if (Result<void> r = csv.close(); !r.ok()) {
    std::fprintf(stderr, "graphfrac run: %s\n", r.error().message.c_str());
    outputOk = false;
  }
  if (writeHaptic) {
    PlotPanel panel{"Haptic force of the push, pull and cut strokes",
                    "time [s]",
                    "|F| on the tool [N]",
                    false,
                    false,
                    hapticSeries};
    if (Result<void> r = writeSvg(
            (outDir / "haptic.svg").string(), {panel},
            sc.name + ": force on the sculpting tool per frame (thesis fig 7.13's analogue)");
        !r.ok()) {
      std::fprintf(stderr, "graphfrac run: %s\n", r.error().message.c_str());
      outputOk = false;
    }
  }
  for (CsvWriter* w : {&events, &gripCsv, &colliderCsv, &hapticCsv}) {
    if (Result<void> r = w->close(); !r.ok()) {
      std::fprintf(stderr, "graphfrac run: %s\n", r.error().message.c_str());
      outputOk = false;
    }
  }
  // The collection lists what was written, also when the run stopped early.
  if (opt.vtk) {
    if (Result<void> r = pvd.write((outDir / "fields.pvd").string()); !r.ok()) {
      std::fprintf(stderr, "graphfrac run: %s\n", r.error().message.c_str());
      outputOk = false;
    }
  }
  if (cutFailed) return kExitScene;
  if (!outputOk) return kExitOutput;

  // ---- summary ------------------------------------------------------------------------
  if (!opt.quiet) {
    const FrameTotals t = sumStats(world, bodies);
    const int n = std::max(frames, 1);
    std::printf(
        "done: %d frames, simulated %.6g s in %s wall (%.2f ms/frame, %.2f ms/frame in "
        "the solver step)\n",
        frames, world.time(), formatDuration(wall).c_str(), 1e3 * wall / n, msTotal / n);
    std::printf("  iterations: %.2f Newton, %.1f linear per frame\n",
                static_cast<double>(newtonTotal) / n, static_cast<double>(linearTotal) / n);
    std::printf(
        "  final energy [J]: kinetic %.6g, elastic %.6g, gravity %.6g, contact %.6g, "
        "total %.6g (initial %.6g)\n",
        t.stats.kineticEnergy, t.stats.elasticEnergy, t.stats.gravityEnergy, t.stats.contactEnergy,
        t.total(), initial.total());
    printDisplacements(world, bodies);
    bool anyFracture = false;
    for (const BodyRecord& b : bodies) {
      if (!b.fracture) continue;
      anyFracture = true;
      const FractureStats f = world.fractureStats(b.id);
      std::printf("  %-16s broken edges %d of %d, fragments %d\n", b.name.c_str(), f.brokenEdges,
                  f.edgeCount, f.fragments);
    }
    if (anyFracture || !sc.cuts.empty()) {
      std::printf("  events: %lld edges broken, %lld fragments created; %zu cut%s applied\n",
                  edgeEvents, fragmentEvents, nextCut, nextCut == 1 ? "" : "s");
    }
    if (flaggedFrames > 0) {
      std::printf("  flagged steps: %d of %d (", flaggedFrames, frames);
      bool first = true;
      for (size_t k = 0; k < std::size(kFlagNames); ++k) {
        if (flagCounts[k] == 0) continue;
        std::printf("%s%s: %d", first ? "" : ", ", kFlagNames[k].name, flagCounts[k]);
        first = false;
      }
      std::printf(")\n  first at frame %d: %s\n", firstFlagFrame, firstFlagMessage.c_str());
    } else {
      std::printf("  all steps ok\n");
    }
    std::printf("  wrote %s\n", (outDir / "stats.csv").string().c_str());
    if (writeGrips) std::printf("  wrote %s\n", (outDir / "grips.csv").string().c_str());
    if (writeColliders) std::printf("  wrote %s\n", (outDir / "colliders.csv").string().c_str());
    if (writeHaptic) {
      std::printf("  wrote %s and haptic.svg\n", (outDir / "haptic.csv").string().c_str());
    }
    if (opt.vtk) std::printf("  wrote %s\n", (outDir / "fields.pvd").string().c_str());
    if (!opt.events.empty()) std::printf("  wrote %s\n", opt.events.c_str());
  } else if (flaggedFrames > 0) {
    std::fprintf(stderr, "graphfrac run: %d of %d steps flagged; first at frame %d: %s\n",
                 flaggedFrames, frames, firstFlagFrame, firstFlagMessage.c_str());
  }
  return flaggedFrames > 0 ? kExitFlagged : kExitOk;
}

}  // namespace gf::cli
