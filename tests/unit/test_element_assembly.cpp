// Element matrices stored as their upper node blocks (kElementMatrixSize, kernels/math.h;
// issue 14): the step matrix assembled from that storage, block (a, b) with a > b read as the
// transpose of block (b, a), against an independent reference, a dense assembly of full 12x12
// element Hessians by central differences of the element gradients, on a few tets sharing
// nodes: one inverted, one with a fibre term, one damaged (the scatterElementDerivatives
// path). The producers (ElementStage one tet at a time, the SIMD lanes) must write that
// storage: their assembly equals the dense assembly of their own full Hessians. The assembled
// matrix must be exactly symmetric, bit for bit. On a box mesh with shuffled corner orders the
// gather (its precomputed block offsets and transpose flags, the lookahead across its blocks
// and thread ranges, adding to or replacing the old values) must give the bits of a plain
// dense scatter of the full element matrices in element order.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "fem/element_lanes.h"
#include "fem/element_stage.h"
#include "graphfrac/jobs.h"
#include "graphfrac/mesh.h"
#include "kernels/damage.h"
#include "kernels/element.h"
#include "solver/block_sparse.h"

namespace {

using gf::Mat12;
using gf::MaterialCoeffs;
using gf::Vec3;
using gf::detail::BlockSparseMatrix;
using gf::detail::ElementGather;

constexpr int kTets = 4;
constexpr int kNodes = 7;
constexpr int kInverted = 2, kDamaged = 1, kFibre = 3;
constexpr uint8_t kBrokenMask = 0b000101;  // two broken edges of the damaged tet

struct Mesh {
  std::vector<int32_t> tets{0, 1, 2, 3, 1, 2, 3, 4, 2, 3, 4, 5, 0, 3, 5, 6};
  std::vector<double> x;  // deformed, 3 per node
  std::vector<gf::Mat3> restInverse;
  std::vector<double> restVolume;

  void corners(int t, Vec3 xe[4]) const { gf::detail::tetCorners(tets.data(), x.data(), t, xe); }
};

double orientation(const Vec3 p[4]) {
  return gf::det(gf::fromColumns(p[1] - p[0], p[2] - p[0], p[3] - p[0]));
}

// Rest nodes jittered off a unit pattern, each tet turned positive; the deformed state a
// general strain and rotation, then node 5 (tets 2 and 3 only) mirrored through the face of
// tet 2 opposite it, which inverts tet 2.
Mesh makeMesh() {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0, 1);
  const Vec3 pattern[kNodes] = {{0, 0, 0}, {1, 0, 0},    {0, 1, 0},       {0, 0, 1},
                                {1, 1, 1}, {-0.4, 1, 1}, {0.2, -0.8, 0.7}};
  Mesh m;
  std::vector<Vec3> X(kNodes);
  for (int a = 0; a < kNodes; ++a) X[a] = 0.1 * (pattern[a] + 0.1 * Vec3{n(rng), n(rng), n(rng)});
  for (int t = 0; t < kTets; ++t) {
    Vec3 p[4];
    for (int a = 0; a < 4; ++a) p[a] = X[m.tets[4 * t + a]];
    if (orientation(p) < 0) std::swap(m.tets[4 * t + 2], m.tets[4 * t + 3]);
    for (int a = 0; a < 4; ++a) p[a] = X[m.tets[4 * t + a]];
    double vol = 0;
    m.restInverse.push_back(gf::restShapeInverse(p, vol));
    m.restVolume.push_back(vol);
  }
  gf::Mat3 F = gf::Mat3::identity();
  for (int e = 0; e < 9; ++e) F.m[e] += 0.15 * n(rng);
  for (const Vec3& p : X) {
    const Vec3 q = F * p;
    m.x.insert(m.x.end(), {q.x, q.y, q.z});
  }
  auto node = [&](int i) { return Vec3{m.x[3 * i], m.x[3 * i + 1], m.x[3 * i + 2]}; };
  const Vec3 a = node(2), b = node(3), c = node(4), p = node(5);
  const Vec3 normal = gf::cross(b - a, c - a);
  const Vec3 mirrored = p - (2 * gf::dot(p - a, normal) / gf::dot(normal, normal)) * normal;
  for (int k = 0; k < 3; ++k) m.x[3 * 5 + k] = mirrored[k];
  return m;
}

