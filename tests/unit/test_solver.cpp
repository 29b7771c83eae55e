// Block-sparse linear algebra of the implicit step, checked against dense Eigen references:
// pattern, gather assembly, SpMV, PCG and Cholesky solves, Dirichlet rows, failure reporting,
// and identical bits for 1 and 4 threads.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "graphfrac/jobs.h"
#include "solver/block_sparse.h"
#include "solver/cholesky.h"
#include "solver/pcg.h"
#include "step/executor.h"

namespace {

using gf::detail::BlockSparseMatrix;
using gf::detail::CholeskySolver;
using gf::detail::ElementGather;
using gf::detail::PcgSolver;
using gf::detail::SolveReport;

// A structured grid of nx*ny*nz unit cubes, each split into 6 tets around its main diagonal
// (Freudenthal split: one tet per ordering of the three axes), so neighbouring cubes conform.
struct Grid {
  std::vector<int32_t> tets;
  std::vector<double> positions;  // 3 per node
  size_t nodes = 0;
  size_t tetCount() const { return tets.size() / 4; }
};

Grid makeGrid(int nx, int ny, int nz) {
  Grid g;
  auto id = [&](int i, int j, int k) {
    return static_cast<int32_t>(i + (nx + 1) * (j + (ny + 1) * k));
  };
  g.nodes = static_cast<size_t>((nx + 1) * (ny + 1) * (nz + 1));
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i)
        g.positions.insert(g.positions.end(), {double(i), double(j), double(k)});
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (const auto& p : perms) {
          int c[3] = {i, j, k};
          g.tets.push_back(id(c[0], c[1], c[2]));
          for (int s = 0; s < 3; ++s) {
            ++c[p[s]];
            g.tets.push_back(id(c[0], c[1], c[2]));
          }
        }
  return g;
}

// Random symmetric positive semi-definite 12x12 element matrices G^T G, scaled per element by
// 10^u with u uniform in [-spread, spread] (spread > 0 makes the sum ill-conditioned).
std::vector<double> randomElementMatrices(size_t tetCount, uint64_t seed, double spread = 0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> out(144 * tetCount);
  for (size_t e = 0; e < tetCount; ++e) {
    Eigen::Matrix<double, 12, 12> g;
    for (int i = 0; i < 144; ++i) g.data()[i] = u(rng);
    const double scale = std::pow(10.0, spread * u(rng));
    Eigen::Matrix<double, 12, 12, Eigen::RowMajor> k = scale * (g.transpose() * g) / 12.0;
    std::memcpy(out.data() + 144 * e, k.data(), 144 * sizeof(double));
  }
  return out;
}

// Full row-major element matrices (144 per tet) as the gather reads them: upper node blocks.
std::vector<double> upperBlocks(const std::vector<double>& full) {
  std::vector<double> out(full.size() / 144 * gf::kElementMatrixSize);
  for (size_t e = 0; e < full.size() / 144; ++e)
    gf::storeUpperBlocks(&full[144 * e], &out[gf::kElementMatrixSize * e]);
  return out;
}

// Linear elastic tet stiffness: K_ab,ij = V (lambda g_a,i g_b,j + mu g_a,j g_b,i + mu d_ij g_a.g_b)
// with g_a the gradients of the barycentric shape functions.
std::vector<double> elasticElementMatrices(const Grid& g, double lambda, double mu) {
  std::vector<double> out(144 * g.tetCount());
  for (size_t e = 0; e < g.tetCount(); ++e) {
    Eigen::Vector3d x[4];
    for (int a = 0; a < 4; ++a) x[a] = Eigen::Vector3d::Map(&g.positions[3 * g.tets[4 * e + a]]);
    Eigen::Matrix3d dm;
    dm << x[1] - x[0], x[2] - x[0], x[3] - x[0];
    const double vol = std::fabs(dm.determinant()) / 6;
    const Eigen::Matrix3d inv = dm.inverse();
    Eigen::Vector3d grad[4];
    for (int a = 1; a < 4; ++a) grad[a] = inv.row(a - 1).transpose();
    grad[0] = -(grad[1] + grad[2] + grad[3]);
    double* k = out.data() + 144 * e;
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            k[(3 * a + i) * 12 + 3 * b + j] =
                vol * (lambda * grad[a][i] * grad[b][j] + mu * grad[a][j] * grad[b][i] +
                       (i == j ? mu * grad[a].dot(grad[b]) : 0.0));
  }
  return out;
}

// Naive scatter of element matrices into a dense matrix (the independent reference).
Eigen::MatrixXd denseScatter(const Grid& g, const std::vector<double>& ke) {
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(3 * g.nodes, 3 * g.nodes);
  for (size_t e = 0; e < g.tetCount(); ++e)
    for (int a = 0; a < 12; ++a)
      for (int b = 0; b < 12; ++b)
        d(3 * g.tets[4 * e + a / 3] + a % 3, 3 * g.tets[4 * e + b / 3] + b % 3) +=
            ke[144 * e + 12 * a + b];
  return d;
}

