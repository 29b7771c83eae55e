// The dense Cholesky stages (solver/dense_cholesky.h) that factorise and solve the multigrid's
// coarsest level where its cycle runs, on the CPU executor and on the device executor
// (gpu/dense_cholesky.cu), against
// the sparse factorisation the host uses today (solver/cholesky.h, CHOLMOD or Eigen) and
// against the system itself (the true residual, computed here). Matrices of 12x12 blocks like a
// coarsest level: banded with random long links (diagonally dominant, so SPD), a chain
// Laplacian (singular: needs the host's diagonal-shift retry) and an indefinite one (must be
// refused). Built twice like test_element_backend.cpp: host build (label `backend`, CI) and the
// CUDA build (labels `backend` and `gpu`; skipped, and reported as skipped, without a device).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "gpu/dense_cholesky.h"
#include "gpu/device.h"
#include "graphfrac/jobs.h"
#include "solver/cholesky.h"
#include "solver/dense_cholesky.h"
#include "step/executor.h"

namespace gf {
namespace {

enum class Kind { kDominant, kChainLaplacian, kIndefinite };

struct DenseCase {
  const char* name;
  int32_t rows;  // 12x12 block rows (coarsest handles)
  Kind kind;
  unsigned seed;
};

std::string caseName(const testing::TestParamInfo<DenseCase>& info) { return info.param.name; }

// A symmetric block CSR matrix (columns ascending in each row).
struct BlockMatrix {
  int32_t rows = 0;
  std::vector<int32_t> rowStart, col;
  std::vector<double> values;  // 144 per block, row-major
  int32_t n() const { return 12 * rows; }
  double at(int32_t i, int32_t j) const {
    const int32_t r = i / 12, c = j / 12;
    for (int32_t k = rowStart[r]; k < rowStart[r + 1]; ++k)
      if (col[k] == c) return values[144 * size_t(k) + 12 * (i % 12) + j % 12];
    return 0;
  }
};

BlockMatrix makeMatrix(const DenseCase& c) {
  const int32_t R = c.rows;
  std::mt19937 rng(c.seed);
  std::uniform_real_distribution<double> u(-1, 1);
  // Block pattern: the band |r - s| <= 2 and, for the dominant kind, a few random long links.
  std::vector<std::vector<int32_t>> links(size_t(R), std::vector<int32_t>{});
  auto link = [&](int32_t r, int32_t s) {
    if (std::find(links[r].begin(), links[r].end(), s) != links[r].end()) return;
    links[r].push_back(s);
    if (r != s) links[s].push_back(r);
  };
  for (int32_t r = 0; r < R; ++r) {
    link(r, r);
    for (int32_t d = 1; d <= (c.kind == Kind::kChainLaplacian ? 1 : 2) && r + d < R; ++d)
      link(r, r + d);
  }
  if (c.kind == Kind::kDominant)
    for (int32_t t = 0; t < R / 4; ++t) link(int32_t(rng() % R), int32_t(rng() % R));
  BlockMatrix m;
  m.rows = R;
  m.rowStart.assign(1, 0);
  for (int32_t r = 0; r < R; ++r) {
    std::sort(links[r].begin(), links[r].end());
    for (int32_t s : links[r]) m.col.push_back(s);
    m.rowStart.push_back(int32_t(m.col.size()));
  }
  m.values.assign(144 * m.col.size(), 0.0);
  auto block = [&](int32_t r, int32_t s) -> double* {
    for (int32_t k = m.rowStart[r]; k < m.rowStart[r + 1]; ++k)
      if (m.col[k] == s) return &m.values[144 * size_t(k)];
    return nullptr;
  };
  // Off-diagonal blocks and their transposes; the diagonal collects what makes each row's
  // scalar sum positive (dominance) or zero (Laplacian: the 12 constant vectors are its null
  // space).
  std::vector<double> rowAbs(size_t(12 * R), 0.0);
  for (int32_t r = 0; r < R; ++r)
    for (int32_t s : links[r]) {
      if (s <= r) continue;
      double* a = block(r, s);
      double* b = block(s, r);
      for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j) {
          const double v = c.kind == Kind::kChainLaplacian ? (i == j ? -1.0 : 0.0) : u(rng);
          a[12 * i + j] = b[12 * j + i] = v;
          rowAbs[12 * r + i] += std::fabs(v);
          rowAbs[12 * s + j] += std::fabs(v);
        }
    }
  for (int32_t r = 0; r < R; ++r) {
    double* d = block(r, r);
    for (int i = 0; i < 12; ++i)
      for (int j = 0; j <= i; ++j) {
        const double v = c.kind == Kind::kChainLaplacian ? 0.0 : 0.1 * u(rng);
        d[12 * i + j] = d[12 * j + i] = v;
      }
    for (int i = 0; i < 12; ++i) {
      double off = rowAbs[12 * r + i];
      for (int j = 0; j < 12; ++j)
        if (j != i) off += std::fabs(d[12 * i + j]);
      d[13 * i] =
          c.kind == Kind::kChainLaplacian ? rowAbs[12 * r + i] : off + 0.5 + std::fabs(u(rng));
    }
  }
  if (c.kind == Kind::kIndefinite)
    for (double& v : m.values) v = -v;
  return m;
}

std::vector<double> multiply(const BlockMatrix& m, const std::vector<double>& x) {
  std::vector<double> y(size_t(m.n()), 0.0);
  for (int32_t r = 0; r < m.rows; ++r)
    for (int32_t k = m.rowStart[r]; k < m.rowStart[r + 1]; ++k)
      for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j)
          y[12 * r + i] += m.values[144 * size_t(k) + 12 * i + j] * x[12 * size_t(m.col[k]) + j];
  return y;
}

