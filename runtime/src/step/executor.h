// The CPU executor of the step's stages. A stage is a plain struct whose GF_HD
// `operator()(int32_t i)` handles item i of an index range and writes only item i's outputs
// (fem/element_stage.h); the CPU runs it through the JobSystem, the CUDA backend through the
// generic __global__ wrapper of gpu/launch.h, so no per-step algorithm exists twice.
// Sums run in the fixed order of step/reduce.h on both.
#pragma once

#include <cstdint>

#include "graphfrac/jobs.h"
#include "step/reduce.h"

namespace gf::detail {

class CpuExecutor {
 public:
  explicit CpuExecutor(JobSystem& jobs) : m_jobs(&jobs) {}

  /// stage(i) for every i in [0, count), in ranges of at least `grain` items.
  template <class Stage>
  void run(int32_t count, uint32_t grain, const Stage& stage) const {
    if (count <= 0) return;
    m_jobs->parallelFor(uint32_t(count), grain, [&stage](uint32_t b, uint32_t e) {
      for (uint32_t i = b; i < e; ++i) stage(int32_t(i));
    });
  }

  /// Op over term(0..count) in the order of chunkedReduce (Op's identity for count 0).
  template <class Op, class Term>
  static double reduce(int32_t count, const Term& term) {
    return chunkedReduce<Op>(term, count);
  }
  static double sum(const double* values, int32_t count) {
    return reduce<SumOp>(count, ArrayTerm{values});
  }
  static double max(const double* values, int32_t count) {
    return reduce<MaxOp>(count, ArrayTerm{values});
  }
  static double min(const double* values, int32_t count) {
    return reduce<MinOp>(count, ArrayTerm{values});
  }
  static double dot(const double* a, const double* b, int32_t count) {
    return reduce<SumOp>(count, DotTerm{a, b});
  }

 private:
  JobSystem* m_jobs;
};

}  // namespace gf::detail
