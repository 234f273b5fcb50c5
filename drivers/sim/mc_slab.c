/* Monte Carlo photon transport through a slab, after MCML (Wang, Jacques & Zheng 1995):
 * exponential free paths with mu_t, absorption deposited as a weight fraction mu_a/mu_t at
 * each interaction, Henyey-Greenstein scattering, Russian roulette below a weight of 1e-4
 * (survival chance 1/10), and at each face Fresnel reflection chosen with its probability
 * (MCML's all-or-none method) or refraction out of the slab. */
#include <math.h>
#include <string.h>

#include "drivers/sim/henyey_greenstein.h"
#include "drivers/sim/mc_events.h"
#include "drivers/sim/rng.h"
#include "drivers/sim/sim_error.h"
#include "drivers/sim/transport.h"

#define DS_MC_ROULETTE_THRESHOLD 1e-4
#define DS_MC_ROULETTE_CHANCE 0.1
#define DS_PSF_MAX_RADIUS 2048u

static gboolean
check_finite_range (const char *name, double v, double lo, gboolean lo_open, double hi,
                    gboolean hi_open, const char *range, GError **error)
{
  gboolean ok = isfinite (v) && (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  if (!ok)
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "slab: %s = %g is outside %s", name, v,
                 range);
  return ok;
}

gboolean
ds_slab_validate (const DsSlab *s, GError **error)
{
  if (!s) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "slab: no slab given");
    return FALSE;
  }
  return check_finite_range ("mua", s->mua, 0, FALSE, INFINITY, TRUE, "[0, inf) per mm", error) &&
         check_finite_range ("mus", s->mus, 0, FALSE, INFINITY, TRUE, "[0, inf) per mm", error) &&
         check_finite_range ("g", s->g, -1, TRUE, 1, TRUE, "(-1, 1)", error) &&
         check_finite_range ("thickness", s->thickness_mm, 0, TRUE, INFINITY, TRUE, "(0, inf) mm", error) &&
         check_finite_range ("n_medium", s->n_medium, 1, FALSE, INFINITY, TRUE, "[1, inf)", error) &&
         check_finite_range ("n_above", s->n_above, 1, FALSE, INFINITY, TRUE, "[1, inf)", error) &&
         check_finite_range ("n_below", s->n_below, 1, FALSE, INFINITY, TRUE, "[1, inf)", error);
}

gboolean
ds_psf_grid_validate (const DsPsfGrid *grid, GError **error)
{
  if (!grid) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "psf grid: none given");
    return FALSE;
  }
  if (!(isfinite (grid->pixel_pitch_mm) && grid->pixel_pitch_mm > 0)) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID,
                 "psf grid: pixel_pitch_mm = %g is outside (0, inf) mm", grid->pixel_pitch_mm);
    return FALSE;
  }
  if (grid->radius_px > DS_PSF_MAX_RADIUS) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID,
                 "psf grid: radius_px = %u is outside [0, %u]", grid->radius_px, DS_PSF_MAX_RADIUS);
    return FALSE;
  }
  double a = grid->acceptance_half_angle_deg;
  if (!(isfinite (a) && a > 0 && a <= 90)) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID,
                 "psf grid: acceptance_half_angle_deg = %g is outside (0, 90] degrees", a);
    return FALSE;
  }
  return TRUE;
}

/* What one run accumulates: per-photon sums and sums of squares for standard errors, and
 * optionally the binned lateral exit positions of scattered, accepted transmitted light, or
 * (events) one record per such photon with its path's crossings of the object planes. */
typedef struct {
  double sum[5], sum2[5]; /* reflectance, transmittance, ballistic, absorbed, in-cone */
  double *bins;           /* side x side or NULL */
  guint radius, side;
  double pitch;
  const DsSlabPlanes *planes; /* with events: the planes to track (may have none) */
  GArray *events;         /* float records of DS_MC_EVENT_FLOATS (n_planes), or NULL */
} Tally;

