#include "daemon/operating/error_model.h"

#include <math.h>
#include <string.h>

#include "daemon/operating/operating_error.h"
#include "proc/harmonic_gain.h"

/* Synthetic pixels: every column position of the sensor's first SYN_MAX_WIDTH columns (they
 * carry the stripe phases the sensor has), in rows of blank pixels (Ld = 0) and lit ones. */
#define SYN_MAX_WIDTH 256u
#define SYN_ROWS 16u
#define SYN_BLANK_ROWS 4u
#define SYN_LEAK_HARMONICS 15u
#define N_EST 3

typedef struct {
  gboolean valid[N_EST];
  double error[N_EST];
  char *refusal[N_EST];   /* the estimator's refusal, or why no pixel of the set is valid */
} SetResult;

static void
set_result_free (gpointer p)
{
  SetResult *r = p;
  for (int i = 0; i < N_EST; i++)
    g_free (r->refusal[i]);
  g_free (r);
}

struct DsErrorModel {
  DsSceneProbe probe;
  DsSeparationParams params;      /* the rig's, estimator and N aside */
  guint width;
  double blank_fraction, ld_lit;  /* two-valued Ld: a fraction blank, the rest at ld_lit */
  float *normals;                 /* [frame][row][column] unit normals, common to all sets */
  guint normal_frames;
  GRand *rand;
  GHashTable *cache;              /* "N/M/f/P/noise/leak" -> SetResult */
  GHashTable *tables;             /* "P/leak" -> pattern_table () */
  DsErrorModel *blurred;          /* blur unknown: the same scene with a blur assumed, whose
                                     prediction wins when it is worse */
  GHashTable *sets;               /* (N << 2 | estimator) -> DsPhaseSet, reused: a set's creation
                                     computes the range quantile of its N, which costs more than
                                     folding the synthetic frames */
};

DsErrorModel *
ds_error_model_new (const DsSceneProbe *probe, const DsSeparationParams *params)
{
  DsErrorModel *m = g_new0 (DsErrorModel, 1);
  m->probe = *probe;
  m->params = *params;
  m->width = MIN (probe->width ? probe->width : SYN_MAX_WIDTH, SYN_MAX_WIDTH);
  double spread = MAX (1.0, probe->light.ld_spread);
  m->blank_fraction = 1.0 - 1.0 / spread;
  m->ld_lit = MAX (probe->light.ld_mean, 1e-9) * spread;
  m->rand = g_rand_new_with_seed (0x5eedu);
  m->cache = g_hash_table_new_full (g_str_hash, g_str_equal, g_free, set_result_free);
  if (probe->blur.source == DS_BLUR_ASSUMED_SHARP) {
    DsSceneProbe b = *probe;
    b.geometry.blur_px = MIN (DS_ERROR_MODEL_UNKNOWN_BLUR_PX, b.geometry.period_px / 8);
    b.blur.source = DS_BLUR_MEASURED; /* no further alternative */
    m->blurred = ds_error_model_new (&b, params);
  }
  m->tables = g_hash_table_new_full (g_str_hash, g_str_equal, g_free, g_free);
  m->sets = g_hash_table_new_full (g_direct_hash, g_direct_equal, NULL, (GDestroyNotify) ds_phase_set_free);
  return m;
}

DsErrorModel *
ds_error_model_new_like (const DsErrorModel *like, const DsSceneProbe *probe)
{
  return ds_error_model_new (probe, &like->params);
}

void
ds_error_model_free (DsErrorModel *m)
{
  if (!m)
    return;
  ds_error_model_free (m->blurred);
  g_hash_table_unref (m->cache);
  g_hash_table_unref (m->sets);
  g_hash_table_unref (m->tables);
  g_rand_free (m->rand);
  g_free (m->normals);
  g_free (m);
}

static void
ensure_normals (DsErrorModel *m, guint frames)
{
  if (frames <= m->normal_frames)
    return;
  gsize per = (gsize) m->width * SYN_ROWS;
  m->normals = g_renew (float, m->normals, per * frames);
  for (gsize i = per * m->normal_frames; i < per * frames; i += 2) {
    /* Box-Muller: two normals from two uniforms in (0, 1]. */
    double u1 = 1.0 - g_rand_double (m->rand), u2 = g_rand_double (m->rand);
    double r = sqrt (-2.0 * log (u1));
    m->normals[i] = (float) (r * cos (2 * G_PI * u2));
    if (i + 1 < per * frames)
      m->normals[i + 1] = (float) (r * sin (2 * G_PI * u2));
  }
  m->normal_frames = frames;
}

/* The pattern as pixels see it, as a function of u = x/P - shift (a pixel's aperture is fixed
 * in u too), with the scattered light's share of each harmonic in phase with it: tabulated over
 * one period once per period, and interpolated, instead of integrated per pixel and phase. */
