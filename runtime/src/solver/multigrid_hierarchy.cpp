// Multigrid hierarchy: furthest-point handles, geodesic binding and the patterns of the
// prolongations and coarse operators (their numbers: multigrid_galerkin.cpp).
#include "solver/multigrid_hierarchy.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <string>

#include "solver/vector_ops.h"

namespace gf::detail {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// MultigridSettings::prolongationFilter on one finer row's smoothing terms (handle, j, block):
// a handle other than the row's own that fewer than `filter` of the terms reach loses its
// block, and its terms join the own handle's block. The smoothing evaluates a term with the
// affine map of the block's handle, and every handle's affine map of one affine field gives
// the same values, so P maps the affine fields as without the filter.
void lumpWeakHandles(std::vector<std::array<int32_t, 3>>& cand, int32_t own, double filter) {
  std::sort(cand.begin(), cand.end());
  const double least = filter * static_cast<double>(cand.size());
  for (size_t c = 0; c < cand.size();) {
    size_t e = c;
    while (e < cand.size() && cand[e][0] == cand[c][0]) ++e;
    if (cand[c][0] != own && static_cast<double>(e - c) < least)
      for (size_t k = c; k < e; ++k) cand[k][0] = own;
    c = e;
  }
}

// A fragment with fewer free nodes than this gets no handle of its own when cracks cut it off:
// its few nodes are left to the smoother (zero rows of U, like Dirichlet nodes), which resolves
// them in a sweep or two, instead of adding coarse unknowns that would be mostly null.
constexpr int32_t kMinFragmentNodes = 4;
// Gram eigenvalues below this fraction of the largest are null directions of an aggregate.
constexpr double kNullTolerance = 1e-9;
// Default hierarchy (MultigridSettings::levels empty): free nodes per level-1 handle, the
// handle ratio between consecutive coarse levels, and the most handles of the coarsest level
// (factorised by Cholesky on every refresh), for the piecewise-affine and for the smoothed
// prolongation. Measured on the beams of the multigrid tests and `graphfrac bench multigrid`
// (docs in defs.h): piecewise-affine aggregates stay large (the coarse operators and the
// coarsest factorisation are cheap, the smoother does the rest); smoothed ones are smaller,
// since smoothing makes each coarse level as good as an exact one of that size.
constexpr double kNodesPerHandle = 64, kNodesPerHandleSmoothed = 27;
constexpr double kCoarsening = 8;
constexpr int32_t kCoarsestHandles = 128, kCoarsestHandlesSmoothed = 96;

// The patterns of Q = A P and of P^T Q are built in fixed chunks of rows (handles), side by
// side on the JobSystem, then joined in chunk order: the same arrays for any thread count.
constexpr int32_t kRowsPerChunk = 512, kHandlesPerChunk = 16;

// One chunk's part of a two-level pattern: per row its block count, per block its column and
// term count, per term its two indices.
struct PatternChunk {
  std::vector<int32_t> perRow, col, terms, first, second;
};

size_t chunkCount(int32_t rows, int32_t perChunk) {
  return static_cast<size_t>((rows + perChunk - 1) / perChunk);
}

// Joins the chunks into CSR arrays: rowStart/col over rows, termStart/first/second over blocks.
void stitch(const std::vector<PatternChunk>& chunks, std::vector<int32_t>& rowStart,
            std::vector<int32_t>& col, std::vector<int32_t>& termStart, std::vector<int32_t>& first,
            std::vector<int32_t>& second) {
  rowStart.assign(1, 0);
  col.clear();
  termStart.assign(1, 0);
  first.clear();
  second.clear();
  for (const PatternChunk& ch : chunks) {
    for (int32_t n : ch.perRow) rowStart.push_back(rowStart.back() + n);
    col.insert(col.end(), ch.col.begin(), ch.col.end());
    for (int32_t n : ch.terms) termStart.push_back(termStart.back() + n);
    first.insert(first.end(), ch.first.begin(), ch.first.end());
    second.insert(second.end(), ch.second.begin(), ch.second.end());
  }
}

struct QueueItem {
  double d;
  int32_t owner;
  int32_t node;
  bool operator>(const QueueItem& o) const {
    if (d != o.d) return d > o.d;
    if (owner != o.owner) return owner > o.owner;
    return node > o.node;
  }
};
using MinQueue = std::priority_queue<QueueItem, std::vector<QueueItem>, std::greater<QueueItem>>;

}  // namespace

NodeGraph NodeGraph::fromPattern(const BlockSparseMatrix& A, const double* rest) {
  NodeGraph g;
  g.n = A.n;
  g.start.assign(static_cast<size_t>(A.n) + 1, 0);
  g.adj.reserve(A.col.size());
  for (int32_t r = 0; r < A.n; ++r) {
    for (int32_t k = A.rowStart[r]; k < A.rowStart[r + 1]; ++k) {
      const int32_t c = A.col[k];
      if (c == r) continue;
      g.adj.push_back(c);
      const double dx = rest[3 * c] - rest[3 * r], dy = rest[3 * c + 1] - rest[3 * r + 1],
                   dz = rest[3 * c + 2] - rest[3 * r + 2];
      g.length.push_back(std::sqrt(dx * dx + dy * dy + dz * dz));
    }
    g.start[r + 1] = static_cast<int32_t>(g.adj.size());
  }
  g.alive.assign(g.adj.size(), 1);
  return g;
}

