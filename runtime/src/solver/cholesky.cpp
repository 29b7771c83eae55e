// Sparse Cholesky reference solver on the scalar expansion of a block-sparse matrix.
//
// Design: the factorisation (CHOLMOD's supernodal LLT when the build found it, else Eigen's
// SimplicialLLT, about 30x slower on a 35k-tet body) reads only the lower triangle, so the scalar
// matrix holds the lower triangle of A in compressed column form. analyze() builds that structure
// and a map from each of its stored values to an entry of A.values, then runs the (AMD-ordered)
// symbolic analysis once; solve() copies values through the map and refactorises. The pattern is
// fixed for a body's life, so nothing is rebuilt per step. A scalar matrix (SymmetricCsc, the
// Is-XFEM step matrix whose size changes with every cut) is copied into the same lower-triangle
// structure, analysed and factorised in one call; a constant matrix then only back-substitutes.
#include "solver/cholesky.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#if GF_HAVE_CHOLMOD
#include <dlfcn.h>

#include <Eigen/CholmodSupport>
#endif
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "solver/vector_ops.h"

namespace gf::detail {

// CHOLMOD's BLAS is OpenBLAS on Debian, which starts a thread per core when it is loaded; they
// spin-wait (sched_yield) between calls: on the bread scene that doubled the CPU time and put
// half of it in the kernel, and threaded BLAS may sum in a different order from run to run.
// The world has its own JobSystem, so BLAS runs on the calling thread and the idle pool is
// stopped (the library must run no thread it does not own). Looked up at run time: another
// BLAS may be installed in its place, and then there is nothing to do.
void blasOnOneThread() {
#if GF_HAVE_CHOLMOD
  static const bool once = [] {
    using SetThreads = void (*)(int);
    using Shutdown = int (*)();
    if (void* f = dlsym(RTLD_DEFAULT, "openblas_set_num_threads")) {
      reinterpret_cast<SetThreads>(f)(1);
      if (void* g = dlsym(RTLD_DEFAULT, "blas_thread_shutdown_")) reinterpret_cast<Shutdown>(g)();
    }
    return true;
  }();
  (void)once;
#endif
}

namespace {
// OpenMP's per-thread max-active-levels, looked up at run time: CHOLMOD brings libgomp in,
// graphfrac itself is not built with OpenMP.
using GetLevels = int (*)();
using SetLevels = void (*)(int);
struct OpenMpLevels {
  GetLevels get = nullptr;
  SetLevels set = nullptr;
};
const OpenMpLevels& openMpLevels() {
  static const OpenMpLevels f = [] {
    OpenMpLevels l;
#if GF_HAVE_CHOLMOD
    void* g = dlsym(RTLD_DEFAULT, "omp_get_max_active_levels");
    void* s = dlsym(RTLD_DEFAULT, "omp_set_max_active_levels");
    if (g && s) {
      l.get = reinterpret_cast<GetLevels>(g);
      l.set = reinterpret_cast<SetLevels>(s);
    }
#endif
    return l;
  }();
  return f;
}
}  // namespace

SerialOpenMpScope::SerialOpenMpScope() {
  const OpenMpLevels& l = openMpLevels();
  if (!l.set) return;
  m_saved = l.get();
  l.set(0);  // no region on this thread is active: each runs on one thread
}

SerialOpenMpScope::~SerialOpenMpScope() {
  if (m_saved >= 0) openMpLevels().set(m_saved);
}

struct CholeskySolver::Impl {
  using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
  SpMat lower;                    // lower triangle of the scalar expansion
  std::vector<int64_t> valueMap;  // lower.valuePtr()[i] = A.values[valueMap[i]]
  Eigen::SimplicialLLT<SpMat, Eigen::Lower, Eigen::AMDOrdering<int> > simplicial;
#if GF_HAVE_CHOLMOD
  Eigen::CholmodSupernodalLLT<SpMat, Eigen::Lower> llt;
  bool useSimplicial = false;
#else
  Eigen::SimplicialLLT<SpMat, Eigen::Lower, Eigen::AMDOrdering<int> >& llt = simplicial;
  static constexpr bool useSimplicial = true;
#endif
  int32_t n = -1;  // block rows of the analysed block pattern; -1 when none
  int32_t blocks = -1;
  int64_t factored = -1;     // scalar size of the current factor; -1 when there is none
  std::vector<double> work;  // 3 n, for the residual