enum { Q_R, Q_T, Q_B, Q_A, Q_C };

/* Per plane: where the photon crossed it first after it last crossed the plane above (phi), and
 * last of all; whether it was still unscattered at phi; how often it crossed. Every crossing of
 * plane j re-arms plane j + 1, so at the end phi_j follows the last crossing of plane j - 1: the
 * points entry, phi_1, last_1, phi_2, last_2, ... exit are in the order the photon met them
 * (docs/transport.md, "Object planes"). */
typedef struct {
  float x[DS_SLAB_MAX_PLANES], y[DS_SLAB_MAX_PLANES];   /* phi */
  float lx[DS_SLAB_MAX_PLANES], ly[DS_SLAB_MAX_PLANES]; /* last crossing */
  guint8 crossings[DS_SLAB_MAX_PLANES], ballistic[DS_SLAB_MAX_PLANES], armed[DS_SLAB_MAX_PLANES];
} PlaneTrack;

static inline void
cross_plane (const DsSlabPlanes *pl, PlaneTrack *tr, guint j, double x, double y, double z, double ux, double uy,
             double uz, guint scatterings)
{
  double t = (pl->depth_mm[j] - z) / uz;
  tr->lx[j] = (float) (x + t * ux);
  tr->ly[j] = (float) (y + t * uy);
  if (tr->armed[j]) {
    tr->x[j] = tr->lx[j];
    tr->y[j] = tr->ly[j];
    tr->ballistic[j] = scatterings == 0;
    tr->armed[j] = FALSE;
  }
  if (tr->crossings[j] < 255)
    tr->crossings[j]++;
  if (j + 1 < pl->n_planes)
    tr->armed[j + 1] = TRUE;
}

/* The photon moves from (x, y, z) by `len` along u: every plane it passes, in the order it
 * meets them. */
static inline void
track_planes (const DsSlabPlanes *pl, PlaneTrack *tr, double x, double y, double z, double len, double ux,
              double uy, double uz, guint scatterings)
{
  double z1 = z + len * uz;
  if (uz > 0) {
    for (guint j = 0; j < pl->n_planes; j++)
      if (z < pl->depth_mm[j] && z1 >= pl->depth_mm[j])
        cross_plane (pl, tr, j, x, y, z, ux, uy, uz, scatterings);
  } else if (uz < 0) {
    for (guint j = pl->n_planes; j-- > 0;)
      if (z >= pl->depth_mm[j] && z1 < pl->depth_mm[j])
        cross_plane (pl, tr, j, x, y, z, ux, uy, uz, scatterings);
  }
}

static inline void
record_event (Tally *t, const PlaneTrack *tr, double x, double y, double w)
{
  guint n = t->planes->n_planes;
  float rec[DS_MC_EVENT_FLOATS (DS_SLAB_MAX_PLANES)];
  rec[0] = (float) x;
  rec[1] = (float) y;
  rec[2] = (float) w;
  for (guint j = 0; j < n; j++) {
    float *p = rec + DS_MC_EVENT_PLANE (j);
    p[0] = tr->x[j];
    p[1] = tr->y[j];
    p[2] = tr->lx[j];
    p[3] = tr->ly[j];
    p[4] = (float) (2 * MIN (tr->crossings[j], 127u) + tr->ballistic[j]);
  }
  g_array_append_vals (t->events, rec, DS_MC_EVENT_FLOATS (n));
}

/* One photon history at a time. `tracking` is a constant at each call site, so the compiler
 * builds a loop without any plane or event work for the totals and plain kernels. */
