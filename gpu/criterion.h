// The fracture criterion on the device: fracture/fracture_stages.h's findCandidateEdges, run by the
// device executor on device copies of the criterion's arrays and on stresses already there
// (gpu/element_pass.h's). Only the candidates come back, and only where there are some. Built
// twice from one source like gpu/element_pass.h.
#pragma once

#include <string>
#include <vector>

#include "fracture/fracture_stages.h"
#include "gpu/device.h"
#include "gpu/executor.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

class DeviceCriterion {
 public:
  /// findCandidateEdges on `stress` (device memory, 6 per tet) against host's arrays: the
  /// model's (edges, grid, averaging weights) copied when their host addresses change, the
  /// strengths and broken flags where their contents changed. Returns the count (-1 on a device
  /// error, error()); where positive, host.candidateEdges (count) and the candidates' entries
  /// of host.edgeStress and host.edgeTet (per edge) receive the device's.
  int32_t find(const detail::CriterionView& host, const double* stress, double weakest);
  const std::string& error() const { return m_error; }

 private:
  int32_t fail(const char* what);

  detail::CriterionView m_from;  // the host arrays the model's copies were made from
  DeviceBuffer<int32_t> m_tetEdges, m_gridStart, m_gridItems, m_gridCell, m_neighbourStart,
      m_neighbourIndex, m_edgeTetStart, m_edgeTets, m_edgeTet, m_chunkCount, m_chunkOffset,
      m_candidateEdges;
  DeviceBuffer<double> m_edgeDirections, m_strength, m_averaged, m_bound, m_cellMax, m_edgeStress;
  DeviceBuffer<float> m_neighbourWeight;
  DeviceBuffer<uint8_t> m_broken, m_candidates, m_edgeFlag;
  DeviceBuffer<double> m_compactStress;
  DeviceBuffer<int32_t> m_compactTet;
  std::vector<double> m_strengthCopy, m_stressCopy;
  std::vector<uint8_t> m_brokenCopy;
  std::vector<int32_t> m_tetCopy;
  Executor m_exec;
  std::string m_error;
};

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