Eigen::MatrixXd toDense(const BlockSparseMatrix& A) {
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(3 * A.n, 3 * A.n);
  for (int32_t r = 0; r < A.n; ++r)
    for (int32_t k = A.rowStart[r]; k < A.rowStart[r + 1]; ++k)
      for (int i = 0; i < 9; ++i) d(3 * r + i / 3, 3 * A.col[k] + i % 3) = A.block(k)[i];
  return d;
}

// Adds s to every diagonal scalar (a lumped-mass-like shift that makes the sum definite).
void shiftDiagonal(BlockSparseMatrix& A, double s) {
  for (int32_t r = 0; r < A.n; ++r) {
    double* m = A.block(A.diagonal(r));
    m[0] += s, m[4] += s, m[8] += s;
  }
}

struct System {
  Grid grid;
  BlockSparseMatrix A;
  ElementGather gather;
  std::vector<double> ke;
};

System randomSystem(int nx, int ny, int nz, uint64_t seed, double spread, double shift,
                    gf::JobSystem& jobs) {
  System s;
  s.grid = makeGrid(nx, ny, nz);
  s.A = BlockSparseMatrix::fromTets(s.grid.tets.data(), s.grid.tetCount(), s.grid.nodes);
  s.gather = ElementGather::build(s.grid.tets.data(), s.grid.tetCount(), s.A);
  s.ke = randomElementMatrices(s.grid.tetCount(), seed, spread);
  gf::detail::gatherElementBlocks(s.gather, upperBlocks(s.ke).data(), 1.0, s.A, jobs);
  shiftDiagonal(s.A, shift);
  return s;
}

std::vector<double> randomVector(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> v(n);
  for (double& x : v) x = u(rng);
  return v;
}

double relError(const std::vector<double>& x, const Eigen::VectorXd& ref) {
  return (Eigen::VectorXd::Map(x.data(), ref.size()) - ref).norm() / ref.norm();
}

bool allFinite(const std::vector<double>& v) {
  for (double x : v)
    if (!std::isfinite(x)) return false;
  return true;
}

TEST(BlockSparse, PatternIsEveryTetPairPlusDiagonal) {
  Grid g = makeGrid(3, 2, 2);
  BlockSparseMatrix A = BlockSparseMatrix::fromTets(g.tets.data(), g.tetCount(), g.nodes);
  std::set<std::pair<int, int>> pairs;
  for (size_t n = 0; n < g.nodes; ++n) pairs.insert({int(n), int(n)});
  for (size_t e = 0; e < g.tetCount(); ++e)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) pairs.insert({g.tets[4 * e + a], g.tets[4 * e + b]});
  ASSERT_EQ(A.n, int(g.nodes));
  ASSERT_EQ(size_t(A.blockCount()), pairs.size());
  EXPECT_EQ(A.values.size(), 9 * pairs.size());
  for (int32_t r = 0; r < A.n; ++r) {
    for (int32_t k = A.rowStart[r]; k < A.rowStart[r + 1]; ++k) {
      EXPECT_TRUE(pairs.count({r, A.col[k]})) << r << "," << A.col[k];
      if (k > A.rowStart[r]) {
        EXPECT_LT(A.col[k - 1], A.col[k]);
      }
      EXPECT_EQ(A.find(r, A.col[k]), k);
      EXPECT_GE(A.find(A.col[k], r), 0);  // symmetric
    }
    EXPECT_GE(A.diagonal(r), 0);
  }
  // Nodes 0 and the far corner share no tet.
  EXPECT_EQ(A.find(0, A.n - 1), -1);
  EXPECT_EQ(A.find(-1, 0), -1);
  EXPECT_EQ(A.find(A.n, 0), -1);
  // An isolated node still gets its diagonal; an out-of-range tet node is skipped, not written.
  const int32_t bad[8] = {0, 1, 2, 3, 0, 1, 2, 99};
  BlockSparseMatrix B = BlockSparseMatrix::fromTets(bad, 2, 5);
  EXPECT_EQ(B.blockCount(), 16 + 1);
  EXPECT_GE(B.diagonal(4), 0);
  EXPECT_EQ(B.find(4, 0), -1);
}

