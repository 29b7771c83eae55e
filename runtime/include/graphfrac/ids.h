// Handles the API gives out instead of pointers (Box2D style): index + generation, 0 = null.
#pragma once

#include <cstdint>

namespace gf {

/// A body in a World. A destroyed body's id goes stale: its generation no longer matches.
struct BodyId {
  uint32_t index = 0;       ///< Slot + 1; 0 means "no body".
  uint32_t generation = 0;  ///< Bumped each time the slot is reused.
  bool isNull() const { return index == 0; }
  friend bool operator==(BodyId a, BodyId b) {
    return a.index == b.index && a.generation == b.generation;
  }
};

}  // namespace gf