static inline __attribute__ ((always_inline)) void
transport (const DsSlab *s, guint64 photons, DsRng *rng_in, double cos_accept, Tally *t, const gboolean tracking)
{
  const double mut = s->mua + s->mus;
  const double absorb_fraction = mut > 0 ? s->mua / mut : 0.0;
  const double inv_mut = mut > 0 ? 1.0 / mut : 0.0;
  const double d = s->thickness_mm;
  const double w0 = 1.0 - ds_fresnel_reflectance (s->n_above, s->n_medium, 1.0);
  /* Matched faces never reflect: no Fresnel evaluation per exit. */
  const gboolean match_above = s->n_above == s->n_medium, match_below = s->n_below == s->n_medium;
  const DsSlabPlanes *pl = tracking ? t->planes : NULL;
  /* Henyey-Greenstein by CDF inversion (as ds_hg_sample_cos) with its constants hoisted:
   * cos = (1 + g^2 - t^2) / (2g), t = (1 - g^2) / (1 - g + 2 g xi). */
  const gboolean isotropic = fabs (s->g) < 1e-6;
  const double hg_num = 1.0 - s->g * s->g, hg_b = 1.0 - s->g, hg_c = 2.0 * s->g, hg_d = 1.0 + s->g * s->g;
  const double hg_inv_2g = isotropic ? 0.0 : 1.0 / (2.0 * s->g);
  DsRng rng = *rng_in;
  for (guint64 i = 0; i < photons; i++) {
    double x = 0, y = 0, z = 0, ux = 0, uy = 0, uz = 1, w = w0;
    double q[5] = { 0, 0, 0, 0, 0 };
    guint scatterings = 0;
    PlaneTrack tr;
    if (tracking) {
      memset (tr.crossings, 0, sizeof tr.crossings);
      memset (tr.armed, 1, sizeof tr.armed);
    }
    for (;;) {
      double step = mut > 0 ? -log (ds_rng_uniform_open0 (&rng)) * inv_mut : INFINITY;
      double to_face = uz > 0 ? (d - z) / uz : uz < 0 ? -z / uz : INFINITY;
      if (step >= to_face) {
        if (tracking)
          track_planes (pl, &tr, x, y, z, to_face, ux, uy, uz, scatterings);
        x += to_face * ux;
        y += to_face * uy;
        z = uz > 0 ? d : 0.0;
        double n_out = uz > 0 ? s->n_below : s->n_above;
        gboolean matched = uz > 0 ? match_below : match_above;
        if (!matched && ds_rng_uniform (&rng) < ds_fresnel_reflectance (s->n_medium, n_out, uz)) {
          /* Reflected back in. The free path is memoryless: a fresh one is as good as the
           * remainder. */
          uz = -uz;
          continue;
        }
        if (uz < 0) {
          q[Q_R] = w;
        } else {
          q[Q_T] = w;
          if (scatterings == 0)
            q[Q_B] = w;
          else if ((matched ? uz : ds_fresnel_cos_transmitted (s->n_medium, n_out, uz)) >= cos_accept) {
            q[Q_C] = w;
            if (tracking && t->events)
              record_event (t, &tr, x, y, w);
            else if (!tracking && t->bins) {
              double fx = floor (x / t->pitch + 0.5), fy = floor (y / t->pitch + 0.5);
              if (fabs (fx) <= t->radius && fabs (fy) <= t->radius)
                t->bins[(gsize) (fy + t->radius) * t->side + (gsize) (fx + t->radius)] += w;
            }
          }
        }
        break;
      }
      if (tracking)
        track_planes (pl, &tr, x, y, z, step, ux, uy, uz, scatterings);
      x += step * ux;
      y += step * uy;
      z += step * uz;
      double dw = w * absorb_fraction;
      q[Q_A] += dw;
      w -= dw;
      if (w < DS_MC_ROULETTE_THRESHOLD) {
        if (w <= 0 || ds_rng_uniform (&rng) >= DS_MC_ROULETTE_CHANCE)
          break;
        w /= DS_MC_ROULETTE_CHANCE;
      }
      /* New direction: HG polar angle, uniform azimuth (cos, sin from a point in the unit
       * disc: no trigonometry). */
      double xi = ds_rng_uniform (&rng), ct;
      if (isotropic)
        ct = 2.0 * xi - 1.0;
      else {
        double tt = hg_num / (hg_b + hg_c * xi);
        ct = CLAMP ((hg_d - tt * tt) * hg_inv_2g, -1.0, 1.0);
      }
      double st = sqrt (MAX (0.0, 1.0 - ct * ct));
      double a, b, r2;
      do {
        a = 2.0 * ds_rng_uniform (&rng) - 1.0;
        b = 2.0 * ds_rng_uniform (&rng) - 1.0;
        r2 = a * a + b * b;
      } while (r2 > 1.0 || r2 == 0.0);
      double inv_r2 = 1.0 / r2;
      double cp = (a * a - b * b) * inv_r2, sp = 2.0 * a * b * inv_r2;
      if (fabs (uz) > 0.99999) {
        ux = st * cp;
        uy = st * sp;
        uz = uz > 0 ? ct : -ct;
      } else {
        double root = sqrt (1.0 - uz * uz), f = st / root;
        double nx = f * (ux * uz * cp - uy * sp) + ux * ct;
        double ny = f * (uy * uz * cp + ux * sp) + uy * ct;
        double nz = -st * cp * root + uz * ct;
        ux = nx;
        uy = ny;
        uz = nz;
      }
      scatterings++;
    }
    for (int k = 0; k < 5; k++) {
      t->sum[k] += q[k];
      t->sum2[k] += q[k] * q[k];
    }
  }
  *rng_in = rng;
}