MaterialCoeffs isotropic() {
  return gf::makeMaterialCoeffs(gf::kStableNeoHookean, 2e6, 0.3, 0, Vec3{1, 0, 0});
}
MaterialCoeffs withFibre() {
  return gf::makeMaterialCoeffs(gf::kStableNeoHookean, 2e6, 0.3, 3e5, Vec3{1, 2, 0.5});
}

// Tet t's gradient at xe and, when h is non-null, its Hessian without the PSD projection:
// the exact second derivative the differences approximate.
void elementDerivatives(int t, const Mesh& m, const Vec3 xe[4], double g[12], Mat12* h) {
  if (t == kDamaged) {
    const gf::Mat<6, 6> identity = gf::Mat<6, 6>::identity();
    uint8_t broken[6];
    for (int k = 0; k < 6; ++k) broken[k] = (kBrokenMask >> k) & 1;
    gf::damagedElementForces(gf::kDamageProjection, isotropic(), identity, identity, 1.0, broken,
                             xe, m.restInverse[t], m.restVolume[t], g, h, false);
    return;
  }
  gf::elementForces(t == kFibre ? withFibre() : isotropic(), xe, m.restInverse[t], m.restVolume[t],
                    g, h, false);
}

// Central differences of the element gradient, all 12 columns.
Mat12 differenceHessian(int t, const Mesh& m) {
  Vec3 xe[4];
  m.corners(t, xe);
  const double step = 1e-7;  // the tets are about 0.1 across
  Mat12 h;
  for (int c = 0; c < 12; ++c) {
    Vec3 xp[4], xm[4];
    std::copy(xe, xe + 4, xp);
    std::copy(xe, xe + 4, xm);
    xp[c / 3][c % 3] += step;
    xm[c / 3][c % 3] -= step;
    double gp[12], gm[12];
    elementDerivatives(t, m, xp, gp, nullptr);
    elementDerivatives(t, m, xm, gm, nullptr);
    for (int r = 0; r < 12; ++r) h(r, c) = (gp[r] - gm[r]) / (2 * step);
  }
  return h;
}

using Dense = std::vector<double>;  // 3 kNodes squared, row-major

void scatter(const Mesh& m, int t, const Mat12& h, Dense& d) {
  constexpr int n = 3 * kNodes;
  for (int r = 0; r < 12; ++r)
    for (int c = 0; c < 12; ++c)
      d[size_t(n * (3 * m.tets[4 * t + r / 3] + r % 3) + 3 * m.tets[4 * t + c / 3] + c % 3)] +=
          h(r, c);
}

Dense toDense(const BlockSparseMatrix& A) {
  constexpr int n = 3 * kNodes;
  Dense d(size_t(n * n), 0.0);
  for (int32_t r = 0; r < A.n; ++r)
    for (int32_t k = A.rowStart[r]; k < A.rowStart[r + 1]; ++k)
      for (int i = 0; i < 9; ++i)
        d[size_t(n * (3 * r + i / 3) + 3 * A.col[k] + i % 3)] = A.block(k)[i];
  return d;
}

BlockSparseMatrix assemble(const Mesh& m, const std::vector<double>& compact) {
  gf::SerialJobSystem jobs;
  BlockSparseMatrix A = BlockSparseMatrix::fromTets(m.tets.data(), kTets, kNodes);
  const ElementGather gather = ElementGather::build(m.tets.data(), kTets, A);
  gf::detail::gatherElementBlocks(gather, compact.data(), 1.0, A, jobs);
  return A;
}

// Largest |a - b| over the largest |b|.
double relDiff(const Dense& a, const Dense& b) {
  double diff = 0, scale = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    diff = std::max(diff, std::abs(a[i] - b[i]));
    scale = std::max(scale, std::abs(b[i]));
  }
  return diff / scale;
}