void NodeGraph::setBroken(const int32_t* edgeNodes, const uint8_t* broken, int32_t edgeCount,
                          JobSystem& jobs) {
  constexpr uint32_t kGrain = 4096;
  forRanges(jobs, static_cast<uint32_t>(alive.size()), kGrain, [&](uint32_t b, uint32_t e) {
    std::fill(alive.begin() + b, alive.begin() + e, uint8_t{1});
  });
  auto kill = [&](int32_t a, int32_t b) {
    if (a < 0 || a >= n) return;
    const int32_t* first = adj.data() + start[a];
    const int32_t* last = adj.data() + start[a + 1];
    const int32_t* it = std::lower_bound(first, last, b);
    if (it != last && *it == b) alive[static_cast<size_t>(it - adj.data())] = 0;
  };
  // Each edge clears its own two entries, so the ranges write apart.
  forRanges(jobs, static_cast<uint32_t>(edgeCount), kGrain, [&](uint32_t b, uint32_t e) {
    for (uint32_t k = b; k < e; ++k) {
      if (!broken[k]) continue;
      kill(edgeNodes[2 * k], edgeNodes[2 * k + 1]);
      kill(edgeNodes[2 * k + 1], edgeNodes[2 * k]);
    }
  });
}

int32_t NodeGraph::components(std::vector<int32_t>& component, JobSystem& jobs) const {
  // Union-find over the unbroken edges, side by side: a root is only ever linked below a lower
  // one, so every component's root ends as its lowest node whatever order the links ran in.
  // Components are numbered by their lowest node, as a search from node 0 upwards numbers them.
  component.resize(static_cast<size_t>(n));
  constexpr uint32_t kGrain = 1024;
  forRanges(jobs, static_cast<uint32_t>(n), kGrain, [&](uint32_t b, uint32_t e) {
    for (uint32_t i = b; i < e; ++i) component[i] = static_cast<int32_t>(i);
  });
  auto root = [&](int32_t i) {
    for (;;) {
      const int32_t p = std::atomic_ref<int32_t>(component[i]).load(std::memory_order_acquire);
      if (p == i) return i;
      i = p;
    }
  };
  forRanges(jobs, static_cast<uint32_t>(n), kGrain, [&](uint32_t b, uint32_t e) {
    for (int32_t u = static_cast<int32_t>(b); u < static_cast<int32_t>(e); ++u)
      for (int32_t k = start[u]; k < start[u + 1]; ++k) {
        if (!alive[k] || adj[k] < u) continue;
        int32_t a = u, c = adj[k];
        for (;;) {
          a = root(a);
          c = root(c);
          if (a == c) break;
          if (a > c) std::swap(a, c);
          int32_t expected = c;
          if (std::atomic_ref<int32_t>(component[c])
                  .compare_exchange_strong(expected, a, std::memory_order_acq_rel))
            break;
        }
      }
  });
  // Roots in ascending order get the numbers; every node then takes its root's.
  forRanges(jobs, static_cast<uint32_t>(n), kGrain, [&](uint32_t b, uint32_t e) {
    for (int32_t i = static_cast<int32_t>(b); i < static_cast<int32_t>(e); ++i)
      std::atomic_ref<int32_t>(component[i]).store(root(i), std::memory_order_release);
  });
  int32_t count = 0;
  std::vector<int32_t> number(static_cast<size_t>(n));
  for (int32_t i = 0; i < n; ++i)
    if (component[i] == i) number[i] = count++;
  forRanges(jobs, static_cast<uint32_t>(n), kGrain, [&](uint32_t b, uint32_t e) {
    for (uint32_t i = b; i < e; ++i) component[i] = number[component[i]];
  });
  return count;
}

std::vector<int32_t> furthestPointSample(const NodeGraph& g, const uint8_t* fixedNode,
                                         int32_t count) {
  std::vector<int32_t> out;
  std::vector<double> dist(static_cast<size_t>(g.n), kInf);
  std::vector<uint8_t> chosen(static_cast<size_t>(g.n), 0);
  MinQueue queue;
  int32_t next = -1;
  for (int32_t i = 0; i < g.n && next < 0; ++i)
    if (!fixedNode[i]) next = i;
  while (next >= 0 && static_cast<int32_t>(out.size()) < count) {
    out.push_back(next);
    chosen[next] = 1;
    // Incremental Dijkstra: only nodes now closer to the new handle change.
    dist[next] = 0;
    queue.push({0.0, 0, next});
    while (!queue.empty()) {
      const QueueItem top = queue.top();
      queue.pop();
      if (top.d > dist[top.node]) continue;
      for (int32_t k = g.start[top.node]; k < g.start[top.node + 1]; ++k) {
        if (!g.alive[k]) continue;
        const double nd = top.d + g.length[k];
        if (nd < dist[g.adj[k]]) {
          dist[g.adj[k]] = nd;
          queue.push({nd, 0, g.adj[k]});
        }
      }
    }
    next = -1;
    double best = -1;
    for (int32_t i = 0; i < g.n; ++i) {
      if (fixedNode[i] || chosen[i]) continue;
      if (dist[i] > best) {
        best = dist[i];
        next = i;
      }
    }
  }
  return out;
}

