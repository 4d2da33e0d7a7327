/* gemm.c -- the weighted sums of per-neighbour terms of B resamples at once
 * (thesis 4.1.2: the normal equations, Eq. 3.9, or a PCA's moments on each
 * resample S_b): W (B x k) times A (k x nc) as rows or in the lanes layout of
 * four LDL^T solves, and the same sums from the draws. Split from poly.c
 * (issue 19); used by the polynomial fits (poly.c) and the bootstrap PCA
 * normals (algo/normals.c). */
#include "common/common.h"
#include "local/local.h"

#include <stdlib.h>
#include <string.h>

/* rows (B x nc) = W (B x k) * A (k x nc). Blocks of 4 rows by 8 columns are
 * accumulated in registers (GCC/Clang vector types: AVX2 in the x86-64-v3
 * clone, SSE2 pairs otherwise, scalar elsewhere); for each output entry the
 * terms are added in the order j = 0, 1, ..., k-1 with a separate multiply
 * and add, exactly as the plain loop below, so every path gives the same
 * bits. */
#if defined(__GNUC__)
typedef double v4d __attribute__((vector_size(32)));
#define HAVE_V4D 1
#endif

#ifndef HAVE_V4D
static void gemm_plain(int b0, int b1, int c0, int c1, int k, int nc, const double *W,
                       const double *A, double *out) {
  for (int b = b0; b < b1; b++) {
    double *o = &out[(size_t)b * nc];
    for (int c = c0; c < c1; c++)
      o[c] = 0;
    for (int j = 0; j < k; j++) {
      const double x = W[(size_t)b * k + j];
      const double *a = &A[(size_t)j * nc];
      for (int c = c0; c < c1; c++)
        o[c] += x * a[c];
    }
  }
}
#endif

#ifdef HAVE_V4D
typedef long long v4l_idx __attribute__((vector_size(32)));
/* The lanes (i, j, k, l) of the 8-lane concatenation of a and b. */
#if defined(__clang__)
#define SHUF2(a, b, i, j, k, l) __builtin_shufflevector(a, b, i, j, k, l)
#else
#define SHUF2(a, b, i, j, k, l) __builtin_shuffle(a, b, (v4l_idx){i, j, k, l})
#endif

/* One block of W A: rows w[0..3] (k weights each) times 2 L columns c ..
 * c + 2L - 1 of A, in vectors V of L doubles (L = 4: AVX2; 8: the
 * x86-64-v4 clone's 512-bit registers, half the loads and instructions a
 * multiply-add); the eight accumulators (row r, half h) written in that
 * order to acc as doubles: acc[(2L / 4) r + q] holds row r, columns c + 4q
 * .. c + 4q + 3. Every entry is summed in the order j = 0..k-1 whatever L. */
#define GEMM_BLOCK(V, L)                                                                           \
  do {                                                                                             \
    V a00 = {0}, a01 = a00, a10 = a00, a11 = a00, a20 = a00, a21 = a00, a30 = a00, a31 = a00;      \
    const double *w0 = w[0], *w1 = w[1], *w2 = w[2], *w3 = w[3];                                   \
    for (int j = 0; j < k; j++) {                                                                  \
      V x0, x1;                                                                                    \
      memcpy(&x0, &A[(size_t)j * nc + c], sizeof x0);                                              \
      memcpy(&x1, &A[(size_t)j * nc + c + (L)], sizeof x1);                                        \
      const double s0 = w0[j], s1 = w1[j], s2 = w2[j], s3 = w3[j];                                 \
      a00 += s0 * x0;                                                                              \
      a01 += s0 * x1;                                                                              \
      a10 += s1 * x0;                                                                              \
      a11 += s1 * x1;                                                                              \
      a20 += s2 * x0;                                                                              \
      a21 += s2 * x1;                                                                              \
      a30 += s3 * x0;                                                                              \
      a31 += s3 * x1;                                                                              \
    }                                                                                              \
    const V all[8] = {a00, a01, a10, a11, a20, a21, a30, a31};                                     \
    memcpy(acc, all, sizeof all);                                                                  \
  } while (0)

