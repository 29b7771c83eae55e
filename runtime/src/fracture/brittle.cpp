#include "fracture/brittle.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <utility>

#include "kernels/damage.h"
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

// Issue 16: where planes cross at acute angles or run less than a cell apart, every tet around
// a node can be cut; the node then has no whole tet and, once its severed edges go, is a loose
// node (glass dust: 11.4 % of the glass bunny's mass). Such a node is given to a piece instead, the
// crack moving round it. As a labelling: the pieces of whole tets after the planes label their
// nodes; a node in none takes the label of a tet of its star whose labelled corners are all in
// one piece and that holds no edge broken before this batch (the criterion's, a blade's: not
// ours to mend), with that tet's other unlabelled corners (a sheet of nodes between two planes
// less than a cell apart has no tet of its own). Of those tets, the one where the edges to mend
// cross their planes nearest to the moving nodes in rest space (sum of the distances; ties by
// tet id): the crack moves the least. Labels only grow, so sweeps in node order repeat until
// one labels nothing: serial, rest space, the same on any thread count. Then the flags follow
// the labels on every edge at a node of this batch's planes that broke before neither: an edge
// is unbroken when both ends have one label, else broken. So a chosen tet is whole, and a tet
// with two labels or an unlabelled corner is split (all edges across are broken): pieces never
// join, each plane still separates what it separated, and a plane edge left unbroken lies in a
// whole tet. The other edges it breaks had only split tets (severed: releaseSevered would
// release them next) but could bridge two pieces through a tet the labelling made whole.
void keepNodesInPieces(const EdgeGraph& g, const RestMeshView& rest,
                       const std::vector<PlaneCut>& fresh, std::vector<uint8_t>& broken,
                       std::vector<BrittleSeed>& seeds, std::vector<PlaneCut>& released) {
  if (fresh.empty()) return;
  const double* x = rest.positions;
  const int32_t N = g.nodeCount, T = rest.tetCount;
  // Per edge: index into `fresh` (this batch's plane edges) or -1.
  std::vector<int32_t> freshOf(broken.size(), -1);
  for (size_t i = 0; i < fresh.size(); ++i) freshOf[size_t(fresh[i].edge)] = int32_t(i);
  const std::vector<uint8_t> before = broken;  // old: broken before this batch
  const auto old = [&](int32_t e) { return before[size_t(e)] && freshOf[size_t(e)] < 0; };
  const auto corner = [&](int32_t t, int i) { return rest.tets[4 * size_t(t) + size_t(i)]; };
  // Pieces of whole tets (corners joined by unbroken edges, as releaseSevered and findChips
  // judge them), by union-find over their corners; -1: in none.
  std::vector<int32_t> label(static_cast<size_t>(N));
  std::iota(label.begin(), label.end(), 0);
  const auto find = [&](int32_t a) {
    while (label[size_t(a)] != a) a = label[size_t(a)] = label[size_t(label[size_t(a)])];
    return a;
  };
  std::vector<uint8_t> inPiece(static_cast<size_t>(N), 0);
  for (int32_t t = 0; t < T; ++t) {
    uint8_t local[6];
    for (int k = 0; k < 6; ++k) local[k] = broken[size_t(g.tetEdges[6 * size_t(t) + size_t(k)])];
    if (cornersDisconnected(local)) continue;
    for (int i = 0; i < 4; ++i) inPiece[size_t(corner(t, i))] = 1;
    for (int i = 1; i < 4; ++i) label[size_t(find(corner(t, i)))] = find(corner(t, 0));
  }
  for (int32_t v = 0; v < N; ++v) label[size_t(v)] = inPiece[size_t(v)] ? find(v) : -1;
  // The nodes in no piece at the planes' edges: only they can have lost their last whole
  // tet here (a node in none before has an old broken edge in every tet: no candidate).
  std::vector<int32_t> nodes;
  for (const PlaneCut& c : fresh)
    for (int i = 0; i < 2; ++i) {
      const int32_t v = g.edgeNodes[2 * size_t(c.edge) + size_t(i)];
      if (label[size_t(v)] < 0) nodes.push_back(v);
    }
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  const double* px = x;
  const auto length = [&](int32_t a, int32_t b) {
    const double dx = px[3 * a] - px[3 * b], dy = px[3 * a + 1] - px[3 * b + 1],
                 dz = px[3 * a + 2] - px[3 * b + 2];
    return std::sqrt(dx * dx + dy * dy + dz * dz);
  };
  std::vector<uint8_t> free(static_cast<size_t>(N), 0);
  for (const int32_t v : nodes) free[size_t(v)] = 1;
  // Whole once the flags follow the labels: one label on all corners, no old break, and either
  // a corner the rule sets the edges of or corners that unbroken edges join already.
  const auto wholeAfter = [&](int32_t t) {
    const int32_t l = label[size_t(corner(t, 0))];
    bool hasFree = false;
    for (int c = 0; c < 4; ++c) {
      if (label[size_t(corner(t, c))] != l || l < 0) return false;
      hasFree |= free[size_t(corner(t, c))] != 0;
    }
    uint8_t local[6];
    for (int k = 0; k < 6; ++k) {
      const int32_t e = g.tetEdges[6 * size_t(t) + size_t(k)];
      if (old(e)) return false;
      local[k] = broken[size_t(e)];
    }
    return hasFree || !cornersDisconnected(local);
  };
  // Calls f(t) for each tet of v's star (3 times each: once per edge at v).
  const auto star = [&](int32_t v, auto&& f) {
    for (int32_t q = g.nodeEdgeStart[v]; q < g.nodeEdgeStart[v + 1]; ++q) {
      const int32_t e0 = g.nodeEdges[size_t(q)];
      for (int32_t r = g.edgeTetStart[e0]; r < g.edgeTetStart[e0 + 1]; ++r)
        f(g.edgeTets[size_t(r)] / 6);
    }
  };
  const auto contains = [&](int32_t t, int32_t v) {
    for (int c = 0; c < 4; ++c)
      if (corner(t, c) == v) return true;
    return false;
  };
  // Each node pulled into a piece, with the node whose tet it came over in.
  std::vector<std::pair<int32_t, int32_t>> pulledBy;
  for (bool pulled = true; pulled;) {
    pulled = false;
    for (bool changed = true; changed;) {
      changed = false;
      for (const int32_t v : nodes) {
        if (label[size_t(v)] >= 0) continue;
        int32_t best = -1, bestPiece = -1;
        double bestCost = 0;
        for (int32_t q = g.nodeEdgeStart[v]; q < g.nodeEdgeStart[v + 1]; ++q) {
          const int32_t e0 = g.nodeEdges[size_t(q)];
          for (int32_t r = g.edgeTetStart[e0]; r < g.edgeTetStart[e0 + 1]; ++r) {
            const int32_t t = g.edgeTets[size_t(r)] / 6;  // met once per edge at v: 3 times
            if (t == best) continue;
            int32_t piece = -1;
            bool ok = true;
            for (int c = 0; c < 4 && ok; ++c) {
              const int32_t l = label[size_t(corner(t, c))];
              ok = l < 0 || piece < 0 || l == piece;
              if (l >= 0) piece = l;
            }
            if (!ok || piece < 0) continue;
            double cost = 0;
            for (int k = 0; k < 6 && ok; ++k) {
              const int32_t e = g.tetEdges[6 * size_t(t) + size_t(k)];
              if (!broken[size_t(e)]) continue;
              if (old(e)) {
                ok = false;
                break;
              }
              // How far the crack moves along this edge: from its end in no piece to the plane.
              const PlaneCut& c = fresh[size_t(freshOf[size_t(e)])];
              const int32_t a = g.edgeNodes[2 * size_t(e)], b = g.edgeNodes[2 * size_t(e) + 1];
              const double len = length(a, b), fromA = c.split * len, fromB = len - fromA;
              const bool aFree = label[size_t(a)] < 0, bFree = label[size_t(b)] < 0;
              cost += aFree && bFree ? std::min(fromA, fromB) : aFree ? fromA : fromB;
            }
            if (!ok || (best >= 0 && (cost > bestCost || (cost == bestCost && t > best)))) continue;
            best = t;
            bestPiece = piece;
            bestCost = cost;
          }
        }
        if (best < 0) continue;
        for (int c = 0; c < 4; ++c) label[size_t(corner(best, c))] = bestPiece;
        changed = true;
      }
    }
    // A node where pieces meet (near where two planes cross) can have only tets with corners in
    // two pieces. Then one such corner u comes over with it, to the piece of the other corners:
    // when every node that shares a whole tet with u keeps a whole tet without u (u is at the
    // rim of its piece, and nothing there turns loose). Rare; the labels grow again after it.
    std::vector<int32_t> more;
    for (const int32_t v : nodes) {
      if (label[size_t(v)] >= 0) continue;
      int32_t best = -1, bestPiece = -1, bestU = -1;
      star(v, [&](int32_t t) {
        if (t == best) return;
        int32_t labels[4], n[2] = {0, 0}, l2[2] = {-1, -1};
        for (int c = 0; c < 4; ++c) {
          labels[c] = label[size_t(corner(t, c))];
          if (labels[c] < 0) continue;
          int i = l2[0] < 0 || l2[0] == labels[c] ? 0 : l2[1] < 0 || l2[1] == labels[c] ? 1 : 2;
          if (i == 2) return;  // three pieces
          l2[i] = labels[c];
          ++n[i];
        }
        if (l2[1] < 0) return;
        for (int k = 0; k < 6; ++k)
          if (old(g.tetEdges[6 * size_t(t) + size_t(k)])) return;
        for (int side = 0; side < 2; ++side) {
          if (n[side] != 1) continue;
          int32_t u = -1;
          for (int c = 0; c < 4; ++c)
            if (labels[c] == l2[side]) u = corner(t, c);
          // Everyone who shares a whole tet with u keeps one without it.
          bool ok = true;
          star(u, [&](int32_t tu) {
            if (!ok || !wholeAfter(tu)) return;
            for (int c = 0; c < 4 && ok; ++c) {
              const int32_t w = corner(tu, c);
              if (w == u) continue;
              bool other = false;
              star(w, [&](int32_t tw) { other = other || (!contains(tw, u) && wholeAfter(tw)); });
              ok = other;
            }
          });
          if (ok && (best < 0 || t < best)) {
            best = t;
            bestPiece = l2[1 - side];
            bestU = u;
          }
        }
      });
      if (best < 0) continue;
      for (int c = 0; c < 4; ++c) label[size_t(corner(best, c))] = bestPiece;
      if (!free[size_t(bestU)]) more.push_back(bestU);
      pulledBy.push_back({bestU, v});
      free[size_t(bestU)] = 1;
      pulled = true;
    }
    nodes.insert(nodes.end(), more.begin(), more.end());
    std::sort(nodes.begin(), nodes.end());
  }
  // Flags from the labels on the edges at the nodes that were in no piece (`free`); edges
  // elsewhere keep theirs, so a crack that an edge arrested inside one piece stays. And the
  // unbroken edges across two pieces in the tets of a node that joined one: severed, but they
  // would join the pieces through that tet once it is whole. The events' plane for an edge no
  // plane crossed is the first that cut an edge at its ends, else at the node whose rule set it.
  std::vector<int32_t> planeAt(static_cast<size_t>(N), -1);
  for (const PlaneCut& c : fresh)
    for (int i = 0; i < 2; ++i) {
      int32_t& p = planeAt[size_t(g.edgeNodes[2 * size_t(c.edge) + size_t(i)])];
      p = p < 0 ? c.plane : std::min(p, c.plane);
    }
  // A node pulled in, at the end of no plane's edge, takes the plane of the node it came with.
  for (const auto& [u, v] : pulledBy)
    if (planeAt[size_t(u)] < 0) planeAt[size_t(u)] = planeAt[size_t(v)];
  // An edge whose tets include one with all corners in one piece and no old break: that tet
  // is whole once its free corners' edges are set by this rule.
  const auto inOnePiece = [&](int32_t e) {
    for (int32_t r = g.edgeTetStart[e]; r < g.edgeTetStart[e + 1]; ++r) {
      const int32_t t = g.edgeTets[size_t(r)] / 6;
      bool one = label[size_t(corner(t, 0))] >= 0;
      for (int c = 1; c < 4 && one; ++c)
        one = label[size_t(corner(t, c))] == label[size_t(corner(t, 0))];
      for (int k = 0; k < 6 && one; ++k) one = !old(g.tetEdges[6 * size_t(t) + size_t(k)]);
      if (one) return true;
    }
    return false;
  };
  const auto set = [&](int32_t e, bool cut, int32_t v) {
    if (old(e)) return;
    const int32_t a = g.edgeNodes[2 * size_t(e)], b = g.edgeNodes[2 * size_t(e) + 1];
    if (freshOf[size_t(e)] >= 0) {
      if (!cut && broken[size_t(e)])
        ++seeds[size_t(fresh[size_t(freshOf[size_t(e)])].plane)].edgesKept;
    } else if (cut && !broken[size_t(e)]) {
      const int32_t at = planeAt[size_t(a)] >= 0 ? a : planeAt[size_t(b)] >= 0 ? b : v;
      released.push_back({e, planeAt[size_t(at)], 0.5});
    }
    broken[size_t(e)] = cut;
  };
  for (const int32_t v : nodes) {
    for (int32_t q = g.nodeEdgeStart[v]; q < g.nodeEdgeStart[v + 1]; ++q) {
      const int32_t e = g.nodeEdges[size_t(q)];
      const int32_t a = g.edgeNodes[2 * size_t(e)], b = g.edgeNodes[2 * size_t(e) + 1];
      if (a != v && free[size_t(a)] && a < v) continue;  // done from a
      if (b != v && free[size_t(b)] && b < v) continue;
      set(e, !inOnePiece(e), v);
    }
    if (label[size_t(v)] < 0) continue;
    for (int32_t q = g.nodeEdgeStart[v]; q < g.nodeEdgeStart[v + 1]; ++q) {
      const int32_t e0 = g.nodeEdges[size_t(q)];
      for (int32_t r = g.edgeTetStart[e0]; r < g.edgeTetStart[e0 + 1]; ++r)
        for (int k = 0; k < 6; ++k) {
          const int32_t e = g.tetEdges[6 * size_t(g.edgeTets[size_t(r)] / 6) + size_t(k)];
          const int32_t a = g.edgeNodes[2 * size_t(e)], b = g.edgeNodes[2 * size_t(e) + 1];
          if (!free[size_t(a)] && !free[size_t(b)] && label[size_t(a)] != label[size_t(b)])
            set(e, true, v);
        }
    }
  }
  std::sort(released.begin(), released.end(),
            [](const PlaneCut& p, const PlaneCut& q) { return p.edge < q.edge; });
}

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

  // The first plane (in seed order) that crossed an edge owns it; edges broken before stay.
  std::sort(cuts.begin(), cuts.end(), [](const PlaneCut& a, const PlaneCut& b) {
    return a.edge != b.edge ? a.edge < b.edge : a.plane < b.plane;
  });
  std::vector<PlaneCut> fresh;  // one per edge this batch breaks, in edge order
  for (size_t i = 0; i < cuts.size(); ++i) {
    const PlaneCut& c = cuts[i];
    if ((i > 0 && cuts[i - 1].edge == c.edge) || broken[size_t(c.edge)]) continue;
    broken[size_t(c.edge)] = 1;
    fresh.push_back(c);
  }
  std::vector<PlaneCut> released;
  if (options.keepNodesWhole) keepNodesInPieces(graph, rest, fresh, broken, seeds, released);

  // Events in edge order, the planes' breaks and then the edges released with them.
  const double* px = positions ? positions : rest.positions;
  for (const PlaneCut& c : fresh) {
    if (!broken[size_t(c.edge)]) continue;  // kept by keepNodesInPieces
    BrittleSeed& seed = seeds[size_t(c.plane)];
    ++seed.edgesBroken;
    EdgeBreak ev;
    ev.edge = c.edge;
    ev.tet = seed.tet;
    ev.stress = seed.principal;
    ev.split = c.split;
    const double* xa = px + 3 * size_t(graph.edgeNodes[2 * size_t(c.edge)]);
    const double* xb = px + 3 * size_t(graph.edgeNodes[2 * size_t(c.edge) + 1]);
    ev.position = {xa[0] + c.split * (xb[0] - xa[0]), xa[1] + c.split * (xb[1] - xa[1]),
                   xa[2] + c.split * (xb[2] - xa[2])};
    events.push_back(ev);
  }
  for (const PlaneCut& c : released) {
    ++seeds[size_t(c.plane)].edgesReleased;
    EdgeBreak ev;  // as FractureBody::releaseSevered reports one
    ev.edge = c.edge;
    ev.split = 0.5;
    const double* xa = px + 3 * size_t(graph.edgeNodes[2 * size_t(c.edge)]);
    const double* xb = px + 3 * size_t(graph.edgeNodes[2 * size_t(c.edge) + 1]);
    ev.position = {0.5 * (xa[0] + xb[0]), 0.5 * (xa[1] + xb[1]), 0.5 * (xa[2] + xb[2])};
    events.push_back(ev);
  }
  return seeds;
}

}  // namespace gf::detail
