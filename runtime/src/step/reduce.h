// Reductions of the step (energy sums, stress bounds) in one fixed order for both executors:
// chunks of kSumChunk items (chunkReduce's fixed order inside), then the chunk results in chunk
// order. Either executor reduces the chunks in parallel and adds their results on one thread,
// so both give the same bits for any thread count or launch shape.
#pragma once

#include <cstdint>

#include "kernels/gf_hd.h"

namespace gf::detail {

/// Items per chunk of a reduction.
constexpr int32_t kSumChunk = 256;

struct SumOp {
  GF_HD static double identity() { return 0.0; }
  GF_HD static double apply(double a, double b) { return a + b; }
};
struct MaxOp {
  GF_HD static double identity() { return -HUGE_VAL; }
  GF_HD static double apply(double a, double b) { return b > a ? b : a; }
};
struct MinOp {
  GF_HD static double identity() { return HUGE_VAL; }
  GF_HD static double apply(double a, double b) { return b < a ? b : a; }
};

/// Number of chunks of a reduction over `count` items.
GF_HD int32_t sumChunks(int32_t count) { return (count + kSumChunk - 1) / kSumChunk; }

/// Items first, first + 1, ... of a stage or a term, run as items 0, 1, ...: a part of an index
/// range (a cluster's nodes among all coupled bodies').
template <class Stage>
struct OffsetStage {
  Stage stage;
  int32_t first = 0;
  GF_HD auto operator()(int32_t i) const { return stage(first + i); }
};

/// The items of a reduction over an array.
struct ArrayTerm {
  const double* values = nullptr;
  GF_HD double operator()(int32_t i) const { return values[i]; }
};

/// The items of a dot product a . b.
struct DotTerm {
  const double* a = nullptr;
  const double* b = nullptr;
  GF_HD double operator()(int32_t i) const { return a[i] * b[i]; }
};

/// Op over chunk c of term(0..count): four interleaved lanes (items i with i % 4 == lane, in
/// index order), then the lanes as (0 op 1) op (2 op 3). Each term(i) is called once, in index
/// order, so a term may also write item i (a fused update and its norm).
template <class Op, class Term>
GF_HD double chunkReduce(const Term& term, int32_t count, int32_t c) {
  const int32_t end = (c + 1) * kSumChunk < count ? (c + 1) * kSumChunk : count;
  double r0 = Op::identity(), r1 = Op::identity(), r2 = Op::identity(), r3 = Op::identity();
  int32_t i = c * kSumChunk;
  for (; i + 4 <= end; i += 4) {
    r0 = Op::apply(r0, term(i));
    r1 = Op::apply(r1, term(i + 1));
    r2 = Op::apply(r2, term(i + 2));
    r3 = Op::apply(r3, term(i + 3));
  }
  for (; i < end; ++i) r0 = Op::apply(r0, term(i));
  return Op::apply(Op::apply(r0, r1), Op::apply(r2, r3));
}

/// Op over term(0..count): the chunk results of ChunkReduceStage combined in chunk order.
template <class Op, class Term>
GF_HD double chunkedReduce(const Term& term, int32_t count) {
  double r = Op::identity();
  for (int32_t c = 0; c < sumChunks(count); ++c) r = Op::apply(r, chunkReduce<Op>(term, count, c));
  return r;
}

/// One chunk per item: the parallel half of chunkedReduce.
template <class Op, class Term = ArrayTerm>
struct ChunkReduceStage {
  Term term;
  int32_t count = 0;
  double* partials = nullptr;  ///< sumChunks(count)

  GF_HD void operator()(int32_t c) const { partials[c] = chunkReduce<Op>(term, count, c); }
};

/// The serial half of chunkedReduce on the executor (one item), so a device result stays on
/// the device until it is asked for.
template <class Op>
struct ChunkTotalStage {
  const double* partials = nullptr;
  int32_t chunks = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t) const {
    double r = Op::identity();
    for (int32_t c = 0; c < chunks; ++c) r = Op::apply(r, partials[c]);
    *out = r;
  }
};

}  // namespace gf::detail