TEST(BlockSparse, GatherMatchesNaiveScatterAndSpmvMatchesDense) {
  gf::SerialJobSystem jobs;
  System s = randomSystem(4, 3, 3, 7, 0.0, 0.0, jobs);
  const Eigen::MatrixXd ref = denseScatter(s.grid, s.ke);
  const Eigen::MatrixXd got = toDense(s.A);
  EXPECT_LE((got - ref).cwiseAbs().maxCoeff(), 1e-13 * ref.cwiseAbs().maxCoeff());
  // Every block the scatter touches is in the pattern (toDense would miss it otherwise).
  for (Eigen::Index i = 0; i < ref.rows(); ++i)
    for (Eigen::Index j = 0; j < ref.cols(); ++j)
      if (ref(i, j) != 0) {
        ASSERT_GE(s.A.find(int32_t(i / 3), int32_t(j / 3)), 0);
      }
  for (size_t e = 0; e < s.grid.tetCount(); ++e)
    for (int ab = 0; ab < 16; ++ab)
      ASSERT_EQ(s.gather.elementBlockIndex[16 * e + ab],
                s.A.find(s.grid.tets[4 * e + ab / 4], s.grid.tets[4 * e + ab % 4]));

  // Gather adds with a scale: A += 2 K gives 3 K.
  gf::detail::gatherElementBlocks(s.gather, upperBlocks(s.ke).data(), 2.0, s.A, jobs);
  EXPECT_LE((toDense(s.A) - 3 * ref).cwiseAbs().maxCoeff(), 1e-12 * ref.cwiseAbs().maxCoeff());

  const std::vector<double> x = randomVector(3 * s.grid.nodes, 11);
  std::vector<double> y(x.size());
  s.A.multiply(x.data(), y.data(), jobs);
  const Eigen::VectorXd yRef = 3 * ref * Eigen::VectorXd::Map(x.data(), x.size());
  EXPECT_LE(relError(y, yRef), 1e-14);

  s.A.setZero(jobs);
  for (double v : s.A.values) ASSERT_EQ(v, 0.0);
}

TEST(BlockSparse, IdenticalBitsForOneAndFourThreads) {
  gf::ThreadPoolJobSystem one(1), four(4);
  System s1 = randomSystem(12, 11, 10, 3, 1.0, 0.1, one);
  System s4 = randomSystem(12, 11, 10, 3, 1.0, 0.1, four);
  ASSERT_GT(s1.A.n, 1000);
  ASSERT_EQ(s1.A.values.size(), s4.A.values.size());
  EXPECT_EQ(std::memcmp(s1.A.values.data(), s4.A.values.data(), 8 * s1.A.values.size()), 0);

  const std::vector<double> x = randomVector(3 * s1.grid.nodes, 5);
  std::vector<double> y1(x.size()), y4(x.size());
  s1.A.multiply(x.data(), y1.data(), one);
  s1.A.multiply(x.data(), y4.data(), four);
  EXPECT_EQ(std::memcmp(y1.data(), y4.data(), 8 * y1.size()), 0);

  // Dot over many chunks: same bits, and equal to a long-double reference to rounding.
  const std::vector<double> a = randomVector(1000003, 1), b = randomVector(1000003, 2);
  std::vector<double> p1, p4;
  const double d1 = gf::detail::CpuExecutor(one, &p1).dot(a.data(), b.data(), int32_t(a.size()));
  const double d4 = gf::detail::CpuExecutor(four, &p4).dot(a.data(), b.data(), int32_t(a.size()));
  EXPECT_EQ(std::memcmp(&d1, &d4, 8), 0);
  long double ref = 0;
  for (size_t i = 0; i < a.size(); ++i) ref += static_cast<long double>(a[i]) * b[i];
  EXPECT_NEAR(d1, double(ref), 1e-11 * std::sqrt(double(a.size())));

  PcgSolver pcg1, pcg4;
  std::vector<double> x1(x.size(), 0.0), x4(x.size(), 0.0);
  SolveReport r1 = pcg1.solve(s1.A, y1.data(), x1.data(), 500, 1e-10, one);
  SolveReport r4 = pcg4.solve(s1.A, y1.data(), x4.data(), 500, 1e-10, four);
  EXPECT_TRUE(r1.converged);
  EXPECT_GT(r1.iterations, 5);
  EXPECT_EQ(r1.iterations, r4.iterations);
  EXPECT_EQ(std::memcmp(&r1.relativeResidual, &r4.relativeResidual, 8), 0);
  EXPECT_EQ(std::memcmp(x1.data(), x4.data(), 8 * x1.size()), 0);
  EXPECT_LE(relError(x1, Eigen::VectorXd::Map(x.data(), x.size())), 1e-8);
}

