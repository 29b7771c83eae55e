// The World: owns bodies, steps them with implicit FEM, and reports what happened.
#pragma once

#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "defs.h"
#include "events.h"
#include "ids.h"
#include "sculpt.h"
#include "status.h"
#include "surface.h"

namespace gf {

/// Energies and momenta of one body, for diagnostics and conservation tests.
struct BodyStats {
  double kineticEnergy = 0;       ///< 1/2 v^T M v [J]
  double elasticEnergy = 0;       ///< sum V_e Psi(F_e) [J]
  double gravityEnergy = 0;       ///< -sum m_i g . x_i [J]
  double contactEnergy = 0;       ///< penalty energy of colliders [J]
  glm::dvec3 linearMomentum{0};   ///< sum m_i v_i
  glm::dvec3 angularMomentum{0};  ///< sum x_i x m_i v_i (about the origin)
  double mass = 0;
};

/// A blade for World::cut: a triangle mesh in its own frame, moved rigidly from `from` to `to`
/// over the cut (equal poses: a static cut). Every edge it crosses breaks.
struct Blade {
  std::vector<glm::vec3> vertices;
  std::vector<uint32_t> triangles;  ///< 3 vertex indices per triangle
  glm::mat4 from{1.0f};             ///< blade-to-world at the start of the sweep
  glm::mat4 to{1.0f};               ///< blade-to-world at the end of the sweep
};

/// Fracture state of one body.
struct FractureStats {
  int32_t edgeCount = 0;
  int32_t brokenEdges = 0;
  int32_t fragments = 1;
  /// Of those fragments, the chips: ones that hold no whole tet (in the degradation model, a
  /// node all of whose tets a crack or blade split). Loose matter with mass and no stiffness, so
  /// fragments - chips is the number of pieces.
  int32_t chips = 0;
};

/// A fragment as a rigid body (World::fragmentInfo, World::detachFragment). The fragment is
/// the union of its nodes' corner cells: its mass is the FEM's (lumped) mass, its inertia the
/// exact one of those cells. x = rotation * X + translation maps rest positions X onto the
/// rigid pose that fits the current positions best (least squares, mass-weighted). For a piece
/// of a body in CutMode::Xfem: the exact moments of the piece's cells (consistent mass), and the
/// rigid pose best fitting its field in the mass norm; nodeCount counts the nodes whose
/// functions reach into it.
struct RigidFragmentInfo {
  int32_t nodeCount = 0;
  double mass = 0;                ///< [kg]
  double volume = 0;              ///< Rest volume [m^3].
  glm::dvec3 centreOfMass{0};     ///< Current [m].
  glm::dmat3 inertia{1.0};        ///< About the centre of mass, world axes [kg m^2].
  glm::dvec3 linearVelocity{0};   ///< Momentum / mass of the nodes [m/s].
  glm::dvec3 angularVelocity{0};  ///< inertia^-1 (nodes' angular momentum about the COM).
  glm::dvec3 translation{0};      ///< Rest-to-current frame.
  glm::dquat rotation{1, 0, 0, 0};
};

/// Timing of the last step, per stage [ms].
struct StepTimings {
  double fractureMs = 0;    ///< Stresses, criterion, fragments (0 without fracture).
  double plasticityMs = 0;  ///< Plastic flow after each substep (0 without plasticity).
  double surfaceMs = 0;     ///< Render-surface updates that surface() did since this step.
  double elementsMs = 0;    ///< Per-element energy, forces and Hessians.
  double assemblyMs = 0;    ///< Gathering element blocks into the sparse matrix.
  double solveMs = 0;       ///< Linear solves.
  /// Body-body and self contact: surfaces, broad and narrow phase, momentum exchange (0 when no
  /// body takes part, BodyDef::contact).
  double contactMs = 0;
  /// Wet and dry brushes, water diffusion and the wet stiffness (0 for bodies never wetted).
  double wettingMs = 0;
  double totalMs = 0;
  /// Vertex-triangle contact pairs the step's substeps found (summed over substeps).
  int64_t contactPairs = 0;
};

/// A copy of everything a step reads (positions, velocities, plastic state, damage, broken
/// edges, fragments, strengths, material, grip velocities, pending forces and cuts, water,
/// solver history, time) for rollback and replays; see World::snapshot. An opaque, immutable value:
/// copies share one buffer.
class WorldSnapshot {
 public:
  /// True for a default-constructed snapshot (restoring it is an error).
  bool empty() const { return m_data == nullptr; }
  /// Simulated time the snapshot was taken at [s].
  double time() const;

