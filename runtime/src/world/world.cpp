// World: body storage (generational slots), creation and stepping, and the queries of state.
#include <algorithm>
#include <cstring>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "graphfrac/jobs.h"
#include "kernels/edge_stress.h"
#include "solver/cholesky.h"
#include "solver/vector_ops.h"
#include "solver/vector_stages.h"
#include "step/executor.h"
#include "step/timing.h"
#include "world/validation.h"
#include "world/world_impl.h"

namespace gf {

namespace detail {
uint64_t nextWorldId() {
  static std::atomic<uint64_t> next{1};
  return next++;
}

ColliderData toData(const Collider& c) {
  ColliderData d;
  d.kind = static_cast<int>(c.kind);
  d.point = {c.point.x, c.point.y, c.point.z};
  Vec3 n{c.normal.x, c.normal.y, c.normal.z};
  const double len = norm(n);
  d.normal = len > 0 ? (1.0 / len) * n : Vec3{0, 1, 0};
  d.halfExtents = {c.halfExtents.x, c.halfExtents.y, c.halfExtents.z};
  d.radius = c.radius;
  d.halfLength = c.halfLength;
  d.velocity = {c.velocity.x, c.velocity.y, c.velocity.z};
  d.angularVelocity = {c.angularVelocity.x, c.angularVelocity.y, c.angularVelocity.z};
  d.friction = c.friction;
  const glm::dquat q(c.rotation);
  const double ql = glm::length(q);
  const glm::dmat3 R = glm::mat3_cast(ql > 0 ? q / ql : glm::dquat(1, 0, 0, 0));
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) d.rotation(i, j) = R[j][i];  // glm is column-major
  return d;
}

}  // namespace detail

namespace {
// Bodies below this many tets are stepped side by side over the JobSystem, each serial inside:
// their loops (256 tets, 128 rows a range) would give a thread a range or two at most, and
// each parallelFor would cost more than the work it splits.
constexpr int32_t kBatchBelowTets = 2048;
// Items per range of the world's own per-node passes.
constexpr uint32_t kVectorGrain = 2048;

// Builds a body's model, state, solver and fracture from a checked def; throws std::bad_alloc
// when the machine has not the memory for it.
Result<std::unique_ptr<BodyRecord>> buildBody(BodyDef&& def, JobSystem& jobs, Vec3 gravity) {
  auto body = std::make_unique<BodyRecord>();
  if (def.cutMode == CutMode::Xfem) {
    auto xfem = detail::buildXfem(def, gravity);
    if (!xfem) return xfem.error();
    body->xfem = std::move(xfem.value());
  }
  body->model = detail::buildFemModel(def);
  body->state = detail::buildFemState(def, body->model);
  for (size_t i = 0; i < body->state.v.size(); ++i)
    body->state.v[i] = def.initialVelocity[int(i % 3)];
  body->integrator = std::make_unique<detail::Integrator>(body->model);
  if (Result<void> r = body->integrator->setupSolver(body->model, body->state); !r.ok())
    return r.error();
  if (def.fracture.enabled) {
    auto fb = detail::FractureBody::create(body->model, body->state, jobs);
    if (!fb) return fb.error();
    body->fracture = std::move(fb.value());
  }
  body->integrator->attach(body->fracture.get());

  if (body->xfem) detail::syncXfemState(*body);
  body->gripForces.assign(def.grips.size(), glm::dvec3(0));
  body->grips = std::move(def.grips);
  return body;
}

}  // namespace

