// The World's internals, shared by its source files (one concern each: world.cpp creates and
// steps, world_commands.cpp takes the game's commands, world_surface.cpp the render surfaces,
// world_snapshot.cpp snapshots, world_handoff.cpp the hand-off of fragments to rigid physics).
#pragma once

#include <atomic>
#include <cmath>
#include <glm/gtc/quaternion.hpp>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "contact/body_contact.h"
#include "fem/fem_body.h"
#include "fem/integrator.h"
#include "fracture/fracture_body.h"
#include "graphfrac/world.h"
#include "sculpt/brush_stages.h"
#include "sculpt/wetting.h"
#include "surface/crack_surface.h"
#include "surface/embedded_mesh.h"
#include "world/backend.h"
#include "world/validation.h"
#include "xfem/cut_body.h"

namespace gf {
namespace detail {

// A body in CutMode::Xfem (world_xfem.cpp): the Is-XFEM body that steps it, its pieces as the
// body's fragments, the events of its last cut (reported by the next step) and its render
// surface. Its FemState's x and v mirror the standard DOFs (rest + u, v) after every step.
struct XfemRecord {
  std::unique_ptr<XfemBody> body;
  std::vector<int32_t> pieceFragment;  // piece -> public fragment id (stable across cuts)
  int32_t fragmentCount = 1;
  std::vector<FractureEvent> pendingBreaks;  // of World::cut, for the next step
  std::vector<FragmentEvent> pendingSplits;
  XfemContactReport contact;  // of the last substep
  // Pieces handed to rigid physics (World::detachFragment): their cells are out of the system
  // (XfemBodyDef::dropped) and their surface is the rest surface moved by the rigid pose
  // x = rotation X + translation that setFragmentTransform gives.
  struct Detached {
    int32_t fragment = 0;
    Vec3 restCentre;
    Mat3 rotation = Mat3::identity();
    Vec3 translation;
    Vec3 velocity, angularVelocity;  // of the centre of mass; world axes
  };
  std::vector<Detached> detached;
  // World::surface's buffers, all pieces concatenated.
  std::vector<float> positions, normals;
  std::vector<uint32_t> indices;
  std::vector<uint8_t> crackMask;
  std::vector<int32_t> vertexFragment, vertexNode;
  uint64_t topologyVersion = 1;
  bool built = false;  // buffers hold the current topology
};

// Contact penalty stiffness per unit mass when the collider names none: dt^2 k = 100 makes
// contact a hundred times stiffer than inertia, so a node is pushed out within about a step
// and rests g dt^2 / 100 deep.
constexpr double kAutoContactStiffnessDt2 = 100.0;
// The largest move of any iterate between two contact sweeps (World::Impl::contactSweeps), as
// a fraction of the finest cell, at which they stop before WorldDef::contactSweeps.
constexpr double kContactSweepTolerance = 1e-4;

/// A new id for each World, so that a snapshot is restored only into the world it was taken of.
uint64_t nextWorldId();

// The render surface of a body, created on the first World::surface() call.
struct SurfaceRecord {
  TetMesh rest;                      // CrackSurface keeps references to these two
  detail::EdgeGraph ownGraph;        // for bodies without fracture
  std::vector<uint8_t> noBreaks;     // idem
  std::vector<int32_t> oneFragment;  // idem
  detail::CrackSurface surface;
  // The body's render mesh deformed with it (null without BodyDef::renderMesh); it borrows
  // the crack faces and local maps of `surface`.
  std::unique_ptr<detail::EmbeddedSurface> embedded;
  uint64_t brokenCount = 0;
};

struct BodyRecord {
  detail::FemModel model;
  detail::FemState state;
  std::unique_ptr<detail::Integrator> integrator;
  std::unique_ptr<detail::FractureBody> fracture;          // null: no fracture, no edge stresses
  std::unique_ptr<detail::XfemRecord> xfem;                // null: CutMode::Graph
  std::unique_ptr<SurfaceRecord> surface;                  // null until somebody asks for it
  std::unique_ptr<detail::EmbeddedBinding> renderBinding;  // BodyDef::renderMesh, bound
  std::vector<Grip> grips;                                 // node lists for setGripVelocity
  std::vector<double> pendingForce;  // applyForce, next step only; empty: none
  // Fragments handed to rigid physics (detachFragment): id and rest centre of mass, in
  // detach order.
  std::vector<std::pair<int32_t, Vec3>> rigid;
  // A step or setFragmentTransform moved nodes since the render surface was updated; the next
  // surface() call updates it (once per rendered frame, not once per step or substep).
  bool surfaceStale = false;
  std::vector<double> nodeStrain;      // World::nodeStrain's output
  std::vector<double> nodeWeight;      // its scratch
  std::vector<glm::dvec3> gripForces;  // World::gripForces's output
  std::vector<double> nodeForce;       // its scratch
  // The integrator still holds the start of the step that led to the current state, so the
  // grips' forces can be evaluated (false before the first step and after state overwrites).
  bool stepEndValid = false;
  // Every node is in a detached fragment: the body only moves rigidly, so a step just advances
  // the nodes by their prescribed velocities (what the integrator would do, without its cost).
  bool allRigid = false;
  // Body-body and self contact (BodyDef::contact): the surface, made at the first step that
  // uses it, and its scratch of excluded (detached) fragments.
  std::unique_ptr<detail::ContactSurface> contactSurface;
  std::vector<uint8_t> contactExcluded;
  // Water (World::wet): the transport model, made at the first brush (null: never wetted; the
  // water itself is state, FemState::water), the strokes of the next step, and
  // World::saturation's output.
  std::unique_ptr<detail::WettingModel> wetting;
  std::vector<detail::WaterStroke> strokes;
  std::vector<double> saturation;
  // World::deform: the brushes whose kernel scales the velocities at the next step's end.
  std::vector<DeformBrush> deformBrushes;
  std::vector<detail::DeformBrushData> deformBrushData;  // the stage's copy, per step
  // World::pull: per node, the summed stiffness [1/s^2] of the next step's pulls and the
  // stiffness-weighted sum of their targets (3 per node; both empty: no pull), the nodes pulled,
  // and the impulse the pulls gave the body over the current step, then World::pullForce.
  std::vector<double> pullStiffness, pullTargetSum;
  std::vector<int32_t> pulledNodes;
  Vec3 pullImpulse{0, 0, 0};
  glm::dvec3 pullForce{0};
};

/// Kernel vectors and matrices as glm's, for the public API.
inline glm::dvec3 toGlm(Vec3 v) { return {v.x, v.y, v.z}; }
inline glm::dmat3 toGlm(const Mat3& m) {
  glm::dmat3 g;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) g[j][i] = m(i, j);  // glm is column-major
  return g;
}

struct BodyRecord;
/// The Is-XFEM body of a def in CutMode::Xfem (checked), with the world's gravity.
Result<std::unique_ptr<XfemRecord>> buildXfem(const BodyDef& def, Vec3 gravity);
/// Sets an Is-XFEM body's node positions and velocities from its standard DOFs.
void syncXfemState(BodyRecord& b);
/// The hand-off of an Is-XFEM piece (world_xfem.cpp): its rigid properties (`call` names the
/// World call in errors), taking it out of the system, and its rigid pose.
Result<RigidFragmentInfo> xfemFragmentInfo(const BodyRecord& b, const char* call, int32_t fragment);
Result<RigidFragmentInfo> detachXfemPiece(BodyRecord& b, int32_t fragment);
Result<void> setXfemPieceTransform(BodyRecord& b, int32_t fragment, const Mat3& rotation,
                                   Vec3 translation, Vec3 velocity, Vec3 angularVelocity);

/// Kernel form of a collider; the stiffness is filled in per step (World::Impl::context).
ColliderData toData(const Collider& c);

struct Slot {
  uint32_t generation = 1;
  std::unique_ptr<BodyRecord> body;  // null when free
};
}  // namespace detail

