// The device backend's linear solve (gpu/pcg.cu) against the CPU's PcgSolver on the same
// systems: the step matrix of a clamped bar, whole and with a band of broken tets (which only
// keep their mass), solved to a tolerance, cut off by the iteration cap, and with a zero
// right-hand side. One source: the host build must give the CPU's bits; a device may contract
// multiply-adds differently, which moves the iterates by round-off. Either way the solution is
// checked against the system itself (its true residual, computed here).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "common/elastic_system.h"
#include "gpu/pcg.h"
#include "graphfrac/mesh.h"
#include "solver/pcg.h"

namespace gf {
namespace {

struct Case {
  const char* name;
  bool broken;  // a band of tets near the middle keeps only its mass
  int maxIterations;
  bool zeroRhs;
};

std::string caseName(const testing::TestParamInfo<Case>& info) { return info.param.name; }

test::ElasticSystem barSystem(const Case& c) {
  TetMesh mesh = gen::box(0.6, 0.1, 0.1, 24, 4, 4);
  std::vector<double> centreX(mesh.tetCount());
  for (size_t t = 0; t < mesh.tetCount(); ++t) {
    double s = 0;
    for (int a = 0; a < 4; ++a) s += mesh.positions[3 * mesh.tets[4 * t + a]];
    centreX[t] = s / 4;
  }
  test::ElasticSystem s = test::assembleElasticSystem(
      std::move(mesh), 1e7, 0.35, 1000, 1.0 / 60, [](double x, double, double) { return x < 1e-9; },
      serialJobs(), [&](size_t t) { return c.broken && std::fabs(centreX[t] - 0.3) < 0.02; });
  if (c.zeroRhs) std::fill(s.b.begin(), s.b.end(), 0.0);
  return s;
}

double trueRelativeResidual(const test::ElasticSystem& s, const std::vector<double>& x) {
  std::vector<double> ax(x.size());
  s.A.multiply(x.data(), ax.data(), serialJobs());
  double rr = 0, bb = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    rr += (s.b[i] - ax[i]) * (s.b[i] - ax[i]);
    bb += s.b[i] * s.b[i];
  }
  return bb > 0 ? std::sqrt(rr / bb) : std::sqrt(rr);
}

class SolverBackend : public testing::TestWithParam<Case> {};

TEST_P(SolverBackend, PcgMatchesTheCpu) {
  std::string why;
  if (!gpu::deviceAvailable(why)) GTEST_SKIP() << why;
  const Case& c = GetParam();
  const test::ElasticSystem s = barSystem(c);
  const size_t n3 = s.b.size();
  const double tol = 1e-10;

  // A non-zero start, as the integrator gives (the constant-velocity guess).
  std::vector<double> xCpu(n3), xDev(n3);
  for (size_t i = 0; i < n3; ++i)
    xCpu[i] = xDev[i] = s.fixed[i / 3] ? 0.0 : 1e-4 * std::sin(0.1 * double(i));
  ThreadPoolJobSystem jobs(2);
  detail::PcgSolver cpu;
  const detail::SolveReport rc =
      cpu.solve(s.A, s.b.data(), xCpu.data(), c.maxIterations, tol, jobs);

  gpu::DevicePcg dev;
  ASSERT_TRUE(dev.upload(s.A)) << dev.error();
  detail::SolveReport rd;
  ASSERT_TRUE(dev.solve(s.b.data(), xDev.data(), c.maxIterations, tol, rd)) << dev.error();

  double diff = 0, scale = 0;
  for (size_t i = 0; i < n3; ++i) {
    diff = std::max(diff, std::fabs(xCpu[i] - xDev[i]));
    scale = std::max(scale, std::fabs(xCpu[i]));
  }
  const double dx = scale > 0 ? diff / scale : diff;
  std::printf(
      "  %s on %s: %zu unknowns; CPU %d iterations, residual %.2e; device %d, %.2e; "
      "max relative difference %.1e\n",
      c.name, gpu::deviceName().c_str(), n3, rc.iterations, rc.relativeResidual, rd.iterations,
      rd.relativeResidual, dx);

  EXPECT_EQ(rc.converged, c.maxIterations > 100);
  EXPECT_EQ(rd.converged, rc.converged);
  if (c.zeroRhs) {
    EXPECT_EQ(rc.iterations, 0);
    EXPECT_EQ(scale, 0.0);
  } else {
    EXPECT_GT(rc.iterations, 0);
    // The report tells the truth about the returned x.
    EXPECT_NEAR(trueRelativeResidual(s, xDev), rd.relativeResidual, 1e-3 * rd.relativeResidual);
    if (rc.converged) {
      EXPECT_LE(trueRelativeResidual(s, xDev), tol);
    }
  }
#if defined(GF_GPU_CUDA)
  EXPECT_LE(std::abs(rd.iterations - rc.iterations), 2);
  EXPECT_LE(dx, rc.converged ? 1e-8 : 1e-6);
#else
  EXPECT_EQ(rd.iterations, rc.iterations);
  EXPECT_EQ(rd.relativeResidual, rc.relativeResidual);
  EXPECT_EQ(xDev, xCpu);
#endif
}

const Case kCases[] = {
    {"Converged", false, 1000, false},
    {"BrokenBand", true, 1000, false},
    {"IterationCap", false, 12, false},
    {"ZeroRightHandSide", false, 1000, true},
};

#if defined(GF_GPU_CUDA)
INSTANTIATE_TEST_SUITE_P(Device, SolverBackend, testing::ValuesIn(kCases), caseName);
#else
INSTANTIATE_TEST_SUITE_P(HostBuild, SolverBackend, testing::ValuesIn(kCases), caseName);
#endif

}  // namespace
}  // namespace gf