 private:
  friend class World;
  struct Data;
  std::shared_ptr<const Data> m_data;
};

class World {
 public:
  /// Creates a world. An invalid def (WorldDef::check fails: e.g. substeps < 1, a collider
  /// with an infinite stiffness) or a backend that cannot run (Backend::Cuda, see Backend)
  /// makes a world that refuses to run: createBody returns the error and every step returns
  /// kStepInvalidInput with it.
  explicit World(const WorldDef& def = {});
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  /// The backend that runs the bodies (Cpu or Cuda, never Auto).
  Backend backend() const;
  /// That backend and why, in words, e.g. "cpu: no CUDA device"; empty when the world does
  /// not run.
  const std::string& backendDescription() const;

  /// Validates the def (BodyDef::check) and adds a body. On error, including a body too large
  /// for the memory the process can get (the message says how much it needs), the world is
  /// unchanged.
  Result<BodyId> createBody(BodyDef def);
  /// Removes a body; a stale or null id is an error.
  Result<void> destroyBody(BodyId id);
  /// True while the id refers to a live body.
  bool isValid(BodyId id) const;

  /// Advances every body by dt (> 0, finite) in the world's fixed substeps.
  StepStatus step(double dt);

  /// Current positions / velocities, 3 per node; empty for an invalid id.
  std::span<const double> positions(BodyId id) const;
  std::span<const double> velocities(BodyId id) const;
  /// Overwrites the velocity of every node (e.g. an initial swing); error for a bad id or
  /// a value that is not finite or above 1e9 m/s.
  Result<void> setVelocity(BodyId id, glm::dvec3 v);
  /// Overwrites all node velocities (3 per node); error for a bad id, a wrong size or a value
  /// that is not finite or above 1e9 m/s.
  Result<void> setVelocities(BodyId id, std::span<const double> v);
  /// Overwrites all node positions (3 per node), e.g. to teleport a body or to start from a
  /// deformed shape; error for a bad id, a wrong size or a coordinate that is not finite or
  /// farther than 1e9 m from the origin (a unit mistake the float render surface cannot hold).
  Result<void> setPositions(BodyId id, std::span<const double> x);
  /// Energies and momenta; zeroes for an invalid id or during step(). Reads the body only, so
  /// threads may call it between steps.
  BodyStats stats(BodyId id) const;
  /// Cuts a body with a blade; the edges it crosses break at the start of the next step and
  /// show up in that step's events. A body in CutMode::Xfem is cut through its tets at once (its
  /// state unchanged: the new enriched DOFs start at zero) and the next step reports the cut
  /// (one FractureEvent per cut tet, a FragmentEvent per new piece). Error, with nothing
  /// changed, for a bad id, a body without fracture (graph mode), an empty blade, an index out of
  /// range or a non-finite vertex; in Xfem mode also for more than 32 cuts or more than 4
  /// through one tet (CutMode).
  Result<void> cut(BodyId id, const Blade& blade);
  /// Edges broken and fragments created during the last step, sorted by (body, edge) and
  /// (body, fragment). Valid until the next step.
  std::span<const FractureEvent> fractureEvents() const;
  std::span<const FragmentEvent> fragmentEvents() const;
  /// Broken edges and fragments of a body; zeroes for an invalid id. A body in CutMode::Xfem has
  /// no edges; its fragments are its pieces.
  FractureStats fractureStats(BodyId id) const;
  /// Fragment id of every node (empty for an invalid id or a body without fracture).
  std::span<const int32_t> nodeFragments(BodyId id) const;
  /// 1 for every fragment that is a chip (FractureStats::chips), 0 for a piece; one per
  /// fragment. Empty for an invalid id or a body without fracture.
  std::span<const uint8_t> chipFlags(BodyId id) const;
  /// The two nodes of every edge of the fracture graph, 2 per edge, in the order that
  /// setEdgeStrengths, brokenEdges and FractureEvent::edge use. Empty for an invalid id or a
  /// body without fracture. Fixed for the body's lifetime.
  std::span<const int32_t> edges(BodyId id) const;
  /// Per edge (same order as edges()), 1 when broken. Empty for an invalid id or a body
  /// without fracture. Valid until the next step.
  std::span<const uint8_t> brokenEdges(BodyId id) const;
  /// Per grip of BodyDef::grips, the force [N] it exerts on the body at the end of the last
  /// step: what holds its nodes on their prescribed path against inertia, elasticity, gravity,
  /// applied forces and contact (the residual of the implicit step's momentum balance on them).
  /// Zero before the first step; empty for a body in CutMode::Xfem (not computed). Computed on each
  /// call, O(tets); valid until the next call, step or body creation/destruction. Empty for an
  /// invalid id or during step().
  std::span<const glm::dvec3> gripForces(BodyId id);
  /// Per node, the largest principal Lagrangian strain (F^T F - I) / 2 of its tets, averaged
  /// with the tets' rest volumes as weights: what a strain colour map shows (map it to the
  /// surface with SurfaceView::vertexNode). Computed on each call, O(tets); valid until the
  /// next call, step or body creation/destruction. Empty for an invalid id or during step().
  std::span<const double> nodeStrain(BodyId id);

