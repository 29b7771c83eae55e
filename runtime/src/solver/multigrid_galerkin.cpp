// Multigrid hierarchy, the numeric half: prolongator smoothing (smoothed aggregation), the
// Galerkin products A_{l+1} = P^T A_l P and the transfers P, P^T. The patterns these fill are
// built in multigrid_hierarchy.cpp; every product sums precomputed block pairs in a fixed
// order and every parallel loop writes disjoint blocks (the same bits for any thread count).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "solver/multigrid_hierarchy.h"
#include "solver/vector_ops.h"

namespace gf::detail {

namespace {

// Power iterations for rho(D^-1 A_F) of the prolongator smoothing.
constexpr int kPowerIterations = 10;
// Handles per parallel range of the coarse assembly and the transfers.
constexpr uint32_t kHandleGrain = 8;
constexpr uint32_t kNodeGrain = 256;

}  // namespace

namespace {

// The finer level's matrix values (B x B blocks, row-major) and its diagonal block per row.
template <int B>
struct FinerValues {
  const double* values = nullptr;
  const double* block(int32_t k) const { return values + static_cast<size_t>(B * B) * k; }
};

// out (B x C) = a (B x B) * b (B x C), or += with add.
template <int B, int C>
inline void mulAdd(const double* a, const double* b, double* out) {
  for (int i = 0; i < B; ++i) {
    double* o = out + C * i;
    for (int m = 0; m < B; ++m) {
      const double am = a[B * i + m];
      if (am == 0) continue;
      const double* bm = b + C * m;
      for (int j = 0; j < C; ++j) o[j] += am * bm[j];
    }
  }
}

// out (B x 12) += a (B x B) T_j, T_j the tentative block of finer row j (eq 6.6-6.8).
template <int B>
inline void tentativeRight(const CoarseLevel& lv, const double* a, int32_t j, double* out) {
  if constexpr (B == 3) {
    const double* x = lv.coord.data() + 3 * static_cast<size_t>(j);
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k) {
        const double v = a[3 * i + k];
        double* o = out + 12 * i;
        o[k] += x[0] * v;
        o[3 + k] += x[1] * v;
        o[6 + k] += x[2] * v;
        o[9 + k] += v;
      }
  } else {
    const double* d = lv.childOffset.data() + 3 * static_cast<size_t>(j);
    const double ratio = lv.childRatio;
    for (int i = 0; i < 12; ++i) {
      const double* ai = a + 12 * i;
      double* o = out + 12 * i;
      for (int c = 0; c < 9; ++c) o[c] += ratio * ai[c] + ai[9 + c % 3] * d[c / 3];
      for (int k = 0; k < 3; ++k) o[9 + k] += ai[9 + k];
    }
  }
}

// out (12 x 12) += T_r^T q, q = Q_rK (B x 12), T_r the tentative block of finer row r.
template <int B>
inline void tentativeLeft(const CoarseLevel& lv, int32_t r, const double* q, double* out) {
  if constexpr (B == 3) {
    const double* x = lv.coord.data() + 3 * static_cast<size_t>(r);
    for (int k = 0; k < 3; ++k) {
      const double* qk = q + 12 * k;
      for (int a = 0; a < 3; ++a) {
        double* o = out + 12 * (3 * a + k);
        for (int c = 0; c < 12; ++c) o[c] += x[a] * qk[c];
      }
      double* o = out + 12 * (9 + k);
      for (int c = 0; c < 12; ++c) o[c] += qk[c];
    }
  } else {
    const double* d = lv.childOffset.data() + 3 * static_cast<size_t>(r);
    const double ratio = lv.childRatio;
    for (int j = 0; j < 9; ++j) {
      const double* qj = q + 12 * j;
      const double* qt = q + 12 * (9 + j % 3);
      double* o = out + 12 * j;
      for (int c = 0; c < 12; ++c) o[c] += ratio * qj[c] + d[j / 3] * qt[c];
    }
    for (int k = 0; k < 3; ++k) {
      const double* qk = q + 12 * (9 + k);
      double* o = out + 12 * (9 + k);
      for (int c = 0; c < 12; ++c) o[c] += qk[c];
    }
  }
}

}  // namespace

