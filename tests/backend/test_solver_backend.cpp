// The device backend's linear solves (gpu/pcg.cu, gpu/multigrid.cu) against the CPU's
// PcgSolver and MultigridSolver on the same systems: the step matrix of a clamped bar, whole
// and with a band of broken tets (which only keep their mass), solved to a tolerance, cut off
// by the iteration cap, and with a zero right-hand side; the multigrid with each smoother, one
// and two coarse levels, both prolongations, as CG's preconditioner and cycling alone. One source:
// the host build must give the CPU's bits; a device may contract multiply-adds differently, which
// moves the iterates by round-off. Either way the solution is checked against the system itself
// (its true residual, computed here).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "common/elastic_system.h"
#include "gpu/multigrid.h"
#include "gpu/pcg.h"
#include "graphfrac/mesh.h"
#include "solver/multigrid.h"
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

struct MultigridCase {
  const char* name;
  bool broken;
  Smoother smoother;
  std::vector<int32_t> levels;  // coarsest first; empty: chosen from the size
  bool smoothed, preconditionCG;
  int maxIterations;
  bool refreshOnDevice;  // the coarse operators of this matrix computed by the device
  bool denseCoarsest;    // the coarsest level factorised and solved by the device executor
};

std::string multigridCaseName(const testing::TestParamInfo<MultigridCase>& info) {
  return info.param.name;
}

class MultigridBackend : public testing::TestWithParam<MultigridCase> {};

TEST_P(MultigridBackend, MultigridMatchesTheCpu) {
  std::string why;
  if (!gpu::deviceAvailable(why)) GTEST_SKIP() << why;
  const MultigridCase& c = GetParam();
  const test::ElasticSystem s = barSystem({c.name, c.broken, c.maxIterations, false});
  const size_t n3 = s.b.size();
  const double tol = 1e-8;
  MultigridSettings settings;
  settings.smoother = c.smoother;
  settings.levels = c.levels;
  settings.smoothedProlongation = c.smoothed;
  settings.preconditionCG = c.preconditionCG;
  settings.cycles = c.maxIterations;
  settings.directBelowNodes = 0;

  std::vector<double> xCpu(n3), xDev(n3);
  for (size_t i = 0; i < n3; ++i)
    xCpu[i] = xDev[i] = s.fixed[i / 3] ? 0.0 : 1e-4 * std::sin(0.1 * double(i));
  ThreadPoolJobSystem jobs(2);
  detail::MultigridSolver cpu, host;
  ASSERT_TRUE(cpu.setup(settings, s.mesh.positions.data(), s.fixed.data(), s.A).ok());
  ASSERT_TRUE(host.setup(settings, s.mesh.positions.data(), s.fixed.data(), s.A).ok());
  const detail::SolveReport rc =
      cpu.solve(s.A, s.b.data(), xCpu.data(), c.maxIterations, tol, jobs);

  // The device solver mirrors what the host set up; with refreshOnDevice the host sets up for
  // the other bar (whole or broken) and the device recomputes the levels for this one.
  const test::ElasticSystem other = barSystem({c.name, !c.broken, c.maxIterations, false});
  ASSERT_EQ(other.A.col, s.A.col);
  host.prepare(c.refreshOnDevice ? other.A : s.A, jobs);
  gpu::HostMultigrid mirrored{host.cycleLevels(c.refreshOnDevice ? other.A : s.A),
                              host.galerkinLevels(), host.cycleSettings(),
                              [&](const double* values) { host.factorCoarsest(values); },
                              [&](const double* b, double* x) { host.solveCoarsest(b, x, jobs); }};
  mirrored.denseCoarsestOnDevice = c.denseCoarsest;
  gpu::DeviceMultigrid dev;
  ASSERT_TRUE(dev.upload(c.refreshOnDevice ? other.A : s.A, mirrored)) << dev.error();
  ASSERT_EQ(dev.coarsestOnDevice(), c.denseCoarsest);
  if (c.refreshOnDevice) {
    ASSERT_TRUE(dev.refresh(s.A.values.data())) << dev.error();
  }
  detail::MultigridRun run;
  run.preconditionCG = c.preconditionCG;
  run.cycles = c.maxIterations;
  detail::SolveReport rd;
  ASSERT_TRUE(dev.solve(s.b.data(), xDev.data(), c.maxIterations, tol, run, rd)) << dev.error();

  double diff = 0, scale = 0;
  for (size_t i = 0; i < n3; ++i) {
    diff = std::max(diff, std::fabs(xCpu[i] - xDev[i]));
    scale = std::max(scale, std::fabs(xCpu[i]));
  }
  const double dx = diff / scale;
  std::printf(
      "  %s on %s: %zu unknowns, %d coarse levels; CPU %d iterations (%d V-cycles), residual "
      "%.2e; device %d (%d), %.2e; max relative difference %.1e\n",
      c.name, gpu::deviceName().c_str(), n3, cpu.hierarchy().coarseLevelCount(), rc.iterations,
      cpu.stats().cycles, rc.relativeResidual, rd.iterations, run.vCycles, rd.relativeResidual, dx);

  ASSERT_GT(cpu.stats().cycles, 0);
  EXPECT_EQ(cpu.hierarchy().coarseLevelCount(), c.levels.empty() ? 1 : int(c.levels.size()));
  // The report tells the truth about the returned x, and a converged solve solved the system.
  EXPECT_NEAR(trueRelativeResidual(s, xDev), rd.relativeResidual, 1e-3 * rd.relativeResidual);
  EXPECT_EQ(rd.converged, rc.converged);
  if (rd.converged) {
    EXPECT_LE(trueRelativeResidual(s, xDev), tol);
  }
#if !defined(GF_GPU_CUDA)
  // The dense coarsest factor rounds differently from the host's sparse one (another order of
  // operations), so only the same source with the same coarse solve gives the same bits.
  if (!c.denseCoarsest) {
    EXPECT_EQ(rd.iterations, rc.iterations);
    EXPECT_EQ(run.vCycles, cpu.stats().cycles);
    EXPECT_EQ(rd.relativeResidual, rc.relativeResidual);
    EXPECT_EQ(xDev, xCpu);
    return;
  }
#endif
  EXPECT_LE(std::abs(rd.iterations - rc.iterations), 2);
  EXPECT_LE(dx, 1e-6);
}

