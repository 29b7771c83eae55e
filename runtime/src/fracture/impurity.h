// Impurities and impurity maps of one fracturing body (thesis sec 5.2-5.4, SPEC §4).
//
// Design: impurities act only through the per-edge strengths the criterion already reads
// (FractureModel::strength), so the criterion's per-step work is unchanged and a body without
// impurities has no ImpurityField at all. The field keeps each edge's base strength (the
// material's, times the potency of every map over it), each node's impurity alpha_k and its
// rest and current degree; when edges break, only the edges around their end nodes get new
// strengths (eq 5.1 with the new degrees), O(breaks * degree^2), and nothing is drawn per step.
#pragma once

#include <cstdint>
#include <vector>

#include "graphfrac/defs.h"
#include "graphfrac/status.h"
#include "mesh/edge_graph.h"

namespace gf::detail {

/// Rest geometry an impurity map is placed on.
struct ImpurityRest {
  const double* positions = nullptr;  ///< 3 per node
  const int32_t* tets = nullptr;      ///< 4 per tet
  int32_t nodeCount = 0, tetCount = 0;
  double meanEdgeLength = 0;
};

struct ImpurityField {
  bool upgrade = false;
  bool randomGraph = true;
  std::vector<double> alpha;           ///< alpha_k per node (eq 5.2); 0 = pure
  std::vector<double> baseStrength;    ///< per edge: material strength * map potencies
  std::vector<int32_t> restDegree;     ///< per node, in the intact graph
  std::vector<int32_t> degree;         ///< per node, unbroken incident edges now
  std::vector<int32_t> pendingPrecut;  ///< edges of potency-0 maps, broken by the next step

  /// Draws alpha (when settings.enabled and sigma > 0; else every node is pure) and takes
  /// `strength` as the base strengths. Does not change `strength`: call refreshAll.
  void init(const EdgeGraph& graph, const ImpuritySettings& settings,
            const std::vector<double>& strength);
  /// sigma_th (1 - p_ij) / (1 - p_ref) of edge e (docs/design.md "Impurities").
  double effectiveStrength(const EdgeGraph& graph, int32_t e) const;
  /// Every unbroken edge's effective strength into `strength`.
  void refreshAll(const EdgeGraph& graph, const uint8_t* broken, std::vector<double>& strength);
  /// Degrees after `edges` broke, then the strengths of the unbroken edges at their nodes.
  void onBreaks(const EdgeGraph& graph, const int32_t* edges, size_t count, const uint8_t* broken,
                std::vector<double>& strength);
  /// The edges a map covers, sorted, or an error naming the field (a polyline point off the
  /// surface). Changes nothing.
  static Result<std::vector<int32_t>> mapEdges(const EdgeGraph& graph, const ImpurityRest& rest,
                                               const ImpurityMap& map);
  /// Applies a checked map's edges: base strength * potency, |alpha| >= 1 / potency at their
  /// nodes, potency 0 queues them as pre-cuts.
  void applyMap(const EdgeGraph& graph, const std::vector<int32_t>& edges, double potency);
};

}  // namespace gf::detail