// Converts a body's breaks and splits of the last detect() into public events.
void World::Impl::collectEvents(BodyId id, const BodyRecord& b) {
  const detail::FractureBody& f = *b.fracture;
  const auto& g = f.graph();
  for (size_t i = 0; i < f.breaks().size(); ++i) {
    const detail::EdgeBreak& e = f.breaks()[i];
    FractureEvent ev;
    ev.body = id;
    ev.edge = e.edge;
    ev.nodeA = g.edgeNodes[2 * e.edge];
    ev.nodeB = g.edgeNodes[2 * e.edge + 1];
    const double* xa = &b.state.x[3 * ev.nodeA];
    const double* xb = &b.state.x[3 * ev.nodeB];
    ev.position = glm::vec3(float(0.5 * (xa[0] + xb[0])), float(0.5 * (xa[1] + xb[1])),
                            float(0.5 * (xa[2] + xb[2])));
    ev.stress = float(e.stress);
    if (const double* r = f.splitRatios()) ev.split = float(r[e.edge]);
    ev.cause = static_cast<FractureEvent::Cause>(f.breakCause()[i]);
    fractureEvents.push_back(ev);
  }
  const detail::FragmentProperties& p = f.splitProperties();
  for (const detail::FragmentSplit& s : f.splits()) {
    FragmentEvent ev;
    ev.body = id;
    ev.fragment = s.created;
    ev.parent = s.parent;
    ev.nodeCount = int32_t(f.fragments().nodes(s.created).size());
    ev.volume = p.volume[s.created];
    ev.mass = p.mass[s.created];
    ev.centreOfMass = glm::vec3(float(p.centre[3 * s.created]), float(p.centre[3 * s.created + 1]),
                                float(p.centre[3 * s.created + 2]));
    ev.velocity = glm::vec3(float(p.velocity[3 * s.created]), float(p.velocity[3 * s.created + 1]),
                            float(p.velocity[3 * s.created + 2]));
    fragmentEvents.push_back(ev);
  }
}

// Multiplicative plasticity after the step (eq 2.3-2.5): only yielding elements change.
void World::Impl::plasticUpdate(BodyRecord& b, double h, JobSystem& js) {
  const detail::FemModel& m = b.model;
  detail::FemState& s = b.state;
  detail::PlasticityStage stage;
  stage.tets = m.tets.data();
  stage.x = s.x.data();
  stage.restInverse = m.restInverse.data();
  stage.coeffs = s.coeffs;
  stage.fibreDir = m.fibreDir.empty() ? nullptr : m.fibreDir.data();
  stage.tetLame = s.tetLame.empty() ? nullptr : s.tetLame.data();
  stage.params = {m.plasticity.yieldStress, m.plasticity.flowRate, m.plasticity.hardening};
  stage.h = h;
  stage.Fp = s.Fp.data();
  stage.FpInv = s.FpInv.data();
  stage.delta = s.plasticDelta.data();
  stage.plasticInverse = s.plasticInverse.data();
  detail::CpuExecutor(js).run(m.tetCount, 256, stage);
}

void World::Impl::plasticFlow(size_t si, double h, JobSystem& js) {
  BodyRecord& b = *slots[si].body;
  plasticityMs[si] = 0;
  // A rolled-back body is where it was before the substep: nothing flowed.
  if (b.xfem || !b.model.plasticity.enabled || (reports[si].flags & kStepNanContained)) return;
  const auto tp = detail::Clock::now();
  plasticUpdate(b, h, js);
  plasticityMs[si] = detail::msSince(tp);
}

void World::Impl::stepBody(size_t si, const detail::StepContext& ctx, JobSystem& js) {
  BodyRecord* b = slots[si].body.get();
  detail::BodyStepReport& r = reports[si];
  plasticityMs[si] = 0;
  detail::StepContext own = ctx;
  own.colliderImpulse = colliders.empty() ? nullptr : &bodyImpulse[6 * colliders.size() * si];
  if (own.colliderImpulse) std::fill_n(own.colliderImpulse, 6 * colliders.size(), 0.0);
  if (b->xfem) {
    stepXfem(si, own);
    return;
  }
  own.bodyContacts = bodyContact.halfSpaces(si);
  r = b->integrator->step(b->model, b->state, own, js);
  if (own.bodyContacts.start)
    bodyContact.setBalance(
        si, b->integrator->bodyContactImpulses(b->state, own, (r.flags & kStepNanContained) != 0,
                                               bodyContact.impulseBuffer(si), js));
  if (!sweeping) plasticFlow(si, own.dt, js);
}

