/* The MSE rule's shared pieces (kselect.c: the selection, the tie-break,
 * the two-sheet test; kselect_noise.c: the noise passes): the quadric's
 * running sums, the scratch and the context of the passes. Private to
 * src/algo. */
#ifndef BSURF_KSELECT_H
#define BSURF_KSELECT_H

#include "algo/algo.h"
#include "common/common.h"
#include "local/local.h"
#include "search/search.h"

#include <string.h>

#define QT 6  /* quadric terms 1, u, v, u^2, uv, v^2 */
#define QM 15 /* monomials of degree <= 4 */

/* Running sums of a quadric height fit: the monomials (G's entries), z times
 * the basis, z^2. */
typedef struct quad_sums {
  double mono[QM], phiz[QT], zz;
  int n;
} quad_sums;

static inline void quad_add(quad_sums *q, double u, double v, double z) {
  double m[QM];
  bsurf_poly_basis(4, u, v, m);
  for (int a = 0; a < QM; a++)
    q->mono[a] += m[a];
  for (int a = 0; a < QT; a++)
    q->phiz[a] += m[a] * z;
  q->zz += z * z;
  q->n++;
}

#define quad_solve bsurf_i_ksel_quad_solve
#define local_coords bsurf_i_ksel_local_coords
#define noise_point bsurf_i_ksel_noise_point
#define pool_point bsurf_i_ksel_pool_point
#define pool_global bsurf_i_ksel_pool_global

/* Solves the quadric from the sums: coef (QT), the residual sum of squares,
 * and, when ginv_hh is not NULL, the 3 x 3 block of G^-1 of the Hessian
 * coefficients (3, 4, 5). Returns 0, or -1 when rank-deficient. */
int quad_solve(const quad_sums *q, double coef[QT], double *rss, double ginv_hh[3][3]);
/* The frame of the noise fit and the point's neighbours in it: local x, y
 * scaled by 1 / scale, heights unscaled; returns the scale. */
double local_coords(const double *xyz, const uint32_t *idx, int kn, int kmax, bsurf_frame *f,
                    double *u, double *v, double *z);

typedef struct ksel_scratch {
  double *u, *v, *z;      /* kmax */
  double *terms, *sums;   /* kmax x BSURF_NESTED_COLS, nk x BSURF_NESTED_COLS */
  double *mu, *cov;       /* nk x 3, nk x 6 */
  double *pool;           /* noise_k */
  double *nrm, *var, *qb; /* nk x 3, nk, nk: each candidate's normal, variance, quadric bias^2 */
  double *mse;            /* nk: each candidate's V + Bias^2 */
  double *res;            /* kmax: residuals of the two-sheet test */
  double *tcand, *tcrit;  /* nk x 3, nk: one point's tied candidates, as tie_store takes them */
  int *curve;             /* nk: the curve test's per-candidate verdicts */
  double *rssv, *eb;      /* nk, nk: the quadric's residual variance, the empirical bias^2 */
  int *gate;              /* nk: the lack-of-fit gate (kselect_lof.c) */
  double *scales;         /* (nk + 1) x 4: the noise pass's accepted scales (kselect_noise.c) */
  bsurf_blocks mem;       /* the arrays above */
  size_t unfit, none;
  /* pass 3's tied candidates, in blocks that never move (tie_store) */
  double **tie_blocks;
  int tie_nblocks, tie_cap, tie_nomem;
  size_t tie_used; /* doubles used in the last block */
  /* the polynomial candidates' (kselect_poly.c), or NULL */
  struct kpoly_scratch *poly;
#ifdef BSURF_KSEL_TRACE
  /* per candidate |H t|^2, its noise share's factor, l1, l2, l3, R_K^2
   * (kselect.c, trace_point) */
  double trace[64][6];
#endif
} ksel_scratch;

