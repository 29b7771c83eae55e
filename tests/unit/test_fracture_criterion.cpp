// Fracture criterion (eq 4.10-4.12): edge normal stresses recomputed here from the node
// positions with Eigen, non-local averages against hand-computed weighted means, neighbour
// lists against an O(n^2) search, and thread-count independence.
#include <graphfrac/jobs.h>
#include <graphfrac/mesh.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <vector>

#include "fracture/criterion.h"
#include "fracture/fracture_model.h"
#include "mesh/edge_graph.h"

namespace gf::detail {
namespace {

struct Body {
  TetMesh mesh;
  EdgeGraph graph;
  FractureModel model;
};

// radius in mean edge lengths (the thesis's R_d); a negative value is -nonlocalLength [m].
Body makeBody(TetMesh mesh, double strength, double radius, JobSystem* jobs = nullptr) {
  Body b;
  b.mesh = std::move(mesh);
  b.graph = EdgeGraph::build(b.mesh.tets.data(), b.mesh.tetCount(), b.mesh.nodeCount());
  FractureSettings s;
  s.enabled = true;
  s.strength = strength;
  (radius >= 0 ? s.radius : s.nonlocalLength) = std::abs(radius);
  auto m = FractureModel::build(restView(b.mesh), b.graph, s, jobs);
  EXPECT_TRUE(m.ok()) << (m.ok() ? "" : m.error().message);
  b.model = std::move(m).value();
  return b;
}

Eigen::Vector3d nodeAt(const TetMesh& m, int v) {
  return {m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2]};
}

Eigen::Matrix3d fromVoigt(const double* s) {
  Eigen::Matrix3d m;
  m << s[0], s[3], s[4], s[3], s[1], s[5], s[4], s[5], s[2];
  return m;
}

void toVoigt(const Eigen::Matrix3d& m, double* s) {
  s[0] = m(0, 0);
  s[1] = m(1, 1);
  s[2] = m(2, 2);
  s[3] = m(0, 1);
  s[4] = m(0, 2);
  s[5] = m(1, 2);
}

// Independent edge normal stress: n^T S n with n from the rest node positions.
double sigmaN(const Body& b, int32_t edge, const double* s) {
  Eigen::Vector3d n =
      nodeAt(b.mesh, b.graph.edgeNodes[2 * edge + 1]) - nodeAt(b.mesh, b.graph.edgeNodes[2 * edge]);
  n.normalize();
  return n.dot(fromVoigt(s) * n);
}

// Deterministic pseudo-random numbers in [-1, 1].
struct Lcg {
  uint64_t state = 12345;
  double next() {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return double(state >> 11) / double(1ull << 53) * 2.0 - 1.0;
  }
};

std::vector<double> uniformStress(size_t tets, const Eigen::Matrix3d& m) {
  std::vector<double> s(6 * tets);
  for (size_t t = 0; t < tets; ++t) toVoigt(m, &s[6 * t]);
  return s;
}

TEST(FractureCriterion, SingleTetBreaksExactlyTheEdgesAtStrength) {
  TetMesh m;
  m.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0.2, 0.3, 1};
  m.tets = {0, 1, 2, 3};
  const double strength = 1.5e6;
  Body b = makeBody(m, strength, 0);
  Eigen::Matrix3d S;
  S << 3, 0.4, 0.3, 0.4, 1, 0.2, 0.3, 0.2, -2;
  S *= 1e6;
  std::vector<double> stress = uniformStress(1, S);
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  CriterionWorkspace ws;
  const int32_t n = evaluateCriterion(b.model, b.graph, b.model.strength.data(), stress.data(),
                                      broken, events, ws, serialJobs());
  int expected = 0;
  for (int32_t e = 0; e < b.graph.edgeCount; ++e) {
    const double sig = sigmaN(b, e, stress.data());
    ASSERT_GT(std::fabs(sig - strength), 1e-3 * strength) << "test set-up too close to sigma_th";
    EXPECT_EQ(broken[e] != 0, sig >= strength) << "edge " << e << " sigma_n " << sig;
    expected += sig >= strength;
  }
  ASSERT_GT(expected, 0);
  ASSERT_LT(expected, 6);
  ASSERT_EQ(n, expected);
  ASSERT_EQ(events.size(), size_t(expected));
  for (size_t i = 0; i < events.size(); ++i) {
    if (i > 0) {
      EXPECT_LT(events[i - 1].edge, events[i].edge);
    }
    EXPECT_EQ(events[i].tet, 0);
    EXPECT_NEAR(events[i].stress, sigmaN(b, events[i].edge, stress.data()), 1e-9 * strength);
  }
}

