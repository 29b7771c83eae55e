// World: sculpting commands (thesis ch. 7): wet, dry, deform and pull brushes, the water
// queries, and the haptic probe the step publishes to.
#include <algorithm>
#include <cmath>
#include <string>

#include "kernels/clay.h"
#include "sculpt/brush_stages.h"
#include "solver/vector_ops.h"
#include "step/executor.h"
#include "step/timing.h"
#include "world/world_impl.h"

namespace gf {

namespace {
// The smallest G_d a deform brush applies (World::prepareBrushes).
constexpr double kMinDeformKernel = 1e-6;
// The stiffest pull [1/s^2]: beyond it a tether is a grip (World::setGripVelocity).
constexpr double kMaxPullStiffness = 1e12;

// The checks of wet and dry, then the stroke queued for the next step. `busy` is
// World::Impl::busy's message, `b` the body or null.
Result<void> queueStroke(const std::string& busy, BodyRecord* b, const WetBrush& brush,
                         const char* call, double sign) {
  if (!busy.empty()) return fail(busy);
  if (!b) return fail(call, ": stale or null BodyId");
  if (b->xfem) return fail(call, ": not supported for a body in CutMode::Xfem; nothing changed");
  if (!bounded3(brush.centre))
    return fail(call, ": brush.centre must be finite, within 1e9 m of the origin");
  if (!(std::isfinite(brush.radius) && brush.radius > 0 && brush.radius <= detail::kMaxMagnitude))
    return fail(call, ": brush.radius must be positive and at most 1e9 m, got ",
                std::to_string(brush.radius));
  if (!(std::isfinite(brush.rate) && brush.rate > 0))
    return fail(call, ": brush.rate must be a positive finite saturation per second, got ",
                std::to_string(brush.rate));
  if (!b->wetting) {
    b->wetting = std::make_unique<detail::WettingModel>(
        detail::buildWettingModel(b->model, b->model.wetting));
  }
  if (b->state.water.empty()) b->state.water.assign(size_t(b->model.tetCount), 0.0);
  detail::WaterStroke s;
  s.centre = {brush.centre.x, brush.centre.y, brush.centre.z};
  s.radius = brush.radius;
  s.rate = sign * brush.rate;
  b->strokes.push_back(s);
  return {};
}
}  // namespace

Result<void> World::wet(BodyId id, const WetBrush& brush) {
  return queueStroke(m_impl->busy("wet"), m_impl->get(id), brush, "wet", 1.0);
}

Result<void> World::dry(BodyId id, const WetBrush& brush) {
  return queueStroke(m_impl->busy("dry"), m_impl->get(id), brush, "dry", -1.0);
}

Result<void> World::deform(BodyId id, const DeformBrush& brush) {
  if (std::string e = m_impl->busy("deform"); !e.empty()) return fail(e);
  BodyRecord* b = m_impl->get(id);
  if (!b) return fail("deform: stale or null BodyId");
  if (b->xfem) return fail("deform: not supported for a body in CutMode::Xfem; nothing changed");
  if (!bounded3(brush.centre))
    return fail("deform: brush.centre must be finite, within 1e9 m of the origin");
  if (!(std::isfinite(brush.radius) && brush.radius > 0 && brush.radius <= detail::kMaxMagnitude))
    return fail("deform: brush.radius must be positive and at most 1e9 m, got ",
                std::to_string(brush.radius));
  if (!(std::isfinite(brush.k1) && brush.k1 > 0))
    return fail("deform: brush.k1 must be positive and finite [1/m], got ",
                std::to_string(brush.k1));
  if (!(std::isfinite(brush.k2) && brush.k2 > 0))
    return fail("deform: brush.k2 must be positive and finite [1/m], got ",
                std::to_string(brush.k2));
  b->deformBrushes.push_back(brush);
  return {};
}

Result<void> World::pull(BodyId id, const PullBrush& brush) {
  if (std::string e = m_impl->busy("pull"); !e.empty()) return fail(e);
  BodyRecord* b = m_impl->get(id);
  if (!b) return fail("pull: stale or null BodyId");
  if (b->xfem) return fail("pull: not supported for a body in CutMode::Xfem; nothing changed");
  if (brush.nodes.empty()) return fail("pull: brush.nodes is empty");
  if (brush.targets.size() != brush.nodes.size())
    return fail("pull: brush.targets has ", std::to_string(brush.targets.size()), " entries for ",
                std::to_string(brush.nodes.size()), " nodes");
  if (!(std::isfinite(brush.stiffness) && brush.stiffness > 0 &&
        brush.stiffness <= kMaxPullStiffness))
    return fail("pull: brush.stiffness must be positive and at most 1e12 1/s^2, got ",
                std::to_string(brush.stiffness));
  const int32_t nodeCount = b->model.nodeCount;
  for (size_t i = 0; i < brush.nodes.size(); ++i) {
    if (brush.nodes[i] < 0 || brush.nodes[i] >= nodeCount)
      return fail("pull: brush.nodes[", std::to_string(i), "] = ", std::to_string(brush.nodes[i]),
                  " is out of range [0, ", std::to_string(nodeCount), ")");
    const glm::dvec3 t = brush.targets[i];
    if (!(std::isfinite(t.x) && std::isfinite(t.y) && std::isfinite(t.z) &&
          std::abs(t.x) <= detail::kMaxMagnitude && std::abs(t.y) <= detail::kMaxMagnitude &&
          std::abs(t.z) <= detail::kMaxMagnitude))
      return fail("pull: brush.targets[", std::to_string(i),
                  "] must be finite, within 1e9 m of the origin");
  }
  if (b->pullStiffness.empty()) {
    b->pullStiffness.assign(size_t(nodeCount), 0.0);
    b->pullTargetSum.assign(3 * size_t(nodeCount), 0.0);
  }
  for (size_t i = 0; i < brush.nodes.size(); ++i) {
    const size_t n = size_t(brush.nodes[i]);
    if (b->pullStiffness[n] == 0) b->pulledNodes.push_back(int32_t(n));
    b->pullStiffness[n] += brush.stiffness;
    for (int k = 0; k < 3; ++k)
      b->pullTargetSum[3 * n + size_t(k)] += brush.stiffness * brush.targets[i][k];
  }
  return {};
}

glm::dvec3 World::pullForce(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  return b ? b->pullForce : glm::dvec3(0);
}

void World::Impl::prepareBrushes(double h) {
  const detail::CpuExecutor exec(*jobs);
  for (Slot& s : slots) {
    BodyRecord* b = s.body.get();
    if (!b) continue;
    detail::FemState& st = b->state;
    b->pullImpulse = {0, 0, 0};
    if (!b->pulledNodes.empty()) {
      st.tether.assign(size_t(b->model.nodeCount), 0.0);
      st.tetherTarget.assign(3 * size_t(b->model.nodeCount), 0.0);
      exec.run(int32_t(b->pulledNodes.size()), 256,
               detail::PullTetherStage{b->pulledNodes.data(), st.fixedNode.data(),
                                       b->pullStiffness.data(), b->pullTargetSum.data(), h,
                                       st.tether.data(), st.tetherTarget.data()});
    }
    if (b->deformBrushes.empty()) continue;
    st.drag.assign(size_t(b->model.nodeCount), 0.0);
    b->deformBrushData.clear();
    for (const DeformBrush& br : b->deformBrushes)
      b->deformBrushData.push_back(
          {Vec3{br.centre.x, br.centre.y, br.centre.z}, br.radius, br.k1, br.k2});
    exec.run(b->model.nodeCount, 256,
             detail::DeformDragStage{st.x.data(), st.fixedNode.data(), b->deformBrushData.data(),
                                     int32_t(b->deformBrushData.size()), 1.0 / def.substeps,
                                     kMinDeformKernel, st.drag.data()});
    b->deformBrushes.clear();
  }
}

void World::Impl::sumPullImpulses(double h) {
  const detail::CpuExecutor exec(*jobs);
  for (Slot& s : slots) {
    BodyRecord* b = s.body.get();
    if (!b || b->state.tether.empty()) continue;
    const detail::FemState& st = b->state;
    detail::PullImpulseTerm term{b->pulledNodes.data(),  st.nodeMass.data(), st.tether.data(),
                                 st.tetherTarget.data(), st.x.data(),        h};
    for (int c = 0; c < 3; ++c) {
      term.c = c;
      b->pullImpulse[c] += exec.reduce<detail::SumOp>(int32_t(b->pulledNodes.size()), term);
    }
  }
}

void World::Impl::clearBrushes(double dt) {
  for (Slot& s : slots) {
    BodyRecord* b = s.body.get();
    if (!b) continue;
    b->state.drag.clear();
    b->pullForce = glm::dvec3(0);
    if (b->pulledNodes.empty()) continue;
    b->pullForce = glm::dvec3(b->pullImpulse.x, b->pullImpulse.y, b->pullImpulse.z) / dt;
    b->state.tether.clear();
    b->state.tetherTarget.clear();
    b->pullStiffness.clear();
    b->pullTargetSum.clear();
    b->pulledNodes.clear();
  }
}

Result<TetMesh> World::currentMesh(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  if (!b) return fail("currentMesh: stale or null BodyId");
  TetMesh m;
  m.positions = b->state.x;
  m.tets = b->model.tets;
  for (size_t t = 0; t < m.tetCount(); ++t) {
    double e[3][3];
    const size_t a = 3 * size_t(m.tets[4 * t]);
    for (int k = 0; k < 3; ++k)
      for (int i = 0; i < 3; ++i)
        e[k][i] = m.positions[3 * size_t(m.tets[4 * t + size_t(k) + 1]) + size_t(i)] -
                  m.positions[a + size_t(i)];
    const double det = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                       e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                       e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
    if (!(det > 0))
      return fail("currentMesh: tet ", std::to_string(t),
                  " is inverted or flat in the current shape (6V = ", std::to_string(det), ")");
  }
  return m;
}

std::span<const double> World::waterMass(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  return b ? std::span<const double>(b->state.water) : std::span<const double>();
}

std::span<const double> World::saturation(BodyId id) {
  BodyRecord* b = m_impl->get(id);
  if (!b || !b->wetting || b->state.water.empty() || m_impl->stepping.load()) return {};
  const std::vector<double>& cap = b->wetting->capacity;
  b->saturation.resize(cap.size());
  for (size_t t = 0; t < cap.size(); ++t) b->saturation[t] = b->state.water[t] / cap[t];
  return b->saturation;
}

Result<void> World::attachHapticProbe(HapticProbe* probe, int collider) {
  if (std::string e = m_impl->busy("attachHapticProbe"); !e.empty()) return fail(e);
  if (probe && (collider < 0 || size_t(collider) >= m_impl->colliders.size()))
    return fail("attachHapticProbe: collider ", std::to_string(collider), " out of range [0, ",
                std::to_string(m_impl->colliders.size()), ")");
  m_impl->probe = probe;
  m_impl->probeCollider = collider;
  return {};
}

void World::Impl::advanceWater(double dt) {
  const auto t0 = detail::Clock::now();
  bool any = false;
  for (Slot& s : slots) {
    BodyRecord* b = s.body.get();
    if (!b || !b->wetting || b->state.water.empty()) continue;
    any = true;
    if (b->fracture && (b->fracture->brokenCount() > 0 || !b->wetting->open.empty()))
      detail::updateCrackBarriers(b->model, *b->wetting,
                                  b->fracture->fragments().nodeFragment().data(), *jobs);
    detail::advanceWater(b->model, *b->wetting, b->state.water, b->state.x.data(), b->strokes, dt,
                         *jobs);
    b->strokes.clear();
    detail::refreshWetStiffness(b->model, *b->wetting, b->state, *jobs);
  }
  if (any) timings.wettingMs = detail::msSince(t0);
}

void World::Impl::publishProbe(double dt) {
  // The colliders may have been replaced by fewer since the probe was attached: then nothing.
  if (!probe || size_t(probeCollider) >= impulses.size()) return;
  probe->publish(-impulses[size_t(probeCollider)] / dt, time);
}

}  // namespace gf