int64_t World::Impl::findContacts(const detail::CpuExecutor& exec, double h) {
  contactViews.assign(slots.size(), {});
  contactStates.assign(slots.size(), nullptr);
  for (size_t si = 0; si < slots.size(); ++si) {
    BodyRecord* b = slots[si].body.get();
    if (!b || b->allRigid || !b->model.contact) continue;
    if (!b->contactSurface) {
      b->contactSurface = std::make_unique<detail::ContactSurface>();
      b->contactSurface->init(b->model);
    }
    detail::ContactBodyView& view = contactViews[si];
    const uint8_t* excluded = nullptr;
    uint64_t key = 0;
    if (b->fracture) {
      const detail::Fragments& f = b->fracture->fragments();
      view.nodeFragment = f.nodeFragment();
      view.fragmentCount = f.count();
      // Fragments handed to rigid physics meet the other bodies as Bullet's, not as ours.
      if (!b->rigid.empty()) {
        b->contactExcluded.assign(size_t(f.count()), 0);
        for (const auto& r : b->rigid) b->contactExcluded[size_t(r.first)] = 1;
        excluded = b->contactExcluded.data();
        view.excluded = excluded;
      }
      key = (f.version() << 20) ^ uint64_t(b->rigid.size());
    }
    b->contactSurface->update(b->model,
                              view.nodeFragment.empty() ? nullptr : view.nodeFragment.data(),
                              view.fragmentCount, excluded, key);
    view.model = &b->model;
    view.state = &b->state;
    view.surface = b->contactSurface.get();
    contactStates[si] = &b->state;
  }
  return bodyContact.find(exec, contactViews, h, {def.gravity.x, def.gravity.y, def.gravity.z},
                          detail::kAutoContactStiffnessDt2 / (h * h), kFrictionSlipSpeed * h,
                          def.coupledContact);
}

void World::Impl::keepClustersApart() {
  auto clustered = [&](uint32_t si) { return bodyContact.jointBase(si) >= 0; };
  std::erase_if(single, clustered);
  std::erase_if(batched, clustered);
}

void World::Impl::stepClusters(const detail::StepContext& ctx) {
  for (const detail::BodyContact::Cluster& c : bodyContact.clusters()) {
    std::vector<detail::CoupledBody> members;
    for (uint32_t si : c.slots) {
      BodyRecord* b = slots[si].body.get();
      detail::CoupledBody m;
      m.model = &b->model;
      m.state = &b->state;
      m.integrator = b->integrator.get();
      m.ctx = ctx;
      m.ctx.colliderImpulse = colliders.empty() ? nullptr : &bodyImpulse[6 * colliders.size() * si];
      if (m.ctx.colliderImpulse) std::fill_n(m.ctx.colliderImpulse, 6 * colliders.size(), 0.0);
      m.ctx.bodyContacts = bodyContact.halfSpaces(si);
      reports[si] = {};
      m.report = &reports[si];
      m.jointBase = bodyContact.jointBase(si);
      members.push_back(m);
    }
    detail::CoupledCluster cl;
    cl.contacts = bodyContact.jointView();
    cl.X = bodyContact.jointX();
    cl.Xn = bodyContact.jointXn();
    cl.jointNodes = bodyContact.jointNodes();
    cl.jointPairs = bodyContact.jointPairs();
    cl.nodeBegin = c.nodeBegin;
    cl.nodeEnd = c.nodeEnd;
    cl.pairBegin = c.pairBegin;
    cl.pairEnd = c.pairEnd;
    detail::Integrator::coupledStep(members, cl, coupledWork, *jobs);
    for (uint32_t si : c.slots) plasticFlow(si, ctx.dt, *jobs);
  }
}

void World::Impl::stepBodies(const detail::StepContext& ctx) {
  for (uint32_t si : single) stepBody(si, ctx, *jobs);
  detail::forRanges(*jobs, uint32_t(batched.size()), 1, [&](uint32_t lo, uint32_t hi) {
    for (uint32_t k = lo; k < hi; ++k) stepBody(batched[k], ctx, serialJobs());
  });
}

void World::Impl::flowBodies(double h) {
  for (uint32_t si : single) plasticFlow(si, h, *jobs);
  detail::forRanges(*jobs, uint32_t(batched.size()), 1, [&](uint32_t lo, uint32_t hi) {
    for (uint32_t k = lo; k < hi; ++k) plasticFlow(batched[k], h, serialJobs());
  });
}