TEST(FractureCriterion, BarUnderUniformStressAndCompression) {
  Body b = makeBody(gen::box(2, 0.5, 0.5, 8, 2, 2), 0.85e6, 0);
  Eigen::Matrix3d S;
  S << 1, 0.3, 0.1, 0.3, 0.2, 0, 0.1, 0, -0.5;
  S *= 1e6;
  std::vector<double> stress = uniformStress(b.mesh.tetCount(), S);
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  CriterionWorkspace ws;
  evaluateCriterion(b.model, b.graph, b.model.strength.data(), stress.data(), broken, events, ws,
                    serialJobs());
  int breaks = 0, holds = 0;
  for (int32_t e = 0; e < b.graph.edgeCount; ++e) {
    const double sig = sigmaN(b, e, stress.data());
    ASSERT_GT(std::fabs(sig - 0.85e6), 1e3);
    EXPECT_EQ(broken[e] != 0, sig >= 0.85e6) << "edge " << e;
    (sig >= 0.85e6 ? breaks : holds)++;
  }
  EXPECT_GT(breaks, 0);
  EXPECT_GT(holds, 0);
  EXPECT_EQ(events.size(), size_t(breaks));

  // Compression of any size never breaks, however weak the edges.
  Body weak = makeBody(gen::box(2, 0.5, 0.5, 8, 2, 2), 1.0, 0);
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  C(0, 0) = -1e12;
  C(1, 1) = -3e11;
  std::vector<double> comp = uniformStress(weak.mesh.tetCount(), C);
  std::vector<uint8_t> flags(weak.graph.edgeCount, 0);
  events.clear();
  EXPECT_EQ(evaluateCriterion(weak.model, weak.graph, weak.model.strength.data(), comp.data(),
                              flags, events, ws, serialJobs()),
            0);
  EXPECT_TRUE(events.empty());
}

TEST(FractureCriterion, DamageNeverHeals) {
  Body b = makeBody(gen::box(1, 1, 1, 3, 3, 3), 1e6, 0);
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  S(0, 0) = 2e6;
  std::vector<double> pull = uniformStress(b.mesh.tetCount(), S);
  std::vector<double> rest(pull.size(), 0.0);
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  CriterionWorkspace ws;
  const int32_t first = evaluateCriterion(b.model, b.graph, b.model.strength.data(), pull.data(),
                                          broken, events, ws, serialJobs());
  ASSERT_GT(first, 0);
  const std::vector<uint8_t> after = broken;
  events.clear();
  EXPECT_EQ(evaluateCriterion(b.model, b.graph, b.model.strength.data(), rest.data(), broken,
                              events, ws, serialJobs()),
            0);
  EXPECT_EQ(broken, after);
  // The same load again: everything it could break is already broken.
  EXPECT_EQ(evaluateCriterion(b.model, b.graph, b.model.strength.data(), pull.data(), broken,
                              events, ws, serialJobs()),
            0);
  EXPECT_EQ(broken, after);
  EXPECT_TRUE(events.empty());
}

