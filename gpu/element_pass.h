// Host interface of the CUDA element pass (device pointers in, device pointers out).
#pragma once

#include <cstdint>

#include "kernels/materials.h"
#include "kernels/math.h"

namespace gf::gpu {

/// Device buffers of one element pass; layouts match the CPU integrator's.
struct ElementPassArgs {
  int tetCount = 0;
  const int32_t* tets = nullptr;       ///< 4 per tet
  const double* x = nullptr;           ///< 3 per node
  const Mat3* restInverse = nullptr;   ///< per tet
  const double* restVolume = nullptr;  ///< per tet
  MaterialCoeffs coeffs;
  double* energy = nullptr;  ///< per tet
  double* grad = nullptr;    ///< 12 per tet
  double* hess = nullptr;    ///< 144 per tet, or null for energy and gradient only
};

/// Launches the pass on `stream` (a cudaStream_t, null = default); returns the cudaError_t
/// of the launch (0 = success).
int launchElementPass(const ElementPassArgs& args, void* stream = nullptr);

}  // namespace gf::gpu
