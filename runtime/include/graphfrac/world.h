// The World: owns bodies, steps them with implicit FEM, and reports what happened.
#pragma once

#include <glm/vec3.hpp>
#include <memory>
#include <span>

#include "defs.h"
#include "ids.h"
#include "status.h"

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

/// Timing of the last step, per stage [ms].
struct StepTimings {
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
  /// Timings of the last step.
  const StepTimings& timings() const;
  /// Simulated time [s].
  double time() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

}  // namespace gf