  // Small matrices go to Eigen (see kSimplicialMaxBlocks); the analysis picks the ordering.
  bool analyzeLower() {
    factored = -1;
#if GF_HAVE_CHOLMOD
    useSimplicial = lower.rows() <= 3 * int64_t(kSimplicialMaxBlocks);
    llt.cholmod().print = 0;  // failures are reported to the caller, not on stdout
#endif
    const SerialOpenMpScope serial;
    if (useSimplicial)
      simplicial.analyzePattern(lower);
    else
      llt.analyzePattern(lower);
    return (useSimplicial ? simplicial.info() : llt.info()) == Eigen::Success;
  }
  bool factorizeLower() {
    factored = -1;
    const SerialOpenMpScope serial;
    if (useSimplicial)
      simplicial.factorize(lower);
    else
      llt.factorize(lower);
    if ((useSimplicial ? simplicial.info() : llt.info()) != Eigen::Success) return false;
    factored = lower.rows();
    return true;
  }
  // x = L^-T L^-1 b with the current factor; false and x = 0 when it is not finite.
  bool backSubstitute(const double* b, double* x) {
    const Eigen::Index size = Eigen::Index(factored);
    Eigen::Map<const Eigen::VectorXd> bm(b, size);
    Eigen::Map<Eigen::VectorXd> xm(x, size);
    if (useSimplicial) {
      xm = simplicial.solve(bm);
    } else {
      const SerialOpenMpScope serial;
      xm = llt.solve(bm);
    }
    if (allFinite(x, size_t(size))) return true;
    xm.setZero();
    return false;
  }
};

CholeskySolver::CholeskySolver() : m_impl(std::make_unique<Impl>()) {}
CholeskySolver::~CholeskySolver() = default;
CholeskySolver::CholeskySolver(CholeskySolver&&) noexcept = default;
CholeskySolver& CholeskySolver::operator=(CholeskySolver&&) noexcept = default;

Result<void> CholeskySolver::analyze(const BlockSparseMatrix& A) {
  blasOnOneThread();
  Impl& s = *m_impl;
  s.n = -1;
  // The pattern must be a valid, symmetric block-CSR with every diagonal block present.
  if (A.n < 0 || A.rowStart.size() != static_cast<size_t>(A.n) + 1 || A.rowStart[0] != 0 ||
      static_cast<size_t>(A.rowStart[A.n]) != A.col.size() || A.values.size() != 9 * A.col.size())
    return fail("cholesky: block matrix arrays have inconsistent sizes (n = ", std::to_string(A.n),
                ", blocks = ", std::to_string(A.col.size()), ")");
  for (int32_t r = 0; r < A.n; ++r) {
    if (A.rowStart[r + 1] < A.rowStart[r])
      return fail("cholesky: block row ", std::to_string(r), ": rowStart decreases");
    for (int32_t k = A.rowStart[r]; k < A.rowStart[r + 1]; ++k) {
      const int32_t c = A.col[k];
      if (c < 0 || c >= A.n || (k > A.rowStart[r] && A.col[k - 1] >= c))
        return fail("cholesky: block row ", std::to_string(r), ": column ", std::to_string(c),
                    " out of range or not sorted");
      if (A.find(c, r) < 0)
        return fail("cholesky: block (", std::to_string(r), ", ", std::to_string(c),
                    ") has no transpose: pattern not symmetric");
    }
    if (A.diagonal(r) < 0)
      return fail("cholesky: block row ", std::to_string(r), ": diagonal block missing");
  }

  // Column 3c + jj holds rows 3r + ii >= 3c + jj of the blocks (r, c), r >= c. Row c's sorted
  // columns list the block rows r of block column c (symmetric pattern), ascending.
  const int64_t size = 3 * static_cast<int64_t>(A.n);
  Impl::SpMat& L = s.lower;
  L.resize(size, size);
  L.resizeNonZeros(0);
  int64_t nnz = 0;
  for (int32_t c = 0; c < A.n; ++c)
    for (int32_t k = A.rowStart[c]; k < A.rowStart[c + 1]; ++k)
      if (A.col[k] > c) nnz += 9;
  nnz += 6 * static_cast<int64_t>(A.n);
  L.reserve(nnz);
  s.valueMap.clear();
  s.valueMap.reserve(static_cast<size_t>(nnz));
  for (int32_t c = 0; c < A.n; ++c) {
    for (int jj = 0; jj < 3; ++jj) {
      L.startVec(3 * c + jj);
      for (int32_t k = A.rowStart[c]; k < A.rowStart[c + 1]; ++k) {
        const int32_t r = A.col[k];
        if (r < c) continue;
        const int64_t blk = A.find(r, c);
        for (int ii = 0; ii < 3; ++ii) {
          if (r == c && ii < jj) continue;
          L.insertBack(3 * r + ii, 3 * c + jj) = 0.0;
          s.valueMap.push_back(9 * blk + 3 * ii + jj);
        }
      }
    }
  }
  L.finalize();
  s.n = A.n;
  s.blocks = A.blockCount();
  s.work.assign(static_cast<size_t>(size), 0.0);
  s.factored = -1;
  if (A.n == 0) return {};  // nothing to factorise (CHOLMOD rejects an empty matrix)
  if (!s.analyzeLower()) {
    s.n = -1;
    return fail("cholesky: symbolic analysis failed");
  }
  return {};
}

bool CholeskySolver::factorize(const BlockSparseMatrix& A) {
  Impl& s = *m_impl;
  s.factored = -1;
  if (s.n < 0 || s.n != A.n || s.blocks != A.blockCount()) return false;
  if (A.n == 0) {
    s.factored = 0;
    return true;
  }
  double* v = s.lower.valuePtr();
  for (size_t i = 0; i < s.valueMap.size(); ++i) v[i] = A.values[s.valueMap[i]];
  return s.factorizeLower();
}

Result<void> CholeskySolver::factorize(const SymmetricCsc& A) {
  blasOnOneThread();
  Impl& s = *m_impl;
  s.n = -1;  // the block pattern, if any, is replaced
  s.factored = -1;
  if (A.n < 0 || (A.n > 0 && (!A.colStart || !A.row || !A.value)) ||
      (A.colStart && A.colStart[0] != 0))
    return fail("cholesky: scalar matrix: n = ", std::to_string(A.n),
                " with missing arrays or colStart[0] != 0");
  // Rows ascending in each column, the diagonal present: a missing diagonal cannot be positive
  // definite and is named here rather than reported as a failed factorisation.
  int64_t nnz = 0;
  for (int32_t c = 0; c < A.n; ++c) {
    if (A.colStart[c + 1] < A.colStart[c])
      return fail("cholesky: scalar matrix: column ", std::to_string(c), ": colStart decreases");
    bool diagonal = false;
    for (int32_t k = A.colStart[c]; k < A.colStart[c + 1]; ++k) {
      const int32_t r = A.row[k];
      if (r < 0 || r >= A.n || (k > A.colStart[c] && A.row[k - 1] >= r))
        return fail("cholesky: scalar matrix: column ", std::to_string(c), ": row ",
                    std::to_string(r), " out of range or not ascending");
      diagonal = diagonal || r == c;
      if (r >= c) ++nnz;
    }
    if (!diagonal)
      return fail("cholesky: scalar matrix: column ", std::to_string(c), " has no diagonal entry");
  }
  Impl::SpMat& L = s.lower;
  L.resize(A.n, A.n);
  L.resizeNonZeros(0);
  L.reserve(nnz);
  s.valueMap.clear();
  for (int32_t c = 0; c < A.n; ++c) {
    L.startVec(c);
    for (int32_t k = A.colStart[c]; k < A.colStart[c + 1]; ++k)
      if (A.row[k] >= c) L.insertBack(A.row[k], c) = A.value[k];
  }
  L.finalize();
  if (A.n == 0) {
    s.factored = 0;
    return {};
  }
  if (!s.analyzeLower()) return fail("cholesky: scalar matrix: symbolic analysis failed");
  if (!s.factorizeLower())
    return fail("cholesky: scalar matrix (n = ", std::to_string(A.n), ") is not positive definite");
  return {};
}

bool CholeskySolver::solveFactored(const double* b, double* x) {
  Impl& s = *m_impl;
  if (s.factored <= 0) {
    for (int64_t i = 0; i < std::max<int64_t>(s.factored, 0); ++i) x[i] = 0;
    return s.factored == 0;
  }
  return s.backSubstitute(b, x);
}

int64_t CholeskySolver::factoredSize() const { return std::max<int64_t>(m_impl->factored, 0); }

CholeskyFactorInfo CholeskySolver::factorInfo() const {
  const Impl& s = *m_impl;
  CholeskyFactorInfo info;
  if (s.factored <= 0) return info;
  info.matrixNonZeros = s.lower.nonZeros();
  if (s.useSimplicial) {
    info.factorNonZeros = s.simplicial.matrixL().nestedExpression().nonZeros();
    info.ordering = "amd";
    return info;
  }
#if GF_HAVE_CHOLMOD
  // Eigen keeps the Common non-const only; the analysis left the chosen method's statistics.
  const cholmod_common& c = const_cast<Impl&>(s).llt.cholmod();
  const int m = c.selected >= 0 && c.selected < CHOLMOD_MAXMETHODS ? c.selected : 0;
  info.factorNonZeros = int64_t(c.method[m].lnz);
  info.flops = c.method[m].fl;
  switch (c.method[m].ordering) {
    case CHOLMOD_NATURAL:
      info.ordering = "natural";
      break;
    case CHOLMOD_GIVEN:
      info.ordering = "given";
      break;
    case CHOLMOD_AMD:
      info.ordering = "amd";
      break;
    case CHOLMOD_METIS:
      info.ordering = "metis";
      break;
    case CHOLMOD_NESDIS:
      info.ordering = "nesdis";
      break;
    case CHOLMOD_COLAMD:
      info.ordering = "colamd";
      break;
    default:
      info.ordering = "other";
      break;
  }
  info.supernodal = true;
#endif
  return info;
}

SolveReport CholeskySolver::solve(const BlockSparseMatrix& A, const double* b, double* x) {
  Impl& s = *m_impl;
  SolveReport report;
  report.relativeResidual = std::numeric_limits<double>::infinity();
  const size_t n3 = 3 * static_cast<size_t>(std::max(A.n, 0));
  auto failWithZero = [&]() {
    for (size_t i = 0; i < n3; ++i) x[i] = 0;
    return report;
  };
  if (s.n != A.n || s.blocks != A.blockCount()) return failWithZero();
  if (A.n == 0) {
    report.relativeResidual = 0;
    report.converged = true;
    return report;
  }

  if (!factorize(A)) return failWithZero();  // not positive definite
  if (!s.backSubstitute(b, x)) return failWithZero();

  // |b - A x| / |b| with the block matrix itself (both triangles).
  A.multiply(x, s.work.data(), serialJobs());
  double rr = 0, bb = 0;
  for (size_t i = 0; i < n3; ++i) {
    const double d = b[i] - s.work[i];
    rr += d * d;
    bb += b[i] * b[i];
  }
  report.relativeResidual = bb > 0 ? std::sqrt(rr / bb) : std::sqrt(rr);
  report.converged = std::isfinite(report.relativeResidual);
  if (!report.converged) return failWithZero();
  return report;
}

}  // namespace gf::detail
