// Google Benchmark of single kernels on one fixed mesh (a 1 x 0.25 x 0.25 m box of 40 x 10 x 10
// cells, 24,000 tets, 4,961 nodes): the per-tet element kernel (energy, gradient and projected
// Hessian), the step matrix's assembly from the element matrices, the block-sparse SpMV of the
// step matrix and its 3x3 block-row product, one multigrid V-cycle, and the edge stresses with
// the fracture criterion. items_per_second counts tets (element, edge stresses), blocks
// (assembly), nodes (SpMV) or unknowns (V-cycle), so 1e9 / items_per_second is ns per item.
// BM_Triad measures one core's memory bandwidth (STREAM's triad) and BM_ElementStage, the step's
// element pass, reports the share of that bound it reaches (its counter triad_share: the bytes it
// must move at least, over the triad's rate, against its time). Not a test: ctest only runs it
// once with a tiny minimum time to see that it works.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <ctime>
#include <vector>

#include "common/elastic_system.h"
#include "fem/element_lanes.h"
#include "fem/element_stage.h"
#include "graphfrac/jobs.h"
#include "graphfrac/mesh.h"
#include "kernels/edge_stress.h"
#include "kernels/element.h"
#include "solver/block_row.h"
#include "solver/multigrid.h"

namespace {

constexpr double kE = 1e6, kNu = 0.4, kRho = 1000, kDt = 1.0 / 60;

gf::TetMesh fixedMesh() { return gf::gen::box(1.0, 0.25, 0.25, 40, 10, 10); }

// The deformed state of every benchmark: a 1 % stretch along x with a small bend, so the
// stresses are non-zero and the SVD takes its general path.
gf::Vec3 deform(const double* p) { return {1.01 * p[0], p[1] + 0.01 * std::sin(3 * p[0]), p[2]}; }

// Rest and deformed corners of every tet.
struct TetData {
  std::vector<gf::Vec3> rest, deformed;  // 4 per tet
  size_t tets = 0;
};

TetData tetData(const gf::TetMesh& m) {
  TetData d;
  d.tets = m.tetCount();
  for (size_t e = 0; e < d.tets; ++e)
    for (int a = 0; a < 4; ++a) {
      const double* p = &m.positions[3 * m.tets[4 * e + a]];
      d.rest.push_back({p[0], p[1], p[2]});
      d.deformed.push_back(deform(p));
    }
  return d;
}

void BM_ElementForces(benchmark::State& state) {
  const TetData d = tetData(fixedMesh());
  const gf::MaterialCoeffs c =
      gf::makeMaterialCoeffs(gf::kStableNeoHookean, kE, kNu, 0, gf::Vec3{1, 0, 0});
  std::vector<gf::Mat3> dmInv(d.tets);
  std::vector<double> vol(d.tets);
  for (size_t e = 0; e < d.tets; ++e) dmInv[e] = gf::restShapeInverse(&d.rest[4 * e], vol[e]);
  for (auto _ : state) {
    double energy = 0;
    for (size_t e = 0; e < d.tets; ++e) {
      double grad[12];
      gf::Mat12 H;
      energy += gf::elementForces(c, &d.deformed[4 * e], dmInv[e], vol[e], grad, &H, true);
      benchmark::DoNotOptimize(H);
    }
    benchmark::DoNotOptimize(energy);
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(d.tets));
  state.counters["tets"] = double(d.tets);
}
BENCHMARK(BM_ElementForces)->Unit(benchmark::kMillisecond);

// Bytes per CPU second (one thread, as Google Benchmark's rates) of STREAM's triad a = b + s c
// (24 bytes an element, write-allocate not counted, as STREAM counts) on arrays far larger than
// the caches; 0 until BM_Triad ran.
double g_triadBytesPerSecond = 0;

void BM_Triad(benchmark::State& state) {
  const size_t n = size_t(1) << 23;  // 3 arrays of 64 MB
  std::vector<double> a(n, 0.0), b(n, 1.0), c(n, 2.0);
  const double scale = 3.0;
  const std::clock_t c0 = std::clock();
  for (auto _ : state) {
    for (size_t i = 0; i < n; ++i) a[i] = b[i] + scale * c[i];
    benchmark::DoNotOptimize(a.data());
    benchmark::ClobberMemory();
  }
  const double s = double(std::clock() - c0) / CLOCKS_PER_SEC;
  const double bytes = double(state.iterations()) * 24.0 * double(n);
  if (s > 0) g_triadBytesPerSecond = bytes / s;
  state.SetBytesProcessed(int64_t(bytes));
}
BENCHMARK(BM_Triad)->Unit(benchmark::kMillisecond);

// The step's element pass (fem/element_stage.h, several tets at a time in SIMD lanes where the
// build has them: fem/element_lanes.h) as one core runs it: energy, gradient and PSD
// Hessian of every tet written to the per-tet buffers the assembly reads. Its least traffic a
// tet: the 4 corner indices, Dm^-1 and the rest volume read, energy, gradient and the Hessian's
// upper node blocks (gf::kElementMatrixSize doubles) written, and the node positions once over the
// mesh. state.range(0) = 1: a general state, sheared in every plane and turned by a rigid rotation
// as a moving body is. The stretch and bend of range 0 change only F's (0, 1) columns pair, so
// svd3 there is a 2x2 problem; here it does the Jacobi sweeps of a general F.
void BM_ElementStage(benchmark::State& state) {
  const gf::TetMesh m = fixedMesh();
  const TetData d = tetData(m);
  const size_t tets = d.tets;
  const gf::Vec3 axis = (1.0 / std::sqrt(14.0)) * gf::Vec3{1, 2, 3};
  const double angle = state.range(0) != 0 ? 0.3 : 0.0;
  std::vector<double> x(m.positions.size());
  for (size_t n = 0; n < m.nodeCount(); ++n) {
    const double* r = &m.positions[3 * n];
    gf::Vec3 q = deform(r);
    if (state.range(0) != 0) q += gf::Vec3{0.02 * r[1], 0.015 * r[2], 0.01 * r[0] + 0.02 * r[1]};
    // Rodrigues' rotation of q about axis.
    const gf::Vec3 p = std::cos(angle) * q + std::sin(angle) * gf::cross(axis, q) +
                       (1 - std::cos(angle)) * gf::dot(axis, q) * axis;
    for (int k = 0; k < 3; ++k) x[3 * n + size_t(k)] = p[k];
  }
  std::vector<gf::Mat3> dmInv(tets);
  std::vector<double> vol(tets), energy(tets), grad(12 * tets), hess(gf::kElementMatrixSize * tets);
  for (size_t e = 0; e < tets; ++e) dmInv[e] = gf::restShapeInverse(&d.rest[4 * e], vol[e]);
  gf::detail::ElementStage stage;
  stage.tets = m.tets.data();
  stage.x = x.data();
  stage.restInverse = dmInv.data();
  stage.restVolume = vol.data();
  stage.coeffs = gf::makeMaterialCoeffs(gf::kStableNeoHookean, kE, kNu, 0, gf::Vec3{1, 0, 0});
  stage.energy = energy.data();
  stage.grad = grad.data();
  stage.hess = hess.data();
  const double bytesPerTet = 4 * sizeof(int32_t) + sizeof(gf::Mat3) + 8 + 8 + 12 * 8 +
                             gf::kElementMatrixSize * 8 +
                             24.0 * double(m.nodeCount()) / double(tets);
  const std::clock_t c0 = std::clock();
  for (auto _ : state) {
    gf::detail::evaluateElementRange(stage, 0, int32_t(tets));
    benchmark::DoNotOptimize(hess.data());
    benchmark::ClobberMemory();
  }
  const double s = double(std::clock() - c0) / CLOCKS_PER_SEC;
  const double bytes = double(state.iterations()) * double(tets) * bytesPerTet;
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(tets));
  state.SetBytesProcessed(int64_t(bytes));
  state.counters["bytes_per_tet"] = bytesPerTet;
  state.counters["lanes"] = gf::detail::elementLaneWidth();
  if (g_triadBytesPerSecond > 0 && s > 0)
    state.counters["triad_share"] = bytes / s / g_triadBytesPerSecond;
}
BENCHMARK(BM_ElementStage)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_EdgeStressCriterion(benchmark::State& state) {
  const TetData d = tetData(fixedMesh());
  const gf::MaterialCoeffs c =
      gf::makeMaterialCoeffs(gf::kStableNeoHookean, kE, kNu, 0, gf::Vec3{1, 0, 0});
  std::vector<gf::Mat3> dmInv(d.tets);
  std::vector<gf::Vec3> dirs(6 * d.tets);
  for (size_t e = 0; e < d.tets; ++e) {
    double vol = 0, len[6];
    dmInv[e] = gf::restShapeInverse(&d.rest[4 * e], vol);
    gf::restEdgeDirections(&d.rest[4 * e], &dirs[6 * e], len);
  }
  const double strength = 5e3;  // sigma_th (eq 4.11): some edges of the stretched box reach it
  for (auto _ : state) {
    int reached = 0;
    for (size_t e = 0; e < d.tets; ++e) {
      const gf::Mat3 F = gf::deformationGradient(&d.deformed[4 * e], dmInv[e]);
      double sn[6];
      gf::edgeNormalStresses(gf::materialStress(c, F), &dirs[6 * e], sn);  // eq 4.6-4.8
      for (double s : sn) reached += s >= strength ? 1 : 0;
    }
    benchmark::DoNotOptimize(reached);
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(d.tets));
}
BENCHMARK(BM_EdgeStressCriterion)->Unit(benchmark::kMillisecond);

