// CUDA launcher for the per-element pass: one thread per tet runs the same GF_HD kernel as the
// CPU loop in runtime/src/fem/integrator.cpp (energy, gradient and PSD Hessian, SPEC §1).
// Built whenever the CUDA toolkit is found, so CI proves the kernels compile for the device, and
// tests/gpu checks it against the CPU kernel on a GPU machine. The World does not use it yet.
#include <cuda_runtime.h>

#include "gpu/element_pass.h"
#include "kernels/element.h"

namespace gf::gpu {

namespace {
__global__ void elementPassKernel(int tetCount, const int32_t* tets, const double* x,
                                  const Mat3* restInverse, const double* restVolume,
                                  MaterialCoeffs coeffs, double* energy, double* grad,
                                  double* hess) {
  const int t = blockIdx.x * blockDim.x + threadIdx.x;
  if (t >= tetCount) return;
  Vec3 xe[4];
  for (int a = 0; a < 4; ++a) {
    const int32_t n = tets[4 * t + a];
    xe[a] = {x[3 * n], x[3 * n + 1], x[3 * n + 2]};
  }
  Mat12* h = hess ? reinterpret_cast<Mat12*>(hess + 144 * size_t(t)) : nullptr;
  energy[t] = elementForces(coeffs, xe, restInverse[t], restVolume[t], grad + 12 * size_t(t), h,
                            /*projectPsd=*/true);
}
}  // namespace

int launchElementPass(const ElementPassArgs& a, void* stream) {
  constexpr int kBlock = 128;
  const int blocks = (a.tetCount + kBlock - 1) / kBlock;
  if (blocks == 0) return 0;
  elementPassKernel<<<blocks, kBlock, 0, static_cast<cudaStream_t>(stream)>>>(
      a.tetCount, a.tets, a.x, a.restInverse, a.restVolume, a.coeffs, a.energy, a.grad, a.hess);
  return static_cast<int>(cudaGetLastError());
}

}  // namespace gf::gpu
