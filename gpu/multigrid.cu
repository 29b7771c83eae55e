// gpu/multigrid.h: buffer management around the one multigrid-solve source.
#include <type_traits>

#include "gpu/multigrid.h"
#include "solver/dense_cholesky.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

namespace {

// A V-cycle that is a zero correction while its levels could not be uploaded (multigridSolve
// runs level 0's cycle alone).
template <class VCycle>
struct GuardedCycle {
  const VCycle& v;
  const bool& ok;
  const Executor& exec;
  int32_t n3;
  template <int B>
  void cycle(int l, const double* r, double* z) const {
    if (ok)
      v.template cycle<B>(l, r, z);
    else
      exec.run(n3, 2048, detail::FillStage{0.0, z});
  }
};

}  // namespace

bool DeviceMultigrid::fail(const char* what) {
  m_error = std::string(what) + ": " + lastError();
  return false;
}

template <class T, class Out>
bool DeviceMultigrid::mirror(const T* host, size_t n, Out*& out) {
  out = nullptr;
  if (!host || n == 0) return true;
  DeviceBuffer<T>* buffer;
  if constexpr (std::is_same_v<T, int32_t>)
    buffer = &m_ints.emplace_back();
  else if constexpr (std::is_same_v<T, float>)
    buffer = &m_floats.emplace_back();
  else
    buffer = &m_doubles.emplace_back();
  if (!buffer->upload(host, n)) return false;
  out = buffer->data();
  return true;
}

// Zeroed like the host solver's level vectors: a cycle may scale a vector by zero before its
// first write, which keeps a NaN left in reused memory (before the fill, 3 and 12 of 200
// Jacobi cycles-alone solves of the host build broke down on their first V-cycle).
bool DeviceMultigrid::scratch(size_t n, double*& out) {
  DeviceBuffer<double>& buffer = m_doubles.emplace_back();
  out = buffer.resize(n) ? buffer.data() : nullptr;
  if (out) m_exec.run(int32_t(n), 2048, detail::FillStage{0.0, out});
  return out != nullptr || n == 0;
}

bool DeviceMultigrid::upload(const detail::BlockSparseMatrix& A, const HostMultigrid& host) {
  m_fineReady = false;
  m_n = A.n;
  m_fineBlocks = A.col.size();
  return uploadLevels(host);
}

bool DeviceMultigrid::allocateVectors() {
  const size_t n3 = 3 * size_t(m_n);
  return (m_b.resize(n3) && m_x.resize(n3) && m_r.resize(n3) && m_z.resize(n3) && m_p.resize(n3) &&
          m_ap.resize(n3) && m_rOld.resize(n3)) ||
         fail("allocating the solve's vectors");
}

bool DeviceMultigrid::uploadMatrix(const detail::BlockSparseMatrix& A,
                                   const detail::CycleSettings& settings) {
  m_fineReady = m_fineRowStart.upload(A.rowStart.data(), A.rowStart.size()) &&
                m_fineCol.upload(A.col.data(), A.col.size()) &&
                m_fineValues.upload(A.values.data(), A.values.size());
  if (!m_fineReady) return fail("uploading the matrix");
  m_fineBlocks = A.col.size();
  return useMatrix({A.n, m_fineRowStart.data(), m_fineCol.data(), m_fineValues.data()}, settings);
}

bool DeviceMultigrid::useMatrix(const detail::BlockMatrixView& A,
                                const detail::CycleSettings& settings) {
  m_n = A.n;
  m_host.settings = settings;
  m_fine = A;
  m_A = A;
  m_fineReady = allocateVectors();
  return m_fineReady;
}