#define TABLE 4096u

typedef struct {
  double v[TABLE + 1];
  double leak_min;        /* the scattered stripes' lowest value (<= 0: they have no mean), per Ld */
} PatternTable;

static const PatternTable *
pattern_table (DsErrorModel *m, double period, double leak)
{
  g_autofree char *key = g_strdup_printf ("%.9g/%g", period, leak);
  PatternTable *table = g_hash_table_lookup (m->tables, key);
  if (table)
    return table;
  DsStripeModel g = m->probe.geometry;
  g.period_px = period;
  double leak_c[SYN_LEAK_HARMONICS + 1] = { 0 };
  for (guint h = 1; h <= SYN_LEAK_HARMONICS && leak != 0; h++)
    leak_c[h] = leak * ds_scene_probe_leak (&m->probe, period, h) * ds_stripe_harmonic (&g, h);
  table = g_new0 (PatternTable, 1);
  for (guint i = 0; i <= TABLE; i++) {
    double u = (double) i / TABLE, v = 0;
    for (guint h = 1; h <= SYN_LEAK_HARMONICS; h++)
      if (leak_c[h] != 0)
        v += leak_c[h] * cos (2 * G_PI * h * u);
    table->leak_min = MIN (table->leak_min, v);
    table->v[i] = ds_stripe_value (&g, 0, -u) + v;
  }
  g_hash_table_insert (m->tables, g_steal_pointer (&key), table);
  return table;
}

static const DsEstimator estimators[N_EST] = { DS_ESTIMATOR_MAXMIN, DS_ESTIMATOR_SINE, DS_ESTIMATOR_ROBUST };

/* One synthetic set per estimator at (N, M, exposure factor, period); noise on or off, the
 * scattered stripes at `leak` times the probe's (0: none). Returns the cached result. */