// Smoothed aggregation (Vanek, Mandel & Brezina 1996): P = (I - omega D^-1 A_F) T with
// omega = 4 / (3 rho(D^-1 A_F)), which damps the high-energy part of each tentative basis
// function (the jumps at aggregate borders) while a near-null field T q (here an affine one)
// keeps |D^-1 A_F T q| small: P keeps the affine modes in the interior of a stiff body (A T q
// = 0 there up to the mass term). A_F drops the blocks across broken edges, so no basis
// function reaches across a crack.
template <int B>
void MultigridHierarchy::smoothProlongation(int l, const BlockSparseMatrix& A, JobSystem& jobs) {
  CoarseLevel& lv = m_levels[static_cast<size_t>(l - 1)];
  const FinerValues<B> F{B == 3 ? A.values.data()
                                : m_levels[static_cast<size_t>(l - 2)].A.values.data()};
  const int32_t rows = static_cast<int32_t>(lv.pStart.size()) - 1;
  const size_t len = static_cast<size_t>(B) * rows;
  constexpr int BB = B * B;
  constexpr int BC = B * 12;
  if (!smoothesLevel(l)) {
    forRanges(jobs, static_cast<uint32_t>(rows), kNodeGrain, [&](uint32_t begin, uint32_t end) {
      for (uint32_t r = begin; r < end; ++r)
        for (int32_t p = lv.pStart[r]; p < lv.pStart[r + 1]; ++p)
          tentativeBlock(l, static_cast<int32_t>(r),
                         lv.pValues.data() + BC * static_cast<size_t>(p));
    });
    lv.omega = 0;
    lv.prolongationFresh = true;
    return;
  }
  // D^-1: the diagonal blocks (fStart's first entry of each row).
  double* inv = m_invDiag.data();
  forRanges(jobs, static_cast<uint32_t>(rows), kHandleGrain, [&](uint32_t begin, uint32_t end) {
    for (uint32_t r = begin; r < end; ++r)
      invertSpdBlock<B>(F.block(lv.fBlock[lv.fStart[r]]), inv + BB * static_cast<size_t>(r));
  });
  // rho(D^-1 A_F) by power iteration with the Rayleigh quotient v.A_F v / v.D v from a fixed,
  // non-smooth start (deterministic; fixed-chunk reductions).
  double* v = m_v.data();
  double* w = m_w.data();
  double* t = m_t.data();
  for (size_t i = 0; i < len; ++i) v[i] = 1.0 + 0.37 * static_cast<double>((i * 7919) % 13);
  double lambda = 0;
  for (int it = 0; it < kPowerIterations; ++it) {
    forRanges(jobs, static_cast<uint32_t>(rows), kHandleGrain, [&](uint32_t begin, uint32_t end) {
      for (uint32_t r = begin; r < end; ++r) {
        double* wr = w + B * static_cast<size_t>(r);
        double* tr = t + B * static_cast<size_t>(r);
        std::fill(wr, wr + B, 0.0);
        std::fill(tr, tr + B, 0.0);
        for (int32_t f = lv.fStart[r]; f < lv.fStart[r + 1]; ++f) {
          mulAdd<B, 1>(F.block(lv.fBlock[f]), v + B * static_cast<size_t>(lv.fCol[f]), wr);
          if (f == lv.fStart[r])
            mulAdd<B, 1>(F.block(lv.fBlock[f]), v + B * static_cast<size_t>(r), tr);
        }
      }
    });
    const double vav = dot(v, w, len, m_partials, jobs);
    const double vdv = dot(v, t, len, m_partials, jobs);
    if (!(vdv > 0) || !std::isfinite(vav)) break;
    lambda = vav / vdv;
    forRanges(jobs, static_cast<uint32_t>(rows), kHandleGrain, [&](uint32_t begin, uint32_t end) {
      for (uint32_t r = begin; r < end; ++r) {
        double* vr = v + B * static_cast<size_t>(r);
        std::fill(vr, vr + B, 0.0);
        mulAdd<B, 1>(inv + BB * static_cast<size_t>(r), w + B * static_cast<size_t>(r), vr);
      }
    });
    const double nv = norm2(v, len, m_partials, jobs);
    if (!(nv > 0) || !std::isfinite(nv)) break;
    const double s = 1 / nv;
    for (size_t i = 0; i < len; ++i) v[i] *= s;
  }
  lv.lambdaMax = lambda > 0 && std::isfinite(lambda) ? lambda : 0.0;
  lv.omega = lv.lambdaMax > 0 ? 4.0 / (3.0 * lv.lambdaMax) : 0.0;
  const double omega = lv.omega;
  const std::vector<int32_t>& parent = l == 1 ? lv.nodeHandle : lv.finerParent;
  // P_rK = [K = parent(r)] T_r - omega D_r^-1 sum_j A_rj T_j over the filtered j of parent K.
  forRanges(jobs, static_cast<uint32_t>(rows), B == 3 ? kNodeGrain / 4 : kHandleGrain,
            [&](uint32_t begin, uint32_t end) {
              double tj[BC], acc[BC];
              for (uint32_t r = begin; r < end; ++r) {
                for (int32_t p = lv.pStart[r]; p < lv.pStart[r + 1]; ++p) {
                  std::fill(acc, acc + BC, 0.0);
                  const int32_t K = lv.pCol[p];
                  for (int32_t s = lv.sStart[p]; s < lv.sStart[p + 1]; ++s) {
                    tentativeBlockFor(l, lv.sRow[s], K, tj);
                    mulAdd<B, 12>(F.block(lv.sBlock[s]), tj, acc);
                  }
                  double* out = lv.pValues.data() + BC * static_cast<size_t>(p);
                  tentativeBlock(l, static_cast<int32_t>(r), out);
                  if (K != parent[r]) std::fill(out, out + BC, 0.0);
                  double corr[BC] = {};
                  mulAdd<B, 12>(inv + BB * static_cast<size_t>(r), acc, corr);
                  for (int i = 0; i < BC; ++i) out[i] -= omega * corr[i];
                }
              }
            });
  lv.prolongationFresh = true;
}

