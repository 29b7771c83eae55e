// The element and gather stages of a body on the device: the CPU integrator's stages
// (runtime/src/fem/element_stage.h) run by the CUDA executor on device copies of the same
// buffers. Built twice from one source: element_pass.cu with nvcc, and gpu/host/ with the host
// compiler for the `backend` tests.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "fem/element_stage.h"
#include "fracture/fracture_stages.h"
#include "gpu/device.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

class DeviceElementPass {
 public:
  /// Copies what the host stages read (their outputs are ignored). False when device memory
  /// runs out (error()).
  bool upload(const detail::ElementStage& elements, const detail::GatherStage& gather,
              int32_t tetCount, int32_t nodeCount);
  /// For a body stepped on the device (detail::BodyDevice): what upload() copies, but the
  /// model's arrays (topology, rest volumes and edge matrices, fibres, the gather) only when
  /// their host addresses or the sizes changed since the last call, the state's (rest
  /// inverses, damage, rigid tets, wet Lamé values) only then or with `stateChanged`, each
  /// where its contents changed, and the stage's options and x every call.
  bool prepare(const detail::ElementStage& elements, const detail::GatherStage& gather,
               int32_t tetCount, int32_t nodeCount, bool stateChanged);
  /// Positions only (3 per node), for another pass on the uploaded body.
  bool uploadPositions(const double* x);
  /// Runs the element stage (with Hessians and criterion stresses when asked), the energy sum
  /// and the gather; waits for them. False on a device error (error()). Without gradients the
  /// pass evaluates energies alone (a line search's) and gathers nothing; withNodeGradient
  /// false skips the gather for a caller that gathers the element gradients itself.
  bool run(bool withHessian, bool withStress, bool withGradient = true,
           bool withNodeGradient = true);
  /// The fracture criterion's stress stage on the uploaded body (its arrays the element
  /// stage's copies, its flags `stage`'s), into stresses(). False on a device error (error()).
  bool criterionStresses(const detail::CriterionStressStage& stage);
  /// The stresses of the last run or criterionStresses(), in device memory, 6 per tet.
  const double* stresses() const { return m_stress.data(); }
  /// The last run's element Hessians, in device memory (null before a run with them).
  const double* hessians() const { return m_hess.data(); }
  /// The elastic energy of the last run.
  double energy() const { return m_psi; }
  /// Copies the last run's outputs to the host (null: skip; sizes as in ElementStage, nodeGrad
  /// 3 per node).
  bool download(double* energy, double* grad, double* hess, double* stress, double* nodeGrad) const;
  const std::string& error() const { return m_error; }

 private:
  bool fail(const char* what);

  int32_t m_tetCount = 0, m_nodeCount = 0;
  detail::ElementStage m_host;  // options and coefficients of the uploaded body
  // The host arrays prepare() copied the model's arrays from.
  detail::ElementStage m_modelFrom;
  detail::GatherStage m_gatherFrom;
  DeviceBuffer<int32_t> m_tets, m_nodeRefStart, m_nodeRef;
  DeviceBuffer<double> m_x, m_restVolume, m_chi, m_energy, m_grad, m_hess, m_stress, m_nodeGrad,
      m_partials, m_sum, m_tetLame;
  DeviceBuffer<Mat3> m_restInverse;
  DeviceBuffer<Vec3> m_fibreDir;
  DeviceBuffer<uint8_t> m_tetMask, m_rigidTet;
  DeviceBuffer<Mat<6, 6>> m_edgeMatrix, m_edgeMatrixInverse;
  // Host copies of the state arrays as last copied to the device (mirrorChanged()).
  std::vector<Mat3> m_restInverseCopy;
  std::vector<uint8_t> m_tetMaskCopy, m_rigidTetCopy;
  std::vector<double> m_chiCopy, m_tetLameCopy;
  double m_psi = 0;
  std::string m_error;
};

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
