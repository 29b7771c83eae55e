// World: snapshots (a copy of everything a step reads) and restore, and the state hash that
// determinism checks compare.
#include <memory>
#include <string>
#include <vector>

#include "world/world_impl.h"

namespace gf {

// Everything of one body that a step reads and a run changes; the model is fixed.
struct BodySnapshot {
  uint32_t slot = 0, generation = 0;
  int32_t nodeCount = 0, tetCount = 0;
  detail::FemState state;
  std::vector<double> pendingForce;
  std::vector<detail::WaterStroke> strokes;  // wet and dry brushes queued for the next step
  std::vector<DeformBrush> deformBrushes;    // and deform brushes
  bool hasFracture = false;
  detail::FractureData fracture;
  detail::MultigridState solver;
};

struct WorldSnapshot::Data {
  uint64_t world = 0;  // the World it was taken of
  double time = 0, lastSubstep = 0;
  std::vector<Collider> colliderDefs;  // moving colliders are state too
  std::vector<ColliderData> colliders;
  std::vector<glm::dvec3> impulses, angularImpulses;
  std::vector<BodySnapshot> bodies;  // live bodies in slot order
  std::vector<FractureEvent> fractureEvents;
  std::vector<FragmentEvent> fragmentEvents;
};

double WorldSnapshot::time() const { return m_data ? m_data->time : 0.0; }

WorldSnapshot World::snapshot() const {
  const Impl& w = *m_impl;
  auto d = std::make_shared<WorldSnapshot::Data>();
  d->world = w.id;
  d->time = w.time;
  d->lastSubstep = w.lastSubstep;
  d->colliderDefs = w.def.colliders;
  d->colliders = w.colliders;
  d->impulses = w.impulses;
  d->angularImpulses = w.angularImpulses;
  d->fractureEvents = w.fractureEvents;
  d->fragmentEvents = w.fragmentEvents;
  for (size_t si = 0; si < w.slots.size(); ++si) {
    const BodyRecord* b = w.slots[si].body.get();
    if (!b) continue;
    BodySnapshot s;
    s.slot = uint32_t(si);
    s.generation = w.slots[si].generation;
    s.nodeCount = b->model.nodeCount;
    s.tetCount = b->model.tetCount;
    s.state = b->state;
    s.pendingForce = b->pendingForce;
    s.strokes = b->strokes;
    s.deformBrushes = b->deformBrushes;
    s.hasFracture = b->fracture != nullptr;
    if (b->fracture) s.fracture = b->fracture->data();
    s.solver = b->integrator->solverState();
    d->bodies.push_back(std::move(s));
  }
  WorldSnapshot out;
  out.m_data = std::move(d);
  return out;
}

Result<void> World::restore(const WorldSnapshot& snapshot) {
  if (std::string e = m_impl->busy("restore"); !e.empty()) return fail(e);
  if (snapshot.empty()) return fail("restore: the snapshot is empty");
  Impl& w = *m_impl;
  const WorldSnapshot::Data& d = *snapshot.m_data;
  // All checks first, so a mismatch changes nothing. Another world with the same body slots
  // would pass the checks below and get colliders and states that are not its own.
  if (d.world != w.id) return fail("restore: the snapshot was taken of another World");
  size_t live = 0;
  for (const Slot& s : w.slots) live += s.body ? 1 : 0;
  if (live != d.bodies.size())
    return fail("restore: the world holds ", std::to_string(live), " bodies, the snapshot ",
                std::to_string(d.bodies.size()));
  for (const BodySnapshot& s : d.bodies) {
    const std::string which = "restore: body " + std::to_string(s.slot + 1) + ": ";
    if (s.slot >= w.slots.size() || !w.slots[s.slot].body ||
        w.slots[s.slot].generation != s.generation)
      return fail(which, "not in this world (created or destroyed since the snapshot?)");
    const BodyRecord& b = *w.slots[s.slot].body;
    if (b.model.nodeCount != s.nodeCount || b.model.tetCount != s.tetCount ||
        (b.fracture != nullptr) != s.hasFracture || b.state.Fp.size() != s.state.Fp.size())
      return fail(which, "mesh, fracture or plasticity differ from the snapshot's");
    // The snapshot does not hold which nodes a hand-off prescribed; refuse rather than restore
    // a body half rigid.
    if (b.xfem)
      return fail(which,
                  "is in CutMode::Xfem (its enriched DOFs and cuts are not in a snapshot); "
                  "restoring it is not supported yet");
    if (!b.rigid.empty())
      return fail(which,
                  "has fragments handed to rigid physics (detachFragment); restoring "
                  "across a hand-off is not supported yet");
  }
  for (const BodySnapshot& s : d.bodies) {
    BodyRecord& b = *w.slots[s.slot].body;
    b.state = s.state;
    b.pendingForce = s.pendingForce;
    b.strokes = s.strokes;
    b.deformBrushes = s.deformBrushes;
    if (b.fracture) b.fracture->restore(s.fracture);
    b.stepEndValid = false;
    // Cannot fail: the same set-up succeeded when the body was created.
    if (Result<void> r = b.integrator->restoreSolver(b.model, b.state, s.solver); !r)
      return fail("restore: body ", std::to_string(s.slot + 1), ": ", r.error().message);
    b.contactSurface.reset();  // made again from the restored fragments
    if (b.surface) {
      b.surface->brokenCount = ~uint64_t(0);  // force a full rebuild
      w.updateSurface(b);
    }
  }
  w.time = d.time;
  w.lastSubstep = d.lastSubstep;
  w.def.colliders = d.colliderDefs;
  w.colliders = d.colliders;
  w.impulses = d.impulses;
  w.angularImpulses = d.angularImpulses;
  w.fractureEvents = d.fractureEvents;
  w.fragmentEvents = d.fragmentEvents;
  return {};
}

uint64_t World::stateHash() const {
  uint64_t h = 14695981039346656037ull;  // FNV-1a 64-bit offset basis
  auto mix = [&h](const void* data, size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
  };
  const Impl& w = *m_impl;
  for (size_t si = 0; si < w.slots.size(); ++si) {
    const BodyRecord* b = w.slots[si].body.get();
    if (!b) continue;
    const uint32_t ids[2] = {uint32_t(si + 1), w.slots[si].generation};
    mix(ids, sizeof ids);
    mix(b->state.x.data(), b->state.x.size() * sizeof(double));
    mix(b->state.v.data(), b->state.v.size() * sizeof(double));
    if (b->fracture) mix(b->fracture->broken().data(), b->fracture->broken().size());
    mix(b->state.water.data(), b->state.water.size() * sizeof(double));  // empty: never wetted
    mix(b->state.contactLoad.data(), b->state.contactLoad.size() * sizeof(double));
  }
  mix(&w.time, sizeof w.time);
  return h;
}

}  // namespace gf
