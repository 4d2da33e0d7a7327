/* The neighbourhood's ball against the noise, and the scale rule that widens
 * the neighbourhood when the noise is heavy (issue 22; docs/smoothing.md,
 * "The neighbourhood's scale"). One copy, read by the smoothing guard's
 * noise estimate and misfit test (kappa) and by multipass's choice of K
 * (bsurf_smooth). The variance features choose their K by the power of
 * their test on a simulated edge (features_variance.c); this rule in
 * place of it or beside it was measured and not kept (docs/features.md).
 *
 * The model (the guard's, docs/smoothing.md "The misfit test", step 3): a
 * neighbourhood is the K points nearest its centre in space, a ball of
 * radius R. With the surface a plane, heights N(0, sigma^2) about it over a
 * uniform areal density, the centre at height z0 ~ N(0, sigma^2) and a
 * neighbour at distance rho from the centre's normal line, the neighbour's
 * height is the normal truncated to [z0 - a, z0 + a], a = sqrt(R^2 -
 * rho^2). With t = R / sigma, M and V the mass and variance of N(0, 1)
 * truncated there, mu its mean:
 *
 * - kappa(t) = E_z0[int_0^t rho M V drho / int_0^t rho M drho]: the share
 *   of the noise variance the ball's points keep about the fit (the fit
 *   follows the mean height at each rho). -> 1 for a wide ball, t^2 / 5 (a
 *   uniform ball's heights) as t -> 0; 0.36 at t = 1.7.
 * - pull(t) = E_z0[m(z0)^2], m(z0) = int_0^t rho M mu drho / int_0^t rho M
 *   drho: the ball's mean height, where the fit passes at its centre. A ball
 *   wider than the noise holds the heights of every z0 and m -> 0; a narrow
 *   one holds only the heights near z0, and m -> z0: the fit keeps its
 *   centre's own noise, and a point moved onto it keeps that share of its
 *   error (in sigma^2). 0.0011 at t = 8, 0.28 at t = 2, 0.69 at t = 1 (not
 *   tabulated: the rule below reads kappa; docs/smoothing.md has its table).
 * - count(t) = 2 pi E_z0[int_0^t rho M drho]: the points of the ball per
 *   sigma^2 of area at unit areal density; pi (t^2 - 2) for a wide ball (the
 *   heights' spread E (z - z0)^2 = 2 comes off its squared radius), ~ t^3
 *   as t -> 0 (a ball inside the noise counts a volume).
 *
 * kappa and count are tabulated at u = 1 / t = j / 32 (Gauss-Hermite in z0,
 * Gauss-Legendre in rho; test_smooth_noise recomputes them by quadrature),
 * read by linear interpolation in u. Below t = 1 kappa reads t = 1,
 * count is count(1) t^3 (a volume). */
#include "algo/algo.h"
#include "common/common.h"

#include <math.h>
#include <stdlib.h>

#define PI 3.14159265358979323846

static const double share_tab[33] = {
    1.000000, 0.997375, 0.989423, 0.975911, 0.956412, 0.930258, 0.896645, 0.855485, 0.808270,
    0.757596, 0.706076, 0.655703, 0.607742, 0.562864, 0.521338, 0.483181, 0.448265, 0.416391,
    0.387322, 0.360819, 0.336645, 0.314578, 0.294413, 0.275963, 0.259059, 0.243548, 0.229295,
    0.216176, 0.204084, 0.192920, 0.182598, 0.173040, 0.164176};

/* count(t) / (pi t^2) */
static const double count_tab[33] = {
    1.000000, 0.998047, 0.992188, 0.982422, 0.968750, 0.951172, 0.929709, 0.904516, 0.876074,
    0.845210, 0.812914, 0.780126, 0.747611, 0.715932, 0.685458, 0.656413, 0.628904, 0.602964,
    0.578572, 0.555675, 0.534201, 0.514067, 0.495186, 0.477473, 0.460843, 0.445217, 0.430520,
    0.416682, 0.403638, 0.391328, 0.379699, 0.368699, 0.358283};

static double tab_read(const double *tab, double t) {
  if (!(t > 0)) return tab[32];
  const double u = fmin(1.0 / t, 1.0) * 32.0;
  const int j = u >= 32 ? 31 : (int)u;
  const double f = u - j;
  return tab[j] + f * (tab[j + 1] - tab[j]);
}

double bsurf_ball_share(double t) {
  return tab_read(share_tab, t);
}