bool DeviceMultigrid::uploadLevels(const HostMultigrid& host) {
  const std::vector<detail::CycleLevel>& levels = host.levels;
  m_ints.clear();
  m_floats.clear();
  m_doubles.clear();
  m_levels.assign(levels.size(), detail::CycleLevel{});
  m_galerkin.assign(host.galerkin.size(), detail::GalerkinLevelView{});
  m_colourStart.assign(levels.size(), {});
  m_host = host;
  if (!allocateVectors()) return false;
  const bool gs = host.settings.smoother == detail::CycleSmoother::kGaussSeidel;
  for (size_t l = 0; l < levels.size(); ++l) {
    const detail::CycleLevel& h = levels[l];
    detail::CycleLevel& d = m_levels[l];
    const size_t B = l == 0 ? 3 : 12, n = size_t(h.n), nnz = size_t(h.rowStart[h.n]);
    d.n = h.n;
    d.lambdaMax = h.lambdaMax;
    m_colourStart[l].assign(h.colourStart, h.colourStart + h.colours + 1);
    d.colourStart = m_colourStart[l].data();
    d.colours = h.colours;
    const size_t gsBlocks = gs ? size_t(h.gsRowStart[h.n]) : 0;
    bool ok = true;
    if (l == 0 && m_fineReady) {
      d.rowStart = m_fine.rowStart;
      d.col = m_fine.col;
      d.values = m_fine.values;
    } else {
      ok = mirror(h.rowStart, n + 1, d.rowStart) && mirror(h.col, nnz, d.col) &&
           mirror(h.values, nnz * B * B, d.values);
    }
    ok = ok && mirror(h.diagIndex, n, d.diagIndex) && mirror(h.invDiag, n * B * B, d.invDiag) &&
         mirror(h.colourRows, n, d.colourRows) &&
         mirror(gs ? h.gsRowStart : nullptr, n + 1, d.gsRowStart) &&
         mirror(h.gsCol, gsBlocks, d.gsCol) && mirror(h.gsBlock, gsBlocks, d.gsBlock) &&
         mirror(h.gsValues, gsBlocks * B * B, d.gsValues) &&
         mirror(h.gsValuesSingle, gsBlocks * B * B, d.gsValuesSingle) && scratch(B * n, d.b) &&
         scratch(B * n, d.x) && scratch(B * n, d.r) && scratch(B * n, d.t);
    if (ok && l + 1 < levels.size()) {
      const detail::ProlongationView& hp = h.P;
      detail::ProlongationView& dp = d.P;
      const size_t handles = size_t(levels[l + 1].n), blocks = size_t(hp.pStart[h.n]);
      dp.kind = hp.kind;
      dp.blockRows = hp.blockRows;
      dp.childRatio = hp.childRatio;
      using detail::Prolongation;
      ok = mirror(hp.pStart, n + 1, dp.pStart) && mirror(hp.pCol, blocks, dp.pCol) &&
           mirror(hp.pRow, blocks, dp.pRow) &&
           mirror(hp.kind == Prolongation::kSmoothed ? hp.pValues : nullptr, blocks * 12 * B,
                  dp.pValues) &&
           mirror(hp.kind == Prolongation::kSmoothed ? hp.ptValues : nullptr, blocks * 12 * B,
                  dp.ptValues) &&
           mirror(hp.ptStart, handles + 1, dp.ptStart) && mirror(hp.ptRow, blocks, dp.ptRow) &&
           mirror(hp.kind == Prolongation::kTentativeNodes ? hp.coord : nullptr, 3 * n, dp.coord) &&
           mirror(hp.kind == Prolongation::kTentativeHandles ? hp.childOffset : nullptr, 3 * n,
                  dp.childOffset);
    }
    if (!ok) return fail("uploading the multigrid levels");
  }
  // The coarse operators' inputs; P, the patterns and the values are the levels' copies.
  for (size_t k = 0; k < host.galerkin.size(); ++k) {
    const detail::GalerkinLevelView& h = host.galerkin[k];
    detail::GalerkinLevelView& d = m_galerkin[k];
    const size_t B = k == 0 ? 3 : 12, rows = size_t(h.finerRows), coarse = size_t(h.coarseRows);
    const size_t qBlocks = size_t(h.qStart[rows]), pairs = size_t(h.qcStart[qBlocks]);
    const size_t blocks = size_t(h.rowStart[coarse]), gathered = size_t(h.gatherStart[blocks]);
    d.finerRows = h.finerRows;
    d.coarseRows = h.coarseRows;
    d.P = m_levels[k].P;
    d.rowStart = m_levels[k + 1].rowStart;
    d.col = m_levels[k + 1].col;
    if (!mirror(h.qStart, rows + 1, d.qStart) || !mirror(h.qcStart, qBlocks + 1, d.qcStart) ||
        !mirror(h.qcA, pairs, d.qcA) || !mirror(h.qcP, pairs, d.qcP) ||
        !scratch(qBlocks * B * 12, d.qValues) || !mirror(h.mirror, blocks, d.mirror) ||
        !mirror(h.gatherStart, blocks + 1, d.gatherStart) ||
        !mirror(h.gatherP, gathered, d.gatherP) || !mirror(h.gatherQ, gathered, d.gatherQ) ||
        !mirror(h.nullProjector, 16 * coarse, d.nullProjector))
      return fail("uploading the coarse operators' patterns");
  }
  // Level 0's matrix is A.
  m_A = {m_n, m_levels[0].rowStart, m_levels[0].col, m_levels[0].values};
  const size_t coarseLength = levels.size() > 1 ? 12 * size_t(levels.back().n) : 0;
  m_coarseB.resize(coarseLength);
  m_coarseX.resize(coarseLength);
  m_coarsestValues.resize(levels.size() > 1 ? 144 * size_t(levels.back().rowStart[levels.back().n])
                                            : 0);
  const int64_t coarseSize = levels.size() > 1 ? 12 * int64_t(levels.back().n) : 0;
  m_denseCoarse =
      host.denseCoarsestOnDevice && coarseSize > 0 && coarseSize <= detail::kDenseCholeskyMaxSize;
  m_denseOk = false;
  if (m_denseCoarse) {
    if (!m_coarseDense.resize(size_t(coarseSize * coarseSize)))
      return fail("allocating the coarsest level's factor");
    factorCoarsestOnDevice();
  }
  return true;
}