// Entries (i, j) and (j, i) of the assembled matrix that differ in any bit.
int asymmetricEntries(const BlockSparseMatrix& A) {
  const Dense d = toDense(A);
  constexpr int n = 3 * kNodes;
  int count = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < i; ++j) count += d[size_t(n * i + j)] != d[size_t(n * j + i)];
  return count;
}

TEST(ElementAssembly, UpperBlocksAssembleTheDifferenceHessians) {
  const Mesh m = makeMesh();
  Vec3 xe[4];
  m.corners(kInverted, xe);
  ASSERT_LT(orientation(xe), 0) << "tet " << kInverted << " should be inverted";
  std::vector<double> compact(gf::kElementMatrixSize * kTets);
  Dense reference(size_t(9 * kNodes * kNodes), 0.0);
  for (int t = 0; t < kTets; ++t) {
    m.corners(t, xe);
    double g[12];
    Mat12 h;
    elementDerivatives(t, m, xe, g, &h);
    gf::storeUpperBlocks(h.m, &compact[gf::kElementMatrixSize * size_t(t)]);
    scatter(m, t, differenceHessian(t, m), reference);
  }
  const BlockSparseMatrix A = assemble(m, compact);
  const double diff = relDiff(toDense(A), reference);
  const int asymmetric = asymmetricEntries(A);
  std::printf("[ info ] upper blocks vs difference Hessians: rel. diff %.2e, %d asymmetric\n", diff,
              asymmetric);
  EXPECT_LT(diff, 1e-6);
  EXPECT_EQ(asymmetric, 0);
}

TEST(ElementAssembly, ProducersWriteTheUpperBlocks) {
  const Mesh m = makeMesh();
  const std::vector<uint8_t> mask{0, kBrokenMask, 0, 0};
  const std::vector<double> chi(kTets, 1.0);
  for (const bool fibre : {false, true}) {
    std::vector<double> energy(kTets), grad(12 * kTets), compact(gf::kElementMatrixSize * kTets);
    gf::detail::ElementStage s;
    s.tets = m.tets.data();
    s.x = m.x.data();
    s.restInverse = m.restInverse.data();
    s.restVolume = m.restVolume.data();
    s.coeffs = fibre ? withFibre() : isotropic();
    s.tetMask = mask.data();
    s.damageModel = gf::kDamageProjection;
    s.chi = chi.data();
    s.energy = energy.data();
    s.grad = grad.data();
    s.hess = compact.data();
    // The undamaged tets of the isotropic body go through the SIMD lanes, the others one by one.
    gf::detail::evaluateElementRange(s, 0, kTets);
    Dense reference(size_t(9 * kNodes * kNodes), 0.0);
    for (int t = 0; t < kTets; ++t) {
      double g[12];
      Mat12 h;
      s.evaluate(t, g, &h);
      scatter(m, t, h, reference);
    }
    const BlockSparseMatrix A = assemble(m, compact);
    const double diff = relDiff(toDense(A), reference);
    const int asymmetric = asymmetricEntries(A);
    std::printf("[ info ] %s body: stage's upper blocks vs its full Hessians %.2e, %d asymmetric\n",
                fibre ? "fibre" : "isotropic", diff, asymmetric);
    EXPECT_LT(diff, 1e-12) << (fibre ? "fibre" : "isotropic");
    EXPECT_EQ(asymmetric, 0) << (fibre ? "fibre" : "isotropic");
  }
}