// A step changes more of a body than x and v: its fracture (damage, fragments, events) and its
// plastic flow (Fp, delta). A sweep restores only x and v, so the fracture is judged in the
// first sweep alone (StepContext::judgeFracture; judged again it would break edges twice, the
// second time against the stresses of the first one's damage) and the flow waits for the last
// (flowBodies), which gives the flow of the single step that ends where the sweeps end.
// (Is-XFEM bodies take no body contact.)
void World::Impl::saveSweepStart() {
  sweepX0.resize(slots.size());
  sweepV0.resize(slots.size());
  sweepIterate.resize(slots.size());
  sweepFragment.resize(slots.size());
  sweepTouched.assign(slots.size(), 0);
  for (size_t si = 0; si < slots.size(); ++si) {
    detail::ContactBodyView& view = contactViews[si];
    if (!view.model) continue;
    sweepX0[si] = contactStates[si]->x;
    sweepV0[si] = contactStates[si]->v;
    sweepTouched[si] = bodyContact.halfSpaces(si).start != nullptr;
    // The view borrows the body's labels, which the first sweep's fracture may change; the
    // later sweeps find the pairs on the surfaces and groups of the first.
    sweepFragment[si].assign(view.nodeFragment.begin(), view.nodeFragment.end());
    if (!view.nodeFragment.empty()) view.nodeFragment = sweepFragment[si];
  }
}

int World::Impl::contactSweeps(const detail::CpuExecutor& exec, const detail::StepContext& ctx,
                               double h) {
  std::vector<uint32_t> allSingle = single, allBatched = batched;
  detail::StepContext again = ctx;
  again.judgeFracture = false;
  int sweeps = 1;
  double threshold = HUGE_VAL;
  for (size_t si = 0; si < slots.size(); ++si)
    if (contactViews[si].model)
      threshold = std::min(threshold,
                           detail::kContactSweepTolerance * contactViews[si].surface->cellSize());
  for (; sweeps < def.contactSweeps; ++sweeps) {
    // How far the iterates moved in the last sweep (in slot and node order: the same for any
    // thread count); the first sweep has nothing to compare with.
    double moved = 0;
    for (size_t si = 0; si < slots.size(); ++si) {
      if (!contactViews[si].model) continue;
      const std::vector<double>& x = contactStates[si]->x;
      std::vector<double>& last = sweepIterate[si];
      if (sweeps > 1)
        for (size_t i = 0; i < x.size(); ++i) moved = std::max(moved, std::abs(x[i] - last[i]));
      last = x;
    }
    if (sweeps > 1 && moved <= threshold) break;
    for (size_t si = 0; si < slots.size(); ++si) {
      detail::ContactBodyView& view = contactViews[si];
      if (!view.model) continue;
      view.x = sweepX0[si].data();
      view.v = sweepV0[si].data();
      view.iterate = sweepIterate[si].data();
    }
    const auto tc = detail::Clock::now();
    bodyContact.find(exec, contactViews, h, {def.gravity.x, def.gravity.y, def.gravity.z},
                     detail::kAutoContactStiffnessDt2 / (h * h), kFrictionSlipSpeed * h);
    timings.contactMs += detail::msSince(tc);
    // Only the bodies whose half-spaces may have changed step again; the others' steps would
    // repeat the bits they have.
    single.clear();
    batched.clear();
    for (uint32_t si : allSingle)
      if (sweepTouched[si] || bodyContact.halfSpaces(si).start) single.push_back(si);
    for (uint32_t si : allBatched)
      if (sweepTouched[si] || bodyContact.halfSpaces(si).start) batched.push_back(si);
    for (size_t si = 0; si < slots.size(); ++si)
      if (contactViews[si].model && bodyContact.halfSpaces(si).start) sweepTouched[si] = 1;
    // The step's report keeps the last sweep's figures; the times of the others are added.
    for (const std::vector<uint32_t>* list : {&single, &batched})
      for (uint32_t si : *list) {
        const detail::BodyStepReport& r = reports[si];
        timings.elementsMs += r.elementsMs;
        timings.assemblyMs += r.assemblyMs;
        timings.solveMs += r.solveMs;
        timings.fractureMs += r.fractureMs;
        contactStates[si]->x = sweepX0[si];
        contactStates[si]->v = sweepV0[si];
      }
    stepBodies(again);
  }
  single = allSingle;
  batched = allBatched;
  for (detail::ContactBodyView& view : contactViews) view.x = view.v = view.iterate = nullptr;
  return sweeps;
}