// A failed factorisation (not positive definite after the shifts) zeroes the coarse
// correction, as the host's does; a device error is reported by the caller's next check.
bool DeviceMultigrid::factorCoarsestOnDevice() {
  const detail::CycleLevel& c = m_levels.back();
  m_denseOk = detail::denseCholeskyFactorBlocks(m_exec, c.n, c.rowStart, c.col, c.values,
                                                m_coarseDense.data());
  return m_denseOk;
}

bool DeviceMultigrid::refresh(const double* values) {
  // The levels' matrices are this object's own buffers; only the cycle treats them as const.
  if (!copyToDevice(const_cast<double*>(m_A.values), values, 9 * m_fineBlocks * sizeof(double)))
    return fail("uploading the matrix");
  return prepareValues(true);
}

bool DeviceMultigrid::prepareValues(bool refreshCoarse) {
  auto writable = [](const double* p) { return const_cast<double*>(p); };
  const detail::CycleSettings& s = m_host.settings;
  const bool gs = s.smoother == detail::CycleSmoother::kGaussSeidel;
  const size_t L = m_levels.size() - 1;
  detail::setUpDiagonals<3>(m_exec, m_levels[0], gs);
  if (!refreshCoarse && !gs)
    m_levels[0].lambdaMax =
        detail::estimateLambda<3>(m_exec, m_levels[0], s.powerIterations, s.lambdaMargin);
  if (!refreshCoarse)
    return (!m_exec.takeFailure() && synchronize()) || fail("preparing the levels");
  for (size_t l = 1; l <= L; ++l) {
    if (l == 1)
      detail::galerkinProduct<3>(m_exec, m_galerkin[0], m_levels[0].values,
                                 writable(m_levels[1].values));
    else
      detail::galerkinProduct<12>(m_exec, m_galerkin[l - 1], m_levels[l - 1].values,
                                  writable(m_levels[l].values));
  }
  for (size_t l = 1; l <= L; ++l) detail::setUpDiagonals<12>(m_exec, m_levels[l], gs);
  if (!gs) {
    m_levels[0].lambdaMax =
        detail::estimateLambda<3>(m_exec, m_levels[0], s.powerIterations, s.lambdaMargin);
    for (size_t l = 1; l < L; ++l)
      m_levels[l].lambdaMax =
          detail::estimateLambda<12>(m_exec, m_levels[l], s.powerIterations, s.lambdaMargin);
  }
  if (L > 0 && m_denseCoarse) {
    factorCoarsestOnDevice();
  } else if (L > 0) {
    if (!synchronize() || !copyToHost(m_coarsestValues.data(), m_levels[L].values,
                                      m_coarsestValues.size() * sizeof(double)))
      return fail("reading the coarsest operator");
    m_host.factorCoarsest(m_coarsestValues.data());
  }
  if (m_exec.takeFailure() || !synchronize()) return fail("refreshing the levels");
  return true;
}