// A_l = P^T (A_{l-1} P) (eq 6.4): Q row by row, then each coarse block from its listed pairs.
template <int B>
void MultigridHierarchy::galerkin(int l, const BlockSparseMatrix& A, JobSystem& jobs) {
  CoarseLevel& lv = m_levels[static_cast<size_t>(l - 1)];
  const FinerValues<B> F{B == 3 ? A.values.data()
                                : m_levels[static_cast<size_t>(l - 2)].A.values.data()};
  constexpr int BC = B * 12;
  // A tentative P (one structured block per row, eq 6.6-6.8) is applied from its coordinates:
  // a third of the flops and none of P's memory.
  const bool tentative = !smoothesLevel(l);
  const int32_t rows = static_cast<int32_t>(lv.qStart.size()) - 1;
  forRanges(jobs, static_cast<uint32_t>(rows), B == 3 ? kNodeGrain / 4 : kHandleGrain,
            [&](uint32_t begin, uint32_t end) {
              for (uint32_t r = begin; r < end; ++r)
                for (int32_t q = lv.qStart[r]; q < lv.qStart[r + 1]; ++q) {
                  double* out = lv.qValues.data() + BC * static_cast<size_t>(q);
                  std::fill(out, out + BC, 0.0);
                  for (int32_t c = lv.qcStart[q]; c < lv.qcStart[q + 1]; ++c) {
                    if (tentative) {
                      tentativeRight<B>(lv, F.block(lv.qcA[c]), lv.pRow[lv.qcP[c]], out);
                    } else {
                      mulAdd<B, 12>(F.block(lv.qcA[c]),
                                    lv.pValues.data() + BC * static_cast<size_t>(lv.qcP[c]), out);
                    }
                  }
                }
            });
  CoarseMatrix& C = lv.A;
  forRanges(jobs, static_cast<uint32_t>(C.n), kHandleGrain, [&](uint32_t begin, uint32_t end) {
    for (uint32_t h = begin; h < end; ++h) {
      for (int32_t kc = C.rowStart[h]; kc < C.rowStart[h + 1]; ++kc) {
        if (lv.mirror[kc] >= 0) continue;  // the lower triangle, below
        double out[144] = {};
        for (int32_t g = lv.gatherStart[kc]; g < lv.gatherStart[kc + 1]; ++g) {
          const double* pb = lv.pValues.data() + BC * static_cast<size_t>(lv.gatherP[g]);
          const double* qb = lv.qValues.data() + BC * static_cast<size_t>(lv.gatherQ[g]);
          if (tentative) {
            tentativeLeft<B>(lv, lv.pRow[lv.gatherP[g]], qb, out);
            continue;
          }
          // out += P_rH^T Q_rK.
          for (int m = 0; m < B; ++m) {
            const double* pm = pb + 12 * m;
            const double* qm = qb + 12 * m;
            for (int i = 0; i < 12; ++i) {
              const double a = pm[i];
              if (a == 0) continue;
              double* o = out + 12 * i;
              for (int j = 0; j < 12; ++j) o[j] += a * qm[j];
            }
          }
        }
        if (l == 1 && C.col[kc] == static_cast<int32_t>(h)) {
          // Null directions of the aggregate get the block's mean diagonal (see nullProjector).
          double trace = 0;
          for (int i = 0; i < 12; ++i) trace += out[13 * i];
          const double delta = trace > 0 && std::isfinite(trace) ? trace / 12 : 1.0;
          const double* proj = lv.nullProjector.data() + 16 * static_cast<size_t>(h);
          for (int a = 0; a < 4; ++a)
            for (int c = 0; c < 4; ++c)
              for (int i = 0; i < 3; ++i)
                out[(3 * a + i) * 12 + 3 * c + i] += delta * proj[4 * a + c];
        }
        std::copy(out, out + 144, C.block(kc));
      }
    }
  });
  // The lower triangle is the transpose of the upper: A_l is symmetric to the last bit.
  forRanges(jobs, static_cast<uint32_t>(C.n), kHandleGrain, [&](uint32_t begin, uint32_t end) {
    for (uint32_t h = begin; h < end; ++h)
      for (int32_t kc = C.rowStart[h]; kc < C.rowStart[h + 1]; ++kc) {
        if (lv.mirror[kc] < 0) continue;
        const double* src = C.block(lv.mirror[kc]);
        double* dst = C.block(kc);
        for (int i = 0; i < 12; ++i)
          for (int j = 0; j < 12; ++j) dst[12 * i + j] = src[12 * j + i];
      }
  });
}

