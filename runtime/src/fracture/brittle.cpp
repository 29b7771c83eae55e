#include "fracture/brittle.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "kernels/edge_stress.h"
#include "kernels/eigen_sym.h"

namespace gf::detail {

namespace {

// Edge crossed by one plane; the plane index orders the choice when two planes cross an edge.
struct PlaneCut {
  int32_t edge;
  int32_t plane;
  double split;
};

}  // namespace

Result<std::vector<BrittleSeed>> startBrittleCracks(
    const FractureModel& model, const EdgeGraph& graph, const RestMeshView& rest,
    const double* strength, const double* tetStress, std::vector<uint8_t>& broken,
    std::vector<EdgeBreak>& events, JobSystem& jobs, const double* positions,
    const BrittleOptions& options) {
  const int32_t T = model.tetCount;
  if (model.faceNeighbours.size() != 4 * size_t(T))
    return fail("startBrittleCracks: the fracture model has no face adjacency (brittle off)");
  if (rest.tetCount != T || broken.size() != size_t(model.edgeCount) ||
      graph.edgeCount != model.edgeCount)
    return fail("startBrittleCracks: mesh (", std::to_string(rest.tetCount),
                " tets), broken flags (", std::to_string(broken.size()), ") and model (",
                std::to_string(T), " tets, ", std::to_string(model.edgeCount), " edges) disagree");

  // Maximum principal stress and its direction per tet (rest frame: S is material-frame).
  std::vector<double> principal(static_cast<size_t>(T));
  std::vector<Vec3> direction(static_cast<size_t>(T));
  jobs.parallelFor(uint32_t(T), 256, [&](uint32_t b, uint32_t e) {
    for (uint32_t t = b; t < e; ++t) {
      const double* s = tetStress + 6 * size_t(t);
      const Mat3 m = fromVoigt(s);
      double values[3];
      Mat3 vectors;
      symmetricEigen<3>(m, values, vectors);
      principal[t] = values[0];
      direction[t] = column(vectors, 0);
    }
  });

  // Greedy seeds: most stressed first, each farther than 2 R_seed from all taken.
  std::vector<int32_t> order;
  order.reserve(size_t(T));
  for (int32_t t = 0; t < T; ++t)
    if (principal[size_t(t)] > 0 && std::isfinite(principal[size_t(t)])) order.push_back(t);
  std::sort(order.begin(), order.end(), [&](int32_t a, int32_t b) {
    return principal[size_t(a)] != principal[size_t(b)]
               ? principal[size_t(a)] > principal[size_t(b)]
               : a < b;
  });
  // At least the averaging radius, in whichever unit the settings give it.
  const double seedRadius = std::max(options.seedRadius * model.meanEdgeLength, model.radiusAbs);
  const double separation2 = 4.0 * seedRadius * seedRadius;
  const auto centroid = [&](int32_t t) {
    const double* c = &model.centroids[3 * size_t(t)];
    return Vec3{c[0], c[1], c[2]};
  };
  std::vector<BrittleSeed> seeds;
  const size_t wanted = size_t(std::max(model.settings.regions, 1));
  for (const int32_t t : order) {
    if (seeds.size() >= wanted) break;
    const Vec3 c = centroid(t);
    bool farEnough = true;
    for (const BrittleSeed& s : seeds) {
      const Vec3 d = c - s.point;
      if (dot(d, d) <= separation2) {
        farEnough = false;
        break;
      }
    }
    if (!farEnough) continue;
    BrittleSeed seed;
    seed.tet = t;
    seed.principal = principal[size_t(t)];
    // Sec 4.5.1.2: "each of these fracture surfaces propagates to the boundary". A region
    // seeds because the criterion fired somewhere in the body, not because it reached the
    // strength itself; carrying only its own stress, a plane seeded below the strength stops
    // in its seed tet at the first edge of the body's own strength (the demo's bunny: 7 of 8).
    seed.carried = std::max(seed.principal, model.settings.strength);
    seed.point = c;
    seed.normal = (1.0 / norm(direction[size_t(t)])) * direction[size_t(t)];
    seeds.push_back(seed);
  }

  // Propagate each plane from its seed over face-adjacent cut tets.
  const double* x = rest.positions;
  std::vector<int32_t> stamp(static_cast<size_t>(T), -1);
  std::vector<int32_t> queue;
  std::vector<PlaneCut> cuts;
  for (size_t p = 0; p < seeds.size(); ++p) {
    BrittleSeed& seed = seeds[p];
    const auto dist = [&](int32_t v) {
      return seed.normal.x * (x[3 * v] - seed.point.x) +
             seed.normal.y * (x[3 * v + 1] - seed.point.y) +
             seed.normal.z * (x[3 * v + 2] - seed.point.z);
    };
    queue.assign(1, seed.tet);
    stamp[size_t(seed.tet)] = int32_t(p);
    for (size_t head = 0; head < queue.size(); ++head) {
      const int32_t t = queue[head];
      const int32_t* tn = rest.tets + 4 * size_t(t);
      double d[4];
      bool positive[4];
      for (int i = 0; i < 4; ++i) {
        d[i] = dist(tn[i]);
        positive[i] = d[i] >= 0;
      }
      const bool cut =
          !(positive[0] == positive[1] && positive[1] == positive[2] && positive[2] == positive[3]);
      if (!cut) continue;  // only the seed can get here uncut (a degenerate plane)
      ++seed.tetsCut;
      bool held = false;
      for (int k = 0; k < 6; ++k) {
        const int i = kTetEdgeNodes[k][0], j = kTetEdgeNodes[k][1];
        if (positive[i] == positive[j]) continue;
        const int32_t edge = graph.tetEdges[6 * size_t(t) + k];
        // An edge stronger than the stress the plane carries holds, and arrests the crack.
        if (strength[edge] > seed.carried) {
          held = true;
          continue;
        }
        // Split measured from the edge's first node (the smaller id).
        const bool forward = graph.edgeNodes[2 * size_t(edge)] == tn[i];
        const double da = forward ? d[i] : d[j], db = forward ? d[j] : d[i];
        cuts.push_back({edge, int32_t(p), da / (da - db)});
      }
      if (held) {
        ++seed.tetsArrested;
        continue;  // the front stops in this tet: no propagation beyond it
      }
      for (int f = 0; f < 4; ++f) {
        const int32_t nb = model.faceNeighbours[4 * size_t(t) + f];
        if (nb < 0 || stamp[size_t(nb)] == int32_t(p)) continue;
        // The face opposite node f holds the other three nodes: the plane crosses it (and so
        // the neighbour) only when they are not all on one side.
        bool pos = false, neg = false;
        for (int i = 0; i < 4; ++i)
          if (i != f) (positive[i] ? pos : neg) = true;
        if (!(pos && neg)) continue;
        stamp[size_t(nb)] = int32_t(p);
        queue.push_back(nb);
      }
    }
  }

  // Events in edge order; the first plane (in seed order) that crossed an edge reports it.
  std::sort(cuts.begin(), cuts.end(), [](const PlaneCut& a, const PlaneCut& b) {
    return a.edge != b.edge ? a.edge < b.edge : a.plane < b.plane;
  });
  for (size_t i = 0; i < cuts.size(); ++i) {
    const PlaneCut& c = cuts[i];
    if (i > 0 && cuts[i - 1].edge == c.edge) continue;
    if (broken[size_t(c.edge)]) continue;
    broken[size_t(c.edge)] = 1;
    BrittleSeed& seed = seeds[size_t(c.plane)];
    ++seed.edgesBroken;
    EdgeBreak ev;
    ev.edge = c.edge;
    ev.tet = seed.tet;
    ev.stress = seed.principal;
    ev.split = c.split;
    const double* px = positions ? positions : rest.positions;
    const double* xa = px + 3 * size_t(graph.edgeNodes[2 * size_t(c.edge)]);
    const double* xb = px + 3 * size_t(graph.edgeNodes[2 * size_t(c.edge) + 1]);
    ev.position = {xa[0] + c.split * (xb[0] - xa[0]), xa[1] + c.split * (xb[1] - xa[1]),
                   xa[2] + c.split * (xb[2] - xa[2])};
    events.push_back(ev);
  }
  return seeds;
}

}  // namespace gf::detail