  // Hand-off of fragments to rigid-body physics (integration/bullet). A detached fragment's
  // nodes leave the FEM solve: they move as the game's rigid body says (setFragmentTransform)
  // and the rest of the body sees them like pinned nodes. Contact between them and the rest of
  // the body is up to the rigid physics.

  /// A fragment's rigid-body properties now, without detaching it. Error for a bad id, a body
  /// without fracture or a fragment id out of range.
  Result<RigidFragmentInfo> fragmentInfo(BodyId id, int32_t fragment) const;
  /// Takes a fragment out of the FEM solve and returns its rigid-body properties (momentum and
  /// angular momentum of its nodes carried over). Error (nothing changed) for a bad id, a body
  /// without fracture, a fragment out of range, one holding gripped nodes, or one already
  /// detached; for a body in CutMode::Xfem also for the last piece left in it (see CutMode for
  /// what detaching a piece does there).
  Result<RigidFragmentInfo> detachFragment(BodyId id, int32_t fragment);
  /// Moves a detached fragment rigidly: x = rotation * X + translation for its rest positions
  /// X, and velocities v = linearVelocity + angularVelocity x (x - centre of mass). The render
  /// surface follows. Error for a bad id, a fragment not detached or a non-finite or zero value.
  Result<void> setFragmentTransform(BodyId id, int32_t fragment, glm::dvec3 translation,
                                    glm::dquat rotation, glm::dvec3 linearVelocity,
                                    glm::dvec3 angularVelocity);
  /// Fragments detached since the last step began, sorted by (body, fragment). Valid until
  /// the next step.
  std::span<const HandoffEvent> handoffEvents() const;
  /// The render surface of a body, built on the first call and brought up to date by each
  /// later call after the body moved (a body nobody renders pays nothing, and one rendered once
  /// per frame pays once per frame, however many steps or substeps the frame took). The dirty
  /// range covers the vertices moved since the previous call. A body with a
  /// BodyDef::renderMesh shows that mesh, deformed with its tets, split by fragment and with the
  /// crack faces added (uvs filled when it has UVs; every vertex is dirty after an update);
  /// other bodies show their tet boundary with crack faces; a body in CutMode::Xfem shows each
  /// piece's closed surface with the exact cut polygons (crackMask 1, vertexFragment the piece,
  /// vertexNode a node of the simplex the vertex lies on). Empty for an invalid id or when
  /// called while step() runs.
  SurfaceView surface(BodyId id);
  /// Timings of the last step.
  const StepTimings& timings() const;
  /// Simulated time [s].
  double time() const;

