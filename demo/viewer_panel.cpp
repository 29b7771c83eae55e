// graphfrac-viewer's panel figures and their text (viewer_panel.h).
#include "viewer_panel.h"

#include <cstdarg>
#include <cstdio>

namespace gf::demo {
namespace {

std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
std::string format(const char* fmt, ...) {
  char text[512];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(text, sizeof text, fmt, args);
  va_end(args);
  return text;
}

}  // namespace

const char* materialModelName(MaterialModel m) {
  switch (m) {
    case MaterialModel::Corotated:
      return "corotated";
    case MaterialModel::StVK:
      return "StVK";
    case MaterialModel::NeoHookean:
      return "Neo-Hookean";
    case MaterialModel::StableNeoHookean:
      return "stable Neo-Hookean";
  }
  return "?";
}

PanelFigures panelFigures(const scene::BulletScene& sim, double dt, const StepStatus& lastStep,
                          std::optional<PickedMaterial> picked) {
  PanelFigures f;
  f.frame = sim.frame();
  f.dt = dt;
  f.timings = sim.timings();
  f.lastStep = lastStep;
  for (size_t i = 0; i < sim.bodyCount(); ++i) {
    const FractureStats s = sim.world().fractureStats(sim.body(i));
    if (s.edgeCount > 0) {
      f.brokenEdges += s.brokenEdges;
      f.edgeCount += s.edgeCount;
      f.fragments += s.fragments;
    } else {
      f.fragments += 1;
    }
  }
  f.handedOff = sim.handedOff();
  f.picked = std::move(picked);
  return f;
}

std::vector<std::string> panelLines(const PanelFigures& f) {
  std::vector<std::string> l;
  const StepTimings& w = f.timings.world;
  l.push_back(format("frame %d  t %.3f s  dt %.4g s", f.frame, f.frame * f.dt, f.dt));
  l.push_back(format("frame %.1f ms: world %.1f, Bullet %.1f", f.timings.totalMs, w.totalMs,
                     f.timings.bulletMs));
  l.push_back(
      format("  elements %.1f  assembly %.1f  solve %.1f", w.elementsMs, w.assemblyMs, w.solveMs));
  l.push_back(format("  fracture %.1f  contact %.1f  surface %.1f", w.fractureMs, w.contactMs,
                     w.surfaceMs));
  l.push_back(format("solver: %d Newton, %d linear iterations, residual %.2e",
                     f.lastStep.newtonIterations, f.lastStep.linearIterations,
                     f.lastStep.residual));
  if (!f.lastStep.ok()) l.push_back("step: " + f.lastStep.message);
  l.push_back(format("fragments %lld, broken edges %lld of %lld, handed to Bullet %zu",
                     static_cast<long long>(f.fragments), static_cast<long long>(f.brokenEdges),
                     static_cast<long long>(f.edgeCount), f.handedOff));
  l.emplace_back();
  if (f.picked) {
    const Material& m = f.picked->material;
    l.push_back(format("picked: %s (%s)", f.picked->body.c_str(), materialModelName(m.model)));
    l.push_back(format("  E %.3g Pa  nu %.3g  rho %.4g kg/m^3", m.youngsModulus, m.poissonRatio,
                       m.density));
    if (f.picked->fracture.enabled)
      l.push_back(format("  strength %.3g Pa  R_d %.3g", f.picked->fracture.strength,
                         f.picked->fracture.radius));
    else
      l.push_back("  no fracture");
  }
  return l;
}

}  // namespace gf::demo