void MultigridHierarchy::assemble(const BlockSparseMatrix& A, JobSystem& jobs) {
  for (int l = 1; l <= coarseLevelCount(); ++l) {
    const bool fresh = m_levels[static_cast<size_t>(l - 1)].prolongationFresh;
    if (l == 1) {
      if (!fresh) smoothProlongation<3>(l, A, jobs);
      galerkin<3>(l, A, jobs);
    } else {
      if (!fresh) smoothProlongation<12>(l, A, jobs);
      galerkin<12>(l, A, jobs);
    }
  }
}

void MultigridHierarchy::restrictTo(int level, const double* fine, double* coarse,
                                    JobSystem& jobs) const {
  const CoarseLevel& lv = m_levels[static_cast<size_t>(level)];
  const int B = level == 0 ? 3 : 12;
  const bool tentative = !smoothesLevel(level + 1);
  const uint32_t k = static_cast<uint32_t>(lv.handleNode.size());
  forRanges(jobs, k, kHandleGrain, [&](uint32_t begin, uint32_t end) {
    for (uint32_t h = begin; h < end; ++h) {
      // coarse_H = sum over the column's blocks of P_rH^T fine_r, rows increasing.
      double s[12] = {};
      for (int32_t t = lv.ptStart[h]; t < lv.ptStart[h + 1]; ++t) {
        const int32_t p = lv.ptBlock[t];
        const size_t r = static_cast<size_t>(lv.pRow[p]);
        const double* f = fine + static_cast<size_t>(B) * r;
        if (tentative && level == 0) {
          // U^T of a fine node: [x; 1] (x) r_i (eq 6.7).
          const double* x = lv.coord.data() + 3 * r;
          for (int a = 0; a < 3; ++a)
            for (int i = 0; i < 3; ++i) s[3 * a + i] += x[a] * f[i];
          for (int i = 0; i < 3; ++i) s[9 + i] += f[i];
        } else if (tentative) {
          // Transpose of eq 6.8's change of reference point.
          const double* d = lv.childOffset.data() + 3 * r;
          for (int a = 0; a < 3; ++a)
            for (int i = 0; i < 3; ++i)
              s[3 * a + i] += lv.childRatio * f[3 * a + i] + d[a] * f[9 + i];
          for (int i = 0; i < 3; ++i) s[9 + i] += f[9 + i];
        } else {
          const double* pb = lv.pValues.data() + static_cast<size_t>(12 * B) * p;
          for (int m = 0; m < B; ++m) {
            const double fm = f[m];
            const double* pm = pb + 12 * m;
            for (int i = 0; i < 12; ++i) s[i] += pm[i] * fm;
          }
        }
      }
      std::copy(s, s + 12, coarse + 12 * static_cast<size_t>(h));
    }
  });
}

