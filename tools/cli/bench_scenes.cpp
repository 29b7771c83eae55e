// `graphfrac bench scenes`: the fixed scene list of issue 19 item 3, 4k to 680k tets, each with
// fracture off and on. Per case: ms per stage, fps, the process's peak resident memory and the
// linear solver's error against a converged reference, printed as CSV and written as CSV and
// JSON (--csv, --json) with the same rows.
//
// The reference is the same scene stepped the same frames from the same start with the same
// Newton iterations, but each linear system solved by multigrid-preconditioned CG to a true
// relative residual |b - A x| / |b| of 1e-12 (cap 2000 iterations; when a frame stops short,
// the worst residual the reference reached is printed and kept in the row): the difference is what
// the default solver's tolerance and early stop leave in the positions, not a discretisation error.
// It is reported as |x - x_ref| / |x_ref - X0| over all nodes after the last frame, X0 the start
// positions (relative displacement error). With fracture on, the two runs may break different
// edges; the broken counts of both are kept.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli/bench_args.h"
#include "cli/bench_cases.h"
#include "cli/commands.h"
#include "cli/progress.h"
#include "graphfrac/world.h"
#include "scene/scene.h"

namespace gf::cli {

namespace {

struct Row {
  std::string name;
  bool fracture = false;
  size_t tets = 0;
  int frames = 0;
  double msFrame = 0, fps = 0, cpuMsFrame = 0;
  double msElements = 0, msAssembly = 0, msSolve = 0, msFracture = 0, msContact = 0, msOther = 0;
  double linearIterations = 0;
  double peakMb = -1;  // -1: no /proc/self/status
  bool peakReset = false;
  double solverError = -1;  // -1: reference not run
  int broken = 0, brokenReference = -1;
  double referenceResidual = -1;  // worst relative linear residual the reference reached
};

// Resets the kernel's resident-memory high-water mark (VmHWM) to the current resident size;
// false where /proc/self/clear_refs is missing or refuses "5" (kernels before 4.0, some
// containers), and VmHWM is then the peak since process start.
bool resetPeakMemory() {
  const int fd = ::open("/proc/self/clear_refs", O_WRONLY);
  if (fd < 0) return false;
  const bool ok = ::write(fd, "5", 1) == 1;
  ::close(fd);
  return ok;
}

// VmHWM in MB (2^20 bytes), -1 without /proc.
double peakMemoryMb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;
  return -1;
}

int countBroken(const World& world, BodyId id) {
  int n = 0;
  for (uint8_t b : world.brokenEdges(id)) n += b ? 1 : 0;
  return n;
}

std::string csvHeader() {
  return "case,fracture,tets,frames,ms_frame,fps,cpu_ms_frame,ms_elements,ms_assembly,ms_solve,"
         "ms_fracture,ms_contact,ms_other,linear_iterations,peak_mb,peak_reset,solver_error,"
         "broken_edges,broken_edges_reference,reference_residual";
}

std::string csvLine(const Row& r) {
  char buf[512];
  std::snprintf(
      buf, sizeof buf,
      "%s,%d,%zu,%d,%.2f,%.3f,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.1f,%.1f,%d,%.3e,%d,%d,%.3e",
      r.name.c_str(), r.fracture ? 1 : 0, r.tets, r.frames, r.msFrame, r.fps, r.cpuMsFrame,
      r.msElements, r.msAssembly, r.msSolve, r.msFracture, r.msContact, r.msOther,
      r.linearIterations, r.peakMb, r.peakReset ? 1 : 0, r.solverError, r.broken, r.brokenReference,
      r.referenceResidual);
  return buf;
}

nlohmann::json jsonRow(const Row& r) {
  return {{"case", r.name},
          {"fracture", r.fracture},
          {"tets", r.tets},
          {"frames", r.frames},
          {"ms_frame", r.msFrame},
          {"fps", r.fps},
          {"cpu_ms_frame", r.cpuMsFrame},
          {"ms_elements", r.msElements},
          {"ms_assembly", r.msAssembly},
          {"ms_solve", r.msSolve},
          {"ms_fracture", r.msFracture},
          {"ms_contact", r.msContact},
          {"ms_other", r.msOther},
          {"linear_iterations", r.linearIterations},
          {"peak_mb", r.peakMb},
          {"peak_reset", r.peakReset},
          {"solver_error", r.solverError},
          {"broken_edges", r.broken},
          {"broken_edges_reference", r.brokenReference},
          {"reference_residual", r.referenceResidual}};
}

}  // namespace