using detail::BodyRecord;
using detail::bounded3;
using detail::finite3;
using detail::kMaxMagnitude;
using detail::Slot;
using detail::SurfaceRecord;
using detail::toData;

struct World::Impl {
  const uint64_t id = detail::nextWorldId();
  WorldDef def;
  std::string defError;  // WorldDef::check's message; non-empty: the world refuses to run
  detail::BackendChoice backend;
  JobSystem* jobs = nullptr;
  std::vector<Slot> slots;
  std::vector<ColliderData> colliders;  // at their current pose (def.colliders: as given)
  std::vector<double> colliderImpulse;  // 6 per collider, see StepContext::colliderImpulse
  // Per slot: its body's collider impulses of the substep (6 per collider), added to
  // colliderImpulse in slot order so the sum is the same for any thread count, and its report.
  std::vector<double> bodyImpulse;
  std::vector<detail::BodyStepReport> reports;
  std::vector<double> plasticityMs;
  std::vector<uint32_t> batched, single;  // slots of the substep's small and large bodies
  // Body-body and self contact of the substep: its pairs and half-spaces, the bodies as it
  // sees them (one per slot; null model: not taking part) and their states.
  detail::BodyContact bodyContact;
  std::vector<detail::ContactBodyView> contactViews;
  std::vector<detail::FemState*> contactStates;
  // The contact sweeps' (contactSweeps): per slot, the substep's start positions and
  // velocities and the latest iterate of its end, and the fragment labels the substep's pairs
  // were found with (the first sweep's fracture relabels the body's own).
  std::vector<std::vector<double>> sweepX0, sweepV0, sweepIterate;
  std::vector<std::vector<int32_t>> sweepFragment;
  std::vector<uint8_t> sweepTouched;  // per slot: had half-spaces in some sweep
  // This substep's bodies may be stepped again: their plastic flow waits for the last sweep.
  bool sweeping = false;
  std::vector<glm::dvec3> impulses, angularImpulses;  // of the last step
  StepTimings timings;
  std::vector<FractureEvent> fractureEvents;
  std::vector<FragmentEvent> fragmentEvents;
  std::vector<HandoffEvent> handoffEvents;
  double time = 0;
  double lastSubstep = 1.0 / 60;  // contact stiffness of stats() follows the last step
  // World::attachHapticProbe: where each step's proxy force goes (null: nowhere).
  HapticProbe* probe = nullptr;
  int probeCollider = 0;
  // Brush strokes and diffusion of every wetted body over a step of dt, before its substeps,
  // and the per-tet stiffness that follows (world_sculpt.cpp).
  void advanceWater(double dt);
  // Turns each body's deform brushes into the per-node drag of the step (FemState::drag): a free
  // node that nothing else moves leaves the step with its velocity times G_d (eq 7.7); the
  // drag is implicit, so the elastic solve sees it and the far body holds still. Then forgets
  // the brushes. Turns each body's pulls into the tethers of substeps of h (FemState::tether).
  void prepareBrushes(double h);
  // After each substep of h: the impulse the tethers gave each pulled body.
  void sumPullImpulses(double h);
  // After the step of dt: removes drag and tethers and sets each body's pullForce.
  void clearBrushes(double dt);
  // Publishes the proxy force of the step of dt that just ended to the attached probe.
  void publishProbe(double dt);
  // Set while step() runs: calls that change the world are refused then (a job callback
  // re-entering the world would race the step).
  std::atomic<bool> stepping{false};

