#include "fracture/criterion.h"

#include <algorithm>

#include "step/executor.h"

namespace gf::detail {

namespace {

constexpr uint32_t kTetGrain = 256;

CriterionEdges edgesOf(const FractureModel& model, const EdgeGraph& graph, const double* strength,
                       const uint8_t* broken) {
  return {graph.tetEdges.data(), model.edgeDirections.data(), strength, broken};
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

CriterionView criterionView(const FractureModel& model, const EdgeGraph& graph,
                            const double* strength, const uint8_t* broken, CriterionWorkspace& ws) {
  const size_t T = size_t(model.tetCount), E = size_t(model.edgeCount);
  ws.candidates.resize(T);
  ws.edgeFlag.resize(E);
  ws.edgeStress.resize(E);
  ws.edgeTet.resize(E);
  ws.candidateEdges.resize(E);
  const int32_t chunks = (model.edgeCount + kCompactChunk - 1) / kCompactChunk;
  ws.chunkCount.resize(size_t(chunks));
  ws.chunkOffset.resize(size_t(chunks) + 1);
  CriterionView v;
  v.edges = edgesOf(model, graph, strength, broken);
  v.nonLocal = model.nonLocal();
  if (v.nonLocal) {
    v.grid = gridOf(model.grid);
    v.cells = int32_t(model.grid.start.size() - 1);
    v.average = averageOf(model);
    ws.bound.resize(T);
    ws.cellMax.resize(size_t(v.cells));
    ws.averaged.resize(6 * T);
  }
  v.tetCount = model.tetCount;
  v.edgeCount = model.edgeCount;
  v.edgeTetStart = graph.edgeTetStart.data();
  v.edgeTets = graph.edgeTets.data();
  v.averaged = ws.averaged.data();
  v.candidates = ws.candidates.data();
  v.bound = ws.bound.data();
  v.cellMax = ws.cellMax.data();
  v.edgeFlag = ws.edgeFlag.data();
  v.edgeStress = ws.edgeStress.data();
  v.edgeTet = ws.edgeTet.data();
  v.chunkCount = ws.chunkCount.data();
  v.chunkOffset = ws.chunkOffset.data();
  v.candidateEdges = ws.candidateEdges.data();
  return v;
}

int32_t breakCandidates(const EdgeGraph& graph, const CriterionWorkspace& ws, int32_t count,
                        std::vector<uint8_t>& broken, std::vector<EdgeBreak>& events,
                        JobSystem& jobs, const double* positions) {
  // The decision in edge-id order (eq 4.12): every candidate breaks, its events follow the
  // list's order. Damage is only ever set, never cleared.
  const size_t first = events.size();
  events.resize(first + size_t(count));
  CpuExecutor(jobs).run(
      count, 256,
      BreakEventStage{ws.candidateEdges.data(), ws.edgeStress.data(), ws.edgeTet.data(),
                      graph.edgeNodes.data(), positions, broken.data(), events.data() + first});
  return count;
}

int32_t evaluateCriterion(const FractureModel& model, const EdgeGraph& graph,
                          const double* strength, const double* tetStress,
                          std::vector<uint8_t>& broken, std::vector<EdgeBreak>& events,
                          CriterionWorkspace& ws, JobSystem& jobs, const double* positions) {
  GF_ASSERT(broken.size() == size_t(model.edgeCount) && graph.edgeCount == model.edgeCount,
            "evaluateCriterion: broken flags, graph and model disagree on the edge count");
  if (broken.size() != size_t(model.edgeCount) || graph.edgeCount != model.edgeCount) return 0;
  const CpuExecutor exec(jobs);
  const CriterionView v = criterionView(model, graph, strength, broken.data(), ws);
  const int32_t count = findCandidateEdges(exec, v, tetStress, exec.min(strength, model.edgeCount),
                                           [](const int32_t* p) { return *p; });
  return breakCandidates(graph, ws, count, broken, events, jobs, positions);
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