TEST(Solvers, PcgAndCholeskyMatchDenseLlt) {
  gf::ThreadPoolJobSystem jobs(2);
  System s = randomSystem(5, 4, 3, 21, 0.5, 0.05, jobs);
  const Eigen::MatrixXd dense = toDense(s.A);
  const std::vector<double> b = randomVector(3 * s.grid.nodes, 22);
  const Eigen::VectorXd bm = Eigen::VectorXd::Map(b.data(), b.size());
  Eigen::LLT<Eigen::MatrixXd> llt(dense);
  ASSERT_EQ(llt.info(), Eigen::Success);
  const Eigen::VectorXd ref = llt.solve(bm);

  PcgSolver pcg;
  std::vector<double> x(b.size(), 0.0);
  SolveReport r = pcg.solve(s.A, b.data(), x.data(), 2000, 1e-12, jobs);
  EXPECT_TRUE(r.converged);
  EXPECT_LE(r.relativeResidual, 1e-12);
  EXPECT_LE(relError(x, ref), 1e-8);
  // The reported residual is the true one.
  const double trueRes = (bm - dense * Eigen::VectorXd::Map(x.data(), x.size())).norm() / bm.norm();
  EXPECT_NEAR(r.relativeResidual, trueRes, 1e-3 * trueRes + 1e-16);

  // Warm start from the solution: nothing to do.
  SolveReport again = pcg.solve(s.A, b.data(), x.data(), 2000, 1e-10, jobs);
  EXPECT_TRUE(again.converged);
  EXPECT_EQ(again.iterations, 0);

  CholeskySolver chol;
  ASSERT_TRUE(chol.analyze(s.A).ok());
  std::vector<double> xc(b.size(), 0.0);
  SolveReport rc = chol.solve(s.A, b.data(), xc.data());
  EXPECT_TRUE(rc.converged);
  EXPECT_EQ(rc.iterations, 0);
  EXPECT_LE(rc.relativeResidual, 1e-12);
  EXPECT_LE(relError(xc, ref), 1e-8);

  // Same pattern, new values: refactorise without a new analysis.
  for (double& v : s.A.values) v *= 2;
  SolveReport rc2 = chol.solve(s.A, b.data(), xc.data());
  EXPECT_TRUE(rc2.converged);
  EXPECT_LE(relError(xc, ref / 2), 1e-8);
}

TEST(Solvers, ZeroRightHandSideGivesZero) {
  gf::SerialJobSystem jobs;
  System s = randomSystem(2, 2, 2, 4, 0.0, 1.0, jobs);
  std::vector<double> b(3 * s.grid.nodes, 0.0), x(b.size(), 3.0);
  PcgSolver pcg;
  SolveReport r = pcg.solve(s.A, b.data(), x.data(), 10, 1e-8, jobs);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(r.relativeResidual, 0.0);
  for (double v : x) ASSERT_EQ(v, 0.0);
}

TEST(Solvers, IllConditionedIterationsAreCappedAndReported) {
  gf::SerialJobSystem jobs;
  // A slender elastic bar clamped at x = 0 whose element stiffnesses vary over 8 decades
  // (a badly heterogeneous material): condition number about 6e6, hundreds of PCG iterations.
  System s;
  s.grid = makeGrid(16, 3, 3);
  s.A = BlockSparseMatrix::fromTets(s.grid.tets.data(), s.grid.tetCount(), s.grid.nodes);
  s.gather = ElementGather::build(s.grid.tets.data(), s.grid.tetCount(), s.A);
  s.ke = elasticElementMatrices(s.grid, 2.0, 1.0);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-4, 4);
  for (size_t e = 0; e < s.grid.tetCount(); ++e) {
    const double scale = std::pow(10.0, u(rng));
    for (int i = 0; i < 144; ++i) s.ke[144 * e + i] *= scale;
  }
  gf::detail::gatherElementBlocks(s.gather, upperBlocks(s.ke).data(), 1.0, s.A, jobs);
  std::vector<uint8_t> fixed(s.grid.nodes);
  for (size_t n = 0; n < s.grid.nodes; ++n) fixed[n] = s.grid.positions[3 * n] == 0.0;
  gf::detail::applyDirichlet(s.A, fixed.data());
  const Eigen::MatrixXd dense = toDense(s.A);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(dense, Eigen::EigenvaluesOnly);
  const double cond = eig.eigenvalues().maxCoeff() / eig.eigenvalues().minCoeff();
  EXPECT_GT(cond, 1e6);
  std::vector<double> bv = randomVector(3 * s.grid.nodes, 10);
  for (size_t n = 0; n < s.grid.nodes; ++n)
    if (fixed[n]) bv[3 * n] = bv[3 * n + 1] = bv[3 * n + 2] = 0;
  const std::vector<double>& b = bv;
  const Eigen::VectorXd bm = Eigen::VectorXd::Map(b.data(), b.size());

  PcgSolver pcg;
  std::vector<double> x(b.size(), 0.0);
  SolveReport capped = pcg.solve(s.A, b.data(), x.data(), 10, 1e-10, jobs);
  EXPECT_FALSE(capped.converged);
  EXPECT_EQ(capped.iterations, 10);
  EXPECT_TRUE(allFinite(x));
  const double trueRes = (bm - dense * Eigen::VectorXd::Map(x.data(), x.size())).norm() / bm.norm();
  EXPECT_GT(capped.relativeResidual, 1e-10);
  EXPECT_NEAR(capped.relativeResidual, trueRes, 1e-9 * trueRes);

  std::fill(x.begin(), x.end(), 0.0);
  SolveReport full = pcg.solve(s.A, b.data(), x.data(), 20000, 1e-10, jobs);
  EXPECT_TRUE(full.converged);
  EXPECT_GT(full.iterations, 100);
  EXPECT_LT(full.iterations, 20000);
  std::printf("[ info ] ill-conditioned (cond %.2e, %zu dofs): PCG %d iterations to 1e-10\n", cond,
              b.size(), full.iterations);
  const Eigen::VectorXd ref = dense.llt().solve(bm);
  // Forward error is bounded by cond * residual.
  EXPECT_LE(relError(x, ref), cond * 1e-10 * 10);
}

