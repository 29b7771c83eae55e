// The 3x3 block-row product (solver/block_row.h), of a double and of a float matrix, and the
// stages built on it (SpMV, level residual, a Gauss-Seidel colour on its float copy) against a
// plain long-double reference on random block-sparse matrices of several sizes and patterns, to
// the round-off bound of a dot product. The matrix and the vector end at a page that may not be
// read, so a 4-wide load past the last block or the last node would crash the test rather than
// read silently.
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "solver/block_row.h"
#include "solver/multigrid_stages.h"
#include "solver/sparse_stages.h"

namespace {

// `count` T that end where an unreadable page begins.
template <class T>
class Guarded {
 public:
  explicit Guarded(size_t count) {
    const size_t page = size_t(sysconf(_SC_PAGESIZE));
    m_dataPages = (count * sizeof(T) + page - 1) / page;
    m_bytes = (m_dataPages + 1) * page;
    void* p = mmap(nullptr, m_bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) return;
    m_base = static_cast<char*>(p);
    mprotect(m_base + m_dataPages * page, page, PROT_NONE);
    m_data = reinterpret_cast<T*>(m_base + m_dataPages * page) - count;
  }
  ~Guarded() {
    if (m_base) munmap(m_base, m_bytes);
  }
  Guarded(const Guarded&) = delete;
  Guarded& operator=(const Guarded&) = delete;
  T* data() { return m_data; }
  bool ok() const { return m_data != nullptr; }

 private:
  size_t m_dataPages = 0, m_bytes = 0;
  char* m_base = nullptr;
  T* m_data = nullptr;
};
using GuardedDoubles = Guarded<double>;

// A block-CSR pattern with sorted columns: each row its diagonal block (but every 5th row) and
// up to 2 perRowMax random ones, so rows of 0, 1, 2, 3 and many blocks occur; the last row ends
// with the last node, so the array's last block reads x's last 3 entries.
struct RandomBlockMatrix {
  int32_t n = 0;
  std::vector<int32_t> rowStart, col;
  size_t blocks() const { return col.size(); }
};

RandomBlockMatrix randomPattern(int32_t n, int perRowMax, std::mt19937& rng) {
  RandomBlockMatrix A;
  A.n = n;
  A.rowStart.push_back(0);
  std::uniform_int_distribution<int32_t> node(0, n - 1);
  std::uniform_int_distribution<int> count(0, 2 * perRowMax);
  for (int32_t r = 0; r < n; ++r) {
    std::vector<int32_t> c;
    if (r % 5 != 4) c.push_back(r);
    const int extra = r == n - 1 ? perRowMax : count(rng);
    for (int i = 0; i < extra; ++i) c.push_back(node(rng));
    if (r == n - 1) c.push_back(n - 1);
    std::sort(c.begin(), c.end());
    c.erase(std::unique(c.begin(), c.end()), c.end());
    A.col.insert(A.col.end(), c.begin(), c.end());
    A.rowStart.push_back(int32_t(A.col.size()));
  }
  return A;
}

// Values over several orders of magnitude and both signs.
void fillRandom(double* v, size_t count, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::uniform_int_distribution<int> e(-6, 6);
  for (size_t i = 0; i < count; ++i) v[i] = std::ldexp(u(rng), e(rng));
}

// Random values rounded to single precision, and the same numbers in double (exact).
void fillRandomFloats(float* v, size_t count, std::vector<double>& asDouble, std::mt19937& rng) {
  asDouble.resize(count);
  fillRandom(asDouble.data(), count, rng);
  for (size_t i = 0; i < count; ++i) {
    v[i] = float(asDouble[i]);
    asDouble[i] = v[i];
  }
}

// Row r of A x in long double, and sum |A||x| (the scale of its round-off).
void referenceRow(const RandomBlockMatrix& A, const double* values, const double* x, int32_t r,
                  long double out[3], double scale[3]) {
  for (int i = 0; i < 3; ++i) {
    out[i] = 0;
    scale[i] = 0;
  }
  for (int32_t k = A.rowStart[size_t(r)]; k < A.rowStart[size_t(r) + 1]; ++k)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const double m = values[9 * size_t(k) + 3 * size_t(i) + size_t(j)];
        const double xj = x[3 * size_t(A.col[size_t(k)]) + size_t(j)];
        out[i] += (long double)m * xj;
        scale[i] += std::fabs(m * xj);
      }
}