  // The error of a mutating call made during step(), or empty.
  std::string busy(const char* call) const {
    return stepping.load() ? std::string(call) + ": called while step() runs; nothing changed"
                           : std::string();
  }

  BodyRecord* get(BodyId id) const {
    if (id.index == 0 || id.index > slots.size()) return nullptr;
    const Slot& s = slots[id.index - 1];
    return (s.body && s.generation == id.generation) ? s.body.get() : nullptr;
  }
  // Converts a body's breaks and splits of the last detect() into public events.
  void collectEvents(BodyId id, const BodyRecord& b);
  // CutMode::Xfem (world_xfem.cpp): one substep of the body in slot si (report, collider
  // impulses as stepBody), its pending cut events, a cut, its stats, its render surface.
  void stepXfem(size_t si, const detail::StepContext& ctx);
  void collectXfemEvents(BodyRecord& b);
  Result<void> cutXfem(BodyId id, BodyRecord& b, const Blade& blade);
  BodyStats xfemStats(const BodyRecord& b) const;
  SurfaceView xfemSurface(BodyRecord& b, bool moved);
  // Error when a live Is-XFEM body cannot meet these colliders (plane colliders only).
  std::string xfemColliderError(std::span<const Collider> colliders, const char* where) const;
  // Multiplicative plasticity after the step (eq 2.3-2.5): only yielding elements change.
  void plasticUpdate(BodyRecord& b, double h, JobSystem& js);
  // The plastic flow of the body in slot si over its substep of h, unless that was rolled back.
  void plasticFlow(size_t si, double h, JobSystem& js);
  // One substep of the body in slot si with `js` for its loops: its report into reports[si],
  // its collider impulses into its share of bodyImpulse; its plastic flow unless `sweeping`.
  void stepBody(size_t si, const detail::StepContext& ctx, JobSystem& js);