TEST(Solvers, DirichletMatchesReducedDenseSolve) {
  gf::ThreadPoolJobSystem jobs(2);
  // Elastic stiffness with no mass: singular (rigid modes) until the x = 0 face is fixed.
  Grid g = makeGrid(5, 3, 3);
  BlockSparseMatrix A = BlockSparseMatrix::fromTets(g.tets.data(), g.tetCount(), g.nodes);
  ElementGather gather = ElementGather::build(g.tets.data(), g.tetCount(), A);
  const std::vector<double> ke = elasticElementMatrices(g, 2.0, 1.0);
  gf::detail::gatherElementBlocks(gather, upperBlocks(ke).data(), 1.0, A, jobs);
  const Eigen::MatrixXd full = toDense(A);

  std::vector<uint8_t> fixed(g.nodes, 0);
  std::vector<int> freeDofs;
  for (size_t n = 0; n < g.nodes; ++n) {
    fixed[n] = g.positions[3 * n] == 0.0;
    if (!fixed[n])
      for (int i = 0; i < 3; ++i) freeDofs.push_back(int(3 * n + i));
  }
  gf::detail::applyDirichlet(A, fixed.data());
  std::vector<double> b = randomVector(3 * g.nodes, 31);
  for (size_t n = 0; n < g.nodes; ++n)
    if (fixed[n]) b[3 * n] = b[3 * n + 1] = b[3 * n + 2] = 0;

  // Reduced reference: delete the fixed rows and columns of the unconstrained matrix.
  const int m = int(freeDofs.size());
  Eigen::MatrixXd red(m, m);
  Eigen::VectorXd bred(m);
  for (int i = 0; i < m; ++i) {
    bred[i] = b[freeDofs[i]];
    for (int j = 0; j < m; ++j) red(i, j) = full(freeDofs[i], freeDofs[j]);
  }
  Eigen::LLT<Eigen::MatrixXd> llt(red);
  ASSERT_EQ(llt.info(), Eigen::Success);
  const Eigen::VectorXd xred = llt.solve(bred);
  Eigen::VectorXd ref = Eigen::VectorXd::Zero(3 * g.nodes);
  for (int i = 0; i < m; ++i) ref[freeDofs[i]] = xred[i];

  // The constrained matrix stays symmetric.
  const Eigen::MatrixXd constrained = toDense(A);
  EXPECT_EQ((constrained - constrained.transpose()).cwiseAbs().maxCoeff(), 0.0);

  PcgSolver pcg;
  std::vector<double> x(b.size(), 0.0);
  SolveReport r = pcg.solve(A, b.data(), x.data(), 5000, 1e-12, jobs);
  EXPECT_TRUE(r.converged);
  EXPECT_LE(relError(x, ref), 1e-8);
  CholeskySolver chol;
  ASSERT_TRUE(chol.analyze(A).ok());
  std::vector<double> xc(b.size(), 1.0);
  SolveReport rc = chol.solve(A, b.data(), xc.data());
  EXPECT_TRUE(rc.converged);
  EXPECT_LE(relError(xc, ref), 1e-8);
  for (size_t n = 0; n < g.nodes; ++n)
    if (fixed[n])
      for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(x[3 * n + i], 0.0);
        EXPECT_EQ(xc[3 * n + i], 0.0);
      }
}

