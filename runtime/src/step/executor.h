// The CPU executor of the step's stages. A stage is a plain struct whose GF_HD
// `operator()(int32_t i)` handles item i of an index range and writes only item i's outputs
// (fem/element_stage.h); the CPU runs it through the JobSystem, the CUDA backend through the
// generic __global__ wrapper of gpu/launch.h, so no per-step algorithm exists twice.
// Sums run in the fixed order of step/reduce.h on both.
#pragma once

#include <cstdint>
#include <vector>

#include "graphfrac/jobs.h"
#include "step/reduce.h"

namespace gf::detail {

class CpuExecutor {
 public:
  /// With `partials` (kept by the caller, so a step allocates nothing after warm-up) the
  /// chunks of a reduction run in parallel; without, on the calling thread. Same bits.
  explicit CpuExecutor(JobSystem& jobs, std::vector<double>* partials = nullptr)
      : m_jobs(&jobs), m_partials(partials) {}

  /// stage(i) for every i in [0, count), in ranges of at least `grain` items.
  template <class Stage>
  void run(int32_t count, uint32_t grain, const Stage& stage) const {
    if (count <= 0) return;
    m_jobs->parallelFor(uint32_t(count), grain, [&stage](uint32_t b, uint32_t e) {
      for (uint32_t i = b; i < e; ++i) stage(int32_t(i));
    });
  }

  /// ranges(b, e) over [0, count) split into ranges of at least `grain` items.
  template <class Ranges>
  void runRanges(int32_t count, uint32_t grain, const Ranges& ranges) const {
    if (count <= 0) return;
    m_jobs->parallelFor(uint32_t(count), grain,
                        [&ranges](uint32_t b, uint32_t e) { ranges(int32_t(b), int32_t(e)); });
  }

  /// Op over term(0..count) in the order of chunkedReduce (Op's identity for count 0).
  template <class Op, class Term>
  double reduce(int32_t count, const Term& term) const {
    const int32_t chunks = sumChunks(count);
    if (!m_partials || chunks < 2 || m_jobs->threadCount() < 2)
      return chunkedReduce<Op>(term, count);
    if (m_partials->size() < size_t(chunks)) m_partials->resize(size_t(chunks));
    run(chunks, 4, ChunkReduceStage<Op, Term>{term, count, m_partials->data()});
    double r = Op::identity();
    for (int32_t c = 0; c < chunks; ++c) r = Op::apply(r, (*m_partials)[size_t(c)]);
    return r;
  }
  double sum(const double* values, int32_t count) const {
    return reduce<SumOp>(count, ArrayTerm{values});
  }
  double max(const double* values, int32_t count) const {
    return reduce<MaxOp>(count, ArrayTerm{values});
  }
  double min(const double* values, int32_t count) const {
    return reduce<MinOp>(count, ArrayTerm{values});
  }
  double dot(const double* a, const double* b, int32_t count) const {
    return reduce<SumOp>(count, DotTerm{a, b});
  }

 private:
  JobSystem* m_jobs;
  std::vector<double>* m_partials;
};

}  // namespace gf::detail
