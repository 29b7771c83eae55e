// `graphfrac report error-vs-time SCENE`: what accuracy each solver setting pays for its speed
// (the multigrid trade-off of thesis sec 6.3.3-6.3.4). The scene runs once per solver setting, all
// in one process on the same machine state: first the reference (sparse Cholesky inside full Newton
// to 1e-10, i.e. the converged backward Euler step), then the direct solver with the scene's
// Newton count, PCG with several iteration caps, and multigrid setups as fixed V-cycle counts
// and as CG preconditioner. For each: ms per frame, the relative displacement error against
// the reference after N frames, the volume gain (table 6.1), broken edges and fragments. The
// result is a CSV and an SVG plot.
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "cli/csv_writer.h"
#include "cli/progress.h"
#include "cli/svg_plot.h"
#include "graphfrac/jobs.h"
#include "graphfrac/world.h"
#include "scene/scene.h"

namespace gf::cli {
namespace {

constexpr const char* kReportUsage =
    "usage: graphfrac report all [--quick] [--out DIR] [--results FILE] (see report all --help)\n"
    "       graphfrac report lab [--quick] [--only TEST] [--out DIR]   (see report lab --help)\n"
    "       graphfrac report error-vs-time SCENE [--frames N] [--out DIR] [--threads T]\n"
    "                    [--compare-threads T2] [--levels L1,L2,...] [--cycles C1,C2,...]\n"
    "                    [--pcg-caps K1,K2,...] [--tolerances R1,R2,...] [--smoothed 0|1]\n"
    "\n"
    "Runs SCENE once per solver setting, in one process, and writes DIR/error_vs_time.csv and\n"
    "DIR/error_vs_time.svg (default DIR = out/<scene name>/report):\n"
    "  reference  sparse Cholesky, full Newton to 1e-10 (the converged implicit step)\n"
    "  direct     sparse Cholesky with the scene's Newton iterations\n"
    "  pcg        block-Jacobi PCG capped at each of --pcg-caps (default 10,30,100,300)\n"
    "  mg         multigrid setups --levels (default: the scene's, 50/all and auto, the\n"
    "             size-chosen default), as --cycles V-cycles alone (default 1,2,4) and as the\n"
    "             preconditioner of CG to each relative residual of --tolerances (default\n"
    "             1e-6,1e-4,1e-3); with --smoothed 1 (the default) also with the smoothed\n"
    "             prolongation, as CG's preconditioner to the default tolerance (1e-4)\n"
    "Columns: ms per frame (wall clock of World::step) and CPU ms per frame (process CPU time,\n"
    "robust to other load; the plot's x axis), relative displacement error\n"
    "|x - x_ref| / |x_ref - X| after N frames (and the same against the direct run: the linear\n"
    "solver's share), volume gain 100 (V_N / V_0 - 1) [%], broken edges, fragments, average\n"
    "linear iterations per frame, flagged frames. With --compare-threads every setting but the\n"
    "reference runs again on T2 threads in the same process: its ms per frame there, the\n"
    "speed-up T -> T2, and whether the positions have the same bits (they must).\n";

struct Options {
  std::string scene, out;
  std::optional<int> frames, threads, compareThreads;
  std::vector<std::vector<int32_t>> levels;
  std::vector<int> cycles{1, 2, 4}, pcgCaps{10, 30, 100, 300};
  std::vector<double> tolerances{1e-6, 1e-4, 1e-3};
  bool smoothed = true;
};

struct SolverConfig {
  std::string family, label;
  // Applied to every body: kind, Newton iterations (0 = keep the scene's), caps, multigrid.
  LinearSolverKind kind = LinearSolverKind::Direct;
  int newton = 0;
  double newtonTolerance = 0;  // 0 = keep
  int maxLinear = 0;           // 0 = keep
  double linearTolerance = 0;  // 0 = keep
  std::optional<MultigridSettings> multigrid;
};

struct Outcome {
  bool ok = false;
  std::string error;
  double msPerFrame = 0, cpuMsPerFrame = 0, volumeGain = 0, linearPerFrame = 0, relError = 0;
  double relErrorDirect = 0;  // against the direct solver with the same Newton count
  int broken = 0, fragments = 0, flaggedFrames = 0;
  std::vector<double> x;  // all bodies' positions after the last frame, concatenated
  // The same setting on --compare-threads: ms per frame (0: not run) and whether x matched.
  double msCompare = 0;
  bool sameBits = false;
};

std::string levelsText(const std::vector<int32_t>& levels) {
  if (levels.empty()) return "auto";
  std::string s;
  for (int32_t n : levels) s += std::to_string(n) + "/";
  return s + "all";
}

// Comma-separated values, each accepted by parseOne(part, value); false on an empty list.
template <class T, class ParseOne>
bool parseList(const char* text, std::vector<T>& out, const ParseOne& parseOne) {
  out.clear();
  const std::string s(text);
  size_t pos = 0;
  while (pos <= s.size()) {
    const size_t comma = s.find(',', pos);
    const std::string part = s.substr(pos, comma == std::string::npos ? comma : comma - pos);
    T v{};
    if (part.empty() || !parseOne(part, v)) return false;
    out.push_back(v);
    if (comma == std::string::npos) break;
    pos = comma + 1;
  }
  return !out.empty();
}

bool parseIntList(const char* text, std::vector<int>& out) {
  return parseList(text, out, [](const std::string& part, int& v) {
    char* end = nullptr;
    const long n = std::strtol(part.c_str(), &end, 10);
    v = static_cast<int>(n);
    return *end == '\0' && n >= 1 && n <= 100000;
  });
}

// "1e-6,1e-3" -> {1e-6, 1e-3}: relative residuals in (0, 1).
bool parseToleranceList(const char* text, std::vector<double>& out) {
  return parseList(text, out, [](const std::string& part, double& v) {
    char* end = nullptr;
    v = std::strtod(part.c_str(), &end);
    return *end == '\0' && v > 0 && v < 1;
  });
}

// "50/all,50/1000/all" -> {{50}, {50, 1000}}.
bool parseLevels(const char* text, std::vector<std::vector<int32_t>>& out) {
  out.clear();
  std::string s(text);
  size_t pos = 0;
  while (pos <= s.size()) {
    const size_t comma = s.find(',', pos);
    std::string setup = s.substr(pos, comma == std::string::npos ? comma : comma - pos);
    std::vector<int32_t> levels;
    size_t p = 0;
    while (setup != "auto") {  // "auto": chosen from each body's size (no counts)
      const size_t slash = setup.find('/', p);
      const std::string part = setup.substr(p, slash == std::string::npos ? slash : slash - p);
      if (slash == std::string::npos) {
        if (part != "all" || levels.empty()) return false;
        break;
      }
      char* end = nullptr;
      const long v = std::strtol(part.c_str(), &end, 10);
      if (part.empty() || *end != '\0' || v < 1 || v > 10'000'000 ||
          (!levels.empty() && v <= levels.back()))
        return false;
      levels.push_back(static_cast<int32_t>(v));
      p = slash + 1;
    }
    out.push_back(levels);
    if (comma == std::string::npos) break;
    pos = comma + 1;
  }
  return !out.empty();
}

std::optional<std::string> parseOptions(int argc, char** argv, Options& opt) {
  // argv[0] = "report", argv[1] = "error-vs-time".
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
    if (a == "--frames" || a == "--threads" || a == "--compare-threads") {
      const char* v = value();
      char* end = nullptr;
      const long n = v ? std::strtol(v, &end, 10) : -1;
      if (!v || *end != '\0' || n < (a == "--frames" ? 1 : 0) || n > 1'000'000)
        return a + ": expected a non-negative integer (frames >= 1)";
      (a == "--frames"    ? opt.frames
       : a == "--threads" ? opt.threads
                          : opt.compareThreads) = static_cast<int>(n);
    } else if (a == "--out") {
      const char* v = value();
      if (!v) return std::string("--out: expected a directory");
      opt.out = v;
    } else if (a == "--levels") {
      const char* v = value();
      if (!v || !parseLevels(v, opt.levels))
        return std::string("--levels: expected setups like 50/all,50/1000/all,auto");
    } else if (a == "--cycles") {
      const char* v = value();
      if (!v || !parseIntList(v, opt.cycles))
        return std::string("--cycles: expected positive integers like 1,2,4");
    } else if (a == "--pcg-caps") {
      const char* v = value();
      if (!v || !parseIntList(v, opt.pcgCaps))
        return std::string("--pcg-caps: expected positive integers like 10,30,100");
    } else if (a == "--tolerances") {
      const char* v = value();
      if (!v || !parseToleranceList(v, opt.tolerances))
        return std::string("--tolerances: expected relative residuals in (0, 1) like 1e-6,1e-3");
    } else if (a == "--smoothed") {
      const char* v = value();
      if (!v || (std::strcmp(v, "0") != 0 && std::strcmp(v, "1") != 0))
        return std::string("--smoothed: expected 0 or 1");
      opt.smoothed = v[0] == '1';
    } else if (!a.empty() && a[0] == '-') {
      return "unknown option " + a;
    } else if (opt.scene.empty()) {
      opt.scene = a;
    } else {
      return "unexpected argument " + a;
    }
  }
  if (opt.scene.empty()) return std::string("missing SCENE");
  return std::nullopt;
}

double signedVolume(const double* x, const int32_t* t, size_t tets) {
  double v = 0;
  for (size_t e = 0; e < tets; ++e) {
    const double* a = x + 3 * t[4 * e];
    const double* b = x + 3 * t[4 * e + 1];
    const double* c = x + 3 * t[4 * e + 2];
    const double* d = x + 3 * t[4 * e + 3];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double z[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
    v += (u[0] * (w[1] * z[2] - w[2] * z[1]) - u[1] * (w[0] * z[2] - w[2] * z[0]) +
          u[2] * (w[0] * z[1] - w[1] * z[0])) /
         6;
  }
  return v;
}

Outcome runOnce(const scene::Scene& sc, const SolverConfig& cfg, int frames, int threads) {
  Outcome out;
  std::unique_ptr<JobSystem> jobs;
  if (threads != 1) jobs = std::make_unique<ThreadPoolJobSystem>(threads);
  WorldDef wdef = sc.world;
  wdef.jobs = jobs.get();
  World world(wdef);
  std::vector<BodyId> ids;
  std::vector<std::vector<int32_t>> tets;
  double v0 = 0;
  for (const scene::SceneBody& sb : sc.bodies) {
    scene::SceneBody body = sb;
    BodyDef& def = body.def;
    SolverSettings& s = def.solver;
    s.linearSolver = cfg.kind;
    if (cfg.newton > 0) s.newtonIterations = cfg.newton;
    if (cfg.newtonTolerance > 0) s.newtonTolerance = cfg.newtonTolerance;
    if (cfg.maxLinear > 0) s.maxLinearIterations = cfg.maxLinear;
    if (cfg.linearTolerance > 0) s.linearTolerance = cfg.linearTolerance;
    if (cfg.multigrid) s.multigrid = *cfg.multigrid;
    // The report measures the multigrid itself, also on bodies the size rule would solve
    // directly.
    if (cfg.kind == LinearSolverKind::Multigrid) s.multigrid.directBelowNodes = 0;
    v0 += signedVolume(def.mesh.positions.data(), def.mesh.tets.data(), def.mesh.tetCount());
    tets.push_back(def.mesh.tets);
    Result<BodyId> id = scene::addBody(world, body);
    if (!id.ok()) {
      out.error = sb.name + ": " + id.error().message;
      return out;
    }
    ids.push_back(id.value());
  }
  size_t nextCut = 0;
  long linear = 0;
  double ms = 0, cpuMs = 0;
  for (int frame = 1; frame <= frames; ++frame) {
    for (; nextCut < sc.cuts.size() && sc.cuts[nextCut].frame <= frame; ++nextCut) {
      const scene::SceneCut& c = sc.cuts[nextCut];
      if (Result<void> r = world.cut(ids[c.bodyIndex], c.blade); !r.ok()) {
        out.error = "cut: " + r.error().message;
        return out;
      }
    }
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = processCpuMs();
    const StepStatus st = world.step(sc.dt);
    ms += msSince(t0);
    cpuMs += processCpuMs() - c0;
    linear += st.linearIterations;
    if (!st.ok()) ++out.flaggedFrames;
  }
  double v = 0;
  for (size_t b = 0; b < ids.size(); ++b) {
    const std::span<const double> x = world.positions(ids[b]);
    out.x.insert(out.x.end(), x.begin(), x.end());
    v += signedVolume(x.data(), tets[b].data(), tets[b].size() / 4);
    const FractureStats fs = world.fractureStats(ids[b]);
    out.broken += fs.brokenEdges;
    out.fragments += fs.fragments;
  }
  out.msPerFrame = ms / frames;
  out.cpuMsPerFrame = cpuMs / frames;
  out.linearPerFrame = static_cast<double>(linear) / frames;
  out.volumeGain = 100 * (v / v0 - 1);
  out.ok = true;
  return out;
}

std::vector<SolverConfig> buildConfigs(const scene::Scene& sc, const Options& opt) {
  std::vector<SolverConfig> c;
  SolverConfig ref;
  ref.family = "reference";
  ref.label = "reference";
  ref.kind = LinearSolverKind::Direct;
  ref.newton = 50;
  ref.newtonTolerance = 1e-10;
  c.push_back(ref);
  SolverConfig direct;
  direct.family = "direct";
  direct.label = "direct";
  direct.kind = LinearSolverKind::Direct;
  c.push_back(direct);
  for (int cap : opt.pcgCaps) {
    SolverConfig p;
    p.family = "pcg";
    p.label = "pcg " + std::to_string(cap);
    p.kind = LinearSolverKind::PCG;
    p.maxLinear = cap;
    p.linearTolerance = 1e-6;
    c.push_back(p);
  }
  std::vector<std::vector<int32_t>> setups = opt.levels;
  if (setups.empty()) {
    for (const scene::SceneBody& b : sc.bodies)
      if (b.def.solver.linearSolver == LinearSolverKind::Multigrid)
        setups.push_back(b.def.solver.multigrid.levels);
    for (const std::vector<int32_t>& more : {std::vector<int32_t>{50}, std::vector<int32_t>{}})
      if (std::find(setups.begin(), setups.end(), more) == setups.end()) setups.push_back(more);
  }
  for (const auto& levels : setups) {
    for (int cycles : opt.cycles) {
      SolverConfig m;
      m.family = "mg cycles";
      m.label = levelsText(levels) + " x" + std::to_string(cycles);
      m.kind = LinearSolverKind::Multigrid;
      MultigridSettings s;
      s.levels = levels;
      s.preconditionCG = false;
      s.cycles = cycles;
      m.multigrid = s;
      c.push_back(m);
    }
    // The solver's default tolerance keeps the plain label, and the smoothed prolongation
    // solves to it.
    auto mgcg = [&](double tolerance, bool smoothed) {
      SolverConfig m;
      m.family = "mg-cg";
      char tol[32];
      std::snprintf(tol, sizeof tol, " %g", tolerance);
      m.label = levelsText(levels) + " cg" + (smoothed ? " smoothed" : "") +
                (tolerance == SolverSettings{}.linearTolerance ? "" : tol);
      m.kind = LinearSolverKind::Multigrid;
      MultigridSettings s;
      s.levels = levels;
      s.preconditionCG = true;
      s.smoothedProlongation = smoothed;
      m.multigrid = s;
      m.maxLinear = 100;
      m.linearTolerance = tolerance;
      c.push_back(m);
    };
    for (double tolerance : opt.tolerances) mgcg(tolerance, false);
    if (opt.smoothed) mgcg(SolverSettings{}.linearTolerance, true);
  }
  return c;
}

int errorVsTime(int argc, char** argv) {
  Options opt;
  if (argc >= 3 && (!std::strcmp(argv[2], "--help") || !std::strcmp(argv[2], "-h"))) {
    std::fputs(kReportUsage, stdout);
    return kExitOk;
  }
  if (std::optional<std::string> err = parseOptions(argc, argv, opt)) {
    std::fprintf(stderr, "graphfrac report: %s\n\n%s", err->c_str(), kReportUsage);
    return kExitUsage;
  }
  Result<scene::Scene> loaded = scene::loadScene(opt.scene);
  if (!loaded.ok()) {
    std::fprintf(stderr, "%s\n", loaded.error().message.c_str());
    return kExitScene;
  }
  const scene::Scene sc = std::move(loaded).value();
  const int frames = opt.frames.value_or(sc.frames);
  const int threads = opt.threads.value_or(sc.threads);
  namespace fs = std::filesystem;
  const fs::path outDir =
      opt.out.empty() ? fs::path("out") / sc.name / "report" : fs::path(opt.out);
  std::error_code ec;
  fs::create_directories(outDir, ec);
  if (ec) {
    std::fprintf(stderr, "graphfrac report: cannot create %s: %s\n", outDir.string().c_str(),
                 ec.message().c_str());
    return kExitOutput;
  }
  size_t tetCount = 0;
  std::vector<double> rest;
  for (const scene::SceneBody& b : sc.bodies) {
    tetCount += b.def.mesh.tetCount();
    rest.insert(rest.end(), b.def.mesh.positions.begin(), b.def.mesh.positions.end());
  }
  std::printf("graphfrac report error-vs-time: %s, %zu tets, %d frames of %g s, %d thread(s)\n",
              sc.name.c_str(), tetCount, frames, sc.dt, threads);

  const std::vector<SolverConfig> configs = buildConfigs(sc, opt);
  std::vector<Outcome> results;
  for (const SolverConfig& cfg : configs) {
    std::printf("  %-22s ", cfg.label.c_str());
    std::fflush(stdout);
    Outcome o = runOnce(sc, cfg, frames, threads);
    if (!o.ok) {
      std::printf("failed: %s\n", o.error.c_str());
      if (cfg.family == "reference") return kExitScene;
    } else {
      // |x - x_ref| / |x_ref - X|: the error relative to the reference's own displacement.
      // Against the direct solver with the same Newton count it is the linear solver's share.
      auto relativeTo = [&](const Outcome& r) {
        double num = 0, den = 0;
        for (size_t i = 0; i < o.x.size(); ++i) {
          num += (o.x[i] - r.x[i]) * (o.x[i] - r.x[i]);
          den += (r.x[i] - rest[i]) * (r.x[i] - rest[i]);
        }
        return den > 0 ? std::sqrt(num / den) : std::sqrt(num);
      };
      if (!results.empty() && results[0].ok) o.relError = relativeTo(results[0]);
      if (results.size() > 1 && results[1].ok) o.relErrorDirect = relativeTo(results[1]);
      std::printf(
          "%9.2f ms/frame (CPU %.2f)  error %.3e (vs direct %.3e)  volume gain %+.3f %%  broken %d "
          " "
          "fragments %d%s\n",
          o.msPerFrame, o.cpuMsPerFrame, o.relError, o.relErrorDirect, o.volumeGain, o.broken,
          o.fragments, o.flaggedFrames ? "  (flagged frames)" : "");
      if (opt.compareThreads && cfg.family != "reference") {
        const Outcome c = runOnce(sc, cfg, frames, *opt.compareThreads);
        o.msCompare = c.ok ? c.msPerFrame : 0;
        o.sameBits = c.ok && c.x.size() == o.x.size() &&
                     std::memcmp(c.x.data(), o.x.data(), 8 * o.x.size()) == 0;
        std::printf("  %-22s %9.2f ms/frame on %d thread(s): speed-up %.2f, %s\n", "", o.msCompare,
                    *opt.compareThreads, o.msCompare > 0 ? o.msPerFrame / o.msCompare : 0.0,
                    o.sameBits ? "same bits" : "DIFFERENT BITS");
      }
    }
    results.push_back(std::move(o));
  }

  const std::string csvPath = (outDir / "error_vs_time.csv").string();
  CsvWriter csv;
  Result<void> r = csv.open(
      csvPath, {"family", "setting", "ms_per_frame", "cpu_ms_per_frame", "rel_displacement_error",
                "rel_error_vs_direct", "volume_gain_pct", "broken_edges", "fragments",
                "linear_iterations_per_frame", "flagged_frames", "ok", "compare_threads",
                "ms_per_frame_compare", "speedup", "same_bits"});
  for (size_t i = 0; r.ok() && i < configs.size(); ++i) {
    const Outcome& o = results[i];
    r = csv.row({configs[i].family, configs[i].label, o.msPerFrame, o.cpuMsPerFrame, o.relError,
                 o.relErrorDirect, o.volumeGain, int64_t(o.broken), int64_t(o.fragments),
                 o.linearPerFrame, int64_t(o.flaggedFrames), int64_t(o.ok ? 1 : 0),
                 int64_t(o.msCompare > 0 ? *opt.compareThreads : 0), o.msCompare,
                 o.msCompare > 0 ? o.msPerFrame / o.msCompare : 0.0, int64_t(o.sameBits ? 1 : 0)});
  }
  if (r.ok()) r = csv.close();
  if (!r.ok()) {
    std::fprintf(stderr, "graphfrac report: %s\n", r.error().message.c_str());
    return kExitOutput;
  }

  const char* colours[] = {"#000000", "#7f3fbf", "#d62728", "#1f77b4", "#2ca02c"};
  const char* families[] = {"reference", "direct", "pcg", "mg cycles", "mg-cg"};
  PlotPanel err{
      "Error against run time", "CPU ms per frame", "relative displacement error", true, true, {}};
  PlotPanel lin{
      "Linear solver's share", "CPU ms per frame", "relative error against direct", true, true, {}};
  PlotPanel vol{
      "Volume gain against run time", "CPU ms per frame", "volume gain [%]", true, false, {}};
  for (int f = 0; f < 5; ++f) {
    PlotSeries se{families[f], colours[f], {}}, sl = se, sv = se;
    for (size_t i = 0; i < configs.size(); ++i) {
      if (configs[i].family != families[f] || !results[i].ok) continue;
      const Outcome& o = results[i];
      if (f > 0) se.points.push_back({o.cpuMsPerFrame, o.relError, configs[i].label});
      if (f > 1) sl.points.push_back({o.cpuMsPerFrame, o.relErrorDirect, configs[i].label});
      sv.points.push_back({o.cpuMsPerFrame, o.volumeGain, configs[i].label});
    }
    for (auto [panel, series] : {std::pair{&err, &se}, {&lin, &sl}, {&vol, &sv}})
      if (!series->points.empty()) panel->series.push_back(*series);
  }
  char caption[256];
  std::snprintf(caption, sizeof caption, "%s: %zu tets, %d frames of %g s, %d thread(s)",
                sc.name.c_str(), tetCount, frames, sc.dt, threads);
  const std::string svgPath = (outDir / "error_vs_time.svg").string();
  if (Result<void> w = writeSvg(svgPath, {err, lin, vol}, caption); !w.ok()) {
    std::fprintf(stderr, "graphfrac report: %s\n", w.error().message.c_str());
    return kExitOutput;
  }
  std::printf("  wrote %s and %s\n", csvPath.c_str(), svgPath.c_str());
  for (const Outcome& o : results)
    if (!o.ok || o.flaggedFrames > 0 || (o.msCompare > 0 && !o.sameBits)) return kExitFlagged;
  return kExitOk;
}

}  // namespace

int runReportCommand(int argc, char** argv) {
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
    std::fputs(kReportUsage, argc < 2 ? stderr : stdout);
    return argc < 2 ? kExitUsage : kExitOk;
  }
  if (!std::strcmp(argv[1], "error-vs-time")) return errorVsTime(argc, argv);
  if (!std::strcmp(argv[1], "lab")) return runLabReport(argc, argv);
  if (!std::strcmp(argv[1], "all")) return runAllReport(argc, argv);
  std::fprintf(stderr, "graphfrac report: unknown report '%s'\n\n%s", argv[1], kReportUsage);
  return kExitUsage;
}

}  // namespace gf::cli