  // Commands the game issues between steps. Each returns an error naming the argument and the
  // reason (stale id, non-finite value, index or size out of range, a call made while step()
  // runs) and then leaves the world unchanged.

  /// A force [N] at a world point that acts during the next step only. It is spread over the
  /// corners of the tet containing the point with its barycentric weights, so the total force
  /// and the torque about any point are exact. A point outside the body goes to the tet whose
  /// weakest barycentric coordinate is largest, with negative weights clamped: it then acts at
  /// a point of that tet near the given one. Finding the tet is O(tets) per call.
  Result<void> applyForce(BodyId id, glm::vec3 point, glm::vec3 force);
  /// An impulse [N s] at a world point, applied to the velocities at once and spread like
  /// applyForce (node i gets w_i J, dv_i = w_i J / m_i): the momentum changes by exactly J and
  /// the angular momentum by point x J (for a point inside the body). Gripped nodes take it too
  /// but are reset to their grip velocity by the next step.
  Result<void> applyImpulse(BodyId id, glm::vec3 point, glm::vec3 impulse);
  /// Sets the velocity [m/s] of grip `grip` of BodyDef::grips from the next step on.
  Result<void> setGripVelocity(BodyId id, int grip, glm::vec3 velocity);
  /// Replaces the tensile strength sigma_th [Pa] of every edge (one per edge, in edge-graph
  /// order, see fractureStats().edgeCount; positive and finite). Error for a body without
  /// fracture.
  Result<void> setEdgeStrengths(BodyId id, std::span<const double> strength);
  /// Applies an impurity map (thesis sec 5.4) to the body's rest mesh: the edges it covers get
  /// their strength times map.potency and their nodes the impurity 1 / potency; potency 0
  /// cuts them at the next step. Error (nothing changed) for a body without fracture, an
  /// invalid map (ImpurityMap::check) or a polyline point off the rest surface; the message
  /// names the field ("applyImpurityMap: map.points[2]: ...").
  Result<void> applyImpurityMap(BodyId id, const ImpurityMap& map);
  /// Replaces the material (same MaterialModel, validated like createBody; fibreStiffness must
  /// stay zero or non-zero as at creation). A new density changes the lumped masses.
  Result<void> setMaterial(BodyId id, const Material& material);

  // Sculpting (thesis ch. 7).

