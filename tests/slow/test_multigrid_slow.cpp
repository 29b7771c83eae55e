// Slow validation (ctest label "slow"): the multigrid's acceptance figures on a 30k-tet cantilever
// (1 x 0.2 x 0.2 m, 50x10x10 cells, clamped at x = 0, first implicit step at dt = 1/60 under
// gravity), steel and rubber: residual reduction per V-cycle, MG-CG iterations to 1e-6 against
// block-Jacobi PCG, the solution against Cholesky, and the set-up and re-binding costs.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "common/elastic_system.h"
#include "graphfrac/jobs.h"
#include "mesh/edge_graph.h"
#include "solver/cholesky.h"
#include "solver/multigrid.h"
#include "solver/pcg.h"

namespace {

using gf::MultigridSettings;
using gf::Smoother;
using gf::detail::MultigridSolver;
using gf::detail::SolveReport;

struct MaterialCase {
  const char* name;
  double E, nu, rho;
};

struct Setting {
  std::vector<int32_t> levels;  ///< empty: the default, chosen from the body's size
  Smoother smoother;
  int sweeps;
  bool smoothed = true;
  int coarseSweeps = -1;  ///< on the coarse levels above the coarsest; -1: `sweeps`
  double filter = 0;      ///< MultigridSettings::prolongationFilter
};

std::string settingName(const Setting& set) {
  std::string name;
  for (int32_t c : set.levels) name += std::to_string(c) + "/";
  name += set.levels.empty() ? "auto " : "all ";
  name += set.smoothed ? "SA " : "tentative ";
  if (set.filter > 0) name += "filter " + std::to_string(set.filter).substr(0, 4) + " ";
  if (set.coarseSweeps >= 0) name += "coarse " + std::to_string(set.coarseSweeps) + "+ ";
  return name;
}

const char* smootherName(Smoother s) {
  return s == Smoother::Jacobi        ? "jacobi"
         : s == Smoother::GaussSeidel ? "gauss-seidel"
                                      : "chebyshev";
}

double relDiff(const std::vector<double>& a, const std::vector<double>& b) {
  double num = 0, den = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    num += (a[i] - b[i]) * (a[i] - b[i]);
    den += b[i] * b[i];
  }
  return std::sqrt(num / den);
}

struct Result {
  double first = 1, factor = 1;
  int iterations = 0;
  double residual = 0, cgMs = 0, refreshMs = 0, galerkinMs = 0, factorMs = 0, smoothMs = 0,
         coarseMs = 0, transferMs = 0, setupMs = 0, cyclesMs = 0, diff = 0;
  int cycles = 0;
  bool factorOk = true;
  double laterGalerkinMs = 0, laterMs = 0;
  std::vector<int32_t> handles;
  std::string blocks;  ///< P's and the coarse operator's blocks per coarse level, finest first
};