static inline __attribute__((always_inline)) void
gemm_block(const double *const w[4], int k, int nc, const double *A, int c, v4d acc[8]) {
  GEMM_BLOCK(v4d, 4);
}

typedef double v8d __attribute__((vector_size(64)));

static inline __attribute__((always_inline)) void
gemm_block16(const double *const w[4], int k, int nc, const double *A, int c, v4d acc[16]) {
  GEMM_BLOCK(v8d, 8);
}
#undef GEMM_BLOCK

/* Columns c + 4h .. c + 4h + 3 of a 4-row group, rows r0..r3 (one vector
 * each), to the lanes layout: two 4 x 4 transposes' worth. */
static inline __attribute__((always_inline)) void lanes_store4(v4d r0, v4d r1, v4d r2, v4d r3,
                                                               double *oc) {
  const v4d t0 = SHUF2(r0, r1, 0, 4, 2, 6), t1 = SHUF2(r0, r1, 1, 5, 3, 7);
  const v4d t2 = SHUF2(r2, r3, 0, 4, 2, 6), t3 = SHUF2(r2, r3, 1, 5, 3, 7);
  const v4d c0 = SHUF2(t0, t2, 0, 1, 4, 5), c1 = SHUF2(t1, t3, 0, 1, 4, 5);
  const v4d c2 = SHUF2(t0, t2, 2, 3, 6, 7), c3 = SHUF2(t1, t3, 2, 3, 6, 7);
  memcpy(oc, &c0, sizeof c0);
  memcpy(oc + 4, &c1, sizeof c1);
  memcpy(oc + 8, &c2, sizeof c2);
  memcpy(oc + 12, &c3, sizeof c3);
}
#endif

BSURF_CLONES
void bsurf_gemm_lanes(int R, int k, int nc, const double *restrict W, const double *restrict A,
                      double *restrict out) {
#ifdef HAVE_V4D
  int wide = 0; /* 16 columns at a time where the clone has 512-bit vectors */
#if defined(__x86_64__) && !defined(__clang__)
  wide = __builtin_cpu_supports("avx512f");
#endif
  for (int b = 0; b < R; b += 4) {
    const double *w[4] = {&W[(size_t)b * k], &W[(size_t)(b + 1) * k], &W[(size_t)(b + 2) * k],
                          &W[(size_t)(b + 3) * k]};
    double *o = &out[(size_t)b * nc];
    int c = 0;
    if (wide)
      for (; c + 16 <= nc; c += 16) {
        v4d acc[16];
        gemm_block16(w, k, nc, A, c, acc);
        /* column c + 4q + l of rows 0..3 is one vector */
        for (int q = 0; q < 4; q++)
          lanes_store4(acc[q], acc[4 + q], acc[8 + q], acc[12 + q], &o[(size_t)(c + 4 * q) * 4]);
      }
    for (; c < nc; c += 8) {
      v4d acc[8];
      gemm_block(w, k, nc, A, c, acc);
      /* two 4 x 4 transposes: column c + 4h + l of rows 0..3 is one vector */
      for (int h = 0; h < 2; h++)
        lanes_store4(acc[h], acc[2 + h], acc[4 + h], acc[6 + h], &o[(size_t)(c + 4 * h) * 4]);
    }
  }
#else
  double row[BSURF_NCOLS_MAX];
  for (int b = 0; b < R; b++) {
    gemm_plain(0, 1, 0, nc, k, nc, &W[(size_t)b * k], A, row);
    for (int c = 0; c < nc; c++)
      out[(size_t)(b / 4) * 4 * nc + (size_t)c * 4 + b % 4] = row[c];
  }
#endif
}

