// The World: owns bodies, steps them with implicit FEM, and reports what happened.
#pragma once

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <span>
#include <vector>

#include "defs.h"
#include "events.h"
#include "ids.h"
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
};

/// Timing of the last step, per stage [ms].
struct StepTimings {
  double fractureMs = 0;  ///< Stresses, criterion, fragments (0 without fracture).
  double surfaceMs = 0;   ///< Render-surface update (0 until a surface is requested).
  double elementsMs = 0;  ///< Per-element energy, forces and Hessians.
  double assemblyMs = 0;  ///< Gathering element blocks into the sparse matrix.
  double solveMs = 0;     ///< Linear solves.
  double totalMs = 0;
};

class World {
 public:
  /// Creates a world; an invalid def (e.g. substeps < 1) is reported by the first step and
  /// replaced by defaults.
  explicit World(const WorldDef& def = {});
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  /// Validates the def (mesh, material, node indices of grips and forces) and adds a body.
  /// On error the world is unchanged.
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
  /// a non-finite value.
  Result<void> setVelocity(BodyId id, glm::dvec3 v);
  /// Overwrites all node velocities (3 per node); error for a bad id, a wrong size or a
  /// non-finite value.
  Result<void> setVelocities(BodyId id, std::span<const double> v);
  /// Overwrites all node positions (3 per node), e.g. to teleport a body or to start from a
  /// deformed shape; error for a bad id, a wrong size or a non-finite value.
  Result<void> setPositions(BodyId id, std::span<const double> x);
  /// Energies and momenta; zeroes for an invalid id.
  BodyStats stats(BodyId id) const;
  /// Cuts a body with a blade; the edges it crosses break at the start of the next step and
  /// show up in that step's events. Error for a bad id, a body without fracture, an empty
  /// blade, an index out of range or a non-finite vertex.
  Result<void> cut(BodyId id, const Blade& blade);
  /// Edges broken and fragments created during the last step, sorted by (body, edge) and
  /// (body, fragment). Valid until the next step.
  std::span<const FractureEvent> fractureEvents() const;
  std::span<const FragmentEvent> fragmentEvents() const;
  /// Broken edges and fragments of a body; zeroes for an invalid id.
  FractureStats fractureStats(BodyId id) const;
  /// Fragment id of every node (empty for an invalid id or a body without fracture).
  std::span<const int32_t> nodeFragments(BodyId id) const;
  /// The render surface of a body, built on the first call and kept up to date by every step
  /// from then on (a body nobody renders pays nothing). Empty for an invalid id.
  SurfaceView surface(BodyId id);
  /// Timings of the last step.
  const StepTimings& timings() const;
  /// Simulated time [s].
  double time() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

}  // namespace gf
