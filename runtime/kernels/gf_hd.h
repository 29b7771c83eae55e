// GF_HD marks per-element math that both the CPU loops and the CUDA kernels call.
// Kernel headers include nothing but this file, <cmath> and each other: no Eigen, no CUDA
// headers, no allocation, so nvcc and g++ compile the same source.
#pragma once

#if defined(__CUDACC__)
#define GF_HD __host__ __device__ inline
#else
#define GF_HD inline
#endif

#include <cmath>

namespace gf {

/// True for a finite value (false for infinities and NaN): std::isfinite is not a device
/// function, and nvcc's isfinite is not a host one in every standard library.
GF_HD bool isFinite(double v) { return v - v == 0; }

}  // namespace gf