// Random per-tet stresses: an edge breaks iff some incident tet's n^T S n reaches strength,
// and the event names the incident tet with the largest one. R_d = 0 and an R_d so small
// that each list holds only the tet itself give the same result.
TEST(FractureCriterion, LocalCriterionMatchesIndependentMaxOverIncidentTets) {
  const double strength = 0.8e6;
  Body local = makeBody(gen::box(1, 0.6, 0.4, 5, 3, 2), strength, 0);
  Body tiny = makeBody(gen::box(1, 0.6, 0.4, 5, 3, 2), strength, 1e-3);
  ASSERT_FALSE(local.model.nonLocal());
  ASSERT_TRUE(tiny.model.nonLocal());
  for (int32_t t = 0; t < tiny.model.tetCount; ++t)
    ASSERT_EQ(tiny.model.neighbourStart[t + 1] - tiny.model.neighbourStart[t], 1);
  const size_t T = local.mesh.tetCount();
  Lcg rng;
  std::vector<double> stress(6 * T);
  for (double& v : stress) v = 1e6 * rng.next();

  std::vector<uint8_t> broken(local.graph.edgeCount, 0), broken2 = broken;
  std::vector<EdgeBreak> events, events2;
  CriterionWorkspace ws, ws2;
  evaluateCriterion(local.model, local.graph, local.model.strength.data(), stress.data(), broken,
                    events, ws, serialJobs());
  evaluateCriterion(tiny.model, tiny.graph, tiny.model.strength.data(), stress.data(), broken2,
                    events2, ws2, serialJobs());
  EXPECT_EQ(broken, broken2);
  ASSERT_EQ(events.size(), events2.size());

  int count = 0;
  size_t next = 0;
  for (int32_t e = 0; e < local.graph.edgeCount; ++e) {
    double best = -1e300;
    int32_t bestTet = -1;
    for (int32_t s = local.graph.edgeTetStart[e]; s < local.graph.edgeTetStart[e + 1]; ++s) {
      const int32_t t = local.graph.edgeTets[s] / 6;
      const double sig = sigmaN(local, e, &stress[6 * t]);
      if (sig > best + 1e-9 * strength) {
        best = sig;
        bestTet = t;
      }
    }
    EXPECT_EQ(broken[e] != 0, best >= strength) << "edge " << e;
    if (best >= strength) {
      ++count;
      ASSERT_LT(next, events.size());
      EXPECT_EQ(events[next].edge, e);
      EXPECT_EQ(events[next].tet, bestTet);
      EXPECT_NEAR(events[next].stress, best, 1e-9 * strength);
      EXPECT_EQ(events2[next].stress, events[next].stress);
      ++next;
    }
  }
  EXPECT_GT(count, 0);
  EXPECT_LT(count, local.graph.edgeCount);
  EXPECT_EQ(next, events.size());
}

TEST(FractureCriterion, NonLocalAverageMatchesHandComputedWeightedMean) {
  Body b = makeBody(gen::box(1, 1, 1, 2, 1, 1), 1e6, 1.0);
  const size_t T = b.mesh.tetCount();
  Lcg rng;
  std::vector<double> stress(6 * T);
  for (double& v : stress) v = 1e6 * rng.next();
  std::vector<double> avg(6 * T);
  averageStress(b.model, stress.data(), avg.data(), serialJobs());

  // Mean edge length and centroids from the mesh, independently of the model.
  double lsum = 0;
  for (int32_t e = 0; e < b.graph.edgeCount; ++e)
    lsum +=
        (nodeAt(b.mesh, b.graph.edgeNodes[2 * e + 1]) - nodeAt(b.mesh, b.graph.edgeNodes[2 * e]))
            .norm();
  const double R = 1.0 * lsum / b.graph.edgeCount;
  EXPECT_NEAR(b.model.radiusAbs, R, 1e-12);
  std::vector<Eigen::Vector3d> c(T);
  for (size_t t = 0; t < T; ++t) {
    c[t].setZero();
    for (int k = 0; k < 4; ++k) c[t] += 0.25 * nodeAt(b.mesh, b.mesh.tets[4 * t + k]);
  }
  int nontrivial = 0;
  for (size_t i = 0; i < T; ++i) {
    double expect[6] = {0, 0, 0, 0, 0, 0}, wsum = 0;
    int neighbours = 0;
    for (size_t j = 0; j < T; ++j) {
      const double d = (c[i] - c[j]).norm();
      if (d >= R) continue;
      const double w = 1 - d / R;
      neighbours += j != i;
      wsum += w;
      for (int k = 0; k < 6; ++k) expect[k] += w * stress[6 * j + k];
    }
    nontrivial += neighbours > 0;
    for (int k = 0; k < 6; ++k)
      EXPECT_NEAR(avg[6 * i + k], expect[k] / wsum, 1e-6 * 1e6) << "tet " << i << " comp " << k;
  }
  EXPECT_GT(nontrivial, int(T) / 2) << "R too small for the check to mean anything";
}