World::World(const WorldDef& def) : m_impl(std::make_unique<Impl>()) {
  detail::blasOnOneThread();  // the process runs no BLAS threads beside the JobSystem's
  Impl& w = *m_impl;
  w.def = def;
  w.jobs = def.jobs ? def.jobs : &serialJobs();
  if (Result<void> r = def.check(); !r) {
    w.defError = r.error().message + "; the world does not run (check WorldDef before creating it)";
    w.def.colliders.clear();  // nothing of an invalid def is used
    w.def.substeps = 1;
  } else {
    w.backend = detail::chooseBackend(def.backend);
    if (!w.backend.error.empty()) w.defError = w.backend.error + "; the world does not run";
  }
  for (const Collider& c : w.def.colliders) w.colliders.push_back(toData(c));
  w.setColliderStiffness(w.lastSubstep);
  w.impulses.assign(w.colliders.size(), glm::dvec3(0));
  w.angularImpulses = w.impulses;
}

World::~World() = default;

Backend World::backend() const { return m_impl->backend.backend; }
const std::string& World::backendDescription() const { return m_impl->backend.description; }

Result<BodyId> World::createBody(BodyDef def) {
  if (std::string e = m_impl->busy("createBody"); !e.empty()) return fail(e);
  if (!m_impl->defError.empty()) return fail("createBody: ", m_impl->defError);
  if (def.mesh.tetCount() == 0) return fail("BodyDef.mesh: has no tetrahedra");
  // No exception crosses the API: a body too large for the machine is an error that says how
  // much it needs, and the world stays as it was.
  Impl& w = *m_impl;
  const size_t tets = def.mesh.tetCount(), nodes = def.mesh.nodeCount();
  const double bytes = detail::estimateBodyBytes(def);
  try {
    int flipped = 0;
    if (auto r = validate(def.mesh, "BodyDef.mesh", &flipped); !r) return r.error();
    if (auto r = detail::checkBodySettings(def); !r) return fail("BodyDef.", r.error().message);
    std::unique_ptr<detail::EmbeddedBinding> binding;
    if (def.renderMesh) {
      Result<detail::EmbeddedBinding> bound =
          detail::EmbeddedBinding::bind(def.mesh, *def.renderMesh, "BodyDef.renderMesh");
      if (!bound) return bound.error();
      binding = std::make_unique<detail::EmbeddedBinding>(std::move(bound.value()));
    }
    if (def.cutMode == CutMode::Xfem)
      if (std::string e =
              w.xfemColliderError(w.def.colliders, "BodyDef.cutMode: WorldDef.colliders");
          !e.empty())
        return fail(e);
    const glm::vec3 g = w.def.gravity;
    Result<std::unique_ptr<BodyRecord>> built = buildBody(std::move(def), *w.jobs, {g.x, g.y, g.z});
    if (!built) return built.error();
    if (w.backend.device) {
      std::unique_ptr<detail::BodyDevice> device = w.backend.device();
      if (!device) return fail("createBody: the CUDA device cannot be had for the body any more");
      built.value()->integrator->useDevice(std::move(device));
    }
    built.value()->renderBinding = std::move(binding);
    size_t slot = 0;
    while (slot < w.slots.size() && w.slots[slot].body) ++slot;
    if (slot == w.slots.size()) w.slots.emplace_back();
    w.slots[slot].body = std::move(built.value());
    return BodyId{uint32_t(slot + 1), w.slots[slot].generation};
  } catch (const std::bad_alloc&) {
    return fail("BodyDef.mesh: not enough memory for a body of ", std::to_string(tets),
                " tets and ", std::to_string(nodes), " nodes: it needs about ",
                std::to_string(int64_t(std::ceil(bytes / 1048576.0))), " MiB");
  }
}

Result<void> World::destroyBody(BodyId id) {
  if (std::string e = m_impl->busy("destroyBody"); !e.empty()) return fail(e);
  if (!m_impl->get(id)) return fail("destroyBody: stale or null BodyId");
  Slot& s = m_impl->slots[id.index - 1];
  s.body.reset();
  ++s.generation;
  return {};
}

bool World::isValid(BodyId id) const { return m_impl->get(id) != nullptr; }