int benchScenes(int argc, char** argv) {
  int frames = 5, bigFrames = 1, referenceOn = 1;
  std::string only, csvPath, jsonPath;
  if (const int e = parseBenchArgs("scenes", argc, argv,
                                   {{"--frames", &frames, 1, kBenchMaxCount},
                                    {"--big-frames", &bigFrames, 1, kBenchMaxCount},
                                    {"--reference", &referenceOn, 0, 1},
                                    {"--only", &only},
                                    {"--csv", &csvPath},
                                    {"--json", &jsonPath}});
      e != kExitOk)
    return e;
  const bool reference = referenceOn != 0;
  if (const std::string e = only.empty() ? "" : unknownBenchCase(only, true); !e.empty()) {
    std::fprintf(stderr, "bench scenes: %s\n", e.c_str());
    return kExitUsage;
  }
  const bool canReset = resetPeakMemory();
  std::printf(
      "# %d frame(s) per case after one warm-up frame; %d frame(s) for the 680k-tet box (seconds "
      "per frame on a small CPU); default solver settings, one thread\n",
      frames, bigFrames);
  std::printf(
      "# peak_mb: VmHWM of the process over the case's world (%s); solver_error: |x - x_ref| / "
      "|x_ref - X0| after the last frame, x_ref the same frames with every linear system solved "
      "by multigrid-preconditioned CG to a true relative residual of 1e-12 (%s)\n",
      canReset ? "high-water mark reset before each case via /proc/self/clear_refs"
               : "NO reset: /proc/self/clear_refs refused, so the peak since process start",
      reference ? "run" : "not run: --reference 0, printed as -1");
  std::printf("%s\n", csvHeader().c_str());
  std::vector<Row> rows;
  for (const BenchCase& c : benchCases()) {
    if (!only.empty() && only != c.name) continue;
    for (bool fracture : {false, true}) {
      Row row;
      row.name = c.name;
      row.fracture = fracture;
      row.frames = c.big ? bigFrames : frames;
      const std::string text = benchSceneText(c, "{}", fracture);
      gf::Result<scene::Scene> sc = scene::parseScene(text, c.name, "");
      if (!sc.ok()) {
        std::fprintf(stderr, "%s\n", sc.error().message.c_str());
        return kExitScene;
      }
      row.tets = sc.value().bodies[0].def.mesh.tetCount();
      const std::vector<double> start = sc.value().bodies[0].def.mesh.positions;
      const double dt = sc.value().dt;
      std::vector<double> x;
      {
        row.peakReset = resetPeakMemory();
        WorldDef wdef = sc.value().world;
        wdef.jobs = nullptr;
        World world(wdef);
        gf::Result<BodyId> id = scene::addBody(world, sc.value().bodies[0]);
        if (!id.ok()) {
          std::fprintf(stderr, "%s: %s\n", c.name, id.error().message.c_str());
          return kExitScene;
        }
        (void)world.step(dt);  // warm-up: first-use allocations
        long linear = 0;
        double total = 0;
        const double cpu0 = processCpuMs();
        const auto t0 = std::chrono::steady_clock::now();
        for (int f = 0; f < row.frames; ++f) {
          const StepStatus st = world.step(dt);
          linear += st.linearIterations;
          const StepTimings& t = world.timings();
          row.msElements += t.elementsMs;
          row.msAssembly += t.assemblyMs;
          row.msSolve += t.solveMs;
          row.msFracture += t.fractureMs;
          row.msContact += t.contactMs;
          total += t.totalMs;
        }
        const double n = row.frames;
        row.msFrame = msSince(t0) / n;
        row.cpuMsFrame = (processCpuMs() - cpu0) / n;
        row.fps = 1000.0 / row.msFrame;
        row.msElements /= n;
        row.msAssembly /= n;
        row.msSolve /= n;
        row.msFracture /= n;
        row.msContact /= n;
        // Everything the step does outside the named stages (integration, grips, bookkeeping).
        row.msOther = total / n - row.msElements - row.msAssembly - row.msSolve - row.msFracture -
                      row.msContact;
        row.linearIterations = double(linear) / n;
        row.peakMb = peakMemoryMb();
        row.broken = countBroken(world, id.value());
        const std::span<const double> p = world.positions(id.value());
        x.assign(p.begin(), p.end());
      }
      if (reference) {
        gf::Result<scene::Scene> ref =
            scene::parseScene(benchSceneText(c,
                                             R"({"linear": "multigrid", "linear_tolerance": 1e-12,
                          "max_linear_iterations": 2000})",
                                             fracture),
                              c.name, "");
        if (!ref.ok()) {
          std::fprintf(stderr, "%s\n", ref.error().message.c_str());
          return kExitScene;
        }
        WorldDef wdef = ref.value().world;
        wdef.jobs = nullptr;
        World world(wdef);
        gf::Result<BodyId> id = scene::addBody(world, ref.value().bodies[0]);
        if (!id.ok()) {
          std::fprintf(stderr, "%s: %s\n", c.name, id.error().message.c_str());
          return kExitScene;
        }
        int short_ = 0;
        row.referenceResidual = 0;
        for (int f = 0; f <= row.frames; ++f) {
          const StepStatus status = world.step(dt);
          short_ += status.has(kStepNotConverged) ? 1 : 0;
          row.referenceResidual = std::max(row.referenceResidual, status.residual);
        }
        // Round-off floors a large system's residual above 1e-12: the row then carries the
        // residual the reference did reach, which bounds how far the error figure can be trusted.
        if (short_ > 0)
          std::printf(
              "# %s: the reference stopped short of 1e-12 in %d frame(s), worst relative "
              "residual %.3e\n",
              c.name, short_, row.referenceResidual);
        const std::span<const double> xr = world.positions(id.value());
        double diff = 0, disp = 0;
        for (size_t k = 0; k < xr.size() && k < x.size(); ++k) {
          diff += (x[k] - xr[k]) * (x[k] - xr[k]);
          disp += (xr[k] - start[k]) * (xr[k] - start[k]);
        }
        row.solverError = disp > 0 ? std::sqrt(diff / disp) : 0;
        row.brokenReference = countBroken(world, id.value());
      }
      std::printf("%s\n", csvLine(row).c_str());
      std::fflush(stdout);
      rows.push_back(row);
    }
  }
  if (!csvPath.empty()) {
    std::ofstream out(csvPath);
    out << csvHeader() << "\n";
    for (const Row& r : rows) out << csvLine(r) << "\n";
    if (!out) {
      std::fprintf(stderr, "bench scenes: cannot write --csv %s\n", csvPath.c_str());
      return kExitOutput;
    }
  }
  if (!jsonPath.empty()) {
    nlohmann::json doc = {
        {"peak_reset_supported", canReset},
        {"reference",
         "same frames, every linear system by multigrid-preconditioned CG to a true "
         "relative residual of 1e-12"},
        {"rows", nlohmann::json::array()}};
    for (const Row& r : rows) doc["rows"].push_back(jsonRow(r));
    std::ofstream out(jsonPath);
    out << doc.dump(1) << "\n";
    if (!out) {
      std::fprintf(stderr, "bench scenes: cannot write --json %s\n", jsonPath.c_str());
      return kExitOutput;
    }
  }
  return kExitOk;
}

}  // namespace gf::cli