static void
run_photons (const DsSlab *s, guint64 photons, DsRng *rng, double cos_accept, Tally *t)
{
  if (t->events)
    transport (s, photons, rng, cos_accept, t, TRUE);
  else
    transport (s, photons, rng, cos_accept, t, FALSE);
}

/* Photons are split into a fixed number of chunks, each with its own random stream, and the
 * chunks' tallies are added in chunk order: the result is the same bits whatever the number
 * of worker threads. */
#define DS_MC_CHUNKS 16u

typedef struct {
  const DsSlab *slab;
  guint64 photons;
  guint64 seed;
  guint chunk;
  double cos_accept;
  Tally tally;
} Chunk;

static gpointer
run_chunk (gpointer data)
{
  Chunk *c = data;
  DsRng rng;
  ds_rng_seed_stream (&rng, c->seed, c->chunk);
  run_photons (c->slab, c->photons, &rng, c->cos_accept, &c->tally);
  return NULL;
}

static guint
resolve_threads (guint threads)
{
  if (threads == 0)
    threads = (guint) MAX (g_get_num_processors (), 1);
  return MIN (threads, DS_MC_CHUNKS);
}

/* threads: resolved (1..DS_MC_CHUNKS). With total->bins, scratch holds threads x side^2 doubles
 * for the chunks' own bins. */