  // The substep's contact pairs (BodyContact::find) among the bodies that take part; returns
  // their count.
  int64_t findContacts(const detail::CpuExecutor& exec, double h);
  // Keeps the contact bodies' x and v at the substep's start, and the fragment labels their
  // pairs were found with, for contactSweeps.
  void saveSweepStart();
  // Steps the bodies in `batched` and `single` once (one substep of ctx.dt).
  void stepBodies(const detail::StepContext& ctx);
  // WorldDef::coupledContact: takes the bodies of the substep's contact clusters out of
  // `batched` and `single`, and after stepBodies steps each cluster as one system.
  void keepClustersApart();
  void stepClusters(const detail::StepContext& ctx);
  detail::CoupledWork coupledWork;
  // The plastic flow of the bodies in `batched` and `single` after the last sweep.
  void flowBodies(double h);
  // Block Jacobi over the bodies that touch (docs/design.md, Contact): the pairs found again
  // against every body's latest end-of-step iterate, and the bodies that have half-spaces
  // stepped again from the substep's start, until the iterates stop moving. A body's fracture
  // is judged in the first sweep only; the later ones keep the damage it left. Call after the
  // first stepBodies of a substep whose findContacts returned pairs, with `sweeping` set;
  // returns the sweeps run.
  int contactSweeps(const detail::CpuExecutor& exec, const detail::StepContext& ctx, double h);

  // Keeps a requested render surface in step with the body: topology only after fractures.
  void updateSurface(BodyRecord& b);

  // The colliders with their stiffness for substep dt filled in.
  void setColliderStiffness(double dt) {
    for (size_t c = 0; c < colliders.size(); ++c) {
      const double k = def.colliders[c].stiffness;
      colliders[c].stiffness = k > 0 ? k : detail::kAutoContactStiffnessDt2 / (dt * dt);
    }
  }
  // What a body step reads; the colliders' stiffness must be set for dt.
  detail::StepContext context(double dt) const {
    detail::StepContext ctx;
    ctx.dt = dt;
    ctx.gravity = {def.gravity.x, def.gravity.y, def.gravity.z};
    ctx.colliders = colliders.data();
    ctx.colliderCount = int(colliders.size());
    return ctx;
  }
};

}  // namespace gf