namespace {

// Dijkstra from the queued items; relaxations keep (distance, owner) lexicographically least,
// so the result is the unique fixed point dist[v] = min over alive neighbours u of
// dist[u] + |uv| (ties to the lower owner) whatever the queue held first.
void settle(const NodeGraph& g, MinQueue& queue, int32_t* owner, double* dist, int32_t* pred) {
  while (!queue.empty()) {
    const QueueItem top = queue.top();
    queue.pop();
    if (top.d != dist[top.node] || top.owner != owner[top.node]) continue;
    for (int32_t k = g.start[top.node]; k < g.start[top.node + 1]; ++k) {
      if (!g.alive[k]) continue;
      const int32_t v = g.adj[k];
      const double nd = top.d + g.length[k];
      // Equal distances go to the lower source index, whatever the pop order.
      if (nd < dist[v] || (nd == dist[v] && top.owner < owner[v])) {
        dist[v] = nd;
        owner[v] = top.owner;
        if (pred) pred[v] = top.node;
        queue.push({nd, top.owner, v});
      }
    }
  }
}

void searchAll(const NodeGraph& g, const int32_t* sources, int32_t sourceCount,
               std::vector<int32_t>& owner, std::vector<double>& dist, int32_t* pred) {
  owner.assign(static_cast<size_t>(g.n), -1);
  dist.assign(static_cast<size_t>(g.n), kInf);
  MinQueue queue;
  for (int32_t s = 0; s < sourceCount; ++s) {
    const int32_t v = sources[s];
    if (owner[v] >= 0) continue;
    owner[v] = s;
    dist[v] = 0;
    if (pred) pred[v] = -1;
    queue.push({0.0, s, v});
  }
  settle(g, queue, owner.data(), dist.data(), pred);
}

}  // namespace

void nearestSources(const NodeGraph& g, const int32_t* sources, int32_t sourceCount,
                    std::vector<int32_t>& owner, std::vector<double>& dist) {
  searchAll(g, sources, sourceCount, owner, dist, nullptr);
}

void NearestSearch::update(const NodeGraph& g, const std::vector<int32_t>& sources) {
  const size_t n = static_cast<size_t>(g.n);
  bool edgesOnlyBroke = aliveThen.size() == g.alive.size() && owner.size() == n;
  for (size_t e = 0; e < g.alive.size() && edgesOnlyBroke; ++e)
    edgesOnlyBroke = !(g.alive[e] && !aliveThen[e]);
  aliveThen = g.alive;
  if (!edgesOnlyBroke || sources != sourcesThen) {
    sourcesThen = sources;
    pred.assign(n, -1);
    searchAll(g, sources.data(), static_cast<int32_t>(sources.size()), owner, dist, pred.data());
    return;
  }
  // Breaking edges only lengthens paths: a node keeps its distance and owner unless its path
  // to its handle crossed a newly broken edge, i.e. it lies below one in the predecessor tree.
  // Those are cleared and searched again from their intact neighbours; the fixed point is
  // unique, so the result equals a full search.
  childStart.assign(n + 1, 0);
  for (size_t v = 0; v < n; ++v)
    if (pred[v] >= 0) ++childStart[static_cast<size_t>(pred[v]) + 1];
  for (size_t v = 0; v < n; ++v) childStart[v + 1] += childStart[v];
  child.resize(childStart[n]);
  {
    std::vector<int32_t> put(childStart.begin(), childStart.end() - 1);
    for (size_t v = 0; v < n; ++v)
      if (pred[v] >= 0)
        child[static_cast<size_t>(put[static_cast<size_t>(pred[v])]++)] = static_cast<int32_t>(v);
  }
  cleared.clear();
  for (int32_t u = 0; u < g.n; ++u)
    for (int32_t k = g.start[u]; k < g.start[u + 1]; ++k) {
      const int32_t v = g.adj[k];
      if (g.alive[k] || pred[v] != u || owner[v] < 0) continue;
      owner[v] = -1;  // -1 marks a cleared node until the search below
      cleared.push_back(v);
    }
  for (size_t c = 0; c < cleared.size(); ++c) {
    const int32_t u = cleared[c];
    for (int32_t q = childStart[u]; q < childStart[u + 1]; ++q)
      if (owner[child[q]] >= 0) {
        owner[child[q]] = -1;
        cleared.push_back(child[q]);
      }
  }
  for (int32_t v : cleared) {
    dist[v] = kInf;
    pred[v] = -1;
  }
  MinQueue queue;
  for (int32_t v : cleared)
    for (int32_t k = g.start[v]; k < g.start[v + 1]; ++k) {
      const int32_t u = g.adj[k];
      if (!g.alive[k] || owner[u] < 0) continue;
      const double nd = dist[u] + g.length[k];
      if (nd < dist[v] || (nd == dist[v] && owner[u] < owner[v])) {
        dist[v] = nd;
        owner[v] = owner[u];
        pred[v] = u;
      }
    }
  for (int32_t v : cleared)
    if (owner[v] >= 0) queue.push({dist[v], owner[v], v});
  settle(g, queue, owner.data(), dist.data(), pred.data());
}