TEST(FractureCriterion, NonLocalAveragingDampsASingleStressedTet) {
  const double strength = 1e6;
  Body local = makeBody(gen::box(1, 1, 1, 5, 5, 5), strength, 0);
  Body avg = makeBody(gen::box(1, 1, 1, 5, 5, 5), strength, 2.0);
  const size_t T = local.mesh.tetCount();
  // The tet nearest the centre carries 3 sigma_th along every direction, the rest nothing.
  size_t hot = 0;
  double bestD = 1e9;
  for (size_t t = 0; t < T; ++t) {
    const double* cc = &local.model.centroids[3 * t];
    const double d = std::hypot(cc[0] - 0.5, cc[1] - 0.5, cc[2] - 0.5);
    if (d < bestD) bestD = d, hot = t;
  }
  std::vector<double> stress(6 * T, 0.0);
  for (int k = 0; k < 3; ++k) stress[6 * hot + k] = 3 * strength;

  std::vector<uint8_t> b1(local.graph.edgeCount, 0), b2 = b1;
  std::vector<EdgeBreak> ev;
  CriterionWorkspace ws1, ws2;
  // Local: all 6 edges of the hot tet break (sigma_n = 3 sigma_th along any direction).
  EXPECT_EQ(evaluateCriterion(local.model, local.graph, local.model.strength.data(), stress.data(),
                              b1, ev, ws1, serialJobs()),
            6);
  // Averaged: the hot tet's weight 1 is divided by the sum over its many neighbours.
  EXPECT_EQ(evaluateCriterion(avg.model, avg.graph, avg.model.strength.data(), stress.data(), b2,
                              ev, ws2, serialJobs()),
            0);
  const int32_t nb = avg.model.neighbourStart[hot + 1] - avg.model.neighbourStart[hot];
  EXPECT_GT(nb, 20);
  double wsum = 0;
  for (int32_t s = avg.model.neighbourStart[hot]; s < avg.model.neighbourStart[hot + 1]; ++s)
    wsum += avg.model.neighbourWeight[s];
  ASSERT_TRUE(ws2.candidates[hot] & 0x80);  // near strength: the bound let it be averaged
  EXPECT_NEAR(ws2.averaged[6 * hot], 3 * strength / wsum, 1e-9 * strength);
  EXPECT_LT(ws2.averaged[6 * hot], strength);
}

