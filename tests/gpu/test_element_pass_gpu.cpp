// The CUDA element pass (gpu/element_pass.cu) against the CPU evaluation of the same GF_HD
// kernel (runtime/kernels/element.h): energy, gradient and projected Hessian of every tet, for
// every material model, on deformed, compressed and inverted tets. Skipped where no CUDA device
// exists (CI); run on a GPU machine with `gf_gpu_tests`. Self-contained on purpose (kernels and
// the CUDA runtime only), so the binary can be carried to a GPU machine without the runtime's
// shared libraries.
#include <cuda_runtime.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "gpu/element_pass.h"
#include "kernels/element.h"

namespace gf {
namespace {

bool haveDevice() {
  int count = 0;
  return cudaGetDeviceCount(&count) == cudaSuccess && count > 0;
}

// Independent tets (4 nodes each) from a jittered regular tet, deformed by a random affine map
// plus per-node noise; every 7th is inverted and every 5th compressed to a tenth of its volume.
struct Soup {
  std::vector<int32_t> tets;
  std::vector<double> x;
  std::vector<Mat3> restInverse;
  std::vector<double> restVolume;
};

Soup makeSoup(int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  Soup s;
  const Vec3 ref[4] = {{0, 0, 0}, {0.1, 0, 0}, {0, 0.1, 0}, {0, 0, 0.1}};
  for (int t = 0; t < count; ++t) {
    Vec3 X[4], x[4];
    for (int a = 0; a < 4; ++a)
      for (int i = 0; i < 3; ++i) X[a][i] = ref[a][i] + 0.02 * u(rng);
    double volume = 0;
    const Mat3 DmInv = restShapeInverse(X, volume);
    Mat3 A;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) A(i, j) = (i == j ? 1.0 : 0.0) + 0.3 * u(rng);
    if (t % 5 == 0)  // ~1/10 of the volume
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) A(i, j) *= 0.46;
    if (t % 7 == 0)
      for (int i = 0; i < 3; ++i) A(i, 0) = -A(i, 0);  // inverted
    for (int a = 0; a < 4; ++a) {
      x[a] = A * X[a];
      for (int i = 0; i < 3; ++i) x[a][i] += 0.005 * u(rng);
      s.tets.push_back(int32_t(4 * t + a));
      for (int i = 0; i < 3; ++i) s.x.push_back(x[a][i]);
    }
    s.restInverse.push_back(DmInv);
    s.restVolume.push_back(volume);
  }
  return s;
}

template <class T>
T* upload(const std::vector<T>& v) {
  T* d = nullptr;
  if (cudaMalloc(&d, v.size() * sizeof(T)) != cudaSuccess) return nullptr;
  cudaMemcpy(d, v.data(), v.size() * sizeof(T), cudaMemcpyHostToDevice);
  return d;
}

struct DeviceResult {
  std::vector<double> energy, grad, hess;
  double kernelMs = 0;
};

DeviceResult runDevice(const Soup& s, const MaterialCoeffs& c, bool hessian) {
  const int n = int(s.restVolume.size());
  DeviceResult r;
  int32_t* tets = upload(s.tets);
  double* x = upload(s.x);
  Mat3* inv = upload(s.restInverse);
  double* vol = upload(s.restVolume);
  double *energy = nullptr, *grad = nullptr, *hess = nullptr;
  cudaMalloc(&energy, size_t(n) * sizeof(double));
  cudaMalloc(&grad, size_t(n) * 12 * sizeof(double));
  if (hessian) cudaMalloc(&hess, size_t(n) * 144 * sizeof(double));
  gpu::ElementPassArgs a{n, tets, x, inv, vol, c, energy, grad, hess};
  EXPECT_EQ(gpu::launchElementPass(a), 0);  // warm-up (module load)
  cudaDeviceSynchronize();
  cudaEvent_t e0, e1;
  cudaEventCreate(&e0);
  cudaEventCreate(&e1);
  cudaEventRecord(e0);
  EXPECT_EQ(gpu::launchElementPass(a), 0);
  cudaEventRecord(e1);
  cudaEventSynchronize(e1);
  float ms = 0;
  cudaEventElapsedTime(&ms, e0, e1);
  r.kernelMs = ms;
  r.energy.resize(size_t(n));
  r.grad.resize(size_t(n) * 12);
  cudaMemcpy(r.energy.data(), energy, r.energy.size() * sizeof(double), cudaMemcpyDeviceToHost);
  cudaMemcpy(r.grad.data(), grad, r.grad.size() * sizeof(double), cudaMemcpyDeviceToHost);
  if (hessian) {
    r.hess.resize(size_t(n) * 144);
    cudaMemcpy(r.hess.data(), hess, r.hess.size() * sizeof(double), cudaMemcpyDeviceToHost);
  }
  EXPECT_EQ(cudaGetLastError(), cudaSuccess);
  for (void* p :
       {(void*)tets, (void*)x, (void*)inv, (void*)vol, (void*)energy, (void*)grad, (void*)hess})
    cudaFree(p);
  cudaEventDestroy(e0);
  cudaEventDestroy(e1);
  return r;
}

