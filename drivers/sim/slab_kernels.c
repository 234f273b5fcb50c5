/* The slab's scattering kernels for the renderer (transport.h, DsSlabKernels): the whole slab's
 * kernel sized by the energy it holds, and with object planes the chain of segment kernels,
 * all binned from one Monte Carlo run's photon records (mc_events.h). docs/transport.md,
 * "Object planes", derives the chain. */
#include <math.h>
#include <string.h>

#include "drivers/sim/mc_events.h"
#include "drivers/sim/sim_error.h"
#include "drivers/sim/transport.h"

#define DS_KERNEL_MAX_RADIUS 2048u
#define DS_KERNEL_MIN_RADIUS 4u

void
ds_slab_kernels_free (DsSlabKernels *k)
{
  if (!k)
    return;
  ds_image_free (k->full);
  for (guint j = 0; j <= DS_SLAB_MAX_PLANES; j++) {
    ds_image_free (k->segments[j].from_ballistic);
    ds_image_free (k->segments[j].from_scattered);
  }
  for (guint j = 0; j < DS_SLAB_MAX_PLANES; j++) {
    ds_image_free (k->crossings[j].recross_ballistic);
    ds_image_free (k->crossings[j].recross_scattered);
  }
  g_free (k);
}

double
ds_kernel_mtf_x (const DsImage *k, double period_px)
{
  int r = (int) k->width / 2;
  double re = 0, im = 0, sum = 0;
  for (guint y = 0; y < k->height; y++) {
    const float *row = ds_image_row (k, y);
    for (guint x = 0; x < k->width; x++) {
      double a = 2 * G_PI * ((int) x - r) / period_px;
      re += row[x] * cos (a);
      im -= row[x] * sin (a);
      sum += row[x];
    }
  }
  return sum > 0 ? hypot (re, im) / sum : 0.0;
}

/* Square radius (Chebyshev, in bins) of an offset. */
static guint
bin_radius (double x, double y, double pitch)
{
  double fx = fabs (floor (x / pitch + 0.5)), fy = fabs (floor (y / pitch + 0.5));
  double m = MAX (fx, fy);
  return m > DS_KERNEL_MAX_RADIUS ? DS_KERNEL_MAX_RADIUS + 1 : (guint) m;
}

/* The smallest square radius holding `fraction` of the records' weight. */
static double
effective_records (const GArray *ev, guint stride)
{
  const float *f = (const float *) ev->data;
  double s = 0, s2 = 0;
  for (guint i = 0; i + stride <= ev->len; i += stride) {
    s += f[i + 2];
    s2 += (double) f[i + 2] * f[i + 2];
  }
  return s2 > 0 ? s * s / s2 : 0.0;
}

static guint
energy_radius (const GArray *ev, guint stride, double pitch, double fraction)
{
  g_autofree double *w_at = g_new0 (double, DS_KERNEL_MAX_RADIUS + 2);
  const float *f = (const float *) ev->data;
  double total = 0;
  for (guint i = 0; i + stride <= ev->len; i += stride) {
    w_at[bin_radius (f[i], f[i + 1], pitch)] += f[i + 2];
    total += f[i + 2];
  }
  double acc = 0;
  for (guint r = 0; r <= DS_KERNEL_MAX_RADIUS; r++) {
    acc += w_at[r];
    if (acc >= fraction * total)
      return MAX (r, DS_KERNEL_MIN_RADIUS);
  }
  return DS_KERNEL_MAX_RADIUS;
}

typedef struct {
  guint radius, side;
  double pitch;
} Grid;

static void
bin_add (double *bins, const Grid *g, double x, double y, double w)
{
  double fx = floor (x / g->pitch + 0.5), fy = floor (y / g->pitch + 0.5);
  if (fabs (fx) <= g->radius && fabs (fy) <= g->radius)
    bins[(gsize) (fy + g->radius) * g->side + (gsize) (fx + g->radius)] += w;
}