// V-cycles alone (first cycle, then the geometric mean per cycle) and MG-CG to 1e-6.
Result run(const gf::test::ElasticSystem& s, const Setting& set, const std::vector<double>* ref,
           gf::JobSystem& jobs) {
  MultigridSettings ms;
  ms.levels = set.levels;
  ms.smoother = set.smoother;
  ms.preSweeps = ms.postSweeps = set.sweeps;
  ms.smoothedProlongation = set.smoothed;
  ms.coarsePreSweeps = ms.coarsePostSweeps = set.coarseSweeps;
  ms.prolongationFilter = set.filter;
  ms.cycles = 6;
  Result out;
  ms.preconditionCG = false;
  MultigridSolver alone;
  EXPECT_TRUE(alone.setup(ms, s.mesh.positions.data(), s.fixed.data(), s.A).ok());
  std::vector<double> x(s.b.size(), 0.0);
  alone.solve(s.A, s.b.data(), x.data(), 0, 1e-14, jobs);
  const std::vector<double>& h = alone.cycleResiduals();
  EXPECT_GE(h.size(), 4u);
  if (h.size() >= 4) {
    out.first = h[1] / h[0];
    out.factor = std::pow(h.back() / h[1], 1.0 / double(h.size() - 2));
  }
  out.cyclesMs = alone.stats().totalMs;
  out.cycles = alone.stats().cycles;

  ms.preconditionCG = true;
  MultigridSolver mg;
  EXPECT_TRUE(mg.setup(ms, s.mesh.positions.data(), s.fixed.data(), s.A).ok());
  std::vector<double> xm(s.b.size(), 0.0);
  const SolveReport r = mg.solve(s.A, s.b.data(), xm.data(), 200, 1e-6, jobs);
  EXPECT_TRUE(r.converged) << settingName(set);
  const auto& st = mg.stats();
  out.iterations = r.iterations;
  out.residual = r.relativeResidual;
  out.cgMs = st.totalMs;
  out.refreshMs = st.refreshMs;
  out.galerkinMs = st.galerkinMs;
  out.factorMs = st.factorMs;
  out.smoothMs = st.smoothMs;
  out.coarseMs = st.coarseSolveMs;
  out.transferMs = st.transferMs;
  out.setupMs = st.setupMs;
  out.handles = st.handles;
  out.factorOk = st.coarseFactorOk;
  for (int l = 1; l <= mg.hierarchy().coarseLevelCount(); ++l)
    out.blocks += (l > 1 ? ", " : "") + std::to_string(mg.hierarchy().level(l).pCol.size()) +
                  " / " + std::to_string(mg.hierarchy().level(l).A.col.size());
  if (ref) out.diff = relDiff(xm, *ref);
  // A second solve: the coarse operators again, with the prolongation kept (as every later
  // step until the next crack re-binding).
  std::fill(xm.begin(), xm.end(), 0.0);
  mg.solve(s.A, s.b.data(), xm.data(), 200, 1e-6, jobs);
  out.laterGalerkinMs = mg.stats().galerkinMs;
  out.laterMs = mg.stats().totalMs;
  return out;
}

void print(const char* mat, size_t tets, const Setting& set, const Result& m) {
  std::string hs;
  for (int32_t c : m.handles) hs += std::to_string(c) + "/";
  std::printf(
      "[ info ] %s %zu tets, %s%s %d+%d (handles %sall): first cycle %.3f, then %.3f per cycle "
      "(%.1fx) in %.0f ms for %d cycles; MG-CG %d its to %.1e in %.0f ms [refresh %.0f (galerkin "
      "%.0f, factor %.0f), smooth %.0f, coarse %.0f, transfer %.0f]; setup %.0f ms; |x - x_chol| "
      "/ |x_chol| = %.1e%s; next solve %.0f ms (galerkin %.0f); blocks of P / A per level %s\n",
      mat, tets, settingName(set).c_str(), smootherName(set.smoother), set.sweeps, set.sweeps,
      hs.c_str(), m.first, m.factor, 1 / m.factor, m.cyclesMs, m.cycles, m.iterations, m.residual,
      m.cgMs, m.refreshMs, m.galerkinMs, m.factorMs, m.smoothMs, m.coarseMs, m.transferMs,
      m.setupMs, m.diff, m.factorOk ? "" : " COARSE FACTORISATION FAILED", m.laterMs,
      m.laterGalerkinMs, m.blocks.c_str());
  std::fflush(stdout);
}

gf::test::ElasticSystem beam(const MaterialCase& mat, int nh, gf::JobSystem& jobs) {
  return gf::test::assembleElasticSystem(
      gf::gen::box(1.0, 0.2, 0.2, 5 * nh, nh, nh), mat.E, mat.nu, mat.rho, 1.0 / 60.0,
      [](double x, double, double) { return x < 1e-9; }, jobs);
}

class MultigridSlow : public ::testing::TestWithParam<MaterialCase> {};

