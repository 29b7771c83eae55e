#include "fracture/criterion.h"

#include <algorithm>
#include <limits>

#include "step/executor.h"

namespace gf::detail {

namespace {

constexpr uint32_t kTetGrain = 256;

CriterionEdges edgesOf(const FractureModel& model, const EdgeGraph& graph, const uint8_t* broken) {
  return {graph.tetEdges.data(), model.edgeDirections.data(), model.strength.data(), broken};
}

NonlocalAverage averageOf(const FractureModel& model) {
  return {model.neighbourStart.data(), model.neighbourIndex.data(), model.neighbourWeight.data()};
}

GridView gridOf(const CentroidGrid& g) {
  return {{g.dims[0], g.dims[1], g.dims[2]}, g.start.data(), g.items.data(), g.tetCell.data()};
}

}  // namespace

void averageStress(const FractureModel& model, const double* tetStress, double* out,
                   JobSystem& jobs) {
  if (!model.nonLocal()) {
    std::copy(tetStress, tetStress + 6 * size_t(model.tetCount), out);
    return;
  }
  CpuExecutor(jobs).run(model.tetCount, kTetGrain, AverageStage{averageOf(model), tetStress, out});
}

int32_t evaluateCriterion(const FractureModel& model, const EdgeGraph& graph,
                          const double* tetStress, std::vector<uint8_t>& broken,
                          std::vector<EdgeBreak>& events, CriterionWorkspace& ws, JobSystem& jobs,
                          const double* positions) {
  GF_ASSERT(broken.size() == size_t(model.edgeCount) && graph.edgeCount == model.edgeCount,
            "evaluateCriterion: broken flags, graph and model disagree on the edge count");
  if (broken.size() != size_t(model.edgeCount) || graph.edgeCount != model.edgeCount) return 0;
  const size_t T = size_t(model.tetCount);
  const uint8_t* flags = broken.data();
  ws.candidates.resize(T);

  const CpuExecutor exec(jobs);
  const CriterionEdges edges = edgesOf(model, graph, flags);
  const double weakest = exec.min(model.strength.data(), model.edgeCount);
  if (!model.nonLocal()) {
    exec.run(model.tetCount, 512,
             LocalCandidateStage{edges, tetStress, weakest, ws.candidates.data()});
  } else {
    // Bound first: per tet, per cell, and against the weakest edge of the body.
    const CentroidGrid& grid = model.grid;
    const int32_t cells = int32_t(grid.start.size() - 1);
    ws.bound.resize(T);
    ws.cellMax.resize(size_t(cells));
    ws.averaged.resize(6 * T);
    exec.run(model.tetCount, 1024, StressBoundStage{tetStress, ws.bound.data()});
    exec.run(cells, 1024, CellMaxStage{gridOf(grid), ws.bound.data(), ws.cellMax.data()});
    if (!(exec.max(ws.cellMax.data(), cells) >= weakest)) {
      std::fill(ws.candidates.begin(), ws.candidates.end(), uint8_t(0));
      return 0;
    }
    exec.run(model.tetCount, kTetGrain,
             NonlocalCandidateStage{edges, gridOf(grid), averageOf(model), tetStress,
                                    ws.cellMax.data(), ws.averaged.data(), ws.candidates.data()});
  }

  ws.candidateEdges.clear();
  for (size_t t = 0; t < T; ++t) {
    const uint8_t mask = ws.candidates[t] & kEdgeBits;
    if (!mask) continue;
    for (int k = 0; k < 6; ++k)
      if (mask & (1u << k)) ws.candidateEdges.push_back(graph.tetEdges[6 * t + k]);
  }
  if (ws.candidateEdges.empty()) return 0;
  std::sort(ws.candidateEdges.begin(), ws.candidateEdges.end());
  ws.candidateEdges.erase(std::unique(ws.candidateEdges.begin(), ws.candidateEdges.end()),
                          ws.candidateEdges.end());

  // Serial decision in edge-id order (eq 4.12): the reporting tet is the incident tet with the
  // largest normal stress; tets the bound skipped cannot reach this edge's strength, so they
  // never report. Damage is only ever set, never cleared.
  int32_t count = 0;
  for (const int32_t edge : ws.candidateEdges) {
    double best = -std::numeric_limits<double>::infinity();
    int32_t bestTet = -1;
    for (int32_t s = graph.edgeTetStart[edge]; s < graph.edgeTetStart[edge + 1]; ++s) {
      const int32_t slot = graph.edgeTets[size_t(s)];
      const size_t t = size_t(slot / 6);
      const double* S = tetStress + 6 * t;
      if (model.nonLocal()) {
        if (!(ws.candidates[t] & kAveragedBit)) continue;
        S = &ws.averaged[6 * t];
      }
      const double sig = edgeNormalStress(S, &model.edgeDirections[18 * t + 3 * (slot % 6)]);
      if (sig > best) {
        best = sig;
        bestTet = int32_t(t);
      }
    }
    broken[size_t(edge)] = 1;
    EdgeBreak ev;
    ev.edge = edge;
    ev.tet = bestTet;
    ev.stress = best;
    ev.split = 0.5;
    if (positions) {
      const double* xa = positions + 3 * size_t(graph.edgeNodes[2 * size_t(edge)]);
      const double* xb = positions + 3 * size_t(graph.edgeNodes[2 * size_t(edge) + 1]);
      ev.position = {0.5 * (xa[0] + xb[0]), 0.5 * (xa[1] + xb[1]), 0.5 * (xa[2] + xb[2])};
    }
    events.push_back(ev);
    ++count;
  }
  return count;
}

void brokenEdgeMasks(const EdgeGraph& graph, const uint8_t* broken, uint8_t* masks,
                     JobSystem& jobs) {
  CpuExecutor(jobs).run(int32_t(graph.tetEdges.size() / 6), 1024,
                        EdgeMaskStage{graph.tetEdges.data(), broken, masks});
}

void applyBreaksToMasks(const EdgeGraph& graph, const EdgeBreak* events, size_t count,
                        uint8_t* masks) {
  for (size_t i = 0; i < count; ++i) {
    const int32_t edge = events[i].edge;
    for (int32_t s = graph.edgeTetStart[edge]; s < graph.edgeTetStart[edge + 1]; ++s) {
      const int32_t slot = graph.edgeTets[size_t(s)];
      masks[slot / 6] |= uint8_t(1u << (slot % 6));
    }
  }
}

std::vector<int32_t> damagedTets(const EdgeGraph& graph, const uint8_t* broken) {
  const size_t T = graph.tetEdges.size() / 6;
  std::vector<int32_t> out;
  for (size_t t = 0; t < T; ++t)
    for (int k = 0; k < 6; ++k)
      if (broken[graph.tetEdges[6 * t + k]]) {
        out.push_back(int32_t(t));
        break;
      }
  return out;
}

}  // namespace gf::detail