static DsImage *
bins_to_kernel (const double *bins, const Grid *g, double scale, GError **error)
{
  DsImage *k = ds_image_new (DS_SAMPLE_F32, g->side, g->side, error);
  if (!k)
    return NULL;
  for (guint y = 0; y < g->side; y++) {
    float *row = ds_image_row (k, y);
    for (guint x = 0; x < g->side; x++)
      row[x] = (float) (bins[(gsize) y * g->side + x] * scale);
  }
  return k;
}

/* Of a photon crossing a plane m >= 3 times: 3, 5, 7 or more -> 0, 1, 2. */
static guint
recross_class (guint crossings)
{
  return MIN ((crossings - 3) / 2, DS_SLAB_RECROSS_CLASSES - 1);
}

/* Per record and plane, whether the photon counts as unscattered in the chain: it was at its
 * first crossing of this plane, and it was unscattered and crossed only once at every plane
 * before (so unscattered light at a plane always came from unscattered light at the one above:
 * the chain's bookkeeping, docs/transport.md). */
typedef struct {
  double w_first[2][DS_SLAB_MAX_PLANES + 1];  /* [ballistic?][plane j]: weight at the first crossing */
  double once[2][DS_SLAB_MAX_PLANES + 1];
  double times[DS_SLAB_MAX_PLANES + 1][DS_SLAB_RECROSS_CLASSES];
  double w_start[2][DS_SLAB_MAX_PLANES + 1];  /* [ballistic?][segment j] */
  double stays[DS_SLAB_MAX_PLANES + 1];
} Sums;

