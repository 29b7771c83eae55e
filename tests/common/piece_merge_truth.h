// The independent truth the piece-merge tests compare with (fem/piece_merge.h): a plain serial
// union-find over the pieces, joining the corner pieces of every tet, each set's root its
// least piece, the roots numbered in increasing order (the host code the stages replaced).
#pragma once

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

namespace gf::test {

/// Renumbers pieceOf (per node, ids below count) so that pieces sharing a tet are one; returns
/// the merged count.
inline int32_t mergePiecesByUnionFind(const std::vector<int32_t>& tets,
                                      std::vector<int32_t>& pieceOf, int32_t count) {
  std::vector<int32_t> root(static_cast<size_t>(count));
  std::iota(root.begin(), root.end(), 0);
  auto find = [&root](int32_t p) {
    while (root[size_t(p)] != p) p = root[size_t(p)] = root[size_t(root[size_t(p)])];
    return p;
  };
  for (size_t t = 0; 4 * t < tets.size(); ++t)
    for (int a = 1; a < 4; ++a) {
      const int32_t p = find(pieceOf[size_t(tets[4 * t])]);
      const int32_t q = find(pieceOf[size_t(tets[4 * t + size_t(a)])]);
      if (p != q) root[size_t(std::max(p, q))] = std::min(p, q);
    }
  std::vector<int32_t> number(size_t(count), -1);
  int32_t merged = 0;
  for (int32_t p = 0; p < count; ++p)
    if (find(p) == p) number[size_t(p)] = merged++;
  for (int32_t& p : pieceOf) p = number[size_t(find(p))];
  return merged;
}

/// A random merge problem: `nodes` nodes in `count` pieces (every piece holds a node, ids in a
/// random order along the node range so that chains of merges run against the ids), and tets
/// that mostly stay inside one piece, a share `crossPercent` of them reaching random nodes.
struct PieceMergeCase {
  std::vector<int32_t> tets, pieceOf;
  int32_t nodes = 0, count = 0;
};

inline PieceMergeCase randomPieceMergeCase(int32_t nodes, int32_t count, int32_t tetCount,
                                           int crossPercent, unsigned seed) {
  std::mt19937 rng(seed);
  PieceMergeCase c;
  c.nodes = nodes;
  c.count = count;
  std::vector<int32_t> id(static_cast<size_t>(count));
  std::iota(id.begin(), id.end(), 0);
  std::shuffle(id.begin(), id.end(), rng);
  // Pieces are runs of consecutive nodes, each at least one node long.
  c.pieceOf.resize(size_t(nodes));
  for (int32_t n = 0; n < nodes; ++n) c.pieceOf[size_t(n)] = id[size_t(int64_t(n) * count / nodes)];
  for (int32_t t = 0; t < tetCount; ++t) {
    const int32_t base = int32_t(rng() % uint32_t(nodes));
    // A joining tet reaches out of the base node's piece with one to three of its corners, at
    // random places among the four (a merge must read every corner).
    const uint32_t outward = int(rng() % 100) < crossPercent ? 1 + rng() % 14 : 0;
    for (int a = 0; a < 4; ++a) {
      int32_t n = base;
      if (outward >> a & 1) {
        n = int32_t(rng() % uint32_t(nodes));
      } else {
        // Inside: a neighbour of the base node in its run (or the base node itself).
        const int32_t m = std::min(nodes - 1, base + int32_t(rng() % 3));
        if (c.pieceOf[size_t(m)] == c.pieceOf[size_t(base)]) n = m;
      }
      c.tets.push_back(n);
    }
  }
  return c;
}

/// A chain: piece ids in random order along a path of nodes, consecutive pieces joined by one
/// tet each, so everything merges through `count` - 1 links (the longest propagation).
inline PieceMergeCase chainPieceMergeCase(int32_t count, unsigned seed) {
  PieceMergeCase c = randomPieceMergeCase(count, count, 0, 0, seed);
  for (int32_t n = 0; n + 1 < count; ++n) c.tets.insert(c.tets.end(), {n, n + 1, n, n + 1});
  return c;
}

}  // namespace gf::test
