// The device backend's element pass (gpu/element_pass.cu) against the CPU executor on the same
// bodies: per-tet energies, gradients, projected Hessians and criterion stresses, the energy
// sum and the node gradients. Bodies are torn by moving grips until elements are damaged, for
// every material model, both damage models, with fibres, a plastic stretch and tets of
// detached fragments. Built twice: against the host build of the device sources (label
// `backend`, runs in CI) and, where CUDA is built, against graphfrac_cuda (labels `backend`
// and `gpu`; skipped, and reported as skipped, where no device exists).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "fem/integrator.h"
#include "fracture/fracture_body.h"
#include "gpu/element_pass.h"
#include "graphfrac/mesh.h"
#include "step/executor.h"

namespace gf {
namespace {

using detail::FemModel;
using detail::FemState;

struct Case {
  MaterialModel material;
  DamageModel damage;
  bool fibres, plastic;
};

std::string caseName(const testing::TestParamInfo<Case>& info) {
  static const char* const kMaterial[] = {"Corotated", "StVK", "NeoHookean", "StableNeoHookean"};
  const Case& c = info.param;
  return std::string(kMaterial[int(c.material)]) +
         (c.damage == DamageModel::Projection ? "Projection" : "Degradation") +
         (c.fibres ? "Fibres" : "") + (c.plastic ? "Plastic" : "");
}

// A bar of which both ends are pulled apart until edges break near the middle.
struct TornBody {
  FemModel model;
  FemState state;
  std::unique_ptr<detail::FractureBody> fracture;
  std::unique_ptr<detail::Integrator> integrator;
};

void tear(const Case& c, TornBody& b) {
  BodyDef def;
  def.mesh = gen::box(0.3, 0.1, 0.1, 9, 3, 3);
  def.material.model = c.material;
  def.material.youngsModulus = 1e6;
  def.material.poissonRatio = 0.3;
  if (c.fibres) {
    def.material.fibreStiffness = 5e5;
    // A per-tet field (a twist about the bar's axis), not one direction: the device must read
    // the field.
    for (size_t t = 0; t < def.mesh.tetCount(); ++t) {
      const float a = 0.01f * float(t);
      def.fibreField.push_back({std::cos(a), std::sin(a), 0.5f});
    }
  }
  def.fracture.enabled = true;
  def.fracture.strength = 1.5e5;
  def.fracture.model = c.damage;
  def.grips.resize(2);
  def.grips[0].velocity = {-0.5f, 0, 0};
  def.grips[1].velocity = {0.5f, 0, 0};
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    const double x = def.mesh.positions[3 * n];
    if (std::fabs(x) < 1e-9) def.grips[0].nodes.push_back(int32_t(n));
    if (std::fabs(x - 0.3) < 1e-9) def.grips[1].nodes.push_back(int32_t(n));
  }
  b.model = detail::buildFemModel(def);
  const FemModel& m = b.model;
  b.state = detail::buildFemState(def, m);
  auto fb = detail::FractureBody::create(m, b.state, serialJobs());
  ASSERT_TRUE(fb.ok()) << fb.error().message;
  b.fracture = std::move(fb.value());
  if (c.plastic) {
    // A uniform volume-preserving plastic stretch, as World keeps it (Dm^-1 Fp^-1, eq 2.3).
    Mat3 FpInv;
    FpInv(0, 0) = 1 / 1.1;
    FpInv(1, 1) = FpInv(2, 2) = std::sqrt(1.1);
    b.state.plasticInverse.clear();
    for (const Mat3& r : m.restInverse) b.state.plasticInverse.push_back(r * FpInv);
  }
  b.integrator = std::make_unique<detail::Integrator>(m);
  ASSERT_TRUE(b.integrator->setupSolver(m, b.state).ok());
  b.integrator->attach(b.fracture.get());
  detail::StepContext ctx;
  ctx.dt = 2e-3;
  for (int s = 0; s < 100 && b.fracture->brokenCount() == 0; ++s)
    (void)b.integrator->step(m, b.state, ctx, serialJobs());
  for (int s = 0; s < 2; ++s) (void)b.integrator->step(m, b.state, ctx, serialJobs());
  // Tets of a fragment handed to rigid physics skip the element physics.
  b.state.rigidTet.assign(size_t(m.tetCount), 0);
  for (int32_t t = 0; t < m.tetCount; t += 13) b.state.rigidTet[size_t(t)] = 1;
}

// Largest |a - b| over the largest |a|, so round-off in a big entry does not hide in a ratio.
double relativeDifference(const std::vector<double>& a, const std::vector<double>& b) {
  double diff = 0, scale = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    diff = std::max(diff, std::fabs(a[i] - b[i]));
    scale = std::max(scale, std::fabs(a[i]));
  }
  return scale > 0 ? diff / scale : diff;
}

class ElementBackend : public testing::TestWithParam<Case> {};