static const SetResult *
run_sets (DsErrorModel *m, guint n, guint averages, double factor, double period, gboolean noise,
          double leak)
{
  /* Noise-free sets too are per exposure: clipping is systematic. */
  g_autofree char *key = g_strdup_printf ("%u/%u/%.6g/%.6g/%d/%g", n, noise ? averages : 0, factor,
                                          period, noise, leak);
  SetResult *res = g_hash_table_lookup (m->cache, key);
  if (res)
    return res;
  res = g_new0 (SetResult, 1);
  const DsSceneProbe *pr = &m->probe;
  DsStripeModel g = pr->geometry;
  g.period_px = period;
  DsPhaseSet *sets[N_EST] = { NULL };
  /* A dark level under everything, and a dark frame of M averaged frames taken off it, as the
   * rig subtracts one: the mask then flags where the dark frame exceeds the darkest phase. */
  const double pedestal = 100.0;
  /* The sensor's clip level over that dark level: frames clip there, and the sets flag the
   * clipped samples when the rig's sets flag at that level (not at a full well the pilot found
   * below the level they know: those pass unflagged, as on the rig). The two-valued Ld keeps
   * the scene's mean and mean square, not its brightest pixels: the level is scaled so that the
   * synthetic brightest pixel clips when the pilot's brightest (clip.bright_dn) would. */
  double syn_bright = m->ld_lit * ds_stripe_value (&g, 0, 0) +
                      pr->light.lg_mean * ds_pattern_mean (g.kind, g.duty, g.black_level);
  double to_syn = pr->clip.bright_dn > 0 && syn_bright > 0 ? syn_bright / pr->clip.bright_dn : 1.0;
  double clip = pr->clip.saturation_dn > 0 ? pedestal + (pr->clip.saturation_dn - pr->noise.dark_dn) * to_syn : INFINITY;
  for (int e = 0; e < N_EST; e++) {
    gpointer key_set = GUINT_TO_POINTER (n << 2 | (guint) e);
    sets[e] = g_hash_table_lookup (m->sets, key_set);
    if (sets[e]) {
      ds_phase_set_reset (sets[e]);
      continue;
    }
    DsSeparationParams p = m->params;
    p.n_phases = n;
    p.estimator = estimators[e];
    p.saturation_level = pr->clip.flagged && isfinite (clip) ? clip : 0;
    GError *err = NULL;
    sets[e] = ds_phase_set_new (&p, m->width, SYN_ROWS, &err);
    if (!sets[e]) {
      res->refusal[e] = g_strdup (err->message);
      g_error_free (err);
      continue;
    }
    g_hash_table_insert (m->sets, key_set, sets[e]);
  }
  double pattern_mean = ds_pattern_mean (g.kind, g.duty, g.black_level);
  const PatternTable *table = pattern_table (m, period, leak);
  /* The scattered stripes are scattered light: modulated light with no mean of its own rides on
   * the scattered light's mean, and no light is negative. A probe whose Lg holds less than their
   * troughs take (a leak of a few % read at P on a scene whose mean shows no scattered light)
   * would put the lit pixels' troughs below the dark frame, where the sets flag every
   * lit pixel and the noise-free error is that of no pixel (+inf). So Lg is at least what the
   * stripes' troughs at the lit pixels take. */
  double lg = MAX (pr->light.lg_mean, pattern_mean > 0 ? -table->leak_min * m->ld_lit / pattern_mean : 0.0);
  if (noise)
    ensure_normals (m, n + 1);
  g_autoptr (DsImage) frame = ds_image_new (DS_SAMPLE_F32, m->width, SYN_ROWS, NULL);
  /* The dark frame's variance at this exposure: read noise and quantisation as in the pilot, the
   * shot noise of its own signal (ambient light, dark current) scaled with the exposure. */
  double var0 = MAX (0.0, pr->noise.var0 - pr->noise.dark_shot) + pr->noise.dark_shot * factor;
  for (guint y = 0; y < SYN_ROWS; y++) {
    float *row = ds_image_row (frame, y);
    const float *z = noise ? m->normals + ((gsize) n * SYN_ROWS + y) * m->width : NULL;
    for (guint x = 0; x < m->width; x++)
      row[x] = (float) (pedestal + (z ? sqrt (var0 / averages) * z[x] : 0.0));
  }
  for (int e = 0; e < N_EST; e++)
    if (sets[e] && !ds_phase_set_set_dark (sets[e], frame, NULL))
      sets[e] = NULL;
  g_autofree double *lit = g_new (double, m->width);
  for (guint k = 0; k < n; k++) {
    double shift = pr->phase_offset + (double) k / n;
    for (guint x = 0; x < m->width; x++) {
      double u = x / period - shift;
      u = (u - floor (u)) * TABLE;
      guint i = MIN ((guint) u, (guint) TABLE - 1);
      double t = u - i;
      lit[x] = table->v[i] * (1 - t) + table->v[i + 1] * t;
    }
    for (guint y = 0; y < SYN_ROWS; y++) {
      float *row = ds_image_row (frame, y);
      double ld = y < SYN_BLANK_ROWS ? 0.0 : m->ld_lit;
      const float *z = noise ? m->normals + ((gsize) k * SYN_ROWS + y) * m->width : NULL;
      for (guint x = 0; x < m->width; x++) {
        double s = factor * (ld * lit[x] + lg * pattern_mean);
        if (z)
          s += sqrt (MAX (0.0, var0 + pr->noise.gain * s) / averages) * z[x];
        row[x] = (float) MIN (pedestal + s, clip);
      }
    }
    for (int e = 0; e < N_EST; e++) {
      GError *err = NULL;
      if (sets[e] && !ds_phase_set_accumulate (sets[e], k, frame, &err)) {
        res->refusal[e] = g_strdup (err->message);
        g_error_free (err);
        sets[e] = NULL;
      }
    }
  }
  /* Weighted relative RMSE: blank rows stand for the blank fraction of the scene. */
  double w_blank = m->blank_fraction / SYN_BLANK_ROWS, w_lit = (1 - m->blank_fraction) / (SYN_ROWS - SYN_BLANK_ROWS);
  const guint8 ignore = DS_MASK_SATURATED | DS_MASK_NONFINITE | DS_MASK_DARK_EXCEEDS;
  for (int e = 0; e < N_EST; e++) {
    if (!sets[e])
      continue;
    GError *err = NULL;
    g_autoptr (DsSeparation) sep = ds_phase_set_finalize (sets[e], &err);
    if (!sep) {
      res->refusal[e] = g_strdup (err->message);
      g_error_free (err);
      continue;
    }
    double se = 0, st = 0;
    guint64 lit_px = 0, saturated = 0, below_dark = 0;
    for (guint y = 0; y < SYN_ROWS; y++) {
      const float *t = ds_image_row (sep->transmissive, y);
      const guint8 *mk = ds_image_row (sep->mask, y);
      double truth = y < SYN_BLANK_ROWS ? 0.0 : factor * m->ld_lit, w = y < SYN_BLANK_ROWS ? w_blank : w_lit;
      for (guint x = 0; x < m->width; x++) {
        if (y >= SYN_BLANK_ROWS) {
          lit_px++;
          saturated += (mk[x] & DS_MASK_SATURATED) != 0;
          below_dark += (mk[x] & DS_MASK_DARK_EXCEEDS) != 0;
        }
        if ((mk[x] & ignore) || !isfinite (t[x]))
          continue;
        se += w * (t[x] - truth) * (t[x] - truth);
        st += w * truth * truth;
      }
    }
    res->valid[e] = st > 0;
    res->error[e] = st > 0 ? sqrt (se / st) : INFINITY;
    if (!res->valid[e])
      res->refusal[e] = g_strdup_printf ("no lit pixel is left to separate at %g x the pilot's exposure: %.0f %% of "
                                         "them clip at the clip level, %.0f %% fall below the dark frame",
                                         factor, 100.0 * (double) saturated / (double) MAX (lit_px, 1),
                                         100.0 * (double) below_dark / (double) MAX (lit_px, 1));
  }
  g_hash_table_insert (m->cache, g_steal_pointer (&key), res);
  return res;
}