int32_t CoarseMatrix::find(int32_t r, int32_t c) const {
  if (r < 0 || r >= n) return -1;
  const int32_t* first = col.data() + rowStart[r];
  const int32_t* last = col.data() + rowStart[r + 1];
  const int32_t* it = std::lower_bound(first, last, c);
  return (it != last && *it == c) ? static_cast<int32_t>(it - col.data()) : -1;
}

std::vector<int32_t> MultigridHierarchy::defaultCounts(int32_t freeNodes, bool smooth) {
  const double perHandle = smooth ? kNodesPerHandleSmoothed : kNodesPerHandle;
  const int32_t coarsest = smooth ? kCoarsestHandlesSmoothed : kCoarsestHandles;
  std::vector<int32_t> counts;
  int32_t k =
      std::max<int32_t>(1, static_cast<int32_t>(std::lround(double(freeNodes) / perHandle)));
  counts.push_back(k);
  while (k > coarsest) {
    k = std::max<int32_t>(1, static_cast<int32_t>(std::lround(double(k) / kCoarsening)));
    counts.push_back(k);
  }
  return counts;
}

Result<void> MultigridHierarchy::build(const std::vector<int32_t>& counts,
                                       const double* restPositions, const uint8_t* fixedNode,
                                       const BlockSparseMatrix& A, bool smooth, double filter) {
  for (size_t l = 0; l < counts.size(); ++l) {
    if (counts[l] <= 0)
      return fail("multigrid.levels: handle count ", std::to_string(counts[l]), " is not positive");
    if (l > 0 && counts[l] >= counts[l - 1])
      return fail("multigrid.levels: handle counts must grow from coarse to fine (",
                  std::to_string(counts[l]), " then ", std::to_string(counts[l - 1]), ")");
  }
  const size_t n = static_cast<size_t>(A.n);
  m_smooth = smooth;
  m_filter = filter;
  m_rest.assign(restPositions, restPositions + 3 * n);
  m_fixed.assign(fixedNode, fixedNode + n);
  m_fineRowStart = A.rowStart;
  m_fineCol = A.col;
  m_fineRow.resize(A.col.size());
  for (int32_t r = 0; r < A.n; ++r)
    for (int32_t k = A.rowStart[r]; k < A.rowStart[r + 1]; ++k) m_fineRow[k] = r;
  m_graph = NodeGraph::fromPattern(A, restPositions);
  // The fine block of each graph entry (fromPattern lists the off-diagonal blocks in order).
  m_graphBlock.clear();
  m_graphBlock.reserve(m_graph.adj.size());
  for (int32_t r = 0; r < A.n; ++r)
    for (int32_t k = A.rowStart[r]; k < A.rowStart[r + 1]; ++k)
      if (A.col[k] != r) m_graphBlock.push_back(k);

  m_levels.clear();
  const std::vector<int32_t> order =
      furthestPointSample(m_graph, fixedNode, counts.empty() ? 0 : counts[0]);
  for (int32_t c : counts) {
    const size_t k = std::min(static_cast<size_t>(c), order.size());
    // Clamping can make levels equal (tiny bodies); a level no coarser than the last is useless.
    if (k == 0 || (!m_levels.empty() && k >= m_levels.back().handleNode.size())) continue;
    CoarseLevel lv;
    lv.handleNode.assign(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(k));
    m_levels.push_back(std::move(lv));
  }
  bindAll(serialJobs());
  buildPatterns(serialJobs());
  return {};
}

void MultigridHierarchy::rebind(const int32_t* edgeNodes, const uint8_t* broken, int32_t edgeCount,
                                JobSystem& jobs) {
  m_graph.setBroken(edgeNodes, broken, edgeCount, jobs);
  bindAll(jobs);
  buildPatterns(jobs);
}

void MultigridHierarchy::invalidateProlongation() {
  for (CoarseLevel& lv : m_levels) lv.prolongationFresh = false;
}