double bsurf_ball_count(double t) {
  if (!(t > 0)) return 0;
  if (t < 1) return PI * count_tab[32] * t * t * t;
  return PI * t * t * tab_read(count_tab, t);
}

/* t with count(t) = c (count increases with t): bisection */
static double ball_radius_of_count(double c) {
  double lo = 0, hi = 1;
  while (bsurf_ball_count(hi) < c && hi < 1e6)
    hi *= 2;
  for (int it = 0; it < 100; it++) {
    const double mid = 0.5 * (lo + hi);
    if (bsurf_ball_count(mid) < c)
      lo = mid;
    else
      hi = mid;
  }
  return 0.5 * (lo + hi);
}

double bsurf_ball_noise(double v, double R) {
  if (!(v > 0) || !(R > 0)) return v;
  double s2 = v;
  for (int step = 0; step < 200; step++) {
    const double next = v / bsurf_ball_share(R / sqrt(s2));
    if (!(fabs(next - s2) > 1e-12 * s2)) return next;
    s2 = next;
  }
  return s2;
}

/* The scale rule. A fit of p coefficients to K points predicts with the
 * variance s^2 p / K on average over its points (the mean leverage is p /
 * K; multipass's stop level uses the same), a share p / K of the noise its
 * points show. The K-ball drops a share 1 - kappa of the noise variance: its
 * points are those whose heights lie near its centre's, and its fit follows
 * that selection (in the model above, the fit at the centre keeps pull(t)
 * of the centre's own noise, 0.05 at t = 3.5, where 1 - kappa = 0.25, and
 * the points it moves are drawn towards its centre's height). The ball is
 * wide enough when what its selection drops is no more than the fit's own
 * variance share:
 *     1 - kappa(t_K) <= p / K,
 * the selection's error at most the fit's own. For a wide ball 1 - kappa ~
 * 2.8 / t^2 and t^2 ~ K h^2 / (pi sigma^2) (h the areal spacing), so on a
 * large enough K the rule reads sigma <~ h sqrt(p / 8.8): a noise below
 * about one spacing keeps k0 (every uniform case of the development set,
 * the cube at gaussian 0.5 h), a heavier one widens K to k_cap; the bias a
 * wider ball takes from the surface's curvature is not in the model (the
 * guard's t test and misfit test, and the degree test, see it). The
 * smallest K that meets it is taken: K = k0, then steps of 2^(1/4), at most
 * k_cap. t_K from the measured t0 = R_k0 / sigma at k0: the ball of K
 * points has count(t_K) = count(t0) K / k0 (one areal density). Returns k0
 * when t0 is not measured. */
int bsurf_scale_k(double t0, int k0, int p, int k_cap, double *t_k) {
  if (t_k) *t_k = t0;
  if (!(t0 > 0) || !isfinite(t0) || k_cap <= k0 || p < 1) return k0;
  const double c0 = bsurf_ball_count(t0);
  int k = k0;
  for (int j = 0;; j++) {
    const double kk = j ? ceil(k0 * pow(2.0, j / 4.0)) : k0;
    k = kk >= k_cap ? k_cap : (int)kk;
    const double t = j ? ball_radius_of_count(c0 * k / k0) : t0;
    if (t_k) *t_k = t;
    if (1 - bsurf_ball_share(t) <= (double)p / k || k >= k_cap) break;
  }
  return k;
}

/* The median over the rows of nb of the distance from the row's point to
 * its k-th (k <= nb->k; the point itself first): the radius of the K-ball. */
bsurf_status bsurf_ball_radius(const double *xyz, const bsurf_neighbors *nb, int k, double *R) {
  const size_t n = nb->point_count;
  *R = 0;
  if (!n || k < 2 || k > nb->k) return BSURF_OK;
  double *r = bsurf_alloc_array(n, sizeof(double));
  if (!r) return BSURF_ERR_NOMEM;
  for (size_t i = 0; i < n; i++) {
    const uint32_t *idx = &nb->idx[i * (size_t)nb->k];
    const double *p = &xyz[3 * (size_t)idx[0]], *q = &xyz[3 * (size_t)idx[k - 1]];
    const double d0 = q[0] - p[0], d1 = q[1] - p[1], d2 = q[2] - p[2];
    r[i] = sqrt(d0 * d0 + d1 * d1 + d2 * d2);
  }
  *R = bsurf_median(r, n);
  free(r);
  return BSURF_OK;
}