// The criterion averages only where the Gershgorin bound of the surrounding cells reaches a
// strength; that shortcut must not change the result: compare with the full average.
TEST(FractureCriterion, BoundedNonLocalCriterionMatchesFullAverage) {
  const double strength = 1e6;
  Body b = makeBody(gen::sphere(1, 10), strength, 1.5);
  const size_t T = b.mesh.tetCount();
  Lcg rng;
  std::vector<double> stress(6 * T);
  for (size_t t = 0; t < T; ++t) {
    const double* c = &b.model.centroids[3 * t];
    const double d2 = (c[0] - 0.4) * (c[0] - 0.4) + (c[1] + 0.2) * (c[1] + 0.2) + c[2] * c[2];
    const double hot = 2.5 * strength * std::exp(-d2 / 0.05);
    for (int k = 0; k < 6; ++k) stress[6 * t + k] = 0.2 * strength * rng.next();
    stress[6 * t] += hot;
    stress[6 * t + 3] += 0.3 * hot;
  }
  std::vector<double> full(6 * T);
  averageStress(b.model, stress.data(), full.data(), serialJobs());
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  CriterionWorkspace ws;
  const int32_t n = evaluateCriterion(b.model, b.graph, b.model.strength.data(), stress.data(),
                                      broken, events, ws, serialJobs());
  size_t averaged = 0;
  for (size_t t = 0; t < T; ++t) averaged += (ws.candidates[t] & 0x80) != 0;
  EXPECT_GT(averaged, 0u);
  EXPECT_LT(averaged, T / 2) << "the bound should skip most of the body";
  int expected = 0;
  size_t next = 0;
  for (int32_t e = 0; e < b.graph.edgeCount; ++e) {
    double best = -1e300;
    int32_t bestTet = -1;
    for (int32_t s = b.graph.edgeTetStart[e]; s < b.graph.edgeTetStart[e + 1]; ++s) {
      const int32_t t = b.graph.edgeTets[s] / 6;
      const double sig = sigmaN(b, e, &full[6 * t]);
      if (sig > best + 1e-9 * strength) best = sig, bestTet = t;
    }
    EXPECT_EQ(broken[e] != 0, best >= strength) << "edge " << e;
    if (best < strength) continue;
    ++expected;
    ASSERT_LT(next, events.size());
    EXPECT_EQ(events[next].edge, e);
    EXPECT_EQ(events[next].tet, bestTet);
    EXPECT_NEAR(events[next].stress, best, 1e-9 * strength);
    ++next;
  }
  EXPECT_GT(expected, 0);
  EXPECT_EQ(n, expected);
  // Nothing near strength anywhere: the call stops after the bound.
  std::vector<double> calm(6 * T);
  for (double& v : calm) v = 0.1 * strength * rng.next();
  std::vector<uint8_t> untouched(b.graph.edgeCount, 0);
  EXPECT_EQ(evaluateCriterion(b.model, b.graph, b.model.strength.data(), calm.data(), untouched,
                              events, ws, serialJobs()),
            0);
}

double tetVolume(const TetMesh& m, int32_t t) {
  const Eigen::Vector3d o = nodeAt(m, m.tets[4 * t]);
  return std::abs(
             (nodeAt(m, m.tets[4 * t + 1]) - o)
                 .dot((nodeAt(m, m.tets[4 * t + 2]) - o).cross(nodeAt(m, m.tets[4 * t + 3]) - o))) /
         6.0;
}

void expectListsMatchBruteForce(const Body& b) {
  const FractureModel& m = b.model;
  const double R = m.radiusAbs, R2 = R * R;
  ASSERT_GT(R, 0);
  // Centroids against the mesh.
  for (int32_t t = 0; t < m.tetCount; ++t) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int k = 0; k < 4; ++k) c += 0.25 * nodeAt(b.mesh, b.mesh.tets[4 * t + k]);
    for (int a = 0; a < 3; ++a) ASSERT_NEAR(m.centroids[3 * t + a], c[a], 1e-12);
  }
  size_t total = 0;
  for (int32_t i = 0; i < m.tetCount; ++i) {
    std::vector<int32_t> expect;
    for (int32_t j = 0; j < m.tetCount; ++j) {
      double d2;
      if (withinRadius(&m.centroids[3 * i], &m.centroids[3 * j], R2, d2)) expect.push_back(j);
    }
    const std::vector<int32_t> got(m.neighbourIndex.begin() + m.neighbourStart[i],
                                   m.neighbourIndex.begin() + m.neighbourStart[i + 1]);
    ASSERT_EQ(got, expect) << "tet " << i;
    for (size_t s = 0; s < got.size(); ++s) {
      double d2;
      withinRadius(&m.centroids[3 * i], &m.centroids[3 * got[s]], R2, d2);
      // In metres the kernel is also weighted by the neighbour's rest volume.
      const double volume = m.settings.nonlocalLength > 0 ? tetVolume(b.mesh, got[s]) : 1.0;
      EXPECT_NEAR(m.neighbourWeight[m.neighbourStart[i] + s], (1 - std::sqrt(d2) / R) * volume,
                  1e-6 * volume);
    }
    total += got.size();
  }
  EXPECT_GT(total, 5 * size_t(m.tetCount));
}