void MultigridHierarchy::bindAll(JobSystem& jobs) {
  constexpr uint32_t kNodeGrain = 1024;
  const int32_t n = m_graph.n;
  std::vector<int32_t> component;
  const int32_t componentCount = m_graph.components(component, jobs);
  std::vector<int32_t> freeCount(static_cast<size_t>(componentCount), 0);
  std::vector<int32_t> firstFree(static_cast<size_t>(componentCount), -1);
  for (int32_t i = 0; i < n; ++i) {
    if (m_fixed[i]) continue;
    if (firstFree[component[i]] < 0) firstFree[component[i]] = i;
    ++freeCount[component[i]];
  }

  for (size_t l = 0; l < m_levels.size(); ++l) {
    CoarseLevel& lv = m_levels[l];
    // A fragment without a handle at this level gets one: on level 1 its lowest free node,
    // deeper its first handle of the finer level (so the levels stay nested).
    std::vector<uint8_t> has(static_cast<size_t>(componentCount), 0);
    for (int32_t h : lv.handleNode) has[component[h]] = 1;
    if (l == 0) {
      for (int32_t c = 0; c < componentCount; ++c)
        if (!has[c] && freeCount[c] >= kMinFragmentNodes) lv.handleNode.push_back(firstFree[c]);
    } else {
      for (int32_t h : m_levels[l - 1].handleNode)
        if (!has[component[h]]) {
          has[component[h]] = 1;
          lv.handleNode.push_back(h);
        }
    }
  }
  // Each level's Dijkstra reads only its own handles, so the levels' searches, the serial
  // bulk of a re-binding, run side by side.
  forRanges(jobs, static_cast<uint32_t>(m_levels.size()), 1, [&](uint32_t begin, uint32_t end) {
    for (uint32_t l = begin; l < end; ++l)
      m_levels[l].search.update(m_graph, m_levels[l].handleNode);
  });
  for (size_t l = 0; l < m_levels.size(); ++l) {
    CoarseLevel& lv = m_levels[l];
    const int32_t k = static_cast<int32_t>(lv.handleNode.size());
    const std::vector<int32_t>& owner = lv.search.owner;

    // Composed binding: a fine node follows its finer handle, which follows the handle its own
    // node is nearest to (the tentative prolongators nest, eq 6.8).
    lv.nodeHandle.resize(static_cast<size_t>(n));
    if (l == 0) {
      forRanges(jobs, static_cast<uint32_t>(n), kNodeGrain, [&](uint32_t b, uint32_t e) {
        for (uint32_t i = b; i < e; ++i) lv.nodeHandle[i] = m_fixed[i] ? -1 : owner[i];
      });
    } else {
      const CoarseLevel& finer = m_levels[l - 1];
      std::vector<int32_t> parent(finer.handleNode.size());
      for (size_t h = 0; h < finer.handleNode.size(); ++h) parent[h] = owner[finer.handleNode[h]];
      forRanges(jobs, static_cast<uint32_t>(n), kNodeGrain, [&](uint32_t b, uint32_t e) {
        for (uint32_t i = b; i < e; ++i)
          lv.nodeHandle[i] = finer.nodeHandle[i] >= 0 ? parent[finer.nodeHandle[i]] : -1;
      });
      lv.finerParent = parent;
    }

    // Level length s_l: RMS distance of the bound nodes to their handle.
    double sum = 0;
    size_t bound = 0;
    for (int32_t i = 0; i < n; ++i) {
      const int32_t h = lv.nodeHandle[i];
      if (h < 0) continue;
      const int32_t hn = lv.handleNode[h];
      for (int a = 0; a < 3; ++a) {
        const double d = m_rest[3 * i + a] - m_rest[3 * hn + a];
        sum += d * d;
      }
      ++bound;
    }
    lv.scale = bound > 0 && sum > 0 ? std::sqrt(sum / double(bound)) : 1.0;
    lv.coord.resize(3 * static_cast<size_t>(n));
    forRanges(jobs, static_cast<uint32_t>(n), kNodeGrain, [&](uint32_t b, uint32_t e) {
      for (uint32_t i = b; i < e; ++i) {
        const int32_t h = lv.nodeHandle[i];
        for (uint32_t a = 0; a < 3; ++a)
          lv.coord[3 * i + a] =
              h < 0 ? 0.0 : (m_rest[3 * i + a] - m_rest[3 * lv.handleNode[h] + a]) / lv.scale;
      }
    });
    if (l > 0) {
      const CoarseLevel& finer = m_levels[l - 1];
      lv.childRatio = finer.scale / lv.scale;
      lv.childOffset.assign(3 * finer.handleNode.size(), 0.0);
      for (size_t h = 0; h < finer.handleNode.size(); ++h)
        for (int a = 0; a < 3; ++a)
          lv.childOffset[3 * h + a] = (m_rest[3 * finer.handleNode[h] + a] -
                                       m_rest[3 * lv.handleNode[lv.finerParent[h]] + a]) /
                                      lv.scale;
    }

    // Null directions of each level-1 aggregate: the Gram matrix of [x; 1] over its nodes.
    lv.nullProjector.assign(16 * static_cast<size_t>(k), 0.0);
    if (l > 0) continue;
    std::vector<Eigen::Matrix4d> gram(static_cast<size_t>(k), Eigen::Matrix4d::Zero());
    for (int32_t i = 0; i < n; ++i) {
      const int32_t h = lv.nodeHandle[i];
      if (h < 0) continue;
      const Eigen::Vector4d x(lv.coord[3 * i], lv.coord[3 * i + 1], lv.coord[3 * i + 2], 1.0);
      gram[h] += x * x.transpose();
    }
    for (int32_t h = 0; h < k; ++h) {
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(gram[h]);
      const double top = eig.eigenvalues()(3);
      Eigen::Matrix4d proj = Eigen::Matrix4d::Zero();
      for (int e = 0; e < 4; ++e)
        if (!(eig.eigenvalues()(e) > kNullTolerance * top))
          proj += eig.eigenvectors().col(e) * eig.eigenvectors().col(e).transpose();
      for (int a = 0; a < 16; ++a) lv.nullProjector[16 * h + a] = proj(a / 4, a % 4);
    }
  }
}

void MultigridHierarchy::tentativeBlock(int l, int32_t row, double* out) const {
  const CoarseLevel& lv = level(l);
  tentativeBlockFor(l, row, l == 1 ? lv.nodeHandle[row] : lv.finerParent[row], out);
}