// Any order of a length-L dot product, fused or not, is within gamma_L sum |a_j x_j| of the
// exact one (Higham, Accuracy and Stability of Numerical Algorithms, sec 3.1); this is
// (L + 3) eps with L = 3 blocks, more than twice gamma_L.
double bound(int32_t rowBlocks, double scale) {
  return 3.0 * (rowBlocks + 1) * std::numeric_limits<double>::epsilon() * scale +
         std::numeric_limits<double>::denorm_min();
}

struct Case {
  int32_t n;
  int perRow;
};
constexpr Case kCases[] = {{1, 0}, {1, 3}, {2, 1}, {3, 2}, {7, 5}, {64, 7}, {500, 13}, {2000, 27}};

TEST(BlockRow, ProductAndStagesMatchTheReferenceToRoundOff) {
  std::mt19937 rng(20261206);
  int checked = 0;
  double worst = 0;  // largest error over its bound
  for (const Case& c : kCases) {
    const RandomBlockMatrix A = randomPattern(c.n, c.perRow, rng);
    GuardedDoubles values(9 * A.blocks()), x(3 * size_t(A.n));
    ASSERT_TRUE(values.ok() && x.ok());
    fillRandom(values.data(), 9 * A.blocks(), rng);
    fillRandom(x.data(), 3 * size_t(A.n), rng);
    std::vector<double> b(3 * size_t(A.n)), y(3 * size_t(A.n)), res(3 * size_t(A.n));
    fillRandom(b.data(), b.size(), rng);
    const gf::detail::BlockMatrixView view{A.n, A.rowStart.data(), A.col.data(), values.data()};
    const gf::detail::LevelMatrix<3> level{A.n, A.rowStart.data(), A.col.data(), values.data()};
    const gf::detail::SpmvStage spmv{view, x.data(), y.data()};
    const gf::detail::LevelResidualStage<3> residual{level, b.data(), x.data(), res.data()};
    for (int32_t r = 0; r < A.n; ++r) {
      spmv(r);
      residual(r);
      double direct[3], scalar[3];
      const int32_t begin = A.rowStart[size_t(r)], end = A.rowStart[size_t(r) + 1];
      gf::detail::blockRowProduct3(A.col.data(), values.data(), begin, end, x.data(), direct);
      gf::detail::blockRowProduct3Scalar(A.col.data(), values.data(), begin, end, x.data(), scalar);
      long double ref[3];
      double scale[3];
      referenceRow(A, values.data(), x.data(), r, ref, scale);
      for (int i = 0; i < 3; ++i) {
        const size_t e = 3 * size_t(r) + size_t(i);
        const double tol = bound(end - begin, scale[i]);
        const double err = double(std::fabs((long double)y[e] - ref[i]));
        ASSERT_LE(err, tol) << "n " << A.n << " row " << r << " component " << i;
        ASSERT_EQ(direct[i], y[e]);
        ASSERT_LE(double(std::fabs((long double)scalar[i] - ref[i])), tol);
        const double resTol =
            tol + (std::fabs(b[e]) + scale[i]) * std::numeric_limits<double>::epsilon();
        ASSERT_LE(double(std::fabs((long double)res[e] - ((long double)b[e] - ref[i]))), resTol);
        worst = std::max(worst, err / tol);
        ++checked;
      }
    }
  }
  std::printf("[ block row ] %d components, largest error %.3g of its bound\n", checked, worst);
}

// A float matrix (the level-0 Gauss-Seidel copy, GsValue in multigrid_stages.h): its entries
// widen to double exactly, so the product is the double product of the rounded matrix, bit for
// bit, and within the same bound of its long-double value.
TEST(BlockRow, FloatMatrixProductIsTheProductOfTheRoundedMatrix) {
  std::mt19937 rng(20261207);
  int checked = 0;
  double worst = 0;
  for (const Case& c : kCases) {
    const RandomBlockMatrix A = randomPattern(c.n, c.perRow, rng);
    Guarded<float> values(9 * A.blocks());
    GuardedDoubles x(3 * size_t(A.n));
    ASSERT_TRUE(values.ok() && x.ok());
    std::vector<double> rounded;
    fillRandomFloats(values.data(), 9 * A.blocks(), rounded, rng);
    fillRandom(x.data(), 3 * size_t(A.n), rng);
    for (int32_t r = 0; r < A.n; ++r) {
      double direct[3], scalar[3], widened[3];
      const int32_t begin = A.rowStart[size_t(r)], end = A.rowStart[size_t(r) + 1];
      gf::detail::blockRowProduct3(A.col.data(), values.data(), begin, end, x.data(), direct);
      gf::detail::blockRowProduct3Scalar(A.col.data(), values.data(), begin, end, x.data(), scalar);
      gf::detail::blockRowProduct3(A.col.data(), rounded.data(), begin, end, x.data(), widened);
      long double ref[3];
      double scale[3];
      referenceRow(A, rounded.data(), x.data(), r, ref, scale);
      for (int i = 0; i < 3; ++i) {
        const double tol = bound(end - begin, scale[i]);
        const double err = double(std::fabs((long double)direct[i] - ref[i]));
        ASSERT_LE(err, tol) << "n " << A.n << " row " << r << " component " << i;
        ASSERT_LE(double(std::fabs((long double)scalar[i] - ref[i])), tol);
        ASSERT_EQ(direct[i], widened[i]) << "n " << A.n << " row " << r << " component " << i;
        worst = std::max(worst, err / tol);
        ++checked;
      }
    }
  }
  std::printf("[ block row ] float matrix: %d components, largest error %.3g of its bound\n",
              checked, worst);
}