const MultigridCase kMultigridCases[] = {
    {"GaussSeidelCG", false, Smoother::GaussSeidel, {}, false, true, 200, false, false},
    {"GaussSeidelCGBrokenBand", true, Smoother::GaussSeidel, {}, false, true, 200, false, false},
    {"TwoLevelsSmoothedCG", false, Smoother::GaussSeidel, {6, 40}, true, true, 200, false, false},
    {"JacobiCyclesAlone", false, Smoother::Jacobi, {6, 40}, false, false, 6, false, false},
    {"ChebyshevCGBrokenBand", true, Smoother::Chebyshev, {}, true, true, 200, false, false},
    // The device refreshes: the broken bar's levels from the whole bar's set-up and back.
    {"GaussSeidelCGRefreshed", true, Smoother::GaussSeidel, {}, false, true, 200, true, false},
    {"TwoLevelsJacobiCGRefreshed", false, Smoother::Jacobi, {6, 40}, false, true, 200, true, false},
    {"TwoLevelsChebyshevCGRefreshed",
     true,
     Smoother::Chebyshev,
     {6, 40},
     false,
     true,
     200,
     true,
     false},
    // The coarsest level factorised and solved by the device executor (solver/dense_cholesky.h)
    // instead of the host's sparse factor: as set up, and refreshed by the device.
    {"GaussSeidelCGDenseCoarsest", false, Smoother::GaussSeidel, {}, false, true, 200, false, true},
    {"TwoLevelsJacobiCyclesDenseCoarsest",
     false,
     Smoother::Jacobi,
     {6, 40},
     false,
     false,
     6,
     false,
     true},
    {"ChebyshevCGDenseCoarsestRefreshed",
     true,
     Smoother::Chebyshev,
     {},
     true,
     true,
     200,
     true,
     true},
};

#if defined(GF_GPU_CUDA)
INSTANTIATE_TEST_SUITE_P(Device, SolverBackend, testing::ValuesIn(kCases), caseName);
INSTANTIATE_TEST_SUITE_P(Device, MultigridBackend, testing::ValuesIn(kMultigridCases),
                         multigridCaseName);
#else
INSTANTIATE_TEST_SUITE_P(HostBuild, SolverBackend, testing::ValuesIn(kCases), caseName);
INSTANTIATE_TEST_SUITE_P(HostBuild, MultigridBackend, testing::ValuesIn(kMultigridCases),
                         multigridCaseName);
#endif

}  // namespace
}  // namespace gf