void MultigridHierarchy::tentativeBlockFor(int l, int32_t row, int32_t handle, double* out) const {
  const CoarseLevel& lv = level(l);
  const double* Xh =
      handle >= 0 ? m_rest.data() + 3 * static_cast<size_t>(lv.handleNode[handle]) : nullptr;
  if (l == 1) {
    std::fill(out, out + 36, 0.0);
    if (handle < 0 || m_fixed[row]) return;
    // eq 6.6-6.7: x_i = T_h [x; 1], so the block is [x; 1]^T (x) I3.
    double x[3];
    if (handle == lv.nodeHandle[row]) {
      for (int a = 0; a < 3; ++a) x[a] = lv.coord[3 * static_cast<size_t>(row) + a];
    } else {
      for (int a = 0; a < 3; ++a)
        x[a] = (m_rest[3 * static_cast<size_t>(row) + a] - Xh[a]) / lv.scale;
    }
    for (int k = 0; k < 3; ++k) {
      for (int a = 0; a < 3; ++a) out[12 * k + 3 * a + k] = x[a];
      out[12 * k + 9 + k] = 1.0;
    }
    return;
  }
  std::fill(out, out + 144, 0.0);
  if (handle < 0) return;
  // eq 6.8: the finer handle's affine map is the coarser one seen from its own origin.
  double d[3];
  if (handle == lv.finerParent[row]) {
    for (int a = 0; a < 3; ++a) d[a] = lv.childOffset[3 * static_cast<size_t>(row) + a];
  } else {
    const double* Xf = m_rest.data() + 3 * static_cast<size_t>(level(l - 1).handleNode[row]);
    for (int a = 0; a < 3; ++a) d[a] = (Xf[a] - Xh[a]) / lv.scale;
  }
  for (int j = 0; j < 9; ++j) out[13 * j] = lv.childRatio;
  for (int k = 0; k < 3; ++k) {
    for (int a = 0; a < 3; ++a) out[12 * (9 + k) + 3 * a + k] = d[a];
    out[12 * (9 + k) + 9 + k] = 1.0;
  }
}