typedef struct ksel_ctx {
  const double *xyz;
  const bsurf_neighbors *nb;
  const bsurf_kselect_options *o;
  int kmax;
  double lof_z;  /* ksel_level_z(o->nk): the lack-of-fit tests' level, once a run */
  double disc_q; /* ksel_disc_level(kmax): the disc test's critical value, once a run */
  /* the cross-section tests' critical values (kselect_noise.c,
   * ksel_section_levels), once a run */
  struct {
    double thin, curve, below; /* F quantiles: (K-3, K-5) lower, (3, K-5) upper, (K-5, K-5) lower */
    double q;                  /* the conic's quartile correction, chi^2_{K-5}/(K-5) */
    int count;                 /* section-sampled points a neighbourhood needs */
  } sect;
  ksel_scratch *scr;
  double *s2;          /* pass 1: 2 per point, the quadric's residual variance
                          and the cross-section estimate (NAN: none) */
  double *noise;       /* pass 2: 2 per point, the two pooled variances;
                          passes 3, 4: 1 per row, the level */
  double *sheet_crit;  /* per candidate: the two-sheet test's critical ratio, or NULL */
  double **tied;       /* pass 3: per point its tied candidates (tie_store) */
  double *fnrm;        /* pass 3: n x 3, the normal of the smallest criterion */
  const double *fref;  /* pass 4: the neighbours' fnrm, indexed like nb->idx */
  const double *fmref; /* pass 4: the neighbours' fmse, indexed like nb->idx */
  /* pass 3: the neighbours' first choices without the empirical bias and
   * their M (the references of kselect_lof.c), indexed like nb->idx; NULL:
   * no empirical bias (the first of the two pass 3s) */
  const double *bref, *bmref;
  int *first; /* pass 3: the candidate of the smallest criterion */
  bsurf_kselect_fields *out;
  double *fmse; /* pass 3: n, the smallest criterion (the first choice's M; pass 4's weights) */
  /* pass 3 without the empirical bias in memory (kselect_run.c,
   * ksel_select with defer): per point 1 where the lack-of-fit gate fires, its
   * tied record then not stored (the point is chosen again with the bias);
   * NULL elsewhere */
  unsigned char *deferred;
} ksel_ctx;

/* The noise passes (kselect_noise.c; the top of kselect.c): pass 1, each
 * point's quadric residual variance and cross-section estimate (c->s2, two
 * per point); pass 2, their lower quartiles over the K_max neighbours
 * (c->noise, two per point); pass 2b, the median over the cloud. */
void noise_point(void *vctx, int thread, size_t i);
/* c->sect from c->o->noise_k and c->kmax. */
#define ksel_section_levels bsurf_i_ksel_section_levels
void ksel_section_levels(ksel_ctx *c);
void pool_point(void *vctx, int thread, size_t i);
/* The section test alone (kselect_noise.c, for bsurf_ksel_section_bound):
 * section_point, c->s2[2 r + 1] by row, the noise_k points' cross-section
 * residual variance where they pass the test (section_noise), whatever
 * their quadric reads, else NAN; section_flag_point, c->noise[r] by row, 1
 * where more of the K_max neighbours (c->s2 read by neighbour) passed than
 * pass 2 asks of a section-sampled neighbourhood (c->sect.count), else 0. */
#define section_point bsurf_i_ksel_section_point
#define section_flag_point bsurf_i_ksel_section_flag_point
void section_point(void *vctx, int thread, size_t i);
void section_flag_point(void *vctx, int thread, size_t i);
bsurf_status pool_global(double *noise, size_t n);

/* sin^2 of the angle between two unit vectors, 1 - (a . b)^2: the drift's
 * and the test errors' disagreement between two normals */
static inline double ksel_sin2(const double *a, const double *b) {
  const double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  return 1.0 - dot * dot;
}

/* The candidates of a point: nk K values, times nd degrees for the
 * polynomial fits (candidate a K * nd + degree index), else one PCA plane. */
static inline int ksel_ndeg(const bsurf_kselect_options *o) {
  return o->nd > 0 ? o->nd : 1;
}

#define curve_sampled bsurf_i_ksel_curve_sampled
#define drift_tol bsurf_i_ksel_drift_tol
#define drift_of bsurf_i_ksel_drift_of
#define ksel_ties bsurf_i_ksel_ties
#define poly_point bsurf_i_ksel_poly_point
#define poly_alloc bsurf_i_ksel_poly_alloc
#define poly_free bsurf_i_ksel_poly_free

/* The curve test of point i (kselect.c, "Curve-sampled neighbourhoods"):
 * 1 where its K_max neighbours sample a curve, curve[a] = 1 for each
 * candidate K a whose own neighbourhood reads fewer than two dimensions. */
int curve_sampled(const double *xyz, const uint32_t *idx, size_t i, const int *ks, int nk,
                  int *curve);
/* The drift's allowance for a candidate compared with `a` less biased ones
 * by their maximum, DRIFT_TOL + ln(a) (kselect.c, the top of the file: a
 * test at level exp(-3) for all a); the rule itself uses drift_tol(1), a
 * single comparison's, and drift_of's two witnesses. */
double drift_tol(int a);
/* The drift of candidate a (normals nrm[3 a..], variances var[a]) against
 * the smaller candidates 0..a-1 with a finite variance: the second largest
 * of sin^2 - c2 (V(j) - V(a)) over two or more, the single term at
 * drift_tol(1) over one, -inf over none (kselect.c, "two witnesses"). */
