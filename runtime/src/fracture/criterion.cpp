#include "fracture/criterion.h"

#include <algorithm>
#include <limits>

namespace gf::detail {

namespace {

constexpr uint8_t kAveragedBit = 0x80;
constexpr uint8_t kEdgeBits = 0x3f;

// eq 4.10, normalised: the list holds the tet itself with a positive weight, so the sum is > 0.
inline void averageOne(const FractureModel& model, const double* tetStress, size_t t, double* out) {
  double acc[6] = {0, 0, 0, 0, 0, 0};
  double wsum = 0;
  for (int32_t s = model.neighbourStart[t]; s < model.neighbourStart[t + 1]; ++s) {
    const double w = model.neighbourWeight[size_t(s)];
    const double* sj = tetStress + 6 * size_t(model.neighbourIndex[size_t(s)]);
    for (int c = 0; c < 6; ++c) acc[c] += w * sj[c];
    wsum += w;
  }
  for (int c = 0; c < 6; ++c) out[c] = acc[c] / wsum;
}

// Bits of the local edges of tet t whose normal stress under S reaches their strength.
inline uint8_t edgesAtStrength(const FractureModel& model, const EdgeGraph& graph,
                               const uint8_t* flags, const double* S, size_t t) {
  uint8_t mask = 0;
  for (int k = 0; k < 6; ++k) {
    const int32_t edge = graph.tetEdges[6 * t + k];
    if (flags[edge]) continue;
    // eq 4.11: tensile only, because strengths are positive.
    if (edgeNormalStress(S, &model.edgeDirections[18 * t + 3 * k]) >= model.strength[edge])
      mask |= uint8_t(1u << k);
  }
  return mask;
}

}  // namespace

void averageStress(const FractureModel& model, const double* tetStress, double* out,
                   JobSystem& jobs) {
  if (!model.nonLocal()) {
    std::copy(tetStress, tetStress + 6 * size_t(model.tetCount), out);
    return;
  }
  jobs.parallelFor(uint32_t(model.tetCount), 256, [&](uint32_t b, uint32_t e) {
    for (uint32_t t = b; t < e; ++t) averageOne(model, tetStress, t, out + 6 * size_t(t));
  });
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

  double weakest = std::numeric_limits<double>::infinity();
  for (const double s : model.strength) weakest = std::min(weakest, s);
  if (!model.nonLocal()) {
    // Local criterion: every tet judged by its own stress; the Gershgorin bound spares the
    // edge gathers of tets far below the weakest strength.
    jobs.parallelFor(uint32_t(T), 512, [&](uint32_t b, uint32_t e) {
      for (uint32_t t = b; t < e; ++t) {
        const double* S = tetStress + 6 * size_t(t);
        ws.candidates[t] =
            maxPrincipalBound(S) >= weakest ? edgesAtStrength(model, graph, flags, S, t) : 0;
      }
    });
  } else {
    // Bound first: per tet, per cell, and against the weakest edge of the body.
    const CentroidGrid& grid = model.grid;
    const size_t cells = grid.start.size() - 1;
    ws.bound.resize(T);
    ws.cellMax.resize(cells);
    ws.averaged.resize(6 * T);
    jobs.parallelFor(uint32_t(T), 1024, [&](uint32_t b, uint32_t e) {
      for (uint32_t t = b; t < e; ++t) ws.bound[t] = maxPrincipalBound(tetStress + 6 * size_t(t));
    });
    jobs.parallelFor(uint32_t(cells), 1024, [&](uint32_t b, uint32_t e) {
      for (uint32_t c = b; c < e; ++c) {
        double m = -std::numeric_limits<double>::infinity();
        for (int32_t s = grid.start[c]; s < grid.start[c + 1]; ++s)
          m = std::max(m, ws.bound[size_t(grid.items[size_t(s)])]);
        ws.cellMax[c] = m;
      }
    });
    double globalMax = -std::numeric_limits<double>::infinity();
    for (const double m : ws.cellMax) globalMax = std::max(globalMax, m);
    if (!(globalMax >= weakest)) {
      std::fill(ws.candidates.begin(), ws.candidates.end(), uint8_t(0));
      return 0;
    }

    jobs.parallelFor(uint32_t(T), 256, [&](uint32_t b, uint32_t e) {
      for (uint32_t t = b; t < e; ++t) {
        double weakestHere = std::numeric_limits<double>::infinity();
        for (int k = 0; k < 6; ++k) {
          const int32_t edge = graph.tetEdges[6 * size_t(t) + k];
          if (!flags[edge]) weakestHere = std::min(weakestHere, model.strength[size_t(edge)]);
        }
        double reach = -std::numeric_limits<double>::infinity();
        grid.forEachCellAround(grid.tetCell[t],
                               [&](int32_t c) { reach = std::max(reach, ws.cellMax[size_t(c)]); });
        if (!(reach >= weakestHere)) {
          ws.candidates[t] = 0;
          continue;
        }
        double* avg = &ws.averaged[6 * size_t(t)];
        averageOne(model, tetStress, t, avg);
        ws.candidates[t] = uint8_t(kAveragedBit | edgesAtStrength(model, graph, flags, avg, t));
      }
    });
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
  const uint32_t T = uint32_t(graph.tetEdges.size() / 6);
  jobs.parallelFor(T, 1024, [&](uint32_t b, uint32_t e) {
    for (uint32_t t = b; t < e; ++t) {
      uint8_t mask = 0;
      for (int k = 0; k < 6; ++k)
        if (broken[graph.tetEdges[6 * size_t(t) + k]]) mask |= uint8_t(1u << k);
      masks[t] = mask;
    }
  });
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