// Every block of the pattern is the sum of its element blocks in element order, as a dense
// scatter of the full 12x12 matrices in element order adds them: the same additions, so the
// same bits, whichever half of a symmetric element matrix the gather reads.
TEST(ElementAssembly, GatherHasTheBitsOfAnElementOrderScatter) {
  gf::TetMesh mesh = gf::gen::box(1.0, 0.6, 0.4, 5, 4, 3);
  const size_t tets = mesh.tetCount(), n = 3 * mesh.nodeCount();
  std::mt19937 rng(11);
  for (size_t t = 0; t < tets; ++t)
    std::shuffle(mesh.tets.begin() + 4 * ptrdiff_t(t), mesh.tets.begin() + 4 * ptrdiff_t(t + 1),
                 rng);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Mat12> full(tets);
  std::vector<double> compact(gf::kElementMatrixSize * tets);
  Dense sum(n * n, 0.0);
  for (size_t t = 0; t < tets; ++t) {
    for (int r = 0; r < 12; ++r)
      for (int c = r; c < 12; ++c) full[t](r, c) = full[t](c, r) = u(rng);
    gf::storeUpperBlocks(full[t].m, &compact[gf::kElementMatrixSize * t]);
    for (int r = 0; r < 12; ++r)
      for (int c = 0; c < 12; ++c)
        sum[n * size_t(3 * mesh.tets[4 * t + r / 3] + r % 3) +
            size_t(3 * mesh.tets[4 * t + c / 3] + c % 3)] += full[t](r, c);
  }
  const double scale = 0.37;
  BlockSparseMatrix A = BlockSparseMatrix::fromTets(mesh.tets.data(), tets, mesh.nodeCount());
  const ElementGather gather = ElementGather::build(mesh.tets.data(), tets, A);
  // Blocks whose list reads some element blocks as they are and some transposed.
  int mixed = 0;
  for (int32_t k = 0; k < A.blockCount(); ++k) {
    int transposed = 0;
    for (int32_t q = gather.start[size_t(k)]; q < gather.start[size_t(k) + 1]; ++q)
      transposed += gather.entry[size_t(q)] & 1;
    mixed += transposed > 0 && transposed < gather.start[size_t(k) + 1] - gather.start[size_t(k)];
  }
  ASSERT_GT(mixed, A.blockCount() / 4) << "too few blocks that read both halves";
  auto dense = [&](const BlockSparseMatrix& M) {
    Dense d(n * n, 0.0);
    for (int32_t r = 0; r < M.n; ++r)
      for (int32_t k = M.rowStart[r]; k < M.rowStart[r + 1]; ++k)
        for (int i = 0; i < 9; ++i)
          d[n * size_t(3 * r + i / 3) + size_t(3 * M.col[k] + i % 3)] = M.block(k)[i];
    return d;
  };
  gf::SerialJobSystem serial;
  gf::ThreadPoolJobSystem three(3);
  // The step's passes: adding to old values, replacing them (NaN must not survive), and the
  // first assembly of a damped body, which also writes K = 0 + sum and adds addScale K last.
  enum Mode { kAdd, kReplace, kDamped };
  const char* modeName[] = {"adding", "replacing", "replacing, writing and adding K"};
  const double addScale = 0.021;
  BlockSparseMatrix K = A;
  for (gf::JobSystem* jobs :
       {static_cast<gf::JobSystem*>(&serial), static_cast<gf::JobSystem*>(&three)}) {
    for (const Mode mode : {kAdd, kReplace, kDamped}) {
      for (double& v : A.values)
        v = mode == kAdd ? u(rng) : std::numeric_limits<double>::quiet_NaN();
      std::fill(K.values.begin(), K.values.end(), std::numeric_limits<double>::quiet_NaN());
      const Dense old = dense(A);
      gf::detail::GatherFusion fusion;
      fusion.accumulate = mode == kAdd;
      if (mode == kDamped) {
        fusion.sum = &K;
        fusion.addAfter = &K;
        fusion.addScale = addScale;
      }
      gf::detail::gatherElementBlocks(gather, compact.data(), scale, A, *jobs, fusion);
      const Dense got = dense(A), gotK = dense(K);
      int differ = 0;
      for (size_t i = 0; i < n * n; ++i) {
        const double k = 0.0 + sum[i];
        double want = (mode == kAdd ? old[i] : 0.0) + scale * sum[i];
        if (mode == kDamped) want += addScale * k;
        differ += std::memcmp(&got[i], &want, sizeof(double)) != 0;
        if (mode == kDamped) differ += std::memcmp(&gotK[i], &k, sizeof(double)) != 0;
      }
      std::printf(
          "[ info ] %zu tets, %d of %d blocks read both halves, %s, %d threads: %d of %zu "
          "entries differ from the dense scatter\n",
          tets, mixed, A.blockCount(), modeName[mode], jobs == &serial ? 1 : 3, differ, n * n);
      EXPECT_EQ(differ, 0) << modeName[mode];
    }
  }
}

}  // namespace