gboolean
ds_error_model_predict (DsErrorModel *m, DsEstimator estimator, guint phases, guint averages,
                        double exposure_factor, double period_px, DsErrorParts *out, GError **error)
{
  int e = 0;
  while (e < N_EST && estimators[e] != estimator)
    e++;
  double period = period_px > 0 ? period_px : m->probe.geometry.period_px;
  if (e == N_EST || phases < 2 || averages < 1 || !(exposure_factor > 0)) {
    g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_CONFIGURATION, "error model: no such configuration");
    return FALSE;
  }
  const SetResult *total = run_sets (m, phases, averages, exposure_factor, period, TRUE, 1);
  if (!total->valid[e]) {
    g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_CONFIGURATION, "%s",
                 total->refusal[e] ? total->refusal[e] : "no valid pixel in the synthetic set");
    return FALSE;
  }
  const SetResult *sys = run_sets (m, phases, 1, exposure_factor, period, FALSE, 1);
  const SetResult *samp = run_sets (m, phases, 1, exposure_factor, period, FALSE, 0);
  /* Noise can leave a few pixels of a set whose noise-free twin has none (samples jittered below
   * the clip level): an error over them says nothing about the scene, and the parts would not be
   * finite. Such a configuration is refused with the reason. */
  const SetResult *invalid = !sys->valid[e] ? sys : !samp->valid[e] ? samp : NULL;
  if (invalid) {
    g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_CONFIGURATION, "%s",
                 invalid->refusal[e] ? invalid->refusal[e] : "no valid pixel in the noise-free synthetic set");
    return FALSE;
  }
  out->total = total->error[e];
  out->systematic = sys->error[e];
  out->sampling = samp->error[e];
  double d = out->systematic * out->systematic - out->sampling * out->sampling;
  out->scattered_stripes = d >= 0 ? sqrt (d) : -sqrt (-d);
  out->noise = sqrt (MAX (0.0, out->total * out->total - out->systematic * out->systematic));
  out->cancellation = 0;
  out->total_upper = out->total;
  out->blur_assumed = FALSE;
  if (out->systematic < out->sampling) {
    /* The scattered stripes cancel part of the sampling error. The remainder is only as good as
     * the leak, which the two-period probe knows to within its own size (scene_probe.h: read at
     * x0.1 to x2 of the kernel's truth on media it cannot resolve), and an error that rests on
     * two large parts cancelling is not known to better than the parts. Over leaks from none to
     * twice the measured one, the noise-free error sqrt (mean (a + s b)^2) is convex in the leak
     * s (the estimators are near linear in a small leak), so its worst is at an end: the
     * prediction takes that, max (E (0), E (2)), and says by how much it exceeds E (1). */
    const SetResult *twice = run_sets (m, phases, 1, exposure_factor, period, FALSE, 2);
    double worst = MAX (out->sampling, twice->valid[e] ? twice->error[e] : 0.0);
    out->cancellation = worst - out->systematic;
    out->total_upper = MAX (out->total, sqrt (out->noise * out->noise + worst * worst));
  }
  /* The blur unknown: the sharp pattern's parts are the prediction, the blurred one's worse end
   * the interval's upper end. */
  DsErrorParts alt;
  if (m->blurred && ds_error_model_predict (m->blurred, estimator, phases, averages, exposure_factor, period_px, &alt, NULL)) {
    out->total_upper = MAX (out->total_upper, MAX (alt.total, alt.total_upper));
    out->blur_assumed = TRUE;
  }
  return TRUE;
}

gboolean
ds_error_model_request_accepts (const DsErrorModel *m, DsEstimator estimator, guint phases, GError **error)
{
  /* What a fixed request is checked with before it runs: the parameters without the stripe
   * geometry, whose sampling check is then the period-free one. */
  DsSeparationParams p;
  ds_separation_params_init (&p, phases);
  p.estimator = estimator;
  p.pattern = m->params.pattern;
  p.duty = m->params.duty;
  p.black_level = m->params.black_level;
  return ds_separation_params_validate (&p, error);
}
