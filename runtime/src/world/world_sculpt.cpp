// World: sculpting commands (thesis ch. 7): wet and dry brushes, the water queries, and the
// haptic probe the step publishes to.
#include <algorithm>
#include <cmath>
#include <string>

#include "kernels/clay.h"
#include "solver/vector_ops.h"
#include "step/timing.h"
#include "world/world_impl.h"

namespace gf {

namespace {
// The smallest G_d a deform brush applies (World::prepareDeformDrag).
constexpr double kMinDeformKernel = 1e-6;

// The checks of wet and dry, then the stroke queued for the next step. `busy` is
// World::Impl::busy's message, `b` the body or null.
Result<void> queueStroke(const std::string& busy, BodyRecord* b, const WetBrush& brush,
                         const char* call, double sign) {
  if (!busy.empty()) return fail(busy);
  if (!b) return fail(call, ": stale or null BodyId");
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

void World::Impl::prepareDeformDrag() {
  for (Slot& s : slots) {
    BodyRecord* b = s.body.get();
    if (!b || b->deformBrushes.empty()) continue;
    detail::FemState& st = b->state;
    st.drag.assign(size_t(b->model.nodeCount), 0.0);
    const std::vector<DeformBrush>& brushes = b->deformBrushes;
    const double perSubstep = 1.0 / def.substeps;
    detail::forRanges(*jobs, uint32_t(b->model.nodeCount), 256, [&](uint32_t lo, uint32_t hi) {
      for (uint32_t n = lo; n < hi; ++n) {
        if (st.fixedNode[n]) continue;  // prescribed by a grip
        double g = 1;
        for (const DeformBrush& br : brushes) {
          const double dx = st.x[3 * n] - br.centre.x, dy = st.x[3 * n + 1] - br.centre.y,
                       dz = st.x[3 * n + 2] - br.centre.z;
          // Eq 7.7.
          g *= clayDamping(std::sqrt(dx * dx + dy * dy + dz * dz), br.radius, br.k1, br.k2);
        }
        // A free node's velocity is scaled by g over the whole step: 1 / (1 + w) per substep.
        // Far from the tool g underflows (exp(k2 r) overflows beyond k2 r = 709): a node held
        // at 1e-6 of its velocity is as still as a frozen one, and w stays finite.
        st.drag[n] = std::pow(std::max(g, kMinDeformKernel), -perSubstep) - 1;
      }
    });
    b->deformBrushes.clear();
  }
}

void World::Impl::clearDeformDrag() {
  for (Slot& s : slots)
    if (s.body) s.body->state.drag.clear();
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