void bsurf_lanes_row(int nc, const double *lanes, int r, double *row) {
  const double *g = &lanes[(size_t)(r / 4) * 4 * nc];
  for (int c = 0; c < nc; c++)
    row[c] = g[(size_t)c * 4 + r % 4];
}

/* Normal equations from the draws (thesis 4.1.2, Eq. 3.9 on a resample):
 * sum_j c_bj a_j, c_bj the number of times replicate b drew point j, is
 * the sum of the k rows a_{d_b1} + ... + a_{d_bk} picked by its draws. One
 * add per draw and column where the dense product has a multiply and an
 * add per point. On a core whose multiplies and adds issue on separate
 * pipes (AMD Zen) both run at about the same speed, bound by the loads
 * (docs/performance.md, fourth round); what the draws save is the weights:
 * no B x k doubles to write and read, so the per-point working set shrinks
 * by a fifth and the residual sums read 16-bit counts. The terms are added
 * in the order drawn, so the sums' last bits differ from
 * bsurf_gemm_lanes's (same terms, another order). */
#ifdef HAVE_V4D
#define DRAW_VMAX 10 /* accumulators per pass: 40 columns (a cubic's) */

/* acc[h][0..NV-1] += columns c0 .. c0 + 4 NV - 1 of A's rows idx[h][t]
 * (idx[h] NULL: row t), t = 0..n-1 in order, for H (1 or 2) rows at once
 * (two independent chains of adds hide the adds' latency when NV is small). */
static inline __attribute__((always_inline)) void draw_sum(int H, int NV, int n, int nc,
                                                           const uint16_t *const idx[2],
                                                           const double *A, int c0,
                                                           v4d acc[2][DRAW_VMAX]) {
  v4d a0[DRAW_VMAX], a1[DRAW_VMAX];
  for (int v = 0; v < NV; v++)
    a0[v] = a1[v] = (v4d){0, 0, 0, 0};
  for (int t = 0; t < n; t++) {
    const double *r0 = &A[(size_t)(idx[0] ? idx[0][t] : t) * nc + c0];
    for (int v = 0; v < NV; v++) {
      v4d x;
      memcpy(&x, r0 + 4 * v, sizeof x);
      a0[v] += x;
    }
    if (H == 2) {
      const double *r1 = &A[(size_t)(idx[1] ? idx[1][t] : t) * nc + c0];
      for (int v = 0; v < NV; v++) {
        v4d x;
        memcpy(&x, r1 + 4 * v, sizeof x);
        a1[v] += x;
      }
    }
  }
  for (int v = 0; v < NV; v++) {
    acc[0][v] = a0[v];
    acc[1][v] = a1[v];
  }
}

/* Two rows of a group (stage0, stage1: nc each) from their draws (idx[h]
 * NULL: every point once; zero[h]: a zero row), NV vectors per pass over
 * the draws, both rows in one pass when H = 2. */
static inline __attribute__((always_inline)) void draw_rows2(int H, int NV, int k, int nc,
                                                             const uint16_t *const idx[2],
                                                             const int zero[2], const double *A,
                                                             double *stage0, double *stage1) {
  v4d acc[2][DRAW_VMAX];
  double *st[2] = {stage0, stage1};
  for (int c0 = 0; c0 < nc; c0 += 4 * NV) {
    if (H == 2 && !zero[1]) {
      draw_sum(2, NV, k, nc, idx, A, c0, acc);
    } else {
      draw_sum(1, NV, k, nc, idx, A, c0, acc);
      if (!zero[1]) {
        const uint16_t *const idx1[2] = {idx[1], NULL};
        v4d acc1[2][DRAW_VMAX];
        draw_sum(1, NV, k, nc, idx1, A, c0, acc1);
        for (int v = 0; v < NV; v++)
          acc[1][v] = acc1[0][v];
      }
    }
    for (int h = 0; h < 2; h++)
      for (int v = 0; v < NV; v++) {
        if (zero[h]) acc[h][v] = (v4d){0, 0, 0, 0};
        memcpy(&st[h][c0 + 4 * v], &acc[h][v], sizeof acc[h][v]);
      }
  }
}
#endif

