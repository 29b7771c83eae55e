// Checks shared by World::createBody and BodyDef::check (runtime/src/world/validation.cpp).
#pragma once

#include "graphfrac/defs.h"

namespace gf::detail {
/// BodyDef::check without the mesh: World::createBody validates (and repairs) the mesh itself.
Result<void> checkBodySettings(const BodyDef& def);
}  // namespace gf::detail
