// The device executor: the CPU executor's interface (step/executor.h: run a stage over an index
// range, reduce a term in step/reduce.h's fixed order) on the device, so an algorithm written
// once over an executor (solver/pcg_stages.h) runs here from the same source. A reduction's
// chunks run one per device thread and their total on one more; only the scalar comes back.
#pragma once

#include <cstdint>
#include <limits>

#include "gpu/device.h"
#include "gpu/launch.h"
#include "step/reduce.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

class Executor {
 public:
  explicit Executor(Stream stream = nullptr) : m_stream(stream) {}

  /// stage(i) for every i in [0, count) (the grain is the CPU's; launches ignore it).
  template <class Stage>
  void run(int32_t count, uint32_t /*grain*/, const Stage& stage) const {
    launch(stage, count, m_stream);
  }

  /// Op over term(0..count) in the order of detail::chunkedReduce; waits for the device. NaN
  /// when the device failed (takeFailure() then says so), so an algorithm reading it breaks down.
  template <class Op, class Term>
  double reduce(int32_t count, const Term& term) const {
    const int32_t chunks = detail::sumChunks(count);
    if (chunks == 0) return Op::identity();
    if (!m_partials.resize(size_t(chunks)) || !m_total.resize(1)) return fail();
    launch(detail::ChunkReduceStage<Op, Term>{term, count, m_partials.data()}, chunks, m_stream);
    launch(detail::ChunkTotalStage<Op>{m_partials.data(), chunks, m_total.data()}, 1, m_stream);
    double r = 0;
    if (!synchronize() || !m_total.download(&r, 1)) return fail();
    return r;
  }
  double dot(const double* a, const double* b, int32_t count) const {
    return reduce<detail::SumOp>(count, detail::DotTerm{a, b});
  }

  /// Whether a reduction met a device error since the last call; clears it.
  bool takeFailure() {
    const bool f = m_failed;
    m_failed = false;
    return f;
  }

 private:
  double fail() const {
    m_failed = true;
    return std::numeric_limits<double>::quiet_NaN();
  }

  Stream m_stream;
  mutable DeviceBuffer<double> m_partials, m_total;
  mutable bool m_failed = false;
};

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
