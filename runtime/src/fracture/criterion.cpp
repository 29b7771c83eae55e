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

int32_t evaluateCriterion(const FractureModel& model, const EdgeGraph& graph,
                          const double* strength, const double* tetStress,
                          std::vector<uint8_t>& broken, std::vector<EdgeBreak>& events,
                          CriterionWorkspace& ws, JobSystem& jobs, const double* positions) {
  GF_ASSERT(broken.size() == size_t(model.edgeCount) && graph.edgeCount == model.edgeCount,
            "evaluateCriterion: broken flags, graph and model disagree on the edge count");
  if (broken.size() != size_t(model.edgeCount) || graph.edgeCount != model.edgeCount) return 0;
  const size_t T = size_t(model.tetCount);
  const uint8_t* flags = broken.data();
  ws.candidates.resize(T);

  const CpuExecutor exec(jobs);
  const CriterionEdges edges = edgesOf(model, graph, strength, flags);
  const double weakest = exec.min(strength, model.edgeCount);
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
  if (!(exec.reduce<MaxOp>(model.tetCount, AnyCandidateTerm{ws.candidates.data()}) > 0)) return 0;
  const int32_t E = model.edgeCount;
  ws.edgeFlag.resize(size_t(E));
  ws.edgeStress.resize(size_t(E));
  ws.edgeTet.resize(size_t(E));
  exec.run(E, 1024,
           EdgeCandidateStage{
               graph.edgeTetStart.data(), graph.edgeTets.data(), ws.candidates.data(), tetStress,
               model.nonLocal() ? ws.averaged.data() : nullptr, model.edgeDirections.data(),
               ws.edgeFlag.data(), ws.edgeStress.data(), ws.edgeTet.data()});
  // The candidates in edge-id order: counts per chunk, their offsets, then each chunk's edges.
  const int32_t chunks = (E + kCompactChunk - 1) / kCompactChunk;
  ws.chunkCount.resize(size_t(chunks));
  ws.chunkOffset.resize(size_t(chunks) + 1);
  exec.run(chunks, 4, CompactCountStage{ws.edgeFlag.data(), E, ws.chunkCount.data()});
  exec.run(1, 1, CompactOffsetStage{ws.chunkCount.data(), chunks, ws.chunkOffset.data()});
  const int32_t count = ws.chunkOffset[size_t(chunks)];
  ws.candidateEdges.resize(size_t(count));
  exec.run(
      chunks, 4,
      CompactScatterStage{ws.edgeFlag.data(), E, ws.chunkOffset.data(), ws.candidateEdges.data()});

  // The decision in edge-id order (eq 4.12): every candidate breaks, its events follow the
  // list's order. Damage is only ever set, never cleared.
  const size_t first = events.size();
  events.resize(first + size_t(count));
  exec.run(
      count, 256,
      BreakEventStage{ws.candidateEdges.data(), ws.edgeStress.data(), ws.edgeTet.data(),
                      graph.edgeNodes.data(), positions, broken.data(), events.data() + first});
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
