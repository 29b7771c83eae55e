// The multigrid's Gauss-Seidel smoothing against a plain colour-by-colour block Gauss-Seidel
// written here: a fine-level V-cycle gives the same bits as the reference sweeps, the same bits
// on 1, 2 and 4 threads, and its stationary iteration reaches the direct solve.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "common/elastic_system.h"
#include "graphfrac/jobs.h"
#include "solver/cholesky.h"
#include "solver/multigrid.h"
#include "step/executor.h"

namespace {

using gf::MultigridSettings;
using gf::detail::BlockSparseMatrix;
using gf::detail::CpuExecutor;
using gf::detail::CycleLevel;
using gf::detail::MultigridSolver;
using gf::test::ElasticSystem;

// A rubber cantilever (1 m, section 0.2 m, clamped at x = 0) at dt = 1/60.
ElasticSystem rubberBeam(int nx, int nh, gf::JobSystem& jobs) {
  return gf::test::assembleElasticSystem(
      gf::gen::box(1.0, 0.2, 0.2, nx, nh, nh), 1e6, 0.45, 1100, 1.0 / 60.0,
      [](double x, double, double) { return x < 1e-9; }, jobs);
}

// Colour-by-colour block Gauss-Seidel on A's rows in the level's colour order:
// x_r += D_r^-1 (b - A x)_r.
void referenceSweep(const BlockSparseMatrix& A, const CycleLevel& lv, const double* b, double* x,
                    bool forward) {
  for (int32_t cc = 0; cc < lv.colours; ++cc) {
    const int32_t c = forward ? cc : lv.colours - 1 - cc;
    for (int32_t q = lv.colourStart[c]; q < lv.colourStart[c + 1]; ++q) {
      const int32_t r = lv.colourRows[q];
      double ax[3] = {0, 0, 0};
      for (int32_t k = A.rowStart[r]; k < A.rowStart[r + 1]; ++k)
        for (int i = 0; i < 3; ++i) {
          double acc = 0;
          for (int j = 0; j < 3; ++j) acc += A.block(k)[3 * i + j] * x[3 * A.col[k] + j];
          ax[i] += acc;
        }
      const double res[3] = {b[3 * r] - ax[0], b[3 * r + 1] - ax[1], b[3 * r + 2] - ax[2]};
      const double* inv = lv.invDiag + 9 * r;
      for (int i = 0; i < 3; ++i) {
        double dx = 0;
        for (int j = 0; j < 3; ++j) dx += inv[3 * i + j] * res[j];
        x[3 * r + i] += dx;
      }
    }
  }
}

double relDiff(const std::vector<double>& a, const std::vector<double>& b) {
  double num = 0, den = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    num += (a[i] - b[i]) * (a[i] - b[i]);
    den += b[i] * b[i];
  }
  return std::sqrt(num / den);
}

// The fine level alone (no coarse correction): a V-cycle is then 2 forward and 2 backward
// Gauss-Seidel sweeps from zero.
TEST(MultigridSmoothing, GaussSeidelCycleIsColouredGaussSeidelAndReachesTheDirectSolution) {
  gf::SerialJobSystem serial;
  for (int nx : {6, 15}) {
    const ElasticSystem s = rubberBeam(nx, 3, serial);
    MultigridSolver mg;
    ASSERT_TRUE(mg.setup(MultigridSettings{}, s.mesh.positions.data(), s.fixed.data(), s.A).ok());
    mg.prepare(s.A, serial);
    const std::vector<CycleLevel> fine = {mg.cycleLevels(s.A)[0]};
    const size_t n3 = s.b.size();

    // One cycle against the reference sweeps (same operations in the same order: same bits).
    std::vector<double> ref(n3, 0.0);
    for (int sweep = 0; sweep < 2; ++sweep)
      referenceSweep(s.A, fine[0], s.b.data(), ref.data(), true);
    for (int sweep = 0; sweep < 2; ++sweep)
      referenceSweep(s.A, fine[0], s.b.data(), ref.data(), false);

    gf::detail::CholeskySolver chol;
    ASSERT_TRUE(chol.analyze(s.A).ok());
    std::vector<double> direct(n3, 0.0);
    ASSERT_TRUE(chol.solve(s.A, s.b.data(), direct.data()).converged);

    std::vector<std::vector<double>> results;
    for (int threads : {1, 2, 4}) {
      gf::ThreadPoolJobSystem jobs(threads);
      std::vector<double> partials;
      const CpuExecutor exec(jobs, &partials);
      auto noCoarse = [](const double*, double*) { FAIL() << "no coarse level"; };
      gf::detail::CycleTimes times;
      const gf::detail::VCycle<CpuExecutor, decltype(noCoarse)> cycle(
          exec, fine, mg.cycleSettings(), noCoarse, times);
      std::vector<double> x(n3, 1.0);  // overwritten: the cycle starts from zero
      cycle.cycle<3>(0, s.b.data(), x.data());
      EXPECT_EQ(std::memcmp(x.data(), ref.data(), 8 * n3), 0) << nx << " " << threads;
      // Stationary iteration x += V (b - A x) to its fixed point, the solution of A x = b.
      std::vector<double> ax(n3), r(n3), e(n3);
      for (int it = 0; it < 3000; ++it) {
        s.A.multiply(x.data(), ax.data(), jobs);
        for (size_t i = 0; i < n3; ++i) r[i] = s.b[i] - ax[i];
        cycle.cycle<3>(0, r.data(), e.data());
        for (size_t i = 0; i < n3; ++i) x[i] += e[i];
      }
      EXPECT_LT(relDiff(x, direct), 1e-9) << nx << " " << threads;
      results.push_back(x);
    }
    for (size_t t = 1; t < results.size(); ++t)
      EXPECT_EQ(std::memcmp(results[t].data(), results[0].data(), 8 * n3), 0) << nx;
  }
}

}  // namespace
