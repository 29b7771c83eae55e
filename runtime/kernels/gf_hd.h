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
