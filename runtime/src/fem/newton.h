// The Newton iteration's constants, shared by a body's step (Integrator::solve) and a coupled
// contact cluster's (fem/coupled_step.cpp).
#pragma once

#include <cstdint>

namespace gf::detail {

// Armijo constant and the smallest step the backtracking line search tries.
inline constexpr double kArmijo = 1e-4;
inline constexpr double kMinLineSearchStep = 1.0 / 1024;
// A step until the Newton step falls below kSweptTolerance of the first one, at most this many
// iterations, for a body whose self pairs are solved with their faces (contact/body_contact.h)
// and for a coupled cluster: a thrown cut piece's landing step took 17 iterations, the next one
// 22 (the pairs' lagged friction, whose Hessian stand-in makes Newton contract by a fixed ratio
// while a vertex slides).
inline constexpr int kMaxSelfIterations = 30;
inline constexpr double kSweptTolerance = 1e-3;
// Newton step, relative to the body's size, below which round-off dominates: converged
// whatever the tolerance (a step that starts at equilibrium has nothing left to solve).
inline constexpr double kNewtonRoundOff = 1e-12;

}  // namespace gf::detail