StepStatus World::step(double dt) {
  StepStatus st;
  Impl& w = *m_impl;
  if (!std::isfinite(dt) || dt <= 0) {
    st.flags = kStepInvalidInput;
    st.message = "step: dt must be positive and finite, got " + std::to_string(dt);
    return st;
  }
  if (!w.defError.empty()) {
    st.flags = kStepInvalidInput;
    st.message = "step: " + w.defError;
    return st;
  }
  if (w.stepping.exchange(true)) {
    st.flags = kStepInvalidInput;
    st.message = "step: called while step() runs; nothing changed";
    return st;
  }
  // Forces of applyForce act over this whole step: swapped in, the constant ones swapped back
  // after (restoring the copy, not subtracting, keeps the constant forces bit-exact).
  const detail::CpuExecutor exec(*w.jobs);
  std::vector<std::vector<double>> constantForces;
  for (Slot& s : w.slots) {
    if (!s.body || s.body->pendingForce.empty()) continue;
    std::vector<double>& f = s.body->state.externalForce;
    constantForces.push_back(f);
    exec.run(int32_t(f.size()), kVectorGrain,
             detail::AxpyStage{f.data(), s.body->pendingForce.data(), 1.0, f.data()});
  }
  const auto t0 = detail::Clock::now();
  w.timings = {};
  w.advanceWater(dt);
  w.fractureEvents.clear();
  w.fragmentEvents.clear();
  w.handoffEvents.clear();
  const double h = dt / w.def.substeps;
  w.lastSubstep = h;
  w.prepareBrushes(h);
  w.setColliderStiffness(h);
  detail::StepContext ctx = w.context(h);
  // Moving colliders: each substep sees them at its end pose; the sums of their impulses are
  // over bodies and substeps.
  std::vector<Vec3> colliderStart(w.colliders.size());
  for (size_t c = 0; c < w.colliders.size(); ++c) colliderStart[c] = w.colliders[c].point;
  w.colliderImpulse.assign(6 * w.colliders.size(), 0.0);
  w.bodyImpulse.resize(6 * w.colliders.size() * w.slots.size());
  w.reports.resize(w.slots.size());
  w.plasticityMs.resize(w.slots.size());
  for (int sub = 0; sub < w.def.substeps; ++sub) {
    for (size_t c = 0; c < w.colliders.size(); ++c) {
      const glm::vec3 v = w.def.colliders[c].velocity;
      w.colliders[c].point = colliderStart[c] + ((sub + 1) * h) * Vec3{v.x, v.y, v.z};
    }
    w.batched.clear();
    w.single.clear();
    for (size_t si = 0; si < w.slots.size(); ++si) {
      BodyRecord* b = w.slots[si].body.get();
      if (!b) continue;
      if (b->allRigid) {
        // The integrator's own update of prescribed nodes, x += h v, v = grip velocity.
        const int32_t n3 = int32_t(b->state.x.size());
        const double* gv = b->state.gripVelocity.data();
        exec.run(n3, kVectorGrain, detail::AxpyStage{b->state.x.data(), gv, h, b->state.x.data()});
        exec.run(n3, kVectorGrain, detail::CopyStage{gv, b->state.v.data()});
        continue;
      }
      (b->model.tetCount < kBatchBelowTets ? w.batched : w.single).push_back(uint32_t(si));
    }
    // Bodies do not interact within a substep (each sees only the colliders), so they can run
    // in any order. A large body spreads its own loops over the JobSystem; small bodies (debris)
    // have loops too short to split, so they run side by side, one body per item, each serial
    // inside. Both give the bits of a serial run (jobs.h), so the state is the same for any
    // thread count.
    // Body contact is a half-space per node that each body's step sees as fixed, so the
    // bodies still step apart; the exchange after evens out their impulses.
    auto tc = detail::Clock::now();
    const int64_t pairs = w.findContacts(exec, h);
    w.timings.contactPairs += pairs;
    w.sweeping = pairs > 0 && w.def.contactSweeps > 1 && !w.def.coupledContact;
    if (w.sweeping) w.saveSweepStart();
    if (w.def.coupledContact) w.keepClustersApart();
    w.timings.contactMs += detail::msSince(tc);
    w.stepBodies(ctx);
    if (w.def.coupledContact) w.stepClusters(ctx);
    if (w.sweeping) {
      w.contactSweeps(exec, ctx, h);
      w.flowBodies(h);
      w.sweeping = false;
    }
    tc = detail::Clock::now();
    w.bodyContact.exchange(exec, w.contactStates);
    w.bodyContact.recordLoads(exec, w.contactStates);
    w.timings.contactMs += detail::msSince(tc);
    w.sumPullImpulses(h);
    // Events, flags and sums in slot order, whichever thread stepped the body.
    for (size_t si = 0; si < w.slots.size(); ++si) {
      BodyRecord* b = w.slots[si].body.get();
      if (!b || b->allRigid) continue;
      const detail::BodyStepReport& r = w.reports[si];
      const BodyId id{uint32_t(si + 1), w.slots[si].generation};
      if (b->fracture) w.collectEvents(id, *b);
      if (b->xfem) w.collectXfemEvents(*b);
      b->stepEndValid = true;
      w.timings.fractureMs += r.fractureMs;
      st.flags |= r.flags;
      if ((r.flags & kStepNanContained) && st.message.empty())
        st.message = "body " + std::to_string(si + 1) + ": " + r.message;
      if (std::string why = b->integrator->takeDeviceFailure(); !why.empty()) {
        const std::string text = "body " + std::to_string(si + 1) +
                                 " runs on the CPU from now on: the device failed (" + why + ")";
        w.backend.description += "; " + text;
        if (st.message.empty()) st.message = text;
      }
      st.newtonIterations += r.newtonIterations;
      st.linearIterations += r.linearIterations;
      st.residual = std::max(st.residual, r.residual);
      w.timings.elementsMs += r.elementsMs;
      w.timings.assemblyMs += r.assemblyMs;
      w.timings.solveMs += r.solveMs;
      w.timings.plasticityMs += w.plasticityMs[si];
      const size_t nc = 6 * w.colliders.size();
      for (size_t k = 0; k < nc; ++k) w.colliderImpulse[k] += w.bodyImpulse[nc * si + k];
    }
  }
  w.clearBrushes(dt);
  for (size_t c = 0; c < w.colliders.size(); ++c) {
    const double* j = &w.colliderImpulse[6 * c];
    w.impulses[c] = {j[0], j[1], j[2]};
    w.angularImpulses[c] = {j[3], j[4], j[5]};
    const Vec3 p = w.colliders[c].point;
    w.def.colliders[c].point = glm::vec3(float(p.x), float(p.y), float(p.z));
  }
  // Events sorted by body, then edge / fragment: the same order for any thread count.
  std::stable_sort(w.fractureEvents.begin(), w.fractureEvents.end(),
                   [](const FractureEvent& a, const FractureEvent& b) {
                     if (a.body.index != b.body.index) return a.body.index < b.body.index;
                     return a.edge != b.edge ? a.edge < b.edge : a.tet < b.tet;
                   });
  std::stable_sort(w.fragmentEvents.begin(), w.fragmentEvents.end(),
                   [](const FragmentEvent& a, const FragmentEvent& b) {
                     return a.body.index != b.body.index ? a.body.index < b.body.index
                                                         : a.fragment < b.fragment;
                   });
  size_t swapped = 0;
  for (Slot& s : w.slots) {
    if (!s.body || s.body->pendingForce.empty()) continue;
    s.body->state.externalForce = std::move(constantForces[swapped++]);
    s.body->pendingForce.clear();
  }
  for (Slot& s : w.slots)
    if (s.body && s.body->surface) s.body->surfaceStale = true;
  w.time += dt;
  w.publishProbe(dt);
  w.timings.totalMs = detail::msSince(t0);
  if (st.message.empty()) {
    if (st.has(kStepNotConverged))
      st.message = "the solver stopped at its iteration cap";
    else if (st.has(kStepLineSearchFailed))
      st.message =
          "Newton's line search reached its smallest step without lowering the incremental "
          "potential: the time step is too large for the load (try substeps or a smaller dt)";
    else if (st.has(kStepContactSwept))
      st.message =
          "a node's path crossed a thin collider within the step; contact was taken at the face "
          "it entered";
  }
  w.stepping.store(false);
  return st;
}