static void
run_chunked (const DsSlab *s, guint64 photons, guint64 seed, double cos_accept, guint threads,
             double *scratch, Tally *total)
{
  gsize nbins = total->bins ? (gsize) total->side * total->side : 0;
  Chunk *round = g_new0 (Chunk, threads);
  GThread **workers = g_new0 (GThread *, threads);
  for (guint base = 0; base < DS_MC_CHUNKS; base += threads) {
    guint k = MIN (threads, DS_MC_CHUNKS - base);
    for (guint i = 0; i < k; i++) {
      Chunk *c = &round[i];
      guint idx = base + i;
      memset (&c->tally, 0, sizeof c->tally);
      c->slab = s;
      c->seed = seed;
      c->chunk = idx;
      c->cos_accept = cos_accept;
      c->photons = photons / DS_MC_CHUNKS + (idx < photons % DS_MC_CHUNKS ? 1 : 0);
      c->tally.radius = total->radius;
      c->tally.side = total->side;
      c->tally.pitch = total->pitch;
      c->tally.bins = nbins ? scratch + (gsize) i * nbins : NULL;
      if (nbins)
        memset (c->tally.bins, 0, nbins * sizeof (double));
      c->tally.planes = total->planes;
      c->tally.events = total->events ? g_array_new (FALSE, FALSE, sizeof (float)) : NULL;
    }
    /* A thread that cannot be started runs its chunk here: same result, only slower. */
    for (guint i = 1; i < k; i++)
      workers[i] = g_thread_try_new ("ds-mc", run_chunk, &round[i], NULL);
    run_chunk (&round[0]);
    for (guint i = 1; i < k; i++) {
      if (workers[i])
        g_thread_join (workers[i]);
      else
        run_chunk (&round[i]);
    }
    for (guint i = 0; i < k; i++) {
      Tally *t = &round[i].tally;
      for (int q = 0; q < 5; q++) {
        total->sum[q] += t->sum[q];
        total->sum2[q] += t->sum2[q];
      }
      for (gsize b = 0; b < nbins; b++)
        total->bins[b] += t->bins[b];
      if (t->events) {
        g_array_append_vals (total->events, t->events->data, t->events->len);
        g_array_unref (t->events);
      }
    }
  }
  g_free (workers);
  g_free (round);
}

static double
cos_of_half_angle (double deg)
{
  return deg >= 90.0 ? -1.0 : cos (deg * G_PI / 180.0);
}

static gboolean
check_photons (guint64 photons, GError **error)
{
  if (photons < 2) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID,
                 "slab: photons = %" G_GUINT64_FORMAT " is outside [2, 2^64)", photons);
    return FALSE;
  }
  return TRUE;
}

gboolean
ds_mc_slab_run_cone (const DsSlab *slab, guint64 photons, guint64 seed,
                     double acceptance_half_angle_deg, DsSlabTally *out, GError **error)
{
  return ds_mc_slab_run_threads (slab, photons, seed, acceptance_half_angle_deg, 0, out, error);
}

static void
tally_to_result (const Tally *t, const DsSlab *slab, guint64 photons, DsSlabTally *out)
{
  double mean[5], se[5];
  for (int k = 0; k < 5; k++) {
    mean[k] = t->sum[k] / (double) photons;
    double var = (t->sum2[k] / (double) photons - mean[k] * mean[k]) * photons / (photons - 1.0);
    se[k] = sqrt (MAX (var, 0.0) / (double) photons);
  }
  memset (out, 0, sizeof *out);
  out->reflectance = mean[Q_R];
  out->transmittance = mean[Q_T];
  out->ballistic = mean[Q_B];
  out->absorbed = mean[Q_A];
  out->scattered_in_cone = mean[Q_C];
  out->se_reflectance = se[Q_R];
  out->se_transmittance = se[Q_T];
  out->se_ballistic = se[Q_B];
  out->se_absorbed = se[Q_A];
  out->se_scattered_in_cone = se[Q_C];
  out->specular = ds_fresnel_reflectance (slab->n_above, slab->n_medium, 1.0);
  out->photons = photons;
}

gboolean
ds_mc_slab_run_threads (const DsSlab *slab, guint64 photons, guint64 seed,
                        double acceptance_half_angle_deg, guint threads, DsSlabTally *out,
                        GError **error)
{
  DsPsfGrid grid = { 1.0, 0, acceptance_half_angle_deg };
  if (!ds_slab_validate (slab, error) || !check_photons (photons, error) ||
      !ds_psf_grid_validate (&grid, error))
    return FALSE;
  Tally t;
  memset (&t, 0, sizeof t);
  run_chunked (slab, photons, seed, cos_of_half_angle (acceptance_half_angle_deg),
               resolve_threads (threads), NULL, &t);
  tally_to_result (&t, slab, photons, out);
  return TRUE;
}

