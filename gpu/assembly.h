// The Newton matrix of a body assembled on the device: the host's assembly stages
// (solver/sparse_stages.h's AssembleStage and DirichletStage, fem/node_stage.h's NodeBlockStage)
// run by the device executor from element Hessians already on the device, into a matrix that
// stays there for the device solves. Built twice from one source like gpu/element_pass.h.
#pragma once

#include <string>

#include "fem/body_device.h"
#include "gpu/device.h"
#include "gpu/executor.h"
#include "solver/block_sparse.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

class DeviceAssembly {
 public:
  /// A's values from `elementMatrices` (device memory) as `in` says. The pattern, the gather
  /// lists and the diagonal blocks are copied when their host addresses change; the per-node
  /// arrays every call. False on a device error (error()).
  bool assemble(const detail::DeviceAssembly& in, const double* elementMatrices);
  /// The assembled matrix, in device memory (n 0 before the first assemble()).
  detail::BlockMatrixView matrix() const {
    return {m_n, m_rowStart.data(), m_col.data(), m_values.data()};
  }
  bool downloadValues(double* values);
  /// y = A x on host arrays of 3 n.
  bool multiply(const double* x, double* y);
  const std::string& error() const { return m_error; }

 private:
  bool fail(const char* what);

  int32_t m_n = 0;
  // The host arrays the model's copies were made from.
  const detail::BlockSparseMatrix* m_patternFrom = nullptr;
  const detail::ElementGather* m_gatherFrom = nullptr;
  const int32_t* m_diagonalFrom = nullptr;
  DeviceBuffer<int32_t> m_rowStart, m_col, m_gatherStart, m_gatherEntry, m_diagonalBlock;
  DeviceBuffer<double> m_values, m_sum, m_nodeMass, m_drag, m_tetherW, m_tetherTarget, m_x, m_y;
  DeviceBuffer<Mat3> m_contactHess;
  DeviceBuffer<uint8_t> m_fixedNode;
  Executor m_exec;
  std::string m_error;
};

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