std::span<const double> World::positions(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  return b ? std::span<const double>(b->state.x) : std::span<const double>();
}

std::span<const double> World::velocities(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  return b ? std::span<const double>(b->state.v) : std::span<const double>();
}

BodyStats World::stats(BodyId id) const {
  BodyStats s;
  const BodyRecord* b = m_impl->get(id);
  if (!b || m_impl->stepping.load()) return s;
  if (b->xfem) return m_impl->xfemStats(*b);
  const auto& m = b->model;
  const auto& x = b->state.x;
  const auto& v = b->state.v;
  const glm::dvec3 g(m_impl->def.gravity);
  for (int32_t n = 0; n < m.nodeCount; ++n) {
    const glm::dvec3 xi(x[3 * n], x[3 * n + 1], x[3 * n + 2]);
    const glm::dvec3 vi(v[3 * n], v[3 * n + 1], v[3 * n + 2]);
    const double mi = b->state.nodeMass[n];
    s.mass += mi;
    s.kineticEnergy += 0.5 * mi * glm::dot(vi, vi);
    s.gravityEnergy -= mi * glm::dot(g, xi);
    s.linearMomentum += mi * vi;
    s.angularMomentum += glm::cross(xi, mi * vi);
  }
  const detail::StepContext ctx = m_impl->context(m_impl->lastSubstep);
  const detail::EnergyBreakdown e =
      b->integrator->energies(m, b->state, x.data(), ctx, *m_impl->jobs);
  s.elasticEnergy = e.elastic;
  s.contactEnergy = e.contact;
  return s;
}