TEST_P(ElementBackend, MatchesTheCpuExecutor) {
  std::string why;
  if (!gpu::deviceAvailable(why)) GTEST_SKIP() << why;
  TornBody b;
  ASSERT_NO_FATAL_FAILURE(tear(GetParam(), b));
  const FemModel& m = b.model;
  const size_t nt = size_t(m.tetCount), nn = size_t(m.nodeCount);
  int32_t damaged = 0, rigid = 0;
  for (size_t t = 0; t < nt; ++t) {
    damaged += b.fracture->tetMask()[t] != 0 && !b.state.rigidTet[t];
    rigid += b.state.rigidTet[t];
  }
  ASSERT_GT(damaged, 0) << "the pull broke no edge: the comparison would miss damaged tets";

  struct Out {
    std::vector<double> energy, grad, hess, stress, nodeGrad;
    double psi = 0;
  };
  auto sized = [&] {
    Out o;
    o.energy.assign(nt, 0);
    o.grad.assign(12 * nt, 0);
    o.hess.assign(kElementMatrixSize * nt, 0);
    o.stress.assign(6 * nt, 0);
    o.nodeGrad.assign(3 * nn, 0);
    return o;
  };
  Out cpu = sized(), dev = sized();
  const detail::ElementStage stage =
      b.integrator->elementStage(m, b.state, b.state.x.data(), cpu.energy.data(), cpu.grad.data(),
                                 cpu.hess.data(), cpu.stress.data());
  const detail::GatherStage gather =
      b.integrator->gatherStage(cpu.grad.data(), cpu.nodeGrad.data());
  ThreadPoolJobSystem jobs(2);
  const detail::CpuExecutor exec(jobs);
  exec.run(m.tetCount, 64, stage);
  cpu.psi = exec.sum(cpu.energy.data(), m.tetCount);
  exec.run(m.nodeCount, 64, gather);

  gpu::DeviceElementPass pass;
  ASSERT_TRUE(pass.upload(stage, gather, m.tetCount, m.nodeCount)) << pass.error();
  ASSERT_TRUE(pass.run(/*withHessian=*/true, /*withStress=*/true)) << pass.error();
  dev.psi = pass.energy();
  ASSERT_TRUE(pass.download(dev.energy.data(), dev.grad.data(), dev.hess.data(), dev.stress.data(),
                            dev.nodeGrad.data()))
      << pass.error();

  // Damaged tets' stresses are FractureBody's to write (ElementStage::stress), so neither
  // executor defines them: compare the others.
  for (size_t t = 0; t < nt; ++t)
    if (b.fracture->tetMask()[t] != 0 && !b.state.rigidTet[t])
      std::fill_n(dev.stress.begin() + 6 * std::ptrdiff_t(t), 6, cpu.stress[6 * t]);
  const double dEnergy = relativeDifference(cpu.energy, dev.energy);
  const double dGrad = relativeDifference(cpu.grad, dev.grad);
  const double dHess = relativeDifference(cpu.hess, dev.hess);
  const double dStress = relativeDifference(cpu.stress, dev.stress);
  const double dNode = relativeDifference(cpu.nodeGrad, dev.nodeGrad);
  const double dPsi = std::fabs(cpu.psi - dev.psi) / std::fabs(cpu.psi);
  std::printf(
      "  %s on %s: %d tets (%d damaged, %d rigid), psi %.6g J; max relative difference: energy "
      "%.1e, gradient %.1e, Hessian %.1e, stress %.1e, node gradient %.1e, sum %.1e\n",
      caseName(testing::TestParamInfo<Case>(GetParam(), 0)).c_str(), gpu::deviceName().c_str(),
      m.tetCount, damaged, rigid, cpu.psi, dEnergy, dGrad, dHess, dStress, dNode, dPsi);
  EXPECT_GT(cpu.psi, 0);
  // One source: on the host the same bits; a device may contract multiply-adds differently,
  // which moves results by a few ulps of the largest entry, far below this bound.
  const double tol = 1e-10;
  EXPECT_LE(dEnergy, tol);
  EXPECT_LE(dGrad, tol);
  EXPECT_LE(dHess, tol);
  EXPECT_LE(dStress, tol);
  EXPECT_LE(dNode, tol);
  EXPECT_LE(dPsi, tol);
}

std::vector<Case> allCases() {
  std::vector<Case> cases;
  for (MaterialModel mat : {MaterialModel::Corotated, MaterialModel::StVK,
                            MaterialModel::NeoHookean, MaterialModel::StableNeoHookean})
    for (DamageModel d : {DamageModel::Projection, DamageModel::Degradation})
      cases.push_back({mat, d, false, false});
  cases.push_back({MaterialModel::StableNeoHookean, DamageModel::Projection, true, false});
  cases.push_back({MaterialModel::StableNeoHookean, DamageModel::Degradation, true, true});
  cases.push_back({MaterialModel::NeoHookean, DamageModel::Projection, false, true});
  return cases;
}

// The host build (gf_backend_tests) and the CUDA build (gf_gpu_tests) name their cases apart.
#if defined(GF_GPU_CUDA)
INSTANTIATE_TEST_SUITE_P(Device, ElementBackend, testing::ValuesIn(allCases()), caseName);
#else
INSTANTIATE_TEST_SUITE_P(HostBuild, ElementBackend, testing::ValuesIn(allCases()), caseName);
#endif

}  // namespace
}  // namespace gf