double drift_of(const double *nrm, const double *var, int a);
/* After pass 3's criterion s->mse of the ncand candidates (s->var finite:
 * assessed; s->nrm their normals): best (the smallest, -1 for none: then
 * `fallback`, counted unassessed) and the candidates tied with it, stored
 * for pass 4's tie-break (tie_store). */
void ksel_ties(ksel_ctx *c, ksel_scratch *s, size_t i, int ncand, int best, double best_mse,
               int fallback);
/* Pass 3 of the polynomial candidates (kselect_poly.c), and its scratch. */
void poly_point(void *vctx, int thread, size_t i);
bsurf_status poly_alloc(ksel_scratch *s, const bsurf_kselect_options *o, int kmax);
void poly_free(ksel_scratch *s);

#define ksel_lof_gate bsurf_i_ksel_lof_gate
#define ksel_level_z bsurf_i_ksel_level_z
#define ksel_thin_plane bsurf_i_ksel_thin_plane
#define ksel_same_plane bsurf_i_ksel_same_plane
#define ksel_disc bsurf_i_ksel_disc
#define ksel_disc_level bsurf_i_ksel_disc_level
#define ksel_emp_bias bsurf_i_ksel_emp_bias
/* The lack-of-fit gate (kselect_lof.c): gate[a] = 1 for the candidates
 * from the first whose quadric residual variance rssv rejects the noise
 * s2 on (at the level z = ksel_level_z(nk)), none where the smallest
 * rejects; returns whether any is gated. */
int ksel_lof_gate(const double *rssv, const int *ks, int nk, double s2, double z, int *gate);
/* The standard normal's upper quantile at a Bonferroni share of 5% over nk
 * candidates (kselect_lof.c). */
double ksel_level_z(int nk);
/* The standard normal's upper quantile z(p), P(Z > z) = p, 0 < p < 0.5
 * (kselect_lof.c). */
#define ksel_normal_upper_quantile bsurf_i_ksel_normal_upper_quantile
double ksel_normal_upper_quantile(double p);
/* 1 where candidate K's plane is thinner than the noise s2 allows (smallest
 * eigenvalue l3, squared distance rk2 to its K-th neighbour, z from
 * ksel_level_z): not the surface's tangent plane (kselect_lof.c). */
int ksel_thin_plane(int K, double l3, double rk2, double s2, double z);
int ksel_same_plane(const double n[3], const double N[3]);
double ksel_disc_level(int K);
int ksel_disc(const double ev[3], double q);
/* The empirical bias^2 eb[a] of each gated candidate (0 elsewhere) against
 * the neighbours' first choices c->bref (kselect_lof.c). */
void ksel_emp_bias(const ksel_ctx *c, const uint32_t *idx, const double *nrm, const double *var,
                   const int *gate, int nk, double *eb);

#define select_point bsurf_i_ksel_select_point
#define tie_point bsurf_i_ksel_tie_point
/* Pass 3, the selection (kselect.c): every candidate's criterion, the
 * first choice (c->first, its normal in c->fnrm) and, with c->tied, the
 * candidates tied with it; pass 4, the tie-break by the neighbours' first
 * choices (c->fref) and the outputs. */
void select_point(void *vctx, int thread, size_t i);
void tie_point(void *vctx, int thread, size_t i);

/* ---- The passes' scaffolding: one run (bsurf_ksel_run, algo.h) holds the
 * options, each thread's scratch and the two-sheet test's critical ratios;
 * its passes run on the rows of any neighbourhood table, so bsurf_select_k
 * runs them on the whole cloud and the tiled job (normals_mse_tiled.c) on
 * each tile's core points, with the neighbours' values of the previous
 * pass given for the halo (docs/scaling.md). A row's point is idx[0] (the
 * row itself on the whole cloud, a local index in a tile); values read at
 * the neighbours (s2 in pass 2, the first choices' normals in pass 4) are
 * indexed like idx, the passes' own values by row. */
struct bsurf_ksel_run {
  bsurf_kselect_options o;
  int kmax, T;
  ksel_scratch *scr;
  double *crit; /* nk critical ratios, then SHEET_DRAWS ratios per candidate; or NULL */
  /* the caller's progress over several passes (kselect_run.c, ksel_pass):
   * slots > 0 divides it into slots ranges of rows, the first passes
   * before the selection's taking one each (slot: the next free) and the
   * selection's pass the last; 0: the passes before it hold at none done */
  int slot, slots;
};
void bsurf_i_ksel_reset(bsurf_ksel_run *r); /* the tied records freed, counts zeroed */
/* The options against rows of nb_k neighbours; `who` names the caller. */
bsurf_status bsurf_i_ksel_check(const char *who, const bsurf_kselect_options *o, int nb_k);

#endif