TEST(FractureCriterion, NeighbourListsMatchBruteForce) {
  expectListsMatchBruteForce(makeBody(gen::box(1, 0.7, 0.5, 6, 4, 3), 1e6, 1.5));
  expectListsMatchBruteForce(makeBody(gen::box(1, 0.7, 0.5, 6, 4, 3), 1e6, 3.0));
  expectListsMatchBruteForce(makeBody(gen::sphere(1, 6), 1e6, 2.0));
  expectListsMatchBruteForce(makeBody(gen::cylinder(0.5, 2, 12, 6, 2), 1e6, 2.5));
  expectListsMatchBruteForce(makeBody(gen::sphere(1, 6), 1e6, -0.7));
}

// The average over a length in metres is an integral over the material: on a mesh whose tets
// crowd towards x = 0, the mean of a stress that grows linearly in x, taken over a ball inside
// the body, is the stress at the ball's centre (a symmetric kernel integrates a linear field
// exactly). Counting tets instead, as R_d in edge lengths does, pulls it towards the crowd.
TEST(FractureCriterion, AverageOverALengthIsIndependentOfTheMeshDensity) {
  TetMesh mesh = gen::box(1, 1, 1, 14, 14, 14);
  for (size_t n = 0; n < mesh.nodeCount(); ++n) {
    double& x = mesh.positions[3 * n];
    x = x * (0.25 + 0.75 * x);  // cells 7 times finer at x = 0 than at x = 1
  }
  const double R = 0.25;
  Body byLength = makeBody(mesh, 1e6, -R);
  Body byCount = makeBody(mesh, 1e6, R / makeBody(mesh, 1e6, 0).model.meanEdgeLength);
  const int32_t T = byLength.model.tetCount;
  std::vector<double> stress(6 * size_t(T), 0.0);
  for (int32_t t = 0; t < T; ++t) stress[6 * size_t(t)] = byLength.model.centroids[3 * size_t(t)];
  std::vector<double> meanByLength(6 * size_t(T)), meanByCount(6 * size_t(T));
  averageStress(byLength.model, stress.data(), meanByLength.data(), serialJobs());
  averageStress(byCount.model, stress.data(), meanByCount.data(), serialJobs());
  double worstLength = 0, worstCount = 0;
  int interior = 0;
  for (int32_t t = 0; t < T; ++t) {
    const double* c = &byLength.model.centroids[3 * size_t(t)];
    if (std::max({std::abs(c[0] - 0.5), std::abs(c[1] - 0.5), std::abs(c[2] - 0.5)}) > 0.2)
      continue;
    ++interior;
    worstLength = std::max(worstLength, std::abs(meanByLength[6 * size_t(t)] - c[0]));
    worstCount = std::max(worstCount, std::abs(meanByCount[6 * size_t(t)] - c[0]));
  }
  std::printf(
      "mean of sigma = x over a 0.25 m ball, %d interior tets of a graded mesh: largest "
      "error %.2e m by volume, %.2e m by tet count\n",
      interior, worstLength, worstCount);
  ASSERT_GT(interior, 100);
  EXPECT_LT(worstLength, 0.01 * R);
  EXPECT_GT(worstCount, 5 * worstLength);
}