TEST(Solvers, IndefiniteMatrixIsReportedNotNan) {
  gf::SerialJobSystem jobs;
  System s = randomSystem(3, 3, 2, 13, 0.0, 0.0, jobs);
  // Shift by minus half the mean diagonal: clearly indefinite.
  double meanDiag = 0;
  for (int32_t r = 0; r < s.A.n; ++r) meanDiag += s.A.block(s.A.diagonal(r))[0];
  shiftDiagonal(s.A, -0.5 * meanDiag / s.A.n);
  const std::vector<double> b = randomVector(3 * s.grid.nodes, 14);

  CholeskySolver chol;
  ASSERT_TRUE(chol.analyze(s.A).ok());
  std::vector<double> x(b.size(), 1.0);
  SolveReport rc = chol.solve(s.A, b.data(), x.data());
  EXPECT_FALSE(rc.converged);
  for (double v : x) ASSERT_EQ(v, 0.0);

  PcgSolver pcg;
  std::vector<double> xp(b.size(), 0.0);
  SolveReport rp = pcg.solve(s.A, b.data(), xp.data(), 1000, 1e-10, jobs);
  EXPECT_FALSE(rp.converged);
  EXPECT_TRUE(allFinite(xp));
  EXPECT_FALSE(std::isnan(rp.relativeResidual));

  // A non-finite right-hand side is a failure, not a NaN solution.
  std::vector<double> bn = b;
  bn[5] = std::nan("");
  std::vector<double> xn(b.size(), 0.0);
  SolveReport rn = pcg.solve(s.A, bn.data(), xn.data(), 100, 1e-8, jobs);
  EXPECT_FALSE(rn.converged);
  EXPECT_TRUE(allFinite(xn));
}

TEST(Solvers, CholeskyRejectsBadPatternAndUnanalysedMatrix) {
  gf::SerialJobSystem jobs;
  System s = randomSystem(2, 2, 1, 17, 0.0, 1.0, jobs);
  CholeskySolver chol;
  std::vector<double> b(3 * s.grid.nodes, 1.0), x(b.size(), 5.0);
  SolveReport r = chol.solve(s.A, b.data(), x.data());  // analyze() never ran
  EXPECT_FALSE(r.converged);
  for (double v : x) ASSERT_EQ(v, 0.0);

  BlockSparseMatrix broken = s.A;
  broken.col[broken.rowStart[1] - 1] = broken.n + 3;
  gf::Result<void> res = chol.analyze(broken);
  EXPECT_FALSE(res.ok());
  EXPECT_NE(res.error().message.find("block row 0"), std::string::npos) << res.error().message;
}

TEST(Solvers, EmptySystem) {
  BlockSparseMatrix A = BlockSparseMatrix::fromTets(nullptr, 0, 0);
  EXPECT_EQ(A.n, 0);
  EXPECT_EQ(A.blockCount(), 0);
  PcgSolver pcg;
  SolveReport r = pcg.solve(A, nullptr, nullptr, 10, 1e-8, gf::serialJobs());
  EXPECT_TRUE(r.converged);
  CholeskySolver chol;
  ASSERT_TRUE(chol.analyze(A).ok());
  EXPECT_TRUE(chol.solve(A, nullptr, nullptr).converged);
}

// The factorise-once / solve-many split: one factorisation serves several right-hand sides,
// and a later change of A's values is not seen until factorize() runs again (solveFactored only
// back-substitutes). Below and above kSimplicialMaxBlocks (Eigen's and CHOLMOD's paths).
TEST(Cholesky, FactorOnceThenBackSubstituteMany) {
  gf::SerialJobSystem jobs;
  for (const auto& dims : {std::array<int, 3>{3, 3, 2}, std::array<int, 3>{6, 5, 4}}) {
    System s = randomSystem(dims[0], dims[1], dims[2], 41, 0.5, 0.05, jobs);
    const Eigen::MatrixXd dense = toDense(s.A);
    const Eigen::LLT<Eigen::MatrixXd> llt(dense);
    ASSERT_EQ(llt.info(), Eigen::Success);
    CholeskySolver chol;
    std::vector<double> x(3 * s.grid.nodes, 7.0);
    EXPECT_FALSE(chol.factorize(s.A));  // not analysed
    EXPECT_FALSE(chol.solveFactored(x.data(), x.data()));
    ASSERT_TRUE(chol.analyze(s.A).ok());
    ASSERT_TRUE(chol.factorize(s.A));
    EXPECT_EQ(chol.factoredSize(), int64_t(3 * s.grid.nodes));
    for (uint64_t seed : {51, 52, 53}) {
      const std::vector<double> b = randomVector(3 * s.grid.nodes, seed);
      ASSERT_TRUE(chol.solveFactored(b.data(), x.data()));
      EXPECT_LE(relError(x, llt.solve(Eigen::VectorXd::Map(b.data(), b.size()))), 1e-10)
          << s.A.n << " blocks, seed " << seed;
    }
    const std::vector<double> b = randomVector(3 * s.grid.nodes, 54);
    const Eigen::VectorXd ref = llt.solve(Eigen::VectorXd::Map(b.data(), b.size()));
    for (double& v : s.A.values) v *= 2;
    ASSERT_TRUE(chol.solveFactored(b.data(), x.data()));
    EXPECT_LE(relError(x, ref), 1e-10);  // still the factor of the old values
    ASSERT_TRUE(chol.factorize(s.A));
    ASSERT_TRUE(chol.solveFactored(b.data(), x.data()));
    EXPECT_LE(relError(x, ref / 2), 1e-10);
  }
}

