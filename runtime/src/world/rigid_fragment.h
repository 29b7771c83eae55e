// Rigid-body properties of a fragment for the hand-off to rigid physics (World::detachFragment).
// The fragment is the union of its nodes' corner cells: its mass is the sum of their lumped
// masses (so momentum carries over exactly) and its inertia is the exact one of those cells
// (kernels/tet_inertia.h), computed on the rest shape that the rigid motion then carries.
#pragma once

#include <cstdint>

#include "fem/fem_body.h"
#include "kernels/math.h"

namespace gf::detail {

struct RigidProperties {
  int32_t nodeCount = 0;
  double mass = 0;
  double volume = 0;          // rest volume of the corner cells
  Vec3 centre;                // exact centre of mass at the current positions
  Vec3 restCentre;            // exact centre of mass at rest
  Mat3 restInertia;           // about restCentre, in rest axes
  Mat3 rotation;              // best-fit rest-to-current rotation (polar factor)
  Vec3 momentum;              // sum m_i v_i (lumped masses: the FEM's own momentum)
  Vec3 angularMomentum;       // sum (x_i - centre) x m_i v_i
  bool hasFixedNode = false;  // a node of the fragment is pinned or gripped
};

/// Properties of the nodes n with nodeFragment[n] == fragment, at the body's positions and
/// velocities.
RigidProperties rigidProperties(const FemModel& m, const FemState& s, const int32_t* nodeFragment,
                                int32_t fragment);

}  // namespace gf::detail
