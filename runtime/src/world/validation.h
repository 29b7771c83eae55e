// Checks shared by World::createBody and BodyDef::check (runtime/src/world/validation.cpp).
#pragma once

#include <cmath>

#include "graphfrac/defs.h"

namespace gf::detail {
/// Lengths [m] and speeds [m/s] beyond this are unit mistakes that overflow squared lengths,
/// the penalty energy and the float render surface; every check refuses them.
constexpr double kMaxMagnitude = 1e9;

inline bool finite3(glm::vec3 v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
/// Finite and no component above kMaxMagnitude.
inline bool bounded3(glm::vec3 v) {
  return finite3(v) && std::abs(v.x) <= kMaxMagnitude && std::abs(v.y) <= kMaxMagnitude &&
         std::abs(v.z) <= kMaxMagnitude;
}

/// BodyDef::check without the mesh: World::createBody validates (and repairs) the mesh itself.
Result<void> checkBodySettings(const BodyDef& def);
/// BodyDef::cutMode and, for CutMode::Xfem, every setting such a body cannot honour (named);
/// part of checkBodySettings, so the scene loader applies the same rules.
Result<void> checkCutMode(const BodyDef& def);
}  // namespace gf::detail
