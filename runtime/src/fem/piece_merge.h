// Fragments that share a tet merged into one free piece (Integrator::groupPieces: under the
// projection damage model a damaged tet still couples the fragments at its corners), as stages
// on either executor, so the device merges from the CPU's source.
//
// Design: the pieces are the nodes of a hypergraph whose hyperedges are the tets (a tet joins
// its corners' pieces); its components are found by the hooking and shortcutting of
// surface/fragment_stages.h: labels are parent pointers to lower or equal pieces, a round reads
// only the last round's labels and lowers the new ones by an order-independent atomic min, so
// the rounds and the result are the same for any thread count or launch shape. At the fixed
// point every tet's corner pieces hold one label, which is its own label (depth one), so each
// piece is labelled with the least piece of its component: the roots of the serial union-find
// this replaces. Roots numbered by a scan in increasing order give the same merged ids.
#pragma once

#include <cstdint>

#include "kernels/gf_hd.h"
#include "step/reduce.h"
#include "step/scan.h"
#include "surface/fragment_stages.h"

namespace gf::detail {

/// One round's hooking from tet t: the least grandparent over its corner pieces lowers each
/// corner's parent (hooking) and each corner (shortcut). Reads `label`, lowers `next` (equal to
/// `label` on entry) by atomicMinLabel only. A tet inside one piece joins nothing; a piece none
/// of whose tets reaches another piece stays its own root.
struct PieceMergeHookStage {
  const int32_t* tets = nullptr;
  const int32_t* pieceOf = nullptr;  ///< per node
  const int32_t* label = nullptr;    ///< per piece
  int32_t* next = nullptr;

  GF_HD void operator()(int32_t t) const {
    int32_t p[4];
    for (int a = 0; a < 4; ++a) p[a] = pieceOf[tets[4 * int64_t(t) + a]];
    if (p[0] == p[1] && p[0] == p[2] && p[0] == p[3]) return;
    int32_t m = 0x7fffffff;
    for (int a = 0; a < 4; ++a) {
      const int32_t gp = label[label[p[a]]];
      m = gp < m ? gp : m;
    }
    for (int a = 0; a < 4; ++a) {
      atomicMinLabel(&next[label[p[a]]], m);
      atomicMinLabel(&next[p[a]], m);
    }
  }
};

/// rootFlag[p] = 1 for a root (its own label), else 0, as an integer for the scan and as a
/// double for the count of roots.
struct PieceRootFlagStage {
  const int32_t* label = nullptr;
  int32_t* rootFlag = nullptr;
  double* rootCount = nullptr;

  GF_HD void operator()(int32_t p) const {
    const bool root = label[p] == p;
    rootFlag[p] = root ? 1 : 0;
    rootCount[p] = root ? 1.0 : 0.0;
  }
};

/// Node n's piece renumbered: the merged id of its piece's root.
struct PieceRenumberStage {
  const int32_t* label = nullptr;
  const int32_t* rootId = nullptr;  ///< per piece, meaningful at roots
  int32_t* pieceOf = nullptr;

  GF_HD void operator()(int32_t n) const { pieceOf[n] = rootId[label[pieceOf[n]]]; }
};

/// Buffers of mergePiecesSharingTets in the executor's memory: `count` entries each for
/// label, next and changed, count + 1 for rootId, and pieceMergeChunks(count) for chunkSum and
/// chunkOffset + 1 for chunkOffset.
struct PieceMergeScratch {
  int32_t* label = nullptr;
  int32_t* next = nullptr;
  double* changed = nullptr;
  int32_t* rootId = nullptr;
  int32_t* chunkSum = nullptr;
  int32_t* chunkOffset = nullptr;
};

/// Chunks of the root numbering's scan for `count` pieces.
GF_HD int32_t pieceMergeChunks(int32_t count) {
  return (count + kCompactChunk - 1) / kCompactChunk;
}

/// Merges the pieces (pieceOf[n] in 0..count-1 for each of nodeCount nodes) that share one of
/// the tetCount tets into one, renumbering pieceOf in place: each merged piece takes the rank of
/// its least old id among the merged pieces' least ids, so the result depends on the partition
/// only. Returns the merged count; `rounds` (if given) receives the rounds that changed a label.
/// Exec is CpuExecutor or gpu::Executor; every pointer is in its memory.
template <class Exec>
int32_t mergePiecesSharingTets(const Exec& exec, const int32_t* tets, int32_t tetCount,
                               int32_t* pieceOf, int32_t nodeCount, int32_t count,
                               const PieceMergeScratch& s, int32_t* rounds = nullptr) {
  if (count <= 1) return count;
  exec.run(count, 1024, FragmentLabelInitStage{nullptr, s.label, s.next});
  int32_t changedRounds = 0;
  for (;;) {
    exec.run(tetCount, 256, PieceMergeHookStage{tets, pieceOf, s.label, s.next});
    exec.run(count, 1024, FragmentLabelSyncStage{nullptr, s.next, s.label, s.changed});
    if (!(exec.template reduce<MaxOp>(count, ArrayTerm{s.changed}) > 0)) break;
    ++changedRounds;
  }
  if (rounds) *rounds = changedRounds;
  // Roots numbered in increasing order: an exclusive scan of the root flags.
  exec.run(count, 1024, PieceRootFlagStage{s.label, s.rootId, s.changed});
  const int32_t merged = int32_t(exec.template reduce<SumOp>(count, ArrayTerm{s.changed}));
  const int32_t chunks = pieceMergeChunks(count);
  exec.run(chunks, 4, ScanChunkStage{s.rootId, count, s.chunkSum});
  exec.run(1, 1, CompactOffsetStage{s.chunkSum, chunks, s.chunkOffset});
  exec.run(chunks, 4, ScanWriteStage{s.rootId, count, s.chunkOffset, s.rootId});
  exec.run(nodeCount, 1024, PieceRenumberStage{s.label, s.rootId, pieceOf});
  return merged;
}

}  // namespace gf::detail