gf::test::ElasticSystem stepSystem(gf::JobSystem& jobs) {
  return gf::test::assembleElasticSystem(
      fixedMesh(), kE, kNu, kRho, kDt, [](double x, double, double) { return x < 1e-9; }, jobs);
}

void BM_BlockSpMV(benchmark::State& state) {
  gf::SerialJobSystem jobs;
  const gf::test::ElasticSystem s = stepSystem(jobs);
  std::vector<double> x(s.b.size(), 1.0), y(s.b.size());
  for (auto _ : state) {
    s.A.multiply(x.data(), y.data(), jobs);
    benchmark::DoNotOptimize(y.data());
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(s.mesh.nodeCount()));
}
BENCHMARK(BM_BlockSpMV)->Unit(benchmark::kMicrosecond);

// The 3x3 block-row product under the SpMV, the level-0 residual and the Gauss-Seidel sweep
// (solver/block_row.h) over every row of the step matrix: state.range(0) = 0 the scalar formula
// (the device's, and the CPU's without AVX2), 1 the host's choice (AVX2 + FMA where the CPU has
// both). ns_per_block: time over the matrix's blocks.
void BM_BlockRowProduct(benchmark::State& state) {
  gf::SerialJobSystem jobs;
  const gf::test::ElasticSystem s = stepSystem(jobs);
  const gf::detail::BlockMatrixView A = s.A.view();
  std::vector<double> x(s.b.size(), 1.0), y(s.b.size());
  for (auto _ : state) {
    for (int32_t r = 0; r < A.n; ++r) {
      if (state.range(0) == 0)
        gf::detail::blockRowProduct3Scalar(A.col, A.values, A.rowStart[r], A.rowStart[r + 1],
                                           x.data(), y.data() + 3 * r);
      else
        gf::detail::blockRowProduct3(A.col, A.values, A.rowStart[r], A.rowStart[r + 1], x.data(),
                                     y.data() + 3 * r);
    }
    benchmark::DoNotOptimize(y.data());
    benchmark::ClobberMemory();
  }
  state.counters["ns_per_block"] =
      benchmark::Counter(double(state.iterations()) * double(A.rowStart[A.n]),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_BlockRowProduct)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// The step matrix's assembly from the element matrices (gatherElementBlocks: every block sums
// the element blocks of the tets that share its node pair, a lower block read transposed) as
// one core runs it, replacing the old values as a step's first assembly does, on element
// matrices of arbitrary values: items are blocks, so 1e9 / items_per_second is ns per block;
// entries_per_block counts the element blocks read.
void BM_ElementAssembly(benchmark::State& state) {
  gf::SerialJobSystem jobs;
  const gf::TetMesh m = fixedMesh();
  gf::detail::BlockSparseMatrix A =
      gf::detail::BlockSparseMatrix::fromTets(m.tets.data(), m.tetCount(), m.nodeCount());
  const gf::detail::ElementGather gather =
      gf::detail::ElementGather::build(m.tets.data(), m.tetCount(), A);
  std::vector<double> hess(gf::kElementMatrixSize * m.tetCount());
  for (size_t i = 0; i < hess.size(); ++i) hess[i] = 1.0 + double(i % 97) / 97;
  for (auto _ : state) {
    gf::detail::gatherElementBlocks(gather, hess.data(), 1e-4, A, jobs, {.accumulate = false});
    benchmark::DoNotOptimize(A.values.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(A.blockCount()));
  state.counters["entries_per_block"] = double(gather.start.back()) / double(A.blockCount());
}
BENCHMARK(BM_ElementAssembly)->Unit(benchmark::kMicrosecond);

// One V-cycle alone (no CG) on the step matrix, from x = 0. The hierarchy is built by a first
// solve outside the timed loop; with the default coarse refresh interval (1) every timed solve
// also recomputes the Galerkin coarse operators, as a game step's solve does, so this is the
// cost of one solve of one cycle, refresh included.
void BM_MultigridVCycle(benchmark::State& state) {
  gf::SerialJobSystem jobs;
  const gf::test::ElasticSystem s = stepSystem(jobs);
  gf::MultigridSettings settings;
  settings.preconditionCG = false;
  settings.cycles = 1;
  settings.directBelowNodes = 0;
  gf::detail::MultigridSolver mg;
  if (!mg.setup(settings, s.mesh.positions.data(), s.fixed.data(), s.A).ok()) {
    state.SkipWithError("multigrid setup failed");
    return;
  }
  std::vector<double> x(s.b.size(), 0.0);
  (void)mg.solve(s.A, s.b.data(), x.data(), 1, 0, jobs);
  for (auto _ : state) {
    std::fill(x.begin(), x.end(), 0.0);
    const gf::detail::SolveReport r = mg.solve(s.A, s.b.data(), x.data(), 1, 0, jobs);
    benchmark::DoNotOptimize(r);
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(s.b.size()));
}
BENCHMARK(BM_MultigridVCycle)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
