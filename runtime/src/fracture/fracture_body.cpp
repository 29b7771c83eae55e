#include "fracture/fracture_body.h"

#include <algorithm>
#include <atomic>

#include "fracture/brittle.h"
#include "graphfrac/events.h"
#include "kernels/damage.h"
#include "kernels/edge_stress.h"
#include "kernels/element.h"
#include "kernels/split_point.h"
#include "step/executor.h"

namespace gf::detail {

namespace {
constexpr uint32_t kTetGrain = 256;

Vec3 load3(const double* p, int32_t i) { return {p[3 * i], p[3 * i + 1], p[3 * i + 2]}; }

uint8_t cause(FractureEvent::Cause c) { return static_cast<uint8_t>(c); }

// A tet whose corners fall into pieces no unbroken edge of it joins (rule after eq 4.33).
bool tetSplit(const EdgeGraph& g, const uint8_t* broken, int32_t t) {
  uint8_t local[6];
  for (int k = 0; k < 6; ++k) local[k] = broken[g.tetEdges[6 * size_t(t) + size_t(k)]];
  return cornersDisconnected(local);
}
}  // namespace

Result<std::unique_ptr<FractureBody>> FractureBody::create(const FemModel& fem,
                                                           const FemState& data, JobSystem& jobs) {
  auto fb = std::make_unique<FractureBody>();
  const size_t nt = fem.tetCount, nn = fem.nodeCount;
  fb->m_graph = EdgeGraph::build(fem.tets.data(), nt, nn);
  const RestMeshView rest{fem.restPositions.data(), fem.tets.data(), fem.nodeCount, fem.tetCount};
  FibreView fibres;
  fibres.present = data.coeffs.fibreMu > 0;
  fibres.constant = data.coeffs.fibreDir;
  if (!fem.fibreDir.empty()) fibres.perTet = fem.fibreDir.data();
  auto model = FractureModel::build(rest, fb->m_graph, fem.fracture, &jobs, fibres);
  if (!model) return fail("BodyDef.fracture: ", model.error().message);
  fb->m_model = std::move(model.value());
  fb->m_data.strength = fb->m_model.strength;
  fb->m_damageModel = fem.fracture.model == DamageModel::Projection ? 0 : 1;

  fb->m_restDir.resize(6 * nt);
  if (fb->m_damageModel == 0) {
    fb->m_T.resize(nt);
    fb->m_Tinv.resize(nt);
  }
  for (size_t t = 0; t < nt; ++t) {
    Vec3 X[4];
    for (int a = 0; a < 4; ++a) X[a] = load3(fem.restPositions.data(), fem.tets[4 * t + a]);
    double L[6];
    restEdgeDirections(X, &fb->m_restDir[6 * t], L);
    if (fb->m_damageModel == 0) {
      fb->m_T[t] = gf::edgeMatrix(&fb->m_restDir[6 * t]);
      if (!invertEdgeMatrix(fb->m_T[t], fb->m_Tinv[t]))
        return fail("BodyDef.mesh: tet ", std::to_string(t),
                    ": too flat for the projection damage model (its edge matrix T is singular)");
    }
  }
  if (fem.fracture.splitPoint == SplitPoint::ForceRatio) {
    fb->m_data.splitRatio.assign(size_t(fb->m_graph.edgeCount), 0.5);
    fb->m_nodeRefStart.assign(nn + 1, 0);
    for (int32_t n : fem.tets) ++fb->m_nodeRefStart[size_t(n) + 1];
    for (size_t i = 0; i < nn; ++i) fb->m_nodeRefStart[i + 1] += fb->m_nodeRefStart[i];
    fb->m_nodeRef.resize(fem.tets.size());
    std::vector<int32_t> fill(fb->m_nodeRefStart.begin(), fb->m_nodeRefStart.end() - 1);
    for (size_t k = 0; k < fem.tets.size(); ++k)
      fb->m_nodeRef[size_t(fill[size_t(fem.tets[k])]++)] = int32_t(k);
  }
  fb->m_data.broken.assign(fb->m_graph.edgeCount, 0);
  fb->m_data.tetMask.assign(nt, 0);
  fb->m_data.chi.assign(nt, 1.0);
  fb->m_stress.assign(6 * nt, 0.0);
  fb->m_nodeVolume = Fragments::nodeVolumes(fem.tets.data(), nt, fem.restPositions.data(), nn);
  fb->m_data.fragments.build(CpuExecutor(jobs), fb->m_graph, fb->m_data.broken.data(),
                             fb->m_fragmentScratch);
  fb->m_data.chip.assign(size_t(fb->m_data.fragments.count()), 0);
  const FractureSettings& fs = fem.fracture;
  if (fs.impurities.enabled || !fs.impurityMaps.empty()) {
    fb->m_data.hasImpurity = true;
    fb->m_data.impurity.init(fb->m_graph, fs.impurities, fb->m_data.strength);
    for (size_t i = 0; i < fs.impurityMaps.size(); ++i)
      if (auto r = fb->applyImpurityMap(fem, fs.impurityMaps[i]); !r)
        return fail("BodyDef.fracture.impurityMaps[", std::to_string(i), "].", r.error().message);
    fb->m_data.impurity.refreshAll(fb->m_graph, fb->m_data.broken.data(), fb->m_data.strength);
  }
  return fb;
}

Result<void> FractureBody::applyImpurityMap(const FemModel& fem, const ImpurityMap& map) {
  const ImpurityRest rest{fem.restPositions.data(), fem.tets.data(), fem.nodeCount, fem.tetCount,
                          m_model.meanEdgeLength};
  auto edges = ImpurityField::mapEdges(m_graph, rest, map);
  if (!edges) return edges.error();
  if (!m_data.hasImpurity) {
    // Pure nodes everywhere: only the map's nodes will carry an impurity.
    ImpuritySettings pure = fem.fracture.impurities;
    pure.enabled = false;
    m_data.impurity.init(m_graph, pure, m_data.strength);
    for (int32_t e = 0; e < m_graph.edgeCount; ++e)
      if (m_data.broken[size_t(e)]) {
        --m_data.impurity.degree[size_t(m_graph.edgeNodes[2 * e])];
        --m_data.impurity.degree[size_t(m_graph.edgeNodes[2 * e + 1])];
      }
    m_data.hasImpurity = true;
  }
  m_data.impurity.applyMap(m_graph, edges.value(), map.potency);
  m_data.impurity.refreshAll(m_graph, m_data.broken.data(), m_data.strength);
  return {};
}

void FractureBody::setStrengths(std::vector<double> strength) {
  m_data.strength = std::move(strength);
  if (!m_data.hasImpurity) return;
  m_data.impurity.baseStrength = m_data.strength;
  m_data.impurity.refreshAll(m_graph, m_data.broken.data(), m_data.strength);
}

CriterionStressStage FractureBody::stressStage(const FemModel& fem, const FemState& data,
                                               const double* x, bool undamagedToo,
                                               double* svdCache) {
  CriterionStressStage s;
  s.tets = fem.tets.data();
  s.x = x;
  // The criterion judges the elastic stress of Fe = F Fp^-1 as the element pass does (eq 2.3).
  s.restInverse = data.plasticInverse.empty() ? fem.restInverse.data() : data.plasticInverse.data();
  s.coeffs = data.coeffs;
  s.fibreDir = fem.fibreDir.empty() ? nullptr : fem.fibreDir.data();
  s.tetLame = data.tetLame.empty() ? nullptr : data.tetLame.data();
  s.tetMask = m_data.tetMask.data();
  s.chi = m_data.chi.data();
  s.rigidTet = data.rigidTet.empty() ? nullptr : data.rigidTet.data();
  s.degradation = m_damageModel == 1;
  s.undamagedToo = undamagedToo;
  s.stress = m_stress.data();
  s.svdCache = svdCache;
  return s;
}

void FractureBody::computeStresses(const FemModel& fem, const FemState& data, const double* x,
                                   bool undamagedToo, double* svdCache, JobSystem& jobs) {
  CpuExecutor(jobs).run(fem.tetCount, kTetGrain, stressStage(fem, data, x, undamagedToo, svdCache));
}

ElementStage bodyElementStage(const FemModel& fem, const FemState& data,
                              const FractureBody* fracture, const double* x) {
  ElementStage s;
  s.tets = fem.tets.data();
  s.x = x;
  // Plastic elements see Fe = F Fp^-1 through an effective rest inverse (eq 2.3).
  s.restInverse = data.plasticInverse.empty() ? fem.restInverse.data() : data.plasticInverse.data();
  s.restVolume = fem.restVolume.data();
  s.coeffs = data.coeffs;
  s.fibreDir = fem.fibreDir.empty() ? nullptr : fem.fibreDir.data();
  if (fracture) {
    s.tetMask = fracture->tetMask();
    s.damageModel = fracture->damageModel();
    s.edgeMatrix = fracture->edgeMatrices();
    s.edgeMatrixInverse = fracture->edgeMatrixInverses();
    s.chi = fracture->chi();
  }
  s.rigidTet = data.rigidTet.empty() ? nullptr : data.rigidTet.data();
  s.tetLame = data.tetLame.empty() ? nullptr : data.tetLame.data();
  return s;
}

ElementStage FractureBody::elementStage(const FemModel& fem, const FemState& data,
                                        const double* x) const {
  return bodyElementStage(fem, data, this, x);
}

void FractureBody::computeSplits(size_t first, const FemModel& fem, const FemState& data,
                                 const double* x, JobSystem& jobs) {
  if (m_data.splitRatio.empty()) return;
  // Breaks with a geometric crossing (blade, brittle plane) split there, where the material
  // parts; stress breaks are contiguous in each batch and take their force ratio.
  size_t stressBegin = m_data.breaks.size(), stressEnd = first;
  for (size_t i = first; i < m_data.breaks.size(); ++i) {
    EdgeBreak& b = m_data.breaks[i];
    if (m_data.breakCause[i] == cause(FractureEvent::Cause::Stress)) {
      stressBegin = std::min(stressBegin, i);
      stressEnd = i + 1;
    } else {
      b.split = clampSplitRatio(b.split);
    }
  }
  if (stressBegin >= stressEnd) return;
  ForceRatioSplitStage stage;
  stage.element = elementStage(fem, data, x);
  stage.nodeRefStart = m_nodeRefStart.data();
  stage.nodeRef = m_nodeRef.data();
  stage.edgeNodes = m_graph.edgeNodes.data();
  stage.breaks = m_data.breaks.data() + stressBegin;
  CpuExecutor(jobs).run(int32_t(stressEnd - stressBegin), 16, stage);
}

void FractureBody::applyBreaks(size_t first, const FemModel& fem, const FemState& data,
                               const double* x, JobSystem& jobs) {
  if (first == m_data.breaks.size()) return;
  std::sort(m_data.breaks.begin() + long(first), m_data.breaks.end(),
            [](const EdgeBreak& a, const EdgeBreak& b) { return a.edge < b.edge; });
  if (!m_data.splitRatio.empty())
    for (size_t i = first; i < m_data.breaks.size(); ++i)
      m_data.splitRatio[size_t(m_data.breaks[i].edge)] = m_data.breaks[i].split;
  applyBreaksToMasks(m_graph, m_data.breaks.data() + first, m_data.breaks.size() - first,
                     m_data.tetMask.data());
  m_newEdges.clear();
  for (size_t i = first; i < m_data.breaks.size(); ++i) {
    m_newEdges.push_back(m_data.breaks[i].edge);
    // The lagged chi of every tet around the edge follows its new mask (eq 4.33).
    const int32_t e = m_data.breaks[i].edge;
    for (int32_t q = m_graph.edgeTetStart[e]; q < m_graph.edgeTetStart[e + 1]; ++q) {
      const int32_t t = m_graph.edgeTets[q] / 6;
      uint8_t brokenLocal[6];
      for (int k = 0; k < 6; ++k) brokenLocal[k] = (m_data.tetMask[t] >> k) & 1;
      double sigmaN[6];
      edgeNormalStresses(stressStage(fem, data, x, false).intactStress(t), &m_restDir[6 * t],
                         sigmaN);
      m_data.chi[t] = degradationFactor(sigmaN, brokenLocal);
    }
  }
  if (m_data.hasImpurity)
    m_data.impurity.onBreaks(m_graph, m_newEdges.data(), m_newEdges.size(), m_data.broken.data(),
                             m_data.strength);
  m_data.brokenCount += int32_t(m_data.breaks.size() - first);
  m_data.breakOrder.insert(m_data.breakOrder.end(), m_newEdges.begin(), m_newEdges.end());
  const CpuExecutor exec(jobs);
  if (m_data.fragments.update(exec, m_graph, m_data.broken.data(), m_newEdges, m_fragmentScratch)) {
    const auto s = m_data.fragments.splits();
    m_data.splits.insert(m_data.splits.end(), s.begin(), s.end());
    m_data.fragments.compute(exec, m_nodeVolume, data.nodeMass, x, data.v.data(), m_data.props,
                             m_fragmentScratch);
  }
  // Here, not in World::fractureStats: a game asks for the stats every frame, edges break rarely.
  findChips(jobs);
}

void FractureBody::findChips(JobSystem& jobs) {
  const std::span<const int32_t> nodeFragment = m_data.fragments.nodeFragment();
  m_data.chip.assign(size_t(m_data.fragments.count()), 1);
  // A tet that holds clears its fragment's flag; every write is a zero, so the tets' ranges may
  // run in any order.
  jobs.parallelFor(uint32_t(m_data.tetMask.size()), kTetGrain, [&](uint32_t b, uint32_t e) {
    for (int32_t t = int32_t(b); t < int32_t(e); ++t)
      if (m_data.tetMask[size_t(t)] == 0 || !tetSplit(m_graph, m_data.broken.data(), t))
        std::atomic_ref<uint8_t>(
            m_data.chip[size_t(
                nodeFragment[size_t(m_graph.edgeNodes[2 * m_graph.tetEdges[6 * size_t(t)]])])])
            .store(0, std::memory_order_relaxed);
  });
  m_data.chips = int32_t(std::count(m_data.chip.begin(), m_data.chip.end(), uint8_t(1)));
}

void FractureBody::releaseSevered(size_t first, const double* x, bool keepSlices) {
  // Projection keeps a lone edge's own strain in a split tet (kernels/damage.h): it still holds.
  if (m_damageModel != kDamageDegradation) return;
  const EdgeGraph& g = m_graph;
  const uint8_t* broken = m_data.broken.data();
  auto whole = [&](int32_t node) {  // the node has a whole tet: it belongs to a piece
    for (int32_t q = g.nodeEdgeStart[node]; q < g.nodeEdgeStart[node + 1]; ++q) {
      const int32_t e = g.nodeEdges[size_t(q)];
      for (int32_t r = g.edgeTetStart[e]; r < g.edgeTetStart[e + 1]; ++r)
        if (!tetSplit(g, broken, g.edgeTets[size_t(r)] / 6)) return true;
    }
    return false;
  };
  // A chip that an unbroken edge still joins to a piece: that edge is severed and goes in this
  // batch, so the chip is the skin of a piece, not part of a slice the blades cut out whole.
  auto touchesPiece = [&](int32_t node) {
    for (int32_t q = g.nodeEdgeStart[node]; q < g.nodeEdgeStart[node + 1]; ++q) {
      const int32_t e = g.nodeEdges[size_t(q)];
      if (broken[e]) continue;
      const int32_t other =
          g.edgeNodes[2 * e] == node ? g.edgeNodes[2 * e + 1] : g.edgeNodes[2 * e];
      if (whole(other)) return true;
    }
    return false;
  };
  auto inSlice = [&](int32_t node) { return !whole(node) && !touchesPiece(node); };
  // Decided on the broken flags before this batch's releases (they remove the evidence of
  // touchesPiece), applied after.
  std::vector<std::pair<int32_t, int32_t>> release;  // (edge, the split tet it was found in)
  m_releaseMark.resize(m_data.broken.size(), 0);
  const size_t end = m_data.breaks.size();
  for (size_t i = first; i < end; ++i) {
    const int32_t e = m_data.breaks[i].edge;
    for (int32_t q = g.edgeTetStart[e]; q < g.edgeTetStart[e + 1]; ++q) {
      const int32_t t = g.edgeTets[size_t(q)] / 6;
      if (!tetSplit(g, broken, t)) continue;
      for (int k = 0; k < 6; ++k) {
        const int32_t f = g.tetEdges[6 * size_t(t) + size_t(k)];
        if (broken[f] || m_releaseMark[size_t(f)]) continue;
        bool held = false;
        for (int32_t r = g.edgeTetStart[f]; r < g.edgeTetStart[f + 1] && !held; ++r)
          held = !tetSplit(g, broken, g.edgeTets[size_t(r)] / 6);
        if (held) continue;
        if (keepSlices && inSlice(g.edgeNodes[2 * f]) && inSlice(g.edgeNodes[2 * f + 1])) continue;
        m_releaseMark[size_t(f)] = 1;
        release.emplace_back(f, t);
      }
    }
  }
  for (const auto& [f, t] : release) {
    m_releaseMark[size_t(f)] = 0;
    m_data.broken[size_t(f)] = 1;
    EdgeBreak b;
    b.edge = f;
    b.tet = t;
    b.position = 0.5 * (load3(x, g.edgeNodes[2 * f]) + load3(x, g.edgeNodes[2 * f + 1]));
    m_data.breaks.push_back(b);
    m_data.breakCause.push_back(cause(FractureEvent::Cause::Severed));
  }
}

int32_t FractureBody::detect(const FemModel& fem, const FemState& data, const double* x,
                             JobSystem& jobs, bool stressesReady, double* svdCache,
                             CriterionDevice* device) {
  m_data.breaks.clear();
  m_data.breakCause.clear();
  m_data.splits.clear();
  for (PendingCut& cut : m_data.pendingCuts) {
    const size_t first = m_data.breaks.size();
    // Validated by World::cut, so the result cannot fail here.
    (void)cutEdges(m_graph, x, cut.blade, cut.from, cut.to, m_data.broken, m_data.breaks, m_cutWs,
                   jobs);
    m_data.breakCause.resize(m_data.breaks.size(), cause(FractureEvent::Cause::Cut));
    if (fem.fracture.releaseEveryBatch) releaseSevered(first, x, true);
    finishBatch(first, fem, data, x, jobs);
  }
  m_data.pendingCuts.clear();
  if (m_data.hasImpurity && !m_data.impurity.pendingPrecut.empty()) {
    // Potency-0 maps are sharp pre-cuts (sec 5.4): their edges open like a blade's.
    const size_t first = m_data.breaks.size();
    for (int32_t e : m_data.impurity.pendingPrecut) {
      if (m_data.broken[size_t(e)]) continue;
      m_data.broken[size_t(e)] = 1;
      EdgeBreak b;
      b.edge = e;
      b.position =
          0.5 * (load3(x, m_graph.edgeNodes[2 * e]) + load3(x, m_graph.edgeNodes[2 * e + 1]));
      m_data.breaks.push_back(b);
    }
    m_data.impurity.pendingPrecut.clear();
    m_data.breakCause.resize(m_data.breaks.size(), cause(FractureEvent::Cause::Cut));
    if (fem.fracture.releaseEveryBatch) releaseSevered(first, x, true);
    finishBatch(first, fem, data, x, jobs);
  }

  size_t first = m_data.breaks.size();
  // On a device, the stresses stay there (with stressesReady its element pass wrote those of
  // the undamaged tets) and only the candidates come back; m_stress is then read back only
  // where brittle planes need it.
  int32_t n = -1;
  bool stressesHere = true;
  if (device && device->stresses(stressStage(fem, data, x, !stressesReady))) {
    const CriterionView view =
        criterionView(m_model, m_graph, m_data.strength.data(), m_data.broken.data(), m_ws);
    const int32_t count =
        device->candidates(view, CpuExecutor(jobs).min(m_data.strength.data(), m_model.edgeCount));
    if (count >= 0) {
      n = breakCandidates(m_graph, m_ws, count, m_data.broken, m_data.breaks, jobs, x);
      stressesHere = false;
    }
  }
  if (n < 0) {
    // Stresses ready on a device that failed are not here.
    computeStresses(fem, data, x, !stressesReady || device, svdCache, jobs);
    n = evaluateCriterion(m_model, m_graph, m_data.strength.data(), m_stress.data(), m_data.broken,
                          m_data.breaks, m_ws, jobs, x);
  }
  m_data.breakCause.resize(m_data.breaks.size(), cause(FractureEvent::Cause::Stress));
  releaseSevered(first, x, false);
  const size_t brittleFirst = m_data.breaks.size();
  if (n > 0 && fem.fracture.brittle && !m_data.brittleFired) {
    // Brittle mode: the first time the criterion fires, the most stressed regions start
    // crack planes through the whole body (sec 4.5.1.2).
    m_data.brittleFired = true;
    if (!stressesHere && !device->readStresses(m_stress.data()))
      computeStresses(fem, data, x, true, svdCache, jobs);
    const RestMeshView rest{fem.restPositions.data(), fem.tets.data(), fem.nodeCount, fem.tetCount};
    const double* seedStress = m_stress.data();
    std::vector<double> averaged;  // once per body: no need to keep it
    if (m_model.nonLocal()) {
      averaged.resize(m_stress.size());
      averageStress(m_model, m_stress.data(), averaged.data(), jobs);
      seedStress = averaged.data();
    }
    const auto seeds = startBrittleCracks(m_model, m_graph, rest, m_data.strength.data(),
                                          seedStress, m_data.broken, m_data.breaks, jobs, x);
    m_data.breakCause.resize(m_data.breaks.size(), cause(FractureEvent::Cause::BrittlePlane));
    // The severed edges the planes' batch released itself (a node it gave to a piece) come last.
    size_t released = 0;
    if (seeds.ok())
      for (const BrittleSeed& s : seeds.value()) released += size_t(s.edgesReleased);
    std::fill(m_data.breakCause.end() - std::ptrdiff_t(released), m_data.breakCause.end(),
              cause(FractureEvent::Cause::Severed));
    // The planes split tets of their own; the criterion's releases above saw none of them.
    if (fem.fracture.releaseEveryBatch) releaseSevered(brittleFirst, x, false);
  }
  finishBatch(first, fem, data, x, jobs);
  return int32_t(m_data.breaks.size());
}

void FractureBody::finishBatch(size_t first, const FemModel& fem, const FemState& data,
                               const double* x, JobSystem& jobs) {
  if (m_data.breaks.size() == first) return;
  computeSplits(first, fem, data, x, jobs);
  // Keep each cause with its break through the sort in applyBreaks.
  std::vector<std::pair<int32_t, uint8_t>> causes;
  for (size_t i = first; i < m_data.breaks.size(); ++i)
    causes.push_back({m_data.breaks[i].edge, m_data.breakCause[i]});
  std::sort(causes.begin(), causes.end());
  applyBreaks(first, fem, data, x, jobs);
  for (size_t i = first; i < m_data.breaks.size(); ++i)
    m_data.breakCause[i] = causes[i - first].second;
}

}  // namespace gf::detail