// Largest |a - b| relative to the largest |b| of the tet's block (scale-aware: entries of a
// block that cancel to ~0 are compared at the block's scale).
double worstRelative(const double* a, const double* b, int block, int count) {
  double worst = 0;
  for (int t = 0; t < count; ++t) {
    double scale = 1e-300, diff = 0;
    for (int k = 0; k < block; ++k) {
      scale = std::max(scale, std::abs(b[size_t(t) * block + k]));
      diff = std::max(diff, std::abs(a[size_t(t) * block + k] - b[size_t(t) * block + k]));
    }
    worst = std::max(worst, diff / scale);
  }
  return worst;
}

class ElementPassGpu : public ::testing::TestWithParam<int> {};

TEST_P(ElementPassGpu, MatchesCpuKernel) {
  if (!haveDevice()) GTEST_SKIP() << "no CUDA device";
  const int model = GetParam();
  const int n = 20000;
  const Soup s = makeSoup(n, 17u + unsigned(model));
  const MaterialCoeffs c =
      makeMaterialCoeffs(model, 1e7, 0.4, model == kStableNeoHookean ? 2e6 : 0, Vec3{1, 1, 0});
  const DeviceResult d = runDevice(s, c, true);
  std::vector<double> energy(static_cast<size_t>(n)), grad(size_t(n) * 12), hess(size_t(n) * 144);
  for (int t = 0; t < n; ++t) {
    Vec3 xe[4];
    for (int a = 0; a < 4; ++a)
      for (int i = 0; i < 3; ++i) xe[a][i] = s.x[3 * size_t(s.tets[4 * t + a]) + i];
    energy[size_t(t)] = elementForces(
        c, xe, s.restInverse[size_t(t)], s.restVolume[size_t(t)], grad.data() + 12 * size_t(t),
        reinterpret_cast<Mat12*>(hess.data() + 144 * size_t(t)), true);
  }
  const double eErr = worstRelative(d.energy.data(), energy.data(), 1, n);
  const double gErr = worstRelative(d.grad.data(), grad.data(), 12, n);
  const double hErr = worstRelative(d.hess.data(), hess.data(), 144, n);
  std::printf(
      "model %d: %d tets, worst relative difference energy %.2e, gradient %.2e, "
      "Hessian %.2e\n",
      model, n, eErr, gErr, hErr);
  // Round-off only: the device contracts multiply-adds (FMA) where the host compiler may not.
  EXPECT_LT(eErr, 1e-11);
  EXPECT_LT(gErr, 1e-10);
  EXPECT_LT(hErr, 1e-8);
}

INSTANTIATE_TEST_SUITE_P(Models, ElementPassGpu,
                         ::testing::Values(int(kCorotated), int(kStVK), int(kNeoHookean),
                                           int(kStableNeoHookean)));

// Not a timed assertion: prints the kernel time against one CPU thread for the same tets.
TEST(ElementPassGpuBench, PrintsDeviceAndCpuTime) {
  if (!haveDevice()) GTEST_SKIP() << "no CUDA device";
  cudaDeviceProp prop{};
  cudaGetDeviceProperties(&prop, 0);
  const int n = 1 << 20;
  const Soup s = makeSoup(n, 3);
  const MaterialCoeffs c = makeMaterialCoeffs(kStableNeoHookean, 1e7, 0.4, 0, Vec3{1, 0, 0});
  const DeviceResult d = runDevice(s, c, true);
  std::vector<double> grad(12), hess(144);
  const int cpuCount = 1 << 16;
  const auto t0 = std::chrono::steady_clock::now();
  double sum = 0;
  for (int t = 0; t < cpuCount; ++t) {
    Vec3 xe[4];
    for (int a = 0; a < 4; ++a)
      for (int i = 0; i < 3; ++i) xe[a][i] = s.x[3 * size_t(s.tets[4 * t + a]) + i];
    sum += elementForces(c, xe, s.restInverse[size_t(t)], s.restVolume[size_t(t)], grad.data(),
                         reinterpret_cast<Mat12*>(hess.data()), true);
  }
  const double cpuMs =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() *
      double(n) / cpuCount;
  std::printf(
      "%s: element pass (energy, gradient, projected Hessian) of %d tets: device %.2f ms "
      "(%.1f ns/tet), one CPU thread %.0f ms (extrapolated from %d tets), ratio %.0fx "
      "[checksum %.3e]\n",
      prop.name, n, d.kernelMs, 1e6 * d.kernelMs / n, cpuMs, cpuCount, cpuMs / d.kernelMs, sum);
  EXPECT_GT(d.kernelMs, 0);
}

}  // namespace
}  // namespace gf