double relativeResidual(const BlockMatrix& m, const std::vector<double>& x,
                        const std::vector<double>& b) {
  const std::vector<double> ax = multiply(m, x);
  double rr = 0, bb = 0;
  for (size_t i = 0; i < b.size(); ++i) {
    rr += (b[i] - ax[i]) * (b[i] - ax[i]);
    bb += b[i] * b[i];
  }
  return std::sqrt(rr / bb);
}

double relativeDifference(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0, s = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    d = std::max(d, std::fabs(a[i] - b[i]));
    s = std::max(s, std::fabs(b[i]));
  }
  return d / s;
}

class DenseCholeskyBackend : public testing::TestWithParam<DenseCase> {};

TEST_P(DenseCholeskyBackend, FactorsAndSolvesLikeTheSparseHostFactor) {
  std::string why;
  if (!gpu::deviceAvailable(why)) GTEST_SKIP() << why;
  const DenseCase& c = GetParam();
  const BlockMatrix m = makeMatrix(c);
  const int32_t n = m.n();
  ASSERT_LE(n, detail::kDenseCholeskyMaxSize);
  std::mt19937 rng(c.seed + 1);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> b(static_cast<size_t>(n));
  for (double& v : b) v = u(rng);
  if (c.kind == Kind::kChainLaplacian)  // b orthogonal to the null space: a solution exists
    for (int j = 0; j < 12; ++j) {
      double mean = 0;
      for (int32_t r = 0; r < c.rows; ++r) mean += b[12 * size_t(r) + j] / c.rows;
      for (int32_t r = 0; r < c.rows; ++r) b[12 * size_t(r) + j] -= mean;
    }

  // CPU executor, host memory.
  ThreadPoolJobSystem jobs(2);
  std::vector<double> dense(size_t(n) * n), xCpu(size_t(n), 0.0);
  const bool cpuOk =
      detail::denseCholeskyFactorBlocks(detail::CpuExecutor(jobs), m.rows, m.rowStart.data(),
                                        m.col.data(), m.values.data(), dense.data());
  if (cpuOk)
    detail::denseCholeskySolve(detail::CpuExecutor(jobs), n, dense.data(), b.data(), xCpu.data());

  // Device executor, device memory.
  gpu::DeviceBuffer<int32_t> dRowStart, dCol;
  gpu::DeviceBuffer<double> dValues, dDense, dB, dX;
  ASSERT_TRUE(dRowStart.upload(m.rowStart.data(), m.rowStart.size()) &&
              dCol.upload(m.col.data(), m.col.size()) &&
              dValues.upload(m.values.data(), m.values.size()) && dDense.resize(dense.size()) &&
              dB.upload(b.data(), b.size()) && dX.resize(b.size()));
  const bool devOk =
      gpu::factorDenseBlocks(m.rows, dRowStart.data(), dCol.data(), dValues.data(), dDense.data());
  std::vector<double> xDev(size_t(n), 0.0);
  if (devOk) {
    gpu::solveDense(n, dDense.data(), dB.data(), dX.data());
    ASSERT_TRUE(gpu::synchronize() && dX.download(xDev.data(), xDev.size()));
  }

  if (c.kind == Kind::kIndefinite) {
    EXPECT_FALSE(cpuOk);
    EXPECT_FALSE(devOk);
    return;
  }
  ASSERT_TRUE(cpuOk);
  ASSERT_TRUE(devOk);
  if (c.kind == Kind::kChainLaplacian) {  // the shift retry is what made it succeed
    std::vector<double> unshifted(dense.size(), 0.0);
    const detail::CpuExecutor cpu(jobs);
    cpu.run(m.rows, 1,
            detail::DenseFromBlocksStage{m.rowStart.data(), m.col.data(), m.values.data(), n, 0.0,
                                         unshifted.data()});
    EXPECT_FALSE(detail::denseCholeskyFactor(cpu, n, unshifted.data()));
  }
  // A singular Laplacian is solved through the shift: residual of the shifted size.
  EXPECT_LT(relativeResidual(m, xCpu, b), c.kind == Kind::kChainLaplacian ? 1e-8 : 1e-13);
#if defined(GF_GPU_CUDA)
  EXPECT_LT(relativeDifference(xDev, xCpu), 1e-10);  // a device contracts multiply-adds
#else
  EXPECT_EQ(xDev, xCpu);  // one source, one order of operations
#endif

  if (c.kind != Kind::kDominant) return;
  // The sparse host factorisation of the same matrix (its lower triangle, column-compressed).
  std::vector<int32_t> colStart(1, 0), row;
  std::vector<double> value;
  for (int32_t j = 0; j < n; ++j) {
    for (int32_t i = j; i < n; ++i)
      if (const double v = m.at(i, j); v != 0) {
        row.push_back(i);
        value.push_back(v);
      }
    colStart.push_back(int32_t(row.size()));
  }
  detail::CholeskySolver sparse;
  ASSERT_TRUE(sparse.factorize(detail::SymmetricCsc{n, colStart.data(), row.data(), value.data()}));
  std::vector<double> xRef(static_cast<size_t>(n));
  ASSERT_TRUE(sparse.solveFactored(b.data(), xRef.data()));
  EXPECT_LT(relativeDifference(xCpu, xRef), 1e-12);
}

const DenseCase kCases[] = {{"OneHandle", 1, Kind::kDominant, 3},
                            {"TwentyHandles", 20, Kind::kDominant, 5},
                            {"SixtyFourHandles", 64, Kind::kDominant, 7},
                            {"SingularChain", 16, Kind::kChainLaplacian, 11},
                            {"Indefinite", 10, Kind::kIndefinite, 13}};

// The host build (gf_backend_tests) and the CUDA build (gf_gpu_tests) name their cases apart.
#if defined(GF_GPU_CUDA)
INSTANTIATE_TEST_SUITE_P(Device, DenseCholeskyBackend, testing::ValuesIn(kCases), caseName);
#else
INSTANTIATE_TEST_SUITE_P(HostBuild, DenseCholeskyBackend, testing::ValuesIn(kCases), caseName);
#endif

}  // namespace
}  // namespace gf