void MultigridHierarchy::buildPatterns(JobSystem& jobs) {
  const int32_t n = m_graph.n;
  size_t scratch = 0;
  // Fine blocks of the filtered matrix A_F: the diagonal and the unbroken edges.
  // A row's graph edges are blocks of the same row, so rows fill apart.
  std::vector<uint8_t> fineAlive(m_fineCol.size(), 0);
  forRanges(jobs, static_cast<uint32_t>(n), kRowsPerChunk, [&](uint32_t begin, uint32_t end) {
    for (int32_t r = static_cast<int32_t>(begin); r < static_cast<int32_t>(end); ++r) {
      for (int32_t b = m_fineRowStart[r]; b < m_fineRowStart[r + 1]; ++b)
        fineAlive[b] = m_fineCol[b] == r ? 1 : 0;
      for (int32_t e = m_graph.start[r]; e < m_graph.start[r + 1]; ++e)
        if (m_graph.alive[e]) fineAlive[m_graphBlock[e]] = 1;
    }
  });
  for (size_t li = 0; li < m_levels.size(); ++li) {
    CoarseLevel& lv = m_levels[li];
    const int l = static_cast<int>(li) + 1;
    const int B = l == 1 ? 3 : 12;
    const int32_t k = static_cast<int32_t>(lv.handleNode.size());
    // The finer level: its rows, the parent (this level's handle) of each, and its matrix
    // pattern (the mesh's on level 1, level l-1's operator deeper).
    const int32_t rows = l == 1 ? n : static_cast<int32_t>(m_levels[li - 1].handleNode.size());
    const int32_t* rowStart = l == 1 ? m_fineRowStart.data() : m_levels[li - 1].A.rowStart.data();
    const int32_t* colIdx = l == 1 ? m_fineCol.data() : m_levels[li - 1].A.col.data();
    const std::vector<int32_t>& parent = l == 1 ? lv.nodeHandle : lv.finerParent;
    scratch = std::max(scratch, static_cast<size_t>(B) * rows);
    const bool smoothHere = smoothesLevel(l);

    // Filtered neighbours of each finer row for the smoothing: itself and the rows joined to
    // it by an unbroken edge (level 1), or whose aggregates an unbroken fine edge joins
    // (deeper), with the matrix block between them. Broken edges never enter P.
    std::vector<int32_t>& fStart = lv.fStart;
    std::vector<int32_t>& fBlock = lv.fBlock;
    std::vector<int32_t>& fCol = lv.fCol;
    std::vector<PatternChunk> rowChunks(chunkCount(rows, kRowsPerChunk));
    auto eachRowChunk = [&](const auto& f) {
      forRanges(jobs, static_cast<uint32_t>(rowChunks.size()), 1,
                [&](uint32_t begin, uint32_t end) {
                  for (uint32_t ci = begin; ci < end; ++ci) {
                    const int32_t r0 = static_cast<int32_t>(ci) * kRowsPerChunk;
                    f(rowChunks[ci], r0, std::min(rows, r0 + kRowsPerChunk));
                  }
                });
    };
    std::vector<int32_t> unusedStart, unusedTerms;
    if (smoothHere) {
      eachRowChunk([&](PatternChunk& ch, int32_t r0, int32_t r1) {
        for (int32_t r = r0; r < r1; ++r) {
          const size_t before = ch.col.size();
          ch.col.push_back(r);
          if (l == 1) {
            ch.first.push_back(
                m_fineRowStart[r] +
                static_cast<int32_t>(std::lower_bound(m_fineCol.data() + m_fineRowStart[r],
                                                      m_fineCol.data() + m_fineRowStart[r + 1], r) -
                                     (m_fineCol.data() + m_fineRowStart[r])));
            for (int32_t e = m_graph.start[r]; e < m_graph.start[r + 1]; ++e) {
              if (!m_graph.alive[e]) continue;
              ch.col.push_back(m_graph.adj[e]);
              ch.first.push_back(m_graphBlock[e]);
            }
          } else {
            // Deeper: the blocks of A_{l-1} that P^T A_F P fills (alive, see
            // CoarseLevel::alive), the diagonal first (the smoothing reads D there).
            const CoarseLevel& finer = m_levels[li - 1];
            ch.first.push_back(finer.A.find(r, r));
            for (int32_t b = finer.A.rowStart[r]; b < finer.A.rowStart[r + 1]; ++b) {
              if (finer.A.col[b] == r || !finer.alive[b]) continue;
              ch.col.push_back(finer.A.col[b]);
              ch.first.push_back(b);
            }
          }
          ch.perRow.push_back(static_cast<int32_t>(ch.col.size() - before));
        }
      });
      stitch(rowChunks, fStart, fCol, unusedStart, fBlock, unusedTerms);
    } else {
      fStart.assign(static_cast<size_t>(rows) + 1, 0);
      fBlock.clear();
      fCol.clear();
    }

    // P's pattern: per finer row, the parents of its filtered neighbours (just its own parent
    // without smoothing); per block, the smoothing terms (A_rj, j) in increasing j.
    for (PatternChunk& ch : rowChunks) ch = PatternChunk{};
    eachRowChunk([&](PatternChunk& ch, int32_t r0, int32_t r1) {
      std::vector<std::array<int32_t, 3>> cand;  // (handle, j, block)
      for (int32_t r = r0; r < r1; ++r) {
        const size_t before = ch.col.size();
        const bool skip = l == 1 && m_fixed[r];
        cand.clear();
        if (!skip && smoothHere && parent[r] >= 0) {
          for (int32_t f = fStart[r]; f < fStart[r + 1]; ++f)
            if (parent[fCol[f]] >= 0) cand.push_back({parent[fCol[f]], fCol[f], fBlock[f]});
          if (m_filter > 0) lumpWeakHandles(cand, parent[r], m_filter);
        } else if (!skip && parent[r] >= 0) {
          cand.push_back({parent[r], r, -1});
        }
        std::sort(cand.begin(), cand.end());
        for (size_t c = 0; c < cand.size(); ++c) {
          if (c == 0 || cand[c][0] != cand[c - 1][0]) {
            ch.col.push_back(cand[c][0]);
            ch.terms.push_back(0);
          }
          if (cand[c][2] >= 0) {
            ++ch.terms.back();
            ch.first.push_back(cand[c][2]);
            ch.second.push_back(cand[c][1]);
          }
        }
        ch.perRow.push_back(static_cast<int32_t>(ch.col.size() - before));
      }
    });
    stitch(rowChunks, lv.pStart, lv.pCol, lv.sStart, lv.sBlock, lv.sRow);
    lv.pRow.resize(lv.pCol.size());
    forRanges(jobs, static_cast<uint32_t>(rows), kRowsPerChunk, [&](uint32_t begin, uint32_t end) {
      for (uint32_t r = begin; r < end; ++r)
        std::fill(lv.pRow.begin() + lv.pStart[r], lv.pRow.begin() + lv.pStart[r + 1],
                  static_cast<int32_t>(r));
    });
    const size_t pBlocks = lv.pCol.size();
    lv.pValues.assign(pBlocks * static_cast<size_t>(B) * 12, 0.0);
    lv.prolongationFresh = false;
    lv.omega = 0;
    // Transpose: per handle, its blocks by increasing row (counting sort keeps row order).
    lv.ptStart.assign(static_cast<size_t>(k) + 1, 0);
    for (int32_t c : lv.pCol) ++lv.ptStart[c + 1];
    for (int32_t h = 0; h < k; ++h) lv.ptStart[h + 1] += lv.ptStart[h];
    lv.ptBlock.resize(pBlocks);
    {
      std::vector<int32_t> put(lv.ptStart.begin(), lv.ptStart.end() - 1);
      for (size_t b = 0; b < pBlocks; ++b) lv.ptBlock[put[lv.pCol[b]]++] = static_cast<int32_t>(b);
    }
    lv.ptRow.resize(pBlocks);
    for (size_t t = 0; t < pBlocks; ++t) lv.ptRow[t] = lv.pRow[lv.ptBlock[t]];
    lv.ptValues.assign(smoothHere ? pBlocks * static_cast<size_t>(B) * 12 : 0, 0.0);

    // Q = A P: only rows that P uses (P^T Q reads no other); terms (A_rj, P_jK) by increasing j.
    std::vector<PatternChunk> chunks(chunkCount(rows, kRowsPerChunk));
    forRanges(jobs, static_cast<uint32_t>(chunks.size()), 1, [&](uint32_t begin, uint32_t end) {
      std::vector<std::array<int32_t, 4>> qc;  // (handle, j, A block, P block)
      for (uint32_t ci = begin; ci < end; ++ci) {
        PatternChunk& ch = chunks[ci];
        const int32_t r0 = static_cast<int32_t>(ci) * kRowsPerChunk;
        for (int32_t r = r0; r < std::min(rows, r0 + kRowsPerChunk); ++r) {
          const size_t before = ch.col.size();
          if (lv.pStart[r + 1] > lv.pStart[r]) {
            qc.clear();
            for (int32_t a = rowStart[r]; a < rowStart[r + 1]; ++a) {
              const int32_t j = colIdx[a];
              for (int32_t p = lv.pStart[j]; p < lv.pStart[j + 1]; ++p)
                qc.push_back({lv.pCol[p], j, a, p});
            }
            std::sort(qc.begin(), qc.end());
            for (size_t c = 0; c < qc.size(); ++c) {
              if (c == 0 || qc[c][0] != qc[c - 1][0]) {
                ch.col.push_back(qc[c][0]);
                ch.terms.push_back(0);
              }
              ++ch.terms.back();
              ch.first.push_back(qc[c][2]);
              ch.second.push_back(qc[c][3]);
            }
          }
          ch.perRow.push_back(static_cast<int32_t>(ch.col.size() - before));
        }
      }
    });
    stitch(chunks, lv.qStart, lv.qCol, lv.qcStart, lv.qcA, lv.qcP);
    lv.qValues.resize(lv.qCol.size() * static_cast<size_t>(B) * 12);  // rewritten per product
    // Which Q blocks the filtered product A_F P fills: a term through an alive finer block.
    std::vector<uint8_t> qAlive(lv.qCol.size(), 0);
    forRanges(jobs, static_cast<uint32_t>(lv.qCol.size()), kRowsPerChunk,
              [&](uint32_t begin, uint32_t end) {
                for (uint32_t q = begin; q < end; ++q)
                  for (int32_t c = lv.qcStart[q]; c < lv.qcStart[q + 1] && !qAlive[q]; ++c)
                    qAlive[q] = l == 1 ? fineAlive[lv.qcA[c]] : m_levels[li - 1].alive[lv.qcA[c]];
              });

    // A_l = P^T Q: per coarse row H, the pairs (P_rH, Q_rK) by increasing r; plus the diagonal.
    CoarseMatrix& C = lv.A;
    C.n = k;
    chunks.assign(chunkCount(k, kHandlesPerChunk), PatternChunk{});
    forRanges(jobs, static_cast<uint32_t>(chunks.size()), 1, [&](uint32_t begin, uint32_t end) {
      std::vector<std::array<int32_t, 4>> gc;  // (K, r, P block, Q block)
      for (uint32_t ci = begin; ci < end; ++ci) {
        PatternChunk& ch = chunks[ci];
        const int32_t h0 = static_cast<int32_t>(ci) * kHandlesPerChunk;
        for (int32_t h = h0; h < std::min(k, h0 + kHandlesPerChunk); ++h) {
          const size_t before = ch.col.size();
          gc.clear();
          gc.push_back({h, -1, -1, -1});  // the diagonal block, even for an empty aggregate
          for (int32_t t = lv.ptStart[h]; t < lv.ptStart[h + 1]; ++t) {
            const int32_t p = lv.ptBlock[t];
            const int32_t r = lv.pRow[p];
            for (int32_t q = lv.qStart[r]; q < lv.qStart[r + 1]; ++q)
              gc.push_back({lv.qCol[q], r, p, q});
          }
          std::sort(gc.begin(), gc.end());
          for (size_t c = 0; c < gc.size(); ++c) {
            if (c == 0 || gc[c][0] != gc[c - 1][0]) {
              ch.col.push_back(gc[c][0]);
              ch.terms.push_back(0);
            }
            if (gc[c][2] >= 0 && gc[c][0] >= h) {  // the upper triangle; the lower mirrors it
              ++ch.terms.back();
              ch.first.push_back(gc[c][2]);
              ch.second.push_back(gc[c][3]);
            }
          }
          ch.perRow.push_back(static_cast<int32_t>(ch.col.size() - before));
        }
      }
    });
    stitch(chunks, C.rowStart, C.col, lv.gatherStart, lv.gatherP, lv.gatherQ);
    C.values.resize(144 * C.col.size());  // rewritten per product
    lv.mirror.assign(C.col.size(), -1);
    for (int32_t h = 0; h < k; ++h)
      for (int32_t c = C.rowStart[h]; c < C.rowStart[h + 1]; ++c)
        if (C.col[c] < h) lv.mirror[c] = C.find(C.col[c], h);
    lv.alive.assign(C.col.size(), 0);
    for (int32_t h = 0; h < k; ++h)
      for (int32_t c = C.rowStart[h]; c < C.rowStart[h + 1]; ++c) {
        lv.alive[c] = C.col[c] == h ? 1 : 0;
        for (int32_t g = lv.gatherStart[c]; g < lv.gatherStart[c + 1] && !lv.alive[c]; ++g)
          lv.alive[c] = qAlive[lv.gatherQ[g]];
      }
    for (size_t c = 0; c < C.col.size(); ++c)
      if (lv.mirror[c] >= 0) lv.alive[c] = lv.alive[lv.mirror[c]];
  }
  if (m_smooth) {
    m_invDiag.assign(scratch * 12, 0.0);  // B x B per row, B <= 12
    m_v.assign(scratch, 0.0);
    m_w.assign(scratch, 0.0);
    m_t.assign(scratch, 0.0);
  }
}

}  // namespace gf::detail
