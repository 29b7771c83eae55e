// Multigrid hierarchy: furthest-point handles, geodesic binding, coarse patterns and transfers.
#include "solver/multigrid_hierarchy.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <string>

#include "solver/vector_ops.h"

namespace gf::detail {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// A fragment with fewer free nodes than this gets no handle of its own when cracks cut it off:
// its few nodes are left to the smoother (zero rows of U, like Dirichlet nodes), which resolves
// them in a sweep or two, instead of adding coarse unknowns that would be mostly null.
constexpr int32_t kMinFragmentNodes = 4;
// Gram eigenvalues below this fraction of the largest are null directions of an aggregate.
constexpr double kNullTolerance = 1e-9;
// Handles per parallel range of the coarse assembly and the transfers.
constexpr uint32_t kHandleGrain = 8;
constexpr uint32_t kNodeGrain = 256;

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

void NodeGraph::setBroken(const int32_t* edgeNodes, const uint8_t* broken, int32_t edgeCount) {
  std::fill(alive.begin(), alive.end(), uint8_t{1});
  auto kill = [&](int32_t a, int32_t b) {
    if (a < 0 || a >= n) return;
    const int32_t* first = adj.data() + start[a];
    const int32_t* last = adj.data() + start[a + 1];
    const int32_t* it = std::lower_bound(first, last, b);
    if (it != last && *it == b) alive[static_cast<size_t>(it - adj.data())] = 0;
  };
  for (int32_t e = 0; e < edgeCount; ++e) {
    if (!broken[e]) continue;
    kill(edgeNodes[2 * e], edgeNodes[2 * e + 1]);
    kill(edgeNodes[2 * e + 1], edgeNodes[2 * e]);
  }
}

int32_t NodeGraph::components(std::vector<int32_t>& component) const {
  component.assign(static_cast<size_t>(n), -1);
  std::vector<int32_t> stack;
  int32_t count = 0;
  for (int32_t s = 0; s < n; ++s) {
    if (component[s] >= 0) continue;
    component[s] = count;
    stack.push_back(s);
    while (!stack.empty()) {
      const int32_t u = stack.back();
      stack.pop_back();
      for (int32_t k = start[u]; k < start[u + 1]; ++k) {
        if (!alive[k] || component[adj[k]] >= 0) continue;
        component[adj[k]] = count;
        stack.push_back(adj[k]);
      }
    }
    ++count;
  }
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

void nearestSources(const NodeGraph& g, const int32_t* sources, int32_t sourceCount,
                    std::vector<int32_t>& owner, std::vector<double>& dist) {
  owner.assign(static_cast<size_t>(g.n), -1);
  dist.assign(static_cast<size_t>(g.n), kInf);
  MinQueue queue;
  for (int32_t s = 0; s < sourceCount; ++s) {
    const int32_t v = sources[s];
    if (owner[v] >= 0) continue;
    owner[v] = s;
    dist[v] = 0;
    queue.push({0.0, s, v});
  }
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
        queue.push({nd, top.owner, v});
      }
    }
  }
}

int32_t CoarseMatrix::find(int32_t r, int32_t c) const {
  if (r < 0 || r >= n) return -1;
  const int32_t* first = col.data() + rowStart[r];
  const int32_t* last = col.data() + rowStart[r + 1];
  const int32_t* it = std::lower_bound(first, last, c);
  return (it != last && *it == c) ? static_cast<int32_t>(it - col.data()) : -1;
}

Result<void> MultigridHierarchy::build(const std::vector<int32_t>& counts,
                                       const double* restPositions, const uint8_t* fixedNode,
                                       const BlockSparseMatrix& A) {
  for (size_t l = 0; l < counts.size(); ++l) {
    if (counts[l] <= 0)
      return fail("multigrid.levels: handle count ", std::to_string(counts[l]), " is not positive");
    if (l > 0 && counts[l] >= counts[l - 1])
      return fail("multigrid.levels: handle counts must grow from coarse to fine (",
                  std::to_string(counts[l]), " then ", std::to_string(counts[l - 1]), ")");
  }
  const size_t n = static_cast<size_t>(A.n);
  m_rest.assign(restPositions, restPositions + 3 * n);
  m_fixed.assign(fixedNode, fixedNode + n);
  m_fineRowStart = A.rowStart;
  m_fineCol = A.col;
  m_fineRow.resize(A.col.size());
  for (int32_t r = 0; r < A.n; ++r)
    for (int32_t k = A.rowStart[r]; k < A.rowStart[r + 1]; ++k) m_fineRow[k] = r;
  m_graph = NodeGraph::fromPattern(A, restPositions);

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
  bindAll();
  buildPatterns();
  return {};
}