bool DeviceMultigrid::downloadLevel(uint64_t version, int level, double* values, size_t count) {
  if (version != m_version || level < 1 || size_t(level) >= m_levels.size()) {
    m_error = "reading a coarse level: the levels were not mirrored";
    return false;
  }
  const detail::CycleLevel& c = m_levels[size_t(level)];
  if (count != 144 * size_t(m_host.levels[size_t(level)].rowStart[c.n])) {
    m_error = "reading a coarse level: another size";
    return false;
  }
  return copyToHost(values, c.values, count * sizeof(double)) || fail("reading a coarse level");
}

bool DeviceMultigrid::solve(const double* b, double* x, int maxIterations, double relativeTolerance,
                            detail::MultigridRun& run, detail::SolveReport& report) {
  return solve(b, x, maxIterations, relativeTolerance, run, report, {});
}

bool DeviceMultigrid::solve(const double* b, double* x, int maxIterations, double relativeTolerance,
                            detail::MultigridRun& run, detail::SolveReport& report,
                            const std::function<const HostMultigrid*()>& prepare) {
  const size_t n3 = 3 * size_t(m_n);
  // Levels that could not be prepared leave every cycle a zero correction, and the solve
  // failed: the caller keeps its x.
  bool levelsOk = true;
  auto prepareLevels = [&] {
    if (!prepare) return;
    const HostMultigrid* host = prepare();
    if (!host) {
      levelsOk = false;
      return;
    }
    // The host's values are copied where it prepared them or where they are new to this
    // mirror (a re-binding, a restore); otherwise the structure mirrored before serves.
    if (host->valuesOnHost || host->version != m_version || m_levels.empty()) {
      m_version = ~host->version;  // until the copy succeeds
      levelsOk = uploadLevels(*host);
      if (levelsOk) m_version = host->version;
    }
    m_host.settings = host->settings;
    // Level 0 is the matrix of this solve, which may live in another buffer than the last's.
    if (levelsOk && m_fineReady) {
      m_levels[0].rowStart = m_fine.rowStart;
      m_levels[0].col = m_fine.col;
      m_levels[0].values = m_fine.values;
      m_A = m_fine;
    }
    if (levelsOk && !host->valuesOnHost) levelsOk = prepareValues(host->refresh);
  };
  if (!m_b.upload(b, n3) || !m_x.upload(x, n3)) return fail("uploading the right-hand side");
  m_coarseFailed = false;
  // The coarsest level is solved on the device, or goes to the host and back; a failed copy
  // zeroes the correction and fails the solve.
  auto coarse = [this](const double* cb, double* cx) {
    const size_t len = m_coarseB.size();
    if (m_denseCoarse) {
      if (m_denseOk)
        detail::denseCholeskySolve(m_exec, int32_t(len), m_coarseDense.data(), cb, cx);
      else
        m_exec.run(int32_t(len), 2048, detail::FillStage{0.0, cx});
      return;
    }
    if (!synchronize() || !copyToHost(m_coarseB.data(), cb, len * sizeof(double))) {
      m_coarseFailed = true;
      return;
    }
    m_host.solveCoarsest(m_coarseB.data(), m_coarseX.data());
    if (!copyToDevice(cx, m_coarseX.data(), len * sizeof(double))) m_coarseFailed = true;
  };
  detail::CycleTimes times;
  const detail::VCycle<Executor, decltype(coarse)> vCycle(m_exec, m_levels, m_host.settings, coarse,
                                                          times);
  const GuardedCycle<decltype(vCycle)> cycle{vCycle, levelsOk, m_exec, int32_t(n3)};
  const detail::CgBuffers work{m_r.data(), m_z.data(), m_p.data(), m_ap.data(), m_rOld.data()};
  report = detail::multigridSolve(m_exec, m_A, m_b.data(), m_x.data(), work, cycle, prepareLevels,
                                  maxIterations, relativeTolerance, run);
  if (!levelsOk) return fail("uploading the multigrid levels");
  if (m_exec.takeFailure() || m_coarseFailed || !synchronize()) return fail("solving");
  return m_x.download(x, n3) || fail("reading the solution");
}

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