/* Bins the records into the full kernel (when want_full), the segments and the crossings. */
static gboolean
bin_records (DsSlabKernels *k, const GArray *ev, guint64 photons, gboolean want_full, GError **error)
{
  guint n = k->planes.n_planes, stride = DS_MC_EVENT_FLOATS (n);
  Grid g = { k->radius_px, 2 * k->radius_px + 1, k->pixel_pitch_mm };
  gsize nb = (gsize) g.side * g.side;
  /* full; per segment j: from ballistic (1 + 2j), from scattered (2 + 2j); per plane j = 1..n:
   * re-crossing of ballistic (2n + 1 + 2j), of scattered (2n + 2 + 2j). */
  guint n_kernels = n ? 1 + 2 * (n + 1) + 2 * n : 1;
  double *bins = g_try_malloc0_n (nb * n_kernels, sizeof (double));
  if (!bins) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_NUMERIC, "kernels: cannot allocate %u kernels of %u x %u",
                 n_kernels, g.side, g.side);
    return FALSE;
  }
  g_autofree Sums *sums = g_new0 (Sums, 1);
  const float *f = (const float *) ev->data;
  for (guint i = 0; i + stride <= ev->len; i += stride) {
    const float *rec = f + i;
    double w = rec[2];
    bin_add (bins, &g, rec[0], rec[1], w);
    /* Segment j runs from (sx, sy), unscattered or not (start_b), to the next plane's first
     * crossing (the exit for the last). */
    double sx = 0, sy = 0;
    gboolean start_b = TRUE;
    for (guint j = 0; n && j <= n; j++) {
      const float *next = j < n ? rec + DS_MC_EVENT_PLANE (j) : NULL;
      double ex = next ? next[0] : rec[0], ey = next ? next[1] : rec[1];
      guint code = next ? (guint) next[4] : 0, m = code >> 1;
      gboolean end_b = start_b && next && (code & 1);
      sums->w_start[start_b][j] += w;
      if (end_b)
        sums->stays[j] += w;
      else
        bin_add (bins + nb * (1 + 2 * j + (start_b ? 0 : 1)), &g, ex - sx, ey - sy, w);
      if (!next)
        break;
      /* Plane j + 1: first crossing here, last crossing at next[2], next[3]. */
      sums->w_first[end_b][j + 1] += w;
      if (m <= 1)
        sums->once[end_b][j + 1] += w;
      else {
        bin_add (bins + nb * (2 * n + 1 + 2 * (j + 1) + (end_b ? 0 : 1)), &g, next[2] - ex, next[3] - ey, w);
        sums->times[j + 1][recross_class (m)] += w;
      }
      sx = next[2];
      sy = next[3];
      start_b = end_b && m <= 1;
    }
  }
  gboolean ok = TRUE;
  if (want_full)
    ok = (k->full = bins_to_kernel (bins, &g, 1.0 / (double) photons, error)) != NULL;
  for (guint j = 0; ok && n && j <= n; j++) {
    DsSlabSegment *s = &k->segments[j];
    /* Segment 0 is per unit of incident beam (every photon starts unscattered); later ones per
     * unit of the light of each kind leaving their start plane. */
    double norm_b = j == 0 ? (double) photons : sums->w_start[1][j], norm_s = sums->w_start[0][j];
    s->from_ballistic = bins_to_kernel (bins + nb * (1 + 2 * j), &g, norm_b > 0 ? 1.0 / norm_b : 0.0, error);
    s->from_scattered =
      j == 0 ? NULL : bins_to_kernel (bins + nb * (2 + 2 * j), &g, norm_s > 0 ? 1.0 / norm_s : 0.0, error);
    s->stays_ballistic = norm_b > 0 ? sums->stays[j] / norm_b : 0.0;
    ok = s->from_ballistic && (j == 0 || s->from_scattered);
  }
  for (guint j = 1; ok && j <= n; j++) {
    DsSlabPlaneCrossing *c = &k->crossings[j - 1];
    double wb = sums->w_first[1][j], ws = sums->w_first[0][j], again = 0;
    /* No light of a kind at a plane: any split will do, none of it arrives. */
    c->once_ballistic = wb > 0 ? sums->once[1][j] / wb : 1.0;
    c->once_scattered = ws > 0 ? sums->once[0][j] / ws : 1.0;
    c->recross_ballistic = bins_to_kernel (bins + nb * (2 * n + 1 + 2 * j), &g, wb > 0 ? 1.0 / wb : 0.0, error);
    c->recross_scattered = bins_to_kernel (bins + nb * (2 * n + 2 + 2 * j), &g, ws > 0 ? 1.0 / ws : 0.0, error);
    ok = c->recross_ballistic && c->recross_scattered;
    for (guint t = 0; t < DS_SLAB_RECROSS_CLASSES; t++)
      again += sums->times[j][t];
    for (guint t = 0; t < DS_SLAB_RECROSS_CLASSES; t++)
      c->recross_times[t] = again > 0 ? sums->times[j][t] / again : t == 0;
  }
  g_free (bins);
  return ok;
}

static double
kernel_sum (const DsImage *k)
{
  double s = 0;
  for (guint y = 0; y < k->height; y++) {
    const float *row = ds_image_row (k, y);
    for (guint x = 0; x < k->width; x++)
      s += row[x];
  }
  return s;
}

/* Diffusion: the radius whose disc holds `fraction` of the analytic profile (a square of that
 * half-side holds at least as much), in pixels. */
static guint
diffusion_radius (const DsSlab *slab, double pitch, double fraction)
{
  double total = ds_slab_diffusion_transmittance (slab);
  if (!(total > 0))
    return DS_KERNEL_MIN_RADIUS;
  /* Midpoint rule on rings 1/8 px wide: the profile is smooth on that scale once away from the
   * axis, and the axis' share is small. */
  double dr = pitch / 8, acc = 0;
  for (guint i = 0; i < 8 * DS_KERNEL_MAX_RADIUS; i++) {
    double rho = (i + 0.5) * dr;
    acc += 2 * G_PI * rho * MAX (ds_slab_diffusion_profile (slab, rho), 0.0) * dr;
    if (acc >= fraction * total)
      return MAX ((guint) ceil ((i + 1) / 8.0), DS_KERNEL_MIN_RADIUS);
  }
  return DS_KERNEL_MAX_RADIUS;
}

