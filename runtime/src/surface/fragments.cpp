// Fragments over unbroken edges: full build, incremental splits, per-fragment totals.
#include "surface/fragments.h"

#include <algorithm>
#include <limits>

namespace gf::detail {

void Fragments::build(const EdgeGraph& graph, const uint8_t* broken) {
  const size_t n = static_cast<size_t>(graph.nodeCount);
  m_nodeFragment.assign(n, -1);
  m_order.clear();
  m_order.reserve(n);
  m_position.assign(n, 0);
  m_start.clear();
  m_count.clear();
  m_minNode.clear();
  m_splits.clear();
  m_mark.assign(n, 0);
  m_epoch = 0;
  m_pending.assign(static_cast<size_t>(graph.edgeCount), 0);

  // Seeds in increasing node order, so ids follow the lowest node of each component and the
  // queue of each search is exactly that fragment's range of m_order.
  for (int32_t seed = 0; seed < graph.nodeCount; ++seed) {
    if (m_nodeFragment[static_cast<size_t>(seed)] >= 0) continue;
    const int32_t f = count();
    const size_t begin = m_order.size();
    m_nodeFragment[static_cast<size_t>(seed)] = f;
    m_order.push_back(seed);
    for (size_t head = begin; head < m_order.size(); ++head) {
      const int32_t u = m_order[head];
      for (int32_t s = graph.nodeEdgeStart[static_cast<size_t>(u)];
           s < graph.nodeEdgeStart[static_cast<size_t>(u) + 1]; ++s) {
        const int32_t e = graph.nodeEdges[static_cast<size_t>(s)];
        if (broken && broken[e]) continue;
        const int32_t w = graph.edgeNodes[2 * static_cast<size_t>(e)] == u
                              ? graph.edgeNodes[2 * static_cast<size_t>(e) + 1]
                              : graph.edgeNodes[2 * static_cast<size_t>(e)];
        if (m_nodeFragment[static_cast<size_t>(w)] >= 0) continue;
        m_nodeFragment[static_cast<size_t>(w)] = f;
        m_order.push_back(w);
      }
    }
    m_start.push_back(static_cast<int32_t>(begin));
    m_count.push_back(static_cast<int32_t>(m_order.size() - begin));
    m_minNode.push_back(seed);
  }
  for (size_t i = 0; i < m_order.size(); ++i) {
    m_position[static_cast<size_t>(m_order[i])] = static_cast<int32_t>(i);
  }
  ++m_version;
}

void Fragments::nextEpoch() {
  // Two marks per search; on wrap-around old marks could alias new ones, so clear them.
  if (m_epoch >= std::numeric_limits<uint32_t>::max() - 4) {
    std::fill(m_mark.begin(), m_mark.end(), 0u);
    m_epoch = 0;
  }
  m_epoch += 2;
}

bool Fragments::separatePiece(const EdgeGraph& graph, const uint8_t* broken, int32_t a, int32_t b) {
  nextEpoch();
  const uint32_t markA = m_epoch, markB = m_epoch + 1;
  m_queueA.clear();
  m_queueB.clear();
  m_queueA.push_back(a);
  m_queueB.push_back(b);
  m_mark[static_cast<size_t>(a)] = markA;
  m_mark[static_cast<size_t>(b)] = markB;
  size_t headA = 0, headB = 0;

  // Expands one node of one search; returns 1 when the searches met, -1 when this search is
  // exhausted (its queue is a whole component without the other endpoint), 0 otherwise.
  auto expand = [&](std::vector<int32_t>& queue, size_t& head, uint32_t mine, uint32_t other) {
    if (head == queue.size()) return -1;
    const int32_t u = queue[head++];
    for (int32_t s = graph.nodeEdgeStart[static_cast<size_t>(u)];
         s < graph.nodeEdgeStart[static_cast<size_t>(u) + 1]; ++s) {
      const int32_t e = graph.nodeEdges[static_cast<size_t>(s)];
      if (broken[e] && !m_pending[static_cast<size_t>(e)]) continue;
      const int32_t w = graph.edgeNodes[2 * static_cast<size_t>(e)] == u
                            ? graph.edgeNodes[2 * static_cast<size_t>(e) + 1]
                            : graph.edgeNodes[2 * static_cast<size_t>(e)];
      const uint32_t mw = m_mark[static_cast<size_t>(w)];
      if (mw == other) return 1;
      if (mw != mine) {
        m_mark[static_cast<size_t>(w)] = mine;
        queue.push_back(w);
      }
    }
    return 0;
  };

  for (;;) {
    int r = expand(m_queueA, headA, markA, markB);
    if (r > 0) return false;
    if (r < 0) {
      m_piece = &m_queueA;
      m_pieceMark = markA;
      return true;
    }
    r = expand(m_queueB, headB, markB, markA);
    if (r > 0) return false;
    if (r < 0) {
      m_piece = &m_queueB;
      m_pieceMark = markB;
      return true;
    }
  }
}

void Fragments::splitOff(int32_t f) {
  const std::vector<int32_t>& piece = *m_piece;
  const size_t fi = static_cast<size_t>(f);
  const int32_t begin = m_start[fi], len = m_count[fi];
  const int32_t k = static_cast<int32_t>(piece.size());
  const int32_t tail = begin + len - k;

  // Move the piece to the tail of f's range: each piece node outside the tail swaps with a
  // non-piece node inside it (O(k): the scan pointer only moves forward through the tail).
  int32_t scan = tail;
  for (int32_t u : piece) {
    const int32_t pu = m_position[static_cast<size_t>(u)];
    if (pu >= tail) continue;
    while (m_mark[static_cast<size_t>(m_order[static_cast<size_t>(scan)])] == m_pieceMark) ++scan;
    const int32_t w = m_order[static_cast<size_t>(scan)];
    m_order[static_cast<size_t>(pu)] = w;
    m_order[static_cast<size_t>(scan)] = u;
    m_position[static_cast<size_t>(w)] = pu;
    m_position[static_cast<size_t>(u)] = scan;
    ++scan;
  }

  int32_t pieceMin = std::numeric_limits<int32_t>::max();
  for (int32_t u : piece) pieceMin = std::min(pieceMin, u);

  const int32_t created = count();
  if (pieceMin != m_minNode[fi]) {
    // Usual case: the piece is new, f keeps the head of its range.
    for (int32_t u : piece) m_nodeFragment[static_cast<size_t>(u)] = created;
    m_count[fi] = len - k;
    m_start.push_back(tail);
    m_count.push_back(k);
    m_minNode.push_back(pieceMin);
  } else {
    // The piece holds f's lowest node, so it keeps f and the rest is relabelled (O(rest)).
    int32_t restMin = std::numeric_limits<int32_t>::max();
    for (int32_t i = begin; i < tail; ++i) {
      const int32_t u = m_order[static_cast<size_t>(i)];
      m_nodeFragment[static_cast<size_t>(u)] = created;
      restMin = std::min(restMin, u);
    }
    m_start[fi] = tail;
    m_count[fi] = k;
    m_start.push_back(begin);
    m_count.push_back(len - k);
    m_minNode.push_back(restMin);
  }
  m_splits.push_back({created, f});
}

bool Fragments::update(const EdgeGraph& graph, const uint8_t* broken,
                       std::span<const int32_t> newlyBroken) {
  m_splits.clear();
  m_pending.resize(static_cast<size_t>(graph.edgeCount), 0);
  // The batch is applied one edge at a time: edges not yet processed count as intact
  // (pending), so each step removes a single edge and splits at most one fragment in two. An
  // edge between two fragments was broken before and is not pending; a listed edge that was
  // already broken inside one fragment is harmless as pending (it joins nothing new).
  auto ends = [&](int32_t e, int32_t& a, int32_t& b) {
    a = graph.edgeNodes[2 * static_cast<size_t>(e)];
    b = graph.edgeNodes[2 * static_cast<size_t>(e) + 1];
  };
  for (int32_t e : newlyBroken) {
    if (e < 0 || e >= graph.edgeCount || !broken[e]) continue;
    int32_t a, b;
    ends(e, a, b);
    if (m_nodeFragment[static_cast<size_t>(a)] == m_nodeFragment[static_cast<size_t>(b)]) {
      m_pending[static_cast<size_t>(e)] = 1;
    }
  }
  for (int32_t e : newlyBroken) {
    if (e < 0 || e >= graph.edgeCount || !m_pending[static_cast<size_t>(e)]) continue;
    m_pending[static_cast<size_t>(e)] = 0;
    int32_t a, b;
    ends(e, a, b);
    const int32_t f = m_nodeFragment[static_cast<size_t>(a)];
    if (f != m_nodeFragment[static_cast<size_t>(b)]) continue;
    if (separatePiece(graph, broken, a, b)) splitOff(f);
  }
  if (m_splits.empty()) return false;
  ++m_version;
  return true;
}

void Fragments::compute(std::span<const double> nodeVolume, std::span<const double> nodeMass,
                        const double* x, const double* v, FragmentProperties& out) const {
  const size_t nf = static_cast<size_t>(count());
  out.volume.assign(nf, 0.0);
  out.mass.assign(nf, 0.0);
  out.centre.assign(3 * nf, 0.0);
  out.velocity.assign(3 * nf, 0.0);
  for (size_t f = 0; f < nf; ++f) {
    double vol = 0, m = 0, mx[3] = {0, 0, 0}, p[3] = {0, 0, 0}, sx[3] = {0, 0, 0},
           sv[3] = {0, 0, 0};
    const std::span<const int32_t> list = nodes(static_cast<int32_t>(f));
    for (int32_t u : list) {
      const size_t ui = static_cast<size_t>(u);
      vol += nodeVolume[ui];
      const double mu = nodeMass[ui];
      m += mu;
      for (size_t c = 0; c < 3; ++c) {
        mx[c] += mu * x[3 * ui + c];
        p[c] += mu * v[3 * ui + c];
        sx[c] += x[3 * ui + c];
        sv[c] += v[3 * ui + c];
      }
    }
    out.volume[f] = vol;
    out.mass[f] = m;
    for (size_t c = 0; c < 3; ++c) {
      // Massless pieces (no lumped mass given) fall back to plain means instead of 0/0.
      const double inv = 1.0 / static_cast<double>(list.size());
      out.centre[3 * f + c] = m > 0 ? mx[c] / m : sx[c] * inv;
      out.velocity[3 * f + c] = m > 0 ? p[c] / m : sv[c] * inv;
    }
  }
}

std::vector<double> Fragments::nodeVolumes(const int32_t* tets, size_t tetCount, const double* rest,
                                           size_t nodeCount) {
  std::vector<double> out(nodeCount, 0.0);
  for (size_t t = 0; t < tetCount; ++t) {
    const int32_t* n = tets + 4 * t;
    const double* a = rest + 3 * static_cast<size_t>(n[0]);
    double e[3][3];
    for (int k = 0; k < 3; ++k) {
      const double* p = rest + 3 * static_cast<size_t>(n[k + 1]);
      for (int c = 0; c < 3; ++c) e[k][c] = p[c] - a[c];
    }
    const double sixV = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                        e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                        e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
    // Midpoint split: each corner cell is V/4 (an affine image of the regular tet's
    // symmetric split, and affine maps keep volume ratios).
    for (int k = 0; k < 4; ++k) out[static_cast<size_t>(n[k])] += sixV / 24.0;
  }
  return out;
}

}  // namespace gf::detail