TEST(FractureCriterion, SameResultForOneAndFourThreads) {
  ThreadPoolJobSystem pool(4);
  SerialJobSystem serial;
  Body b1 = makeBody(gen::sphere(1, 10), 0.55e6, 2.0, &serial);
  Body b4 = makeBody(gen::sphere(1, 10), 0.55e6, 2.0, &pool);
  EXPECT_EQ(b1.model.neighbourStart, b4.model.neighbourStart);
  EXPECT_EQ(b1.model.neighbourIndex, b4.model.neighbourIndex);
  EXPECT_EQ(b1.model.neighbourWeight, b4.model.neighbourWeight);
  const size_t T = b1.mesh.tetCount();
  Lcg rng;
  std::vector<double> stress(6 * T);
  for (double& v : stress) v = 1e6 * rng.next();
  // Per-edge strengths (the override path): the 95th percentile of the averaged edge
  // stresses, so a few per cent of the edges break.
  std::vector<double> avg(6 * T), sig;
  averageStress(b1.model, stress.data(), avg.data(), serial);
  for (size_t t = 0; t < T; ++t)
    for (int k = 0; k < 6; ++k)
      sig.push_back(edgeNormalStress(&avg[6 * t], &b1.model.edgeDirections[18 * t + 3 * k]));
  std::sort(sig.begin(), sig.end());
  const double strength = sig[sig.size() * 95 / 100];
  for (Body* b : {&b1, &b4}) b->model.strength.assign(b->model.strength.size(), strength);
  std::vector<uint8_t> f1(b1.graph.edgeCount, 0), f4 = f1;
  std::vector<EdgeBreak> e1, e4;
  CriterionWorkspace w1, w4;
  const int32_t n1 = evaluateCriterion(b1.model, b1.graph, b1.model.strength.data(), stress.data(),
                                       f1, e1, w1, serial);
  const int32_t n4 = evaluateCriterion(b4.model, b4.graph, b4.model.strength.data(), stress.data(),
                                       f4, e4, w4, pool);
  EXPECT_GT(n1, 0);
  EXPECT_LT(n1, b1.graph.edgeCount / 2);
  EXPECT_EQ(n1, n4);
  EXPECT_EQ(f1, f4);
  ASSERT_EQ(e1.size(), e4.size());
  for (size_t i = 0; i < e1.size(); ++i) {
    EXPECT_EQ(e1[i].edge, e4[i].edge);
    EXPECT_EQ(e1[i].tet, e4[i].tet);
    EXPECT_EQ(e1[i].stress, e4[i].stress);  // bitwise
  }
  EXPECT_EQ(w1.averaged, w4.averaged);
}

TEST(FractureCriterion, DamagedTetsAndMasks) {
  Body b = makeBody(gen::box(1, 1, 1, 3, 3, 3), 1e6, 0);
  std::vector<uint8_t> broken(b.graph.edgeCount, 0);
  std::vector<EdgeBreak> events;
  for (int32_t e : {3, 17, 40, b.graph.edgeCount - 1}) {
    broken[e] = 1;
    EdgeBreak ev;
    ev.edge = e;
    events.push_back(ev);
  }
  std::vector<uint8_t> masks(b.mesh.tetCount(), 0), incremental(b.mesh.tetCount(), 0);
  brokenEdgeMasks(b.graph, broken.data(), masks.data(), serialJobs());
  applyBreaksToMasks(b.graph, events.data(), events.size(), incremental.data());
  EXPECT_EQ(masks, incremental);
  const std::vector<int32_t> damaged = damagedTets(b.graph, broken.data());
  std::vector<int32_t> expect;
  for (size_t t = 0; t < b.mesh.tetCount(); ++t) {
    uint8_t mask = 0;
    for (int k = 0; k < 6; ++k) {
      const int a = b.mesh.tets[4 * t + kTetEdgeNodes[k][0]];
      const int c = b.mesh.tets[4 * t + kTetEdgeNodes[k][1]];
      if (broken[b.graph.find(a, c)]) mask |= uint8_t(1u << k);
    }
    EXPECT_EQ(masks[t], mask) << "tet " << t;
    if (mask) expect.push_back(int32_t(t));
  }
  EXPECT_EQ(damaged, expect);
  // Every tet around a broken edge is damaged (fig 4.5): interior edges have several.
  EXPECT_GT(expect.size(), events.size());
}

TEST(FractureCriterion, BuildRejectsBadSettings) {
  const TetMesh m = gen::box(1, 1, 1, 1, 1, 1);
  const EdgeGraph g = EdgeGraph::build(m.tets.data(), m.tetCount(), m.nodeCount());
  FractureSettings s;
  s.strength = -1;
  auto r = FractureModel::build(restView(m), g, s);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("strength"), std::string::npos);
  s.strength = 1e6;
  s.radius = std::nan("");
  r = FractureModel::build(restView(m), g, s);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("radius"), std::string::npos);
}

}  // namespace
}  // namespace gf::detail