// One Gauss-Seidel colour per row, in order, is the plain sequential block Gauss-Seidel sweep
// x_r += D_r^-1 (b - A x)_r, here with D_r^-1 any block and A read from its float copy: against
// the same with the rounded A in long double.
TEST(BlockRow, GaussSeidelColourStageIsTheSequentialBlockUpdate) {
  std::mt19937 rng(7);
  for (const Case& c : kCases) {
    const RandomBlockMatrix A = randomPattern(c.n, c.perRow, rng);
    Guarded<float> values(9 * A.blocks());
    GuardedDoubles x(3 * size_t(A.n));
    ASSERT_TRUE(values.ok() && x.ok());
    std::vector<double> rounded;
    fillRandomFloats(values.data(), 9 * A.blocks(), rounded, rng);
    fillRandom(x.data(), 3 * size_t(A.n), rng);
    std::vector<double> b(3 * size_t(A.n)), invDiag(9 * size_t(A.n));
    fillRandom(b.data(), b.size(), rng);
    fillRandom(invDiag.data(), invDiag.size(), rng);
    std::vector<int32_t> rows(size_t(A.n));
    for (int32_t r = 0; r < A.n; ++r) rows[size_t(r)] = r;
    std::vector<long double> xr(x.data(), x.data() + 3 * size_t(A.n));
    gf::detail::GaussSeidelColourStage<3> sweep{
        rows.data(),    A.rowStart.data(), A.col.data(), values.data(),
        invDiag.data(), b.data(),          x.data(),     0};
    for (int32_t r = 0; r < A.n; ++r) {
      sweep.first = r;
      sweep(0);
      long double res[3] = {0, 0, 0};
      double scale[3] = {0, 0, 0};
      for (int32_t k = A.rowStart[size_t(r)]; k < A.rowStart[size_t(r) + 1]; ++k)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) {
            const double m = rounded[9 * size_t(k) + 3 * size_t(i) + size_t(j)];
            res[i] -= m * xr[3 * size_t(A.col[size_t(k)]) + size_t(j)];
            scale[i] += std::fabs(m * double(xr[3 * size_t(A.col[size_t(k)]) + size_t(j)]));
          }
      for (int i = 0; i < 3; ++i) {
        res[i] += b[3 * size_t(r) + size_t(i)];
        scale[i] += std::fabs(b[3 * size_t(r) + size_t(i)]);
      }
      const int32_t blocks = A.rowStart[size_t(r) + 1] - A.rowStart[size_t(r)];
      for (int i = 0; i < 3; ++i) {
        long double dx = 0;
        double dxScale = 0;  // its error bound
        for (int j = 0; j < 3; ++j) {
          const double d = invDiag[9 * size_t(r) + 3 * size_t(i) + size_t(j)];
          dx += d * res[j];
          // The residual's error through D^-1, then this product and the update rounded.
          dxScale += std::fabs(d) * bound(blocks + 1, scale[j]) +
                     4 * std::numeric_limits<double>::epsilon() * std::fabs(d * double(res[j]));
        }
        const size_t e = 3 * size_t(r) + size_t(i);
        xr[e] += dx;
        const double tol =
            dxScale + 2 * std::numeric_limits<double>::epsilon() * std::fabs(double(xr[e]));
        ASSERT_LE(double(std::fabs((long double)x.data()[e] - xr[e])), tol)
            << "n " << A.n << " row " << r << " component " << i;
        xr[e] = x.data()[e];  // the next rows read the stage's x, as the sweep does
      }
    }
  }
}

}  // namespace