  /// Wets the tets the brush touches during the next step (see WetBrush and
  /// BodyDef::wetting); the first call on a body sets up its water (O(tets log tets), once).
  /// Error for a bad id, a centre that is not finite or farther than 1e9 m from the origin, a
  /// radius or rate that is not positive and finite.
  Result<void> wet(BodyId id, const WetBrush& brush);
  /// Dries like wet() wets: the touched tets lose rate * dt of saturation, down to 0.
  Result<void> dry(BodyId id, const WetBrush& brush);
  /// Holds the body's nodes by the brush's kernel during the next step (see DeformBrush).
  /// Several brushes in one step multiply. Error for a bad id, a centre that is
  /// not finite or farther than 1e9 m from the origin, a radius, k1 or k2 that is not positive
  /// and finite.
  Result<void> deform(BodyId id, const DeformBrush& brush);
  /// Pulls the brush's nodes toward its targets during the next step (see PullBrush); pulls
  /// given before one step add up. Error, with nothing queued, for a bad id, no nodes, a
  /// targets count that differs from the nodes count, a node index out of range or a target
  /// that is not finite or farther than 1e9 m from the origin (each naming its index), or a
  /// stiffness that is not in (0, 1e12].
  Result<void> pull(BodyId id, const PullBrush& brush);
  /// The mean force [N] the last step's pulls exerted on the body: over each substep of h,
  /// sum m k (t - x') with x' the node's end position, averaged over the step (so the body's
  /// momentum took pullForce * dt from them). Zero when the last step had no pull or for a bad
  /// id. Not during step().
  glm::dvec3 pullForce(BodyId id) const;
  /// The body's tet mesh in its current shape (its tets, the node positions now): what a
  /// sculpting session saves (TetMesh::writeMsh, writeSurface) and reloads as a new body's
  /// rest shape. Broken edges are not cut apart in it. Error for a bad id, or a tet the
  /// deformation has turned inside out (it would not load back), naming the tet.
  Result<TetMesh> currentMesh(BodyId id) const;
  /// Water mass [kg] per tet; empty for an invalid id or a body never wetted.
  std::span<const double> waterMass(BodyId id) const;
  /// Saturation S_w in [0, 1] per tet (water mass over the tet's capacity); computed on each
  /// call, O(tets), valid until the next call, step or body destruction. Empty for an invalid
  /// id, a body never wetted, or during step().
  std::span<const double> saturation(BodyId id);
  /// After every step, publishes to `probe` the force [N] that collider `collider` (a sphere
  /// collider as the sculpting proxy) received from the bodies over that step, -impulse / dt,
  /// with the world's time: a haptic thread polls it (HapticProbe). Null detaches. The probe
  /// must outlive the attachment. Error for a collider index out of range of colliders().
  Result<void> attachHapticProbe(HapticProbe* probe, int collider = 0);

  /// Replaces every collider (WorldDef::colliders included), e.g. with the game's rigid bodies
  /// at their current pose and velocity before each step (integration/bullet does this). The
  /// world treats them as kinematic: they push the bodies and report what they gave
  /// (colliderImpulses); the game applies the opposite to its rigid bodies.
  Result<void> setColliders(std::span<const Collider> colliders);
  /// The colliders now; a moving one's point has advanced by velocity * dt every step.
  std::span<const Collider> colliders() const;
  /// Per collider, the impulse [N s] its contact penalty gave the bodies' free nodes during the
  /// last step, summed over nodes and substeps: h times the contact force that entered the
  /// implicit step's momentum balance (the last Newton step's linearisation of the penalty,
  /// taken to the accepted end-of-substep positions; the force at those positions when the
  /// contact set did not change). A free body's momentum change is this plus its external
  /// impulses, to the linear solver's tolerance.
  std::span<const glm::dvec3> colliderImpulses() const;
  /// Per collider, the moment [N m s] of those impulses about the collider's point (its centre
  /// for a box, sphere or capsule) at the end of each substep.
  std::span<const glm::dvec3> colliderAngularImpulses() const;

  /// Copies the whole world state for rollback and replays (O(state), no solver work).
  WorldSnapshot snapshot() const;
  /// Puts the world back into a snapshot's state: the steps that follow repeat bit for bit.
  /// The snapshot must have been taken of this world, which must hold exactly the snapshot's
  /// bodies (same ids and meshes); otherwise, for an empty snapshot, or during step(), it is an
  /// error and nothing changes. Render surfaces are
  /// rebuilt; events are those of the step before the snapshot. With a multigrid solver the
  /// crack re-binding history is replayed (one re-bind per step that broke edges), unless it
  /// is unchanged since the snapshot. A body with fragments handed to rigid physics
  /// (detachFragment) cannot be restored yet: that is an error.
  Result<void> restore(const WorldSnapshot& snapshot);
  /// FNV-1a over every live body's id, positions, velocities, broken-edge flags, water and
  /// contact loads (what its friction between its own pieces bears next step) and the time:
  /// equal hashes for equal states, for determinism checks across threads and runs.
  uint64_t stateHash() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

}  // namespace gf