gboolean
ds_slab_planes_validate (const DsSlab *slab, const DsSlabPlanes *planes, GError **error)
{
  if (!planes)
    return TRUE;
  if (planes->n_planes > DS_SLAB_MAX_PLANES) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "slab planes: %u planes, at most %u",
                 planes->n_planes, DS_SLAB_MAX_PLANES);
    return FALSE;
  }
  for (guint j = 0; j < planes->n_planes; j++) {
    double z = planes->depth_mm[j];
    if (!(isfinite (z) && z > 0 && z < slab->thickness_mm) || (j > 0 && !(z > planes->depth_mm[j - 1]))) {
      g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID,
                   "slab planes: depth %u = %g mm must be inside (0, %g) mm and deeper than the one before", j, z,
                   slab->thickness_mm);
      return FALSE;
    }
  }
  return TRUE;
}

GArray *
ds_mc_slab_events (const DsSlab *slab, const DsSlabPlanes *planes, guint64 photons, guint64 seed,
                   double acceptance_half_angle_deg, guint threads, DsSlabTally *out, GError **error)
{
  DsPsfGrid grid = { 1.0, 0, acceptance_half_angle_deg };
  static const DsSlabPlanes none = { 0 };
  if (!planes)
    planes = &none;
  if (!ds_slab_validate (slab, error) || !check_photons (photons, error) || !ds_psf_grid_validate (&grid, error) ||
      !ds_slab_planes_validate (slab, planes, error))
    return NULL;
  Tally t;
  memset (&t, 0, sizeof t);
  t.planes = planes;
  t.events = g_array_new (FALSE, FALSE, sizeof (float));
  run_chunked (slab, photons, seed, cos_of_half_angle (acceptance_half_angle_deg), resolve_threads (threads),
               NULL, &t);
  tally_to_result (&t, slab, photons, out);
  return t.events;
}

gboolean
ds_mc_slab_run (const DsSlab *slab, guint64 photons, guint64 seed, DsSlabTally *out,
                GError **error)
{
  return ds_mc_slab_run_cone (slab, photons, seed, 90.0, out, error);
}

DsImage *
ds_slab_psf_monte_carlo (const DsSlab *slab, const DsPsfGrid *grid, guint64 photons,
                         guint64 seed, GError **error)
{
  return ds_slab_psf_monte_carlo_threads (slab, grid, photons, seed, 0, error);
}

DsImage *
ds_slab_psf_monte_carlo_threads (const DsSlab *slab, const DsPsfGrid *grid, guint64 photons,
                                 guint64 seed, guint threads, GError **error)
{
  if (!ds_slab_validate (slab, error) || !ds_psf_grid_validate (grid, error) ||
      !check_photons (photons, error))
    return NULL;
  guint side = 2 * grid->radius_px + 1;
  g_autoptr (DsImage) psf = ds_image_new (DS_SAMPLE_F32, side, side, error);
  if (!psf)
    return NULL;
  Tally t;
  memset (&t, 0, sizeof t);
  t.radius = grid->radius_px;
  t.side = side;
  t.pitch = grid->pixel_pitch_mm;
  threads = resolve_threads (threads);
  gsize nbins = (gsize) side * side;
  /* Up to 2049^2 x 8 bytes per thread and for the total: refuse rather than abort. */
  t.bins = g_try_malloc0_n (nbins * (threads + 1), sizeof (double));
  if (!t.bins) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_NUMERIC,
                 "psf: cannot allocate %u x %u bins for %u threads", side, side, threads);
    return NULL;
  }
  run_chunked (slab, photons, seed, cos_of_half_angle (grid->acceptance_half_angle_deg), threads,
               t.bins + nbins, &t);
  for (guint y = 0; y < side; y++) {
    float *row = ds_image_row (psf, y);
    for (guint x = 0; x < side; x++)
      row[x] = (float) (t.bins[(gsize) y * side + x] / (double) photons);
  }
  g_free (t.bins);
  return g_steal_pointer (&psf);
}