void MultigridHierarchy::rebind(const int32_t* edgeNodes, const uint8_t* broken,
                                int32_t edgeCount) {
  m_graph.setBroken(edgeNodes, broken, edgeCount);
  bindAll();
  buildPatterns();
}

void MultigridHierarchy::bindAll() {
  const int32_t n = m_graph.n;
  std::vector<int32_t> component;
  const int32_t componentCount = m_graph.components(component);
  std::vector<int32_t> freeCount(static_cast<size_t>(componentCount), 0);
  std::vector<int32_t> firstFree(static_cast<size_t>(componentCount), -1);
  for (int32_t i = 0; i < n; ++i) {
    if (m_fixed[i]) continue;
    if (firstFree[component[i]] < 0) firstFree[component[i]] = i;
    ++freeCount[component[i]];
  }

  std::vector<int32_t> owner;
  std::vector<double> dist;
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
    const int32_t k = static_cast<int32_t>(lv.handleNode.size());
    nearestSources(m_graph, lv.handleNode.data(), k, owner, dist);

    // Composed binding: a fine node follows its finer handle, which follows the handle its own
    // node is nearest to (eq 6.8 keeps U piecewise constant).
    lv.nodeHandle.assign(static_cast<size_t>(n), -1);
    lv.childStart.assign(static_cast<size_t>(k) + 1, 0);
    lv.child.clear();
    if (l == 0) {
      for (int32_t i = 0; i < n; ++i)
        if (!m_fixed[i]) lv.nodeHandle[i] = owner[i];
    } else {
      const CoarseLevel& finer = m_levels[l - 1];
      std::vector<int32_t> parent(finer.handleNode.size());
      for (size_t h = 0; h < finer.handleNode.size(); ++h) parent[h] = owner[finer.handleNode[h]];
      for (int32_t i = 0; i < n; ++i)
        if (finer.nodeHandle[i] >= 0) lv.nodeHandle[i] = parent[finer.nodeHandle[i]];
      lv.finerParent = parent;
    }
    // Children lists by counting sort (increasing child index within each handle).
    const std::vector<int32_t>& parentOf = l == 0 ? lv.nodeHandle : lv.finerParent;
    for (int32_t p : parentOf)
      if (p >= 0) ++lv.childStart[p + 1];
    for (int32_t h = 0; h < k; ++h) lv.childStart[h + 1] += lv.childStart[h];
    lv.child.resize(static_cast<size_t>(lv.childStart[k]));
    {
      std::vector<int32_t> fill(lv.childStart.begin(), lv.childStart.end() - 1);
      for (size_t c = 0; c < parentOf.size(); ++c)
        if (parentOf[c] >= 0) lv.child[fill[parentOf[c]]++] = static_cast<int32_t>(c);
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
    lv.coord.assign(3 * static_cast<size_t>(n), 0.0);
    for (int32_t i = 0; i < n; ++i) {
      const int32_t h = lv.nodeHandle[i];
      if (h < 0) continue;
      for (int a = 0; a < 3; ++a)
        lv.coord[3 * i + a] = (m_rest[3 * i + a] - m_rest[3 * lv.handleNode[h] + a]) / lv.scale;
    }
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

    // Null directions of each aggregate: the Gram matrix of [x; 1] over its bound nodes.
    std::vector<Eigen::Matrix4d> gram(static_cast<size_t>(k), Eigen::Matrix4d::Zero());
    for (int32_t i = 0; i < n; ++i) {
      const int32_t h = lv.nodeHandle[i];
      if (h < 0) continue;
      const Eigen::Vector4d x(lv.coord[3 * i], lv.coord[3 * i + 1], lv.coord[3 * i + 2], 1.0);
      gram[h] += x * x.transpose();
    }
    lv.nullProjector.assign(16 * static_cast<size_t>(k), 0.0);
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

void MultigridHierarchy::buildPatterns() {
  const size_t fineBlocks = m_fineCol.size();
  for (CoarseLevel& lv : m_levels) {
    const int32_t k = static_cast<int32_t>(lv.handleNode.size());
    // Candidate columns per coarse row: every fine block between two bound nodes, plus the
    // diagonal; then sort and deduplicate each row.
    std::vector<int32_t> offset(static_cast<size_t>(k) + 1, 0);
    for (int32_t h = 0; h < k; ++h) offset[h + 1] = 1;
    for (size_t b = 0; b < fineBlocks; ++b) {
      const int32_t p = lv.nodeHandle[m_fineRow[b]], q = lv.nodeHandle[m_fineCol[b]];
      if (p >= 0 && q >= 0) ++offset[p + 1];
    }
    for (int32_t h = 0; h < k; ++h) offset[h + 1] += offset[h];
    std::vector<int32_t> cand(static_cast<size_t>(offset[k]));
    std::vector<int32_t> fill(offset.begin(), offset.end() - 1);
    for (int32_t h = 0; h < k; ++h) cand[fill[h]++] = h;
    for (size_t b = 0; b < fineBlocks; ++b) {
      const int32_t p = lv.nodeHandle[m_fineRow[b]], q = lv.nodeHandle[m_fineCol[b]];
      if (p >= 0 && q >= 0) cand[fill[p]++] = q;
    }
    CoarseMatrix& C = lv.A;
    C.n = k;
    C.rowStart.assign(static_cast<size_t>(k) + 1, 0);
    C.col.clear();
    for (int32_t h = 0; h < k; ++h) {
      auto first = cand.begin() + offset[h];
      auto last = cand.begin() + offset[h + 1];
      std::sort(first, last);
      last = std::unique(first, last);
      C.col.insert(C.col.end(), first, last);
      C.rowStart[h + 1] = static_cast<int32_t>(C.col.size());
    }
    C.values.assign(144 * C.col.size(), 0.0);

    // Contribution lists, fine blocks in increasing order inside each coarse block.
    std::vector<int32_t> target(fineBlocks, -1);
    lv.gatherStart.assign(C.col.size() + 1, 0);
    for (size_t b = 0; b < fineBlocks; ++b) {
      const int32_t p = lv.nodeHandle[m_fineRow[b]], q = lv.nodeHandle[m_fineCol[b]];
      if (p < 0 || q < 0) continue;
      target[b] = C.find(p, q);
      ++lv.gatherStart[target[b] + 1];
    }
    for (size_t c = 0; c < C.col.size(); ++c) lv.gatherStart[c + 1] += lv.gatherStart[c];
    lv.gatherBlock.resize(static_cast<size_t>(lv.gatherStart.back()));
    std::vector<int32_t> put(lv.gatherStart.begin(), lv.gatherStart.end() - 1);
    for (size_t b = 0; b < fineBlocks; ++b)
      if (target[b] >= 0) lv.gatherBlock[put[target[b]]++] = static_cast<int32_t>(b);
  }
}

void MultigridHierarchy::assemble(const BlockSparseMatrix& A, JobSystem& jobs) {
  for (CoarseLevel& lv : m_levels) {
    CoarseMatrix& C = lv.A;
    forRanges(jobs, static_cast<uint32_t>(C.n), kHandleGrain, [&](uint32_t begin, uint32_t end) {
      for (uint32_t p = begin; p < end; ++p) {
        for (int32_t kc = C.rowStart[p]; kc < C.rowStart[p + 1]; ++kc) {
          double out[144] = {};
          // eq 6.4: block (P, Q) = sum over fine blocks (i, j) of ([x_i;1] [x_j;1]^T) (x) A_ij.
          for (int32_t g = lv.gatherStart[kc]; g < lv.gatherStart[kc + 1]; ++g) {
            const int32_t b = lv.gatherBlock[g];
            const double* xr = lv.coord.data() + 3 * static_cast<size_t>(m_fineRow[b]);
            const double* xc = lv.coord.data() + 3 * static_cast<size_t>(m_fineCol[b]);
            const double hr[4] = {xr[0], xr[1], xr[2], 1.0};
            const double hc[4] = {xc[0], xc[1], xc[2], 1.0};
            const double* m = A.block(b);
            for (int a = 0; a < 4; ++a)
              for (int c = 0; c < 4; ++c) {
                const double w = hr[a] * hc[c];
                double* o = out + 36 * a + 3 * c;
                for (int i = 0; i < 3; ++i)
                  for (int j = 0; j < 3; ++j) o[12 * i + j] += w * m[3 * i + j];
              }
          }
          if (C.col[kc] == static_cast<int32_t>(p)) {
            // Null directions of the aggregate get the block's mean diagonal (see nullProjector).
            double trace = 0;
            for (int i = 0; i < 12; ++i) trace += out[13 * i];
            const double delta = trace > 0 && std::isfinite(trace) ? trace / 12 : 1.0;
            const double* proj = lv.nullProjector.data() + 16 * static_cast<size_t>(p);
            for (int a = 0; a < 4; ++a)
              for (int c = 0; c < 4; ++c)
                for (int i = 0; i < 3; ++i)
                  out[(3 * a + i) * 12 + 3 * c + i] += delta * proj[4 * a + c];
          }
          std::copy(out, out + 144, C.block(kc));
        }
      }
    });
  }
}

void MultigridHierarchy::restrictTo(int level, const double* fine, double* coarse,
                                    JobSystem& jobs) const {
  const CoarseLevel& lv = m_levels[static_cast<size_t>(level)];
  const uint32_t k = static_cast<uint32_t>(lv.handleNode.size());
  forRanges(jobs, k, kHandleGrain, [&](uint32_t begin, uint32_t end) {
    for (uint32_t h = begin; h < end; ++h) {
      double s[12] = {};
      for (int32_t c = lv.childStart[h]; c < lv.childStart[h + 1]; ++c) {
        const size_t ch = static_cast<size_t>(lv.child[c]);
        if (level == 0) {
          // U^T of a fine node: [x; 1] (x) r_i (eq 6.7).
          const double* x = lv.coord.data() + 3 * ch;
          const double* r = fine + 3 * ch;
          for (int a = 0; a < 3; ++a)
            for (int i = 0; i < 3; ++i) s[3 * a + i] += x[a] * r[i];
          for (int i = 0; i < 3; ++i) s[9 + i] += r[i];
        } else {
          // Transpose of eq 6.8's change of reference point.
          const double* d = lv.childOffset.data() + 3 * ch;
          const double* r = fine + 12 * ch;
          for (int a = 0; a < 3; ++a)
            for (int i = 0; i < 3; ++i)
              s[3 * a + i] += lv.childRatio * r[3 * a + i] + d[a] * r[9 + i];
          for (int i = 0; i < 3; ++i) s[9 + i] += r[9 + i];
        }
      }
      std::copy(s, s + 12, coarse + 12 * static_cast<size_t>(h));
    }
  });
}

void MultigridHierarchy::prolongAdd(int level, const double* coarse, double* fine,
                                    JobSystem& jobs) const {
  const CoarseLevel& lv = m_levels[static_cast<size_t>(level)];
  if (level == 0) {
    forRanges(jobs, static_cast<uint32_t>(m_graph.n), kNodeGrain,
              [&](uint32_t begin, uint32_t end) {
                for (uint32_t i = begin; i < end; ++i) {
                  const int32_t h = lv.nodeHandle[i];
                  if (h < 0) continue;
                  // eq 6.6: x_i = T_h [x; 1].
                  const double* x = lv.coord.data() + 3 * static_cast<size_t>(i);
                  const double* q = coarse + 12 * static_cast<size_t>(h);
                  for (int k = 0; k < 3; ++k)
                    fine[3 * i + k] += x[0] * q[k] + x[1] * q[3 + k] + x[2] * q[6 + k] + q[9 + k];
                }
              });
    return;
  }
  const uint32_t finerCount = static_cast<uint32_t>(lv.finerParent.size());
  forRanges(jobs, finerCount, kHandleGrain * 8, [&](uint32_t begin, uint32_t end) {
    for (uint32_t h = begin; h < end; ++h) {
      // eq 6.8: the finer handle's affine map is the coarser one seen from its own origin.
      const double* q = coarse + 12 * static_cast<size_t>(lv.finerParent[h]);
      const double* d = lv.childOffset.data() + 3 * static_cast<size_t>(h);
      double* out = fine + 12 * static_cast<size_t>(h);
      for (int j = 0; j < 9; ++j) out[j] += lv.childRatio * q[j];
      for (int k = 0; k < 3; ++k)
        out[9 + k] += d[0] * q[k] + d[1] * q[3 + k] + d[2] * q[6 + k] + q[9 + k];
    }
  });
}

}  // namespace gf::detail