// Lower triangle of a dense symmetric matrix, or all of it, as Eigen's compressed columns.
struct Csc {
  Eigen::SparseMatrix<double, Eigen::ColMajor, int> m;
  gf::detail::SymmetricCsc view() const {
    return {int32_t(m.rows()), m.outerIndexPtr(), m.innerIndexPtr(), m.valuePtr()};
  }
};
Csc toCsc(const Eigen::MatrixXd& dense, bool lowerOnly) {
  Csc c;
  c.m = lowerOnly ? Eigen::MatrixXd(dense.triangularView<Eigen::Lower>()).sparseView()
                  : dense.sparseView();
  c.m.makeCompressed();
  return c;
}

// Entries of the Cholesky factor of `dense` in its given order (the fill without reordering).
int64_t naturalFill(const Eigen::MatrixXd& dense) {
  const Eigen::MatrixXd L = dense.llt().matrixL();
  int64_t nnz = 0;
  for (Eigen::Index j = 0; j < L.cols(); ++j)
    for (Eigen::Index i = j; i < L.rows(); ++i) nnz += L(i, j) != 0;
  return nnz;
}

// The scalar entry point (the Is-XFEM step matrix's): full or lower-triangle input gives the
// dense solution; the factor holds at least A's lower triangle (fill cannot be negative) and the
// fill-reducing ordering leaves well under the fill of the grid's own (lexicographic) order.
TEST(Cholesky, ScalarMatrixMatchesDenseSolveAndReducesFill) {
  gf::SerialJobSystem jobs;
  for (const auto& dims : {std::array<int, 3>{3, 3, 2}, std::array<int, 3>{7, 6, 5}}) {
    System s = randomSystem(dims[0], dims[1], dims[2], 61, 0.5, 0.05, jobs);
    const Eigen::MatrixXd dense = toDense(s.A);
    const std::vector<double> b = randomVector(3 * s.grid.nodes, 62);
    const Eigen::VectorXd ref = dense.llt().solve(Eigen::VectorXd::Map(b.data(), b.size()));
    const int64_t natural = naturalFill(dense);
    for (bool lowerOnly : {false, true}) {
      const Csc csc = toCsc(dense, lowerOnly);
      CholeskySolver chol;
      const gf::Result<void> r = chol.factorize(csc.view());
      ASSERT_TRUE(r.ok()) << r.error().message;
      EXPECT_EQ(chol.factoredSize(), int64_t(dense.rows()));
      std::vector<double> x(b.size(), 0.0);
      ASSERT_TRUE(chol.solveFactored(b.data(), x.data()));
      EXPECT_LE(relError(x, ref), 1e-10);
      const gf::detail::CholeskyFactorInfo info = chol.factorInfo();
      const int64_t lower = toCsc(dense, true).m.nonZeros();
      EXPECT_EQ(info.matrixNonZeros, lower);
      EXPECT_GE(info.factorNonZeros, lower);
      std::printf("[ info ] n = %lld: factor %lld entries (%s%s), natural order %lld, A %lld\n",
                  (long long)dense.rows(), (long long)info.factorNonZeros, info.ordering,
                  info.supernodal ? ", supernodal" : "", (long long)natural, (long long)lower);
      if (dense.rows() > 1000) {
        EXPECT_LE(3 * info.factorNonZeros, 2 * natural);  // measured 1.7x less
      }
    }
  }
}

// Bad scalar input is named and leaves no factor behind (a stale one would solve silently).
TEST(Cholesky, ScalarMatrixErrorsNameTheColumnAndKeepNoFactor) {
  gf::SerialJobSystem jobs;
  System s = randomSystem(2, 2, 2, 71, 0.0, 1.0, jobs);
  Eigen::MatrixXd dense = toDense(s.A);
  const std::vector<double> b = randomVector(size_t(dense.rows()), 72);
  std::vector<double> x(b.size(), 0.0);
  CholeskySolver chol;
  ASSERT_TRUE(chol.factorize(toCsc(dense, true).view()).ok());
  ASSERT_TRUE(chol.solveFactored(b.data(), x.data()));

  // Column 1 without its diagonal entry.
  Eigen::MatrixXd noDiagonal = dense;
  noDiagonal(1, 1) = 0;
  gf::Result<void> r = chol.factorize(toCsc(noDiagonal, true).view());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("column 1 has no diagonal"), std::string::npos)
      << r.error().message;
  EXPECT_EQ(chol.factoredSize(), 0);
  std::fill(x.begin(), x.end(), 3.0);
  EXPECT_FALSE(chol.solveFactored(b.data(), x.data()));

  // Rows out of order in column 0.
  Csc swapped = toCsc(dense, true);
  ASSERT_GE(swapped.m.outerIndexPtr()[1], 2);
  std::swap(swapped.m.innerIndexPtr()[0], swapped.m.innerIndexPtr()[1]);
  r = chol.factorize(swapped.view());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("column 0"), std::string::npos) << r.error().message;

  // Indefinite: minus half the mean diagonal.
  const double shift = 0.5 * dense.diagonal().mean();
  Eigen::MatrixXd indefinite = dense;
  indefinite.diagonal().array() -= shift;
  r = chol.factorize(toCsc(indefinite, false).view());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("not positive definite"), std::string::npos)
      << r.error().message;
  EXPECT_FALSE(chol.solveFactored(b.data(), x.data()));

  // Empty: nothing to factorise, nothing to solve.
  EXPECT_TRUE(chol.factorize(gf::detail::SymmetricCsc{}).ok());
  EXPECT_TRUE(chol.solveFactored(nullptr, nullptr));
}