void MultigridHierarchy::prolongAdd(int level, const double* coarse, double* fine,
                                    JobSystem& jobs) const {
  const CoarseLevel& lv = m_levels[static_cast<size_t>(level)];
  const int B = level == 0 ? 3 : 12;
  const bool tentative = !smoothesLevel(level + 1);
  const uint32_t rows = static_cast<uint32_t>(lv.pStart.size()) - 1;
  forRanges(jobs, rows, level == 0 ? kNodeGrain : kHandleGrain * 8,
            [&](uint32_t begin, uint32_t end) {
              for (uint32_t r = begin; r < end; ++r) {
                double* out = fine + static_cast<size_t>(B) * r;
                for (int32_t p = lv.pStart[r]; p < lv.pStart[r + 1]; ++p) {
                  const double* q = coarse + 12 * static_cast<size_t>(lv.pCol[p]);
                  if (tentative && level == 0) {
                    // eq 6.6: x_i = T_h [x; 1].
                    const double* x = lv.coord.data() + 3 * static_cast<size_t>(r);
                    for (int k = 0; k < 3; ++k)
                      out[k] += x[0] * q[k] + x[1] * q[3 + k] + x[2] * q[6 + k] + q[9 + k];
                  } else if (tentative) {
                    // eq 6.8: the coarser affine map seen from the finer handle's origin.
                    const double* d = lv.childOffset.data() + 3 * static_cast<size_t>(r);
                    for (int j = 0; j < 9; ++j) out[j] += lv.childRatio * q[j];
                    for (int k = 0; k < 3; ++k)
                      out[9 + k] += d[0] * q[k] + d[1] * q[3 + k] + d[2] * q[6 + k] + q[9 + k];
                  } else {
                    // eq 6.3: fine_r += P_rK coarse_K.
                    const double* pb = lv.pValues.data() + static_cast<size_t>(12 * B) * p;
                    for (int m = 0; m < B; ++m) {
                      double s = 0;
                      for (int i = 0; i < 12; ++i) s += pb[12 * m + i] * q[i];
                      out[m] += s;
                    }
                  }
                }
              }
            });
}

template <int B>
void invertSpdBlock(const double* m, double* inv) {
  using Mat = Eigen::Matrix<double, B, B, Eigen::RowMajor>;
  Eigen::LLT<Mat> llt(Eigen::Map<const Mat>{m});
  if (llt.info() == Eigen::Success) {
    Eigen::Map<Mat>{inv} = llt.solve(Mat::Identity());
    bool finite = true;
    for (int i = 0; i < B * B; ++i) finite = finite && std::isfinite(inv[i]);
    if (finite) return;
  }
  for (int i = 0; i < B * B; ++i) inv[i] = 0;
  for (int i = 0; i < B; ++i) {
    const double d = m[(B + 1) * i];
    inv[(B + 1) * i] = (d > 0 && std::isfinite(1 / d)) ? 1 / d : 1.0;
  }
}
template void invertSpdBlock<3>(const double*, double*);
template void invertSpdBlock<12>(const double*, double*);

}  // namespace gf::detail