TEST_P(MultigridSlow, ThirtyThousandTetBeam) {
  const MaterialCase mat = GetParam();
  gf::ThreadPoolJobSystem jobs(2);
  const gf::test::ElasticSystem s = beam(mat, 10, jobs);
  ASSERT_EQ(s.mesh.tetCount(), 30000u);

  gf::detail::PcgSolver pcg;
  std::vector<double> xp(s.b.size(), 0.0);
  auto t0 = std::chrono::steady_clock::now();
  const SolveReport rp = pcg.solve(s.A, s.b.data(), xp.data(), 20000, 1e-6, jobs);
  const double pcgMs =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(rp.converged);
  gf::detail::CholeskySolver chol;
  ASSERT_TRUE(chol.analyze(s.A).ok());
  std::vector<double> xc(s.b.size(), 0.0);
  ASSERT_TRUE(chol.solve(s.A, s.b.data(), xc.data()).converged);
  std::printf(
      "[ info ] %s: %zu tets, %zu nodes, %zu blocks; block-Jacobi PCG %d its to 1e-6 (%.0f ms)\n",
      mat.name, s.mesh.tetCount(), s.mesh.nodeCount(), s.A.col.size(), rp.iterations, pcgMs);
  EXPECT_GE(rp.iterations, 200);

  // Measured on 2 shared cores, 2 threads (steel / rubber), per V-cycle after the first, MG-CG
  // iterations to 1e-6 and the time of a later solve (the prolongation kept, P^T A P of it):
  //   auto (95/all) GS 2+2, the default: 1.7x / 1.5x, 16 / 20 its, 37 / 52 ms (2)
  //   64/all GS 2+2 (the former default): 1.5x / 1.4x, 19 / 22 its, 41 / 51 ms (2)
  //   auto smoothed (28/224/all) GS 2+2: 3.4x / 2.0x, 9 / 12 its, 99 / 110 ms (42)
  //   auto smoothed GS 4+4: 5.4x / 3.1x, 7 / 8 its, 113 / 114 ms (45)
  //   224/all smoothed GS 2+2: 3.8x / 2.1x, 9 / 12 its, 144 / 160 ms (47)
  //   224/all smoothed GS 4+4: 7.0x / 3.4x, 7 / 8 its, 146 / 160 ms (47)
  //   auto smoothed GS 4+4, coarse levels 2+2: 4.8x / 2.9x, 8 / 9 its
  //   auto smoothed GS 4+4, coarse levels 1+1: 3.6x / 2.4x, 9 / 11 its
  //   the same, prolongationFilter 0.1: 2.9x / 2.1x, 10 / 11 its; 0.2: 1.7x / 1.7x, 14 / 16
  // The level-1 operator of the auto smoothed hierarchy holds 6908 12x12 blocks (995k entries,
  // 1.33x the fine matrix's 82911 3x3 blocks); the filter cuts it to 5102 (0.1) and 3458 (0.2).
  // One coarse level converges best, but its exact coarse solve is dear: the coarsest
  // factorisation takes ~120 ms (10 for 28/224/all) and each V-cycle ~3 ms of transfers. In
  // `graphfrac bench multigrid` (1 thread, refresh_interval 30) its solve stage still takes
  // 1.25-1.8x the default's on the Charpy bar and the hanging sphere, 1.05x at 162k tets
  // (issue 14), so it is recorded here, not the default.
  const std::vector<Setting> settings = {
      {{}, Smoother::GaussSeidel, 2, false},        {{64}, Smoother::GaussSeidel, 2, false},
      {{}, Smoother::GaussSeidel, 2, true},         {{}, Smoother::GaussSeidel, 4, true},
      {{224}, Smoother::GaussSeidel, 2, true},      {{224}, Smoother::GaussSeidel, 4, true},
      {{}, Smoother::GaussSeidel, 4, true, 2},      {{}, Smoother::GaussSeidel, 4, true, 1},
      {{}, Smoother::GaussSeidel, 4, true, 1, 0.1}, {{}, Smoother::GaussSeidel, 4, true, 1, 0.2}};
  for (const Setting& set : settings) {
    const Result m = run(s, set, &xc, jobs);
    print(mat.name, s.mesh.tetCount(), set, m);
    EXPECT_LT(m.iterations, 25) << settingName(set);
    EXPECT_LT(m.diff, 1e-4) << settingName(set);
    if (set.smoothed && set.sweeps == 4 && set.coarseSweeps < 0 && set.filter == 0) {
      // Issue 14's figures, reached with the smoothed prolongation: <= 8 MG-CG iterations,
      // and >= 5x per V-cycle on steel (rubber, nu = 0.45, 3.1x).
      EXPECT_LE(m.iterations, 8);
      EXPECT_LE(m.factor, mat.E > 1e10 ? 0.2 : 0.35);
    }
  }

  // Crack re-binding cost at 30k tets: every edge crossing x = 0.51 breaks.
  const gf::detail::EdgeGraph eg =
      gf::detail::EdgeGraph::build(s.mesh.tets.data(), s.mesh.tetCount(), s.mesh.nodeCount());
  std::vector<uint8_t> broken(static_cast<size_t>(eg.edgeCount), 0);
  int32_t brokenCount = 0;
  for (int32_t e = 0; e < eg.edgeCount; ++e) {
    const double xa = s.mesh.positions[3 * eg.edgeNodes[2 * e]];
    const double xb = s.mesh.positions[3 * eg.edgeNodes[2 * e + 1]];
    broken[e] = (xa - 0.51) * (xb - 0.51) < 0;
    brokenCount += broken[e];
  }
  for (const std::vector<int32_t>& levels : std::vector<std::vector<int32_t>>{{}, {64}, {512}}) {
    MultigridSettings ms;
    ms.levels = levels;
    MultigridSolver mg;
    ASSERT_TRUE(mg.setup(ms, s.mesh.positions.data(), s.fixed.data(), s.A).ok());
    mg.rebind(eg.edgeNodes.data(), broken.data(), eg.edgeCount);
    std::vector<double> x(s.b.size(), 0.0);
    const SolveReport r = mg.solve(s.A, s.b.data(), x.data(), 200, 1e-6, jobs);
    std::printf(
        "[ info ] %s %s: setup %.1f ms, rebind after %d broken edges %.1f ms (%d handles), "
        "first solve after it %d its, refresh %.1f ms (galerkin and smoothing %.1f)\n",
        mat.name, levels.empty() ? "auto" : (std::to_string(levels[0]) + "/all").c_str(),
        mg.stats().setupMs, brokenCount, mg.stats().rebindMs, mg.hierarchy().handleCount(1),
        r.iterations, mg.stats().refreshMs, mg.stats().galerkinMs);
  }
}

