// Water transport and wet stiffness of a body (sculpt/wetting.h).
#include "sculpt/wetting.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "step/executor.h"

namespace gf::detail {

namespace {
constexpr uint32_t kTetGrain = 256;
constexpr uint32_t kFaceGrain = 512;

Vec3 restNode(const FemModel& m, int32_t n) {
  return {m.restPositions[3 * size_t(n)], m.restPositions[3 * size_t(n) + 1],
          m.restPositions[3 * size_t(n) + 2]};
}
Vec3 restCentroid(const FemModel& m, int32_t t) {
  Vec3 c;
  for (int a = 0; a < 4; ++a) c += restNode(m, m.tets[4 * size_t(t) + a]);
  return 0.25 * c;
}
}  // namespace

WettingModel buildWettingModel(const FemModel& model, const WettingSettings& settings) {
  WettingModel w;
  w.settings = settings;
  const int32_t nt = model.tetCount;
  const double cap = settings.waterDensity * settings.porosity;
  w.capacity.resize(size_t(nt));
  for (int32_t t = 0; t < nt; ++t) w.capacity[size_t(t)] = cap * model.restVolume[size_t(t)];

  // Interior faces: the sorted node triples that two tets share.
  struct FaceRef {
    std::array<int32_t, 3> key;
    int32_t tet;
  };
  std::vector<FaceRef> refs;
  refs.reserve(4 * size_t(nt));
  for (int32_t t = 0; t < nt; ++t) {
    const int32_t* n = &model.tets[4 * size_t(t)];
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int32_t, 3> k{};
      int j = 0;
      for (int a = 0; a < 4; ++a)
        if (a != skip) k[size_t(j++)] = n[a];
      std::sort(k.begin(), k.end());
      refs.push_back({k, t});
    }
  }
  std::sort(refs.begin(), refs.end(), [](const FaceRef& a, const FaceRef& b) {
    return a.key != b.key ? a.key < b.key : a.tet < b.tet;
  });
  for (size_t i = 0; i + 1 < refs.size(); ++i) {
    if (refs[i].key != refs[i + 1].key) continue;
    const int32_t a = refs[i].tet, b = refs[i + 1].tet;
    const Vec3 p0 = restNode(model, refs[i].key[0]), p1 = restNode(model, refs[i].key[1]),
               p2 = restNode(model, refs[i].key[2]);
    const double area = 0.5 * norm(cross(p1 - p0, p2 - p0));
    const double dist = norm(restCentroid(model, a) - restCentroid(model, b));
    w.faceTets.push_back(a);
    w.faceTets.push_back(b);
    w.conductance.push_back(dist > 0 ? cap * settings.diffusivity * area / dist : 0.0);
    ++i;  // a valid mesh has no face of three tets
  }
  const int32_t nf = int32_t(w.conductance.size());
  w.flux.assign(size_t(nf), 0.0);

  // CSR of each tet's faces, in face order (the gather's fixed summation order).
  w.tetFaceStart.assign(size_t(nt) + 1, 0);
  for (int32_t f = 0; f < nf; ++f) {
    ++w.tetFaceStart[size_t(w.faceTets[2 * size_t(f)]) + 1];
    ++w.tetFaceStart[size_t(w.faceTets[2 * size_t(f) + 1]) + 1];
  }
  for (int32_t t = 0; t < nt; ++t) w.tetFaceStart[size_t(t) + 1] += w.tetFaceStart[size_t(t)];
  w.tetFace.resize(size_t(w.tetFaceStart.back()));
  std::vector<int32_t> fill(w.tetFaceStart.begin(), w.tetFaceStart.end() - 1);
  std::vector<double> rate(size_t(nt), 0.0);
  for (int32_t f = 0; f < nf; ++f)
    for (int side = 0; side < 2; ++side) {
      const int32_t t = w.faceTets[2 * size_t(f) + size_t(side)];
      w.tetFace[size_t(fill[size_t(t)]++)] = 2 * f + side;
      rate[size_t(t)] += w.conductance[size_t(f)];
    }
  for (int32_t t = 0; t < nt; ++t)
    if (w.capacity[size_t(t)] > 0)
      w.rateBound = std::max(w.rateBound, rate[size_t(t)] / w.capacity[size_t(t)]);
  return w;
}

void updateCrackBarriers(const FemModel& model, WettingModel& w, const int32_t* nodeFragment,
                         JobSystem& jobs) {
  const CpuExecutor exec(jobs);
  const int32_t nt = model.tetCount, nf = int32_t(w.conductance.size());
  w.owner.resize(size_t(nt));
  w.split.resize(size_t(nt));
  exec.run(nt, kTetGrain,
           CrackOwnerStage{model.tets.data(), nodeFragment, w.owner.data(), w.split.data()});
  if (!(exec.max(w.split.data(), nt) > 0)) {
    w.open.clear();
    return;
  }
  w.open.resize(size_t(nf));
  exec.run(nf, kFaceGrain,
           CrackOpenStage{model.tets.data(), nodeFragment, w.faceTets.data(), w.owner.data(),
                          w.open.data()});
}

int32_t diffusionSubsteps(const WettingModel& w, double dt) {
  return std::max<int32_t>(1, int32_t(std::ceil(dt * w.rateBound)));
}

void advanceWater(const FemModel& model, WettingModel& w, std::vector<double>& water,
                  const double* x, const std::vector<WaterStroke>& strokes, double dt,
                  JobSystem& jobs) {
  const CpuExecutor exec(jobs);
  for (const WaterStroke& s : strokes) {
    WaterBrushStage brush;
    brush.tets = model.tets.data();
    brush.x = x;
    brush.capacity = w.capacity.data();
    brush.centre = s.centre;
    brush.radius = s.radius;
    brush.delta = s.rate * dt;
    brush.water = water.data();
    exec.run(model.tetCount, kTetGrain, brush);
  }
  if (w.conductance.empty()) return;
  const int32_t n = diffusionSubsteps(w, dt);
  WaterFluxStage flux{w.faceTets.data(),
                      w.conductance.data(),
                      w.capacity.data(),
                      water.data(),
                      w.open.empty() ? nullptr : w.open.data(),
                      dt / n,
                      w.flux.data()};
  const WaterGatherStage gather{w.tetFaceStart.data(), w.tetFace.data(), w.flux.data(),
                                water.data()};
  for (int32_t k = 0; k < n; ++k) {
    exec.run(int32_t(w.conductance.size()), kFaceGrain, flux);
    exec.run(model.tetCount, kTetGrain, gather);
  }
}

void refreshWetStiffness(const FemModel& model, const WettingModel& w, FemState& state,
                         JobSystem& jobs) {
  state.tetLame.resize(2 * size_t(model.tetCount));
  WetStiffnessStage stage;
  stage.water = state.water.data();
  stage.capacity = w.capacity.data();
  stage.porosity = w.settings.porosity;
  stage.solid = isoFromYoung(state.material.youngsModulus, state.material.poissonRatio);
  stage.fluid = {w.settings.waterBulkModulus, 0.0};
  stage.model = state.coeffs.model;
  stage.tetLame = state.tetLame.data();
  CpuExecutor(jobs).run(model.tetCount, kTetGrain, stage);
}

}  // namespace gf::detail