std::span<const FractureEvent> World::fractureEvents() const { return m_impl->fractureEvents; }

std::span<const FragmentEvent> World::fragmentEvents() const { return m_impl->fragmentEvents; }

FractureStats World::fractureStats(BodyId id) const {
  FractureStats s;
  const BodyRecord* b = m_impl->get(id);
  if (!b) return s;
  if (b->xfem) return {0, 0, b->xfem->fragmentCount};
  if (!b->fracture) return {0, 0, 1};
  s.edgeCount = b->fracture->graph().edgeCount;
  s.brokenEdges = b->fracture->brokenCount();
  s.fragments = b->fracture->fragments().count();
  s.chips = b->fracture->chipCount();
  return s;
}

std::span<const int32_t> World::nodeFragments(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  if (!b || !b->fracture) return {};
  return b->fracture->fragments().nodeFragment();
}

std::span<const uint8_t> World::chipFlags(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  if (!b || !b->fracture) return {};
  return b->fracture->chipFlags();
}

std::span<const int32_t> World::edges(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  if (!b || !b->fracture) return {};
  return b->fracture->graph().edgeNodes;
}

std::span<const uint8_t> World::brokenEdges(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  if (!b || !b->fracture) return {};
  return b->fracture->broken();
}

std::span<const glm::dvec3> World::gripForces(BodyId id) {
  BodyRecord* b = m_impl->get(id);
  if (!b || m_impl->stepping.load()) return {};
  if (b->xfem) return {};
  std::fill(b->gripForces.begin(), b->gripForces.end(), glm::dvec3(0));
  if (!b->stepEndValid || b->allRigid) return b->gripForces;
  const detail::StepContext ctx = m_impl->context(m_impl->lastSubstep);
  b->integrator->prescribedNodeForces(b->model, b->state, ctx, *m_impl->jobs, b->nodeForce);
  for (size_t g = 0; g < b->grips.size(); ++g)
    for (int32_t n : b->grips[g].nodes)
      b->gripForces[g] += glm::dvec3(b->nodeForce[3 * size_t(n)], b->nodeForce[3 * size_t(n) + 1],
                                     b->nodeForce[3 * size_t(n) + 2]);
  return b->gripForces;
}

const StepTimings& World::timings() const { return m_impl->timings; }

double World::time() const { return m_impl->time; }

// ---- Colliders the game moves between steps (two-way contact with its rigid bodies) ----

Result<void> World::setColliders(std::span<const Collider> colliders) {
  if (std::string e = m_impl->busy("setColliders"); !e.empty()) return fail(e);
  for (size_t i = 0; i < colliders.size(); ++i)
    if (Result<void> r = colliders[i].check(); !r)
      return fail("setColliders: colliders[", std::to_string(i), "].", r.error().message);
  Impl& w = *m_impl;
  for (const Slot& s : w.slots)
    if (s.body && s.body->xfem)
      if (std::string e = w.xfemColliderError(colliders, "setColliders: colliders"); !e.empty())
        return fail(e);
  w.def.colliders.assign(colliders.begin(), colliders.end());
  w.colliders.clear();
  for (const Collider& c : colliders) w.colliders.push_back(toData(c));
  w.setColliderStiffness(w.lastSubstep);
  w.impulses.assign(w.colliders.size(), glm::dvec3(0));
  w.angularImpulses = w.impulses;
  return {};
}

std::span<const Collider> World::colliders() const { return m_impl->def.colliders; }
std::span<const glm::dvec3> World::colliderImpulses() const { return m_impl->impulses; }
std::span<const glm::dvec3> World::colliderAngularImpulses() const {
  return m_impl->angularImpulses;
}

}  // namespace gf