static gboolean
check_spec (const DsSlab *slab, const DsSlabKernelSpec *spec, GError **error)
{
  DsPsfGrid grid = { spec->pixel_pitch_mm, 0, spec->acceptance_half_angle_deg };
  if (!ds_slab_validate (slab, error) || !ds_psf_grid_validate (&grid, error) ||
      !ds_slab_planes_validate (slab, &spec->planes, error))
    return FALSE;
  if (!(spec->energy_fraction > 0 && spec->energy_fraction < 1)) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "kernels: energy fraction %g is outside (0, 1)",
                 spec->energy_fraction);
    return FALSE;
  }
  if (spec->model != DS_TRANSPORT_MONTE_CARLO && spec->model != DS_TRANSPORT_DIFFUSION) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "kernels: unknown transport model %d", (int) spec->model);
    return FALSE;
  }
  return TRUE;
}

DsSlabKernels *
ds_slab_kernels_compute (const DsSlab *slab, const DsSlabKernelSpec *spec, guint threads, GError **error)
{
  if (!check_spec (slab, spec, error))
    return NULL;
  g_autoptr (DsSlabKernels) k = g_new0 (DsSlabKernels, 1);
  k->model = spec->model;
  k->pixel_pitch_mm = spec->pixel_pitch_mm;
  k->acceptance_half_angle_deg = spec->acceptance_half_angle_deg;
  k->planes = spec->planes;
  k->energy_fraction = spec->energy_fraction;
  gboolean need_mc = spec->model == DS_TRANSPORT_MONTE_CARLO || spec->planes.n_planes > 0;
  g_autoptr (GArray) ev = NULL;
  DsSlabTally tally = { 0 };
  guint r_mc = 0, r_diff = 0;
  if (need_mc) {
    ev = ds_mc_slab_events (slab, &spec->planes, spec->photons, spec->seed, spec->acceptance_half_angle_deg,
                            threads, &tally, error);
    if (!ev)
      return NULL;
    r_mc = energy_radius (ev, DS_MC_EVENT_FLOATS (spec->planes.n_planes), spec->pixel_pitch_mm,
                          spec->energy_fraction);
    k->photons = spec->photons;
    k->records = ev->len / DS_MC_EVENT_FLOATS (spec->planes.n_planes);
    if (spec->model == DS_TRANSPORT_MONTE_CARLO)
      k->effective_records = effective_records (ev, DS_MC_EVENT_FLOATS (spec->planes.n_planes));
  }
  if (spec->model == DS_TRANSPORT_DIFFUSION)
    r_diff = diffusion_radius (slab, spec->pixel_pitch_mm, spec->energy_fraction);
  k->radius_px = MAX (r_mc, r_diff);
  if (ev && !bin_records (k, ev, spec->photons, spec->model == DS_TRANSPORT_MONTE_CARLO, error))
    return NULL;
  if (spec->model == DS_TRANSPORT_MONTE_CARLO) {
    k->scattered_in_cone = tally.scattered_in_cone;
    k->se_scattered_in_cone = tally.se_scattered_in_cone;
  } else {
    DsPsfGrid grid = { spec->pixel_pitch_mm, k->radius_px, spec->acceptance_half_angle_deg };
    k->full = ds_slab_psf_diffusion (slab, &grid, error);
    if (!k->full)
      return NULL;
    k->scattered_in_cone = ds_slab_diffusion_transmittance (slab) *
                           ds_slab_diffusion_cone_fraction (slab, spec->acceptance_half_angle_deg);
    k->se_scattered_in_cone = 0;
  }
  double in = kernel_sum (k->full);
  k->held = k->scattered_in_cone > 0 ? in / k->scattered_in_cone : 1.0;
  return g_steal_pointer (&k);
}