BSURF_CLONES
void bsurf_draw_sums_lanes(int B, int k, int nc, const uint16_t *restrict draws,
                           const double *restrict A, double *restrict out) {
  const int R = (B + 4) / 4 * 4; /* bsurf_boot_rows(B): B + 1 rounded up to 4 */
#ifdef HAVE_V4D
  double stage[4][BSURF_NCOLS_MAX];
  for (int g = 0; g < R; g += 4) {
    for (int r = 0; r < 4; r += 2) {
      const uint16_t *idx[2];
      int zero[2];
      for (int h = 0; h < 2; h++) {
        const int b = g + r + h;
        idx[h] = b < B ? &draws[(size_t)b * k] : NULL;
        zero[h] = b > B;
      }
      if (zero[0]) {
        memset(stage[r], 0, (size_t)nc * sizeof(double));
        memset(stage[r + 1], 0, (size_t)nc * sizeof(double));
        continue;
      }
      /* a constant column count keeps the accumulators in registers (at
       * most 12 of the 16): degrees 1 and 2 two rows of 4 or 6 vectors at
       * once, a cubic one row of 10, a quartic two passes of 8 */
      switch (nc) {
      case 16: draw_rows2(2, 4, k, nc, idx, zero, A, stage[r], stage[r + 1]); break;
      case 24: draw_rows2(2, 6, k, nc, idx, zero, A, stage[r], stage[r + 1]); break;
      case 40: draw_rows2(1, 10, k, nc, idx, zero, A, stage[r], stage[r + 1]); break;
      case 64: draw_rows2(1, 8, k, nc, idx, zero, A, stage[r], stage[r + 1]); break;
      default: draw_rows2(1, 2, k, nc, idx, zero, A, stage[r], stage[r + 1]); break;
      }
    }
    /* 4 x 4 transposes into the lanes layout: column c of rows g..g+3 */
    double *o = &out[(size_t)g * nc];
    for (int c = 0; c < nc; c += 4) {
      v4d r0, r1, r2, r3;
      memcpy(&r0, &stage[0][c], sizeof r0);
      memcpy(&r1, &stage[1][c], sizeof r1);
      memcpy(&r2, &stage[2][c], sizeof r2);
      memcpy(&r3, &stage[3][c], sizeof r3);
      const v4d t0 = SHUF2(r0, r1, 0, 4, 2, 6), t1 = SHUF2(r0, r1, 1, 5, 3, 7);
      const v4d t2 = SHUF2(r2, r3, 0, 4, 2, 6), t3 = SHUF2(r2, r3, 1, 5, 3, 7);
      const v4d c0 = SHUF2(t0, t2, 0, 1, 4, 5), c1 = SHUF2(t1, t3, 0, 1, 4, 5);
      const v4d c2 = SHUF2(t0, t2, 2, 3, 6, 7), c3 = SHUF2(t1, t3, 2, 3, 6, 7);
      double *oc = &o[(size_t)c * 4];
      memcpy(oc, &c0, sizeof c0);
      memcpy(oc + 4, &c1, sizeof c1);
      memcpy(oc + 8, &c2, sizeof c2);
      memcpy(oc + 12, &c3, sizeof c3);
    }
  }
#else
  for (int b = 0; b < R; b++) {
    double *g = &out[(size_t)(b / 4) * 4 * nc];
    for (int c = 0; c < nc; c++) {
      double x = 0;
      if (b <= B)
        for (int t = 0; t < k; t++)
          x += A[(size_t)(b < B ? draws[(size_t)b * k + t] : t) * nc + c];
      g[(size_t)c * 4 + b % 4] = x;
    }
  }
#endif
}