// The default hierarchy grows with the body: MG-CG iterations to 1e-6 from 30k to 175k tets
// (the same beam, 5n x n x n cells), piecewise-affine (2+2) and smoothed (4+4).
TEST_P(MultigridSlow, DefaultIterationsGrowSlowlyWithSize) {
  const MaterialCase mat = GetParam();
  gf::ThreadPoolJobSystem jobs(2);
  const std::vector<Setting> settings = {{{}, Smoother::GaussSeidel, 2, false},
                                         {{}, Smoother::GaussSeidel, 4, true}};
  std::vector<std::vector<int>> its(settings.size());
  for (int nh : {10, 18}) {
    const gf::test::ElasticSystem s = beam(mat, nh, jobs);
    for (size_t k = 0; k < settings.size(); ++k) {
      const Result m = run(s, settings[k], nullptr, jobs);
      print(mat.name, s.mesh.tetCount(), settings[k], m);
      its[k].push_back(m.iterations);
    }
  }
  for (size_t k = 0; k < settings.size(); ++k)
    std::printf("[ info ] %s %s: MG-CG iterations 30k -> 175k tets: %d -> %d (%.2fx)\n", mat.name,
                settingName(settings[k]).c_str(), its[k][0], its[k][1],
                double(its[k][1]) / its[k][0]);
  // Measured (steel / rubber): piecewise-affine 16 -> 27 / 20 -> 30, smoothed 4+4 7 -> 7 /
  // 8 -> 8. The bound of 1.5x holds for the smoothed prolongation; the
  // piecewise-affine default grows as its extra coarse level weakens it.
  EXPECT_LE(double(its[1][1]), 1.5 * double(its[1][0]));
  EXPECT_LE(double(its[0][1]), 1.8 * double(its[0][0]));
}

INSTANTIATE_TEST_SUITE_P(Materials, MultigridSlow,
                         ::testing::Values(MaterialCase{"steel", 200e9, 0.3, 7800},
                                           MaterialCase{"rubber", 1e6, 0.45, 1100}),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