// Timing on a ~30k-tet elastic grid (17^3 cubes * 6 = 29478 tets). Disabled by default; run with
// --gtest_also_run_disabled_tests --gtest_filter='*SolverTiming*'.
TEST(Solvers, DISABLED_SolverTiming) {
  using Clock = std::chrono::steady_clock;
  Grid g = makeGrid(17, 17, 17);
  BlockSparseMatrix A = BlockSparseMatrix::fromTets(g.tets.data(), g.tetCount(), g.nodes);
  ElementGather gather = ElementGather::build(g.tets.data(), g.tetCount(), A);
  // Steel-like (E = 200 GPa, nu = 0.3) unit cells of 1 cm, mass / dt^2 at 1/60 s: M/h^2 + K.
  const double h = 0.01, e = 2e11, nu = 0.3, rho = 7800, dt = 1.0 / 60;
  for (double& p : g.positions) p *= h;
  const double lambda = e * nu / ((1 + nu) * (1 - 2 * nu)), mu = e / (2 * (1 + nu));
  const std::vector<double> ke = upperBlocks(elasticElementMatrices(g, lambda, mu));
  for (int threads : {1, 2}) {
    gf::ThreadPoolJobSystem jobs(threads);
    A.setZero(jobs);
    auto t0 = Clock::now();
    gf::detail::gatherElementBlocks(gather, ke.data(), 1.0, A, jobs);
    const double tGather = std::chrono::duration<double>(Clock::now() - t0).count();
    shiftDiagonal(A, rho * h * h * h / (dt * dt));  // lumped mass per node, interior value
    const std::vector<double> b = randomVector(3 * g.nodes, 1);
    std::vector<double> y(b.size()), x(b.size(), 0.0);
    const int reps = 200;
    t0 = Clock::now();
    for (int i = 0; i < reps; ++i) A.multiply(b.data(), y.data(), jobs);
    const double tSpmv = std::chrono::duration<double>(Clock::now() - t0).count() / reps;
    PcgSolver pcg;
    SolveReport r = pcg.solve(A, b.data(), x.data(), 2000, 1e-8, jobs);  // warm-up
    std::fill(x.begin(), x.end(), 0.0);
    t0 = Clock::now();
    r = pcg.solve(A, b.data(), x.data(), 2000, 1e-8, jobs);
    const double tPcg = std::chrono::duration<double>(Clock::now() - t0).count();
    std::printf(
        "[ timing ] threads %d: %zu tets, %zu nodes, %d blocks: gather %.3f ms, SpMV %.3f ms, "
        "PCG %d it to %.1e in %.2f ms (%.3f ms/it)\n",
        threads, g.tetCount(), g.nodes, A.blockCount(), 1e3 * tGather, 1e3 * tSpmv, r.iterations,
        r.relativeResidual, 1e3 * tPcg, 1e3 * tPcg / std::max(r.iterations, 1));
    EXPECT_TRUE(r.converged);
    if (threads == 1) {
      CholeskySolver chol;
      t0 = Clock::now();
      ASSERT_TRUE(chol.analyze(A).ok());
      const double tAnalyze = std::chrono::duration<double>(Clock::now() - t0).count();
      std::vector<double> xc(b.size());
      t0 = Clock::now();
      SolveReport rc = chol.solve(A, b.data(), xc.data());
      const double tChol = std::chrono::duration<double>(Clock::now() - t0).count();
      std::printf("[ timing ] Cholesky: analyze %.1f ms, factorize+solve %.1f ms, residual %.1e\n",
                  1e3 * tAnalyze, 1e3 * tChol, rc.relativeResidual);
      EXPECT_TRUE(rc.converged);
      EXPECT_LE(relError(x, Eigen::VectorXd::Map(xc.data(), xc.size())), 1e-6);
    }
  }
}

}  // namespace
