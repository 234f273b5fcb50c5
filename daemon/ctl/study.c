#include "daemon/ctl/study.h"

#include <math.h>
#include <string.h>

#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"
#include "proc/metrics.h"
#include "proc/preview.h"

typedef struct {
  DsPhaseSet *set;
  DsEstimator estimator;
  double compute_us;
} EstimatorRun;

static guint64
count_saturated (const DsImage *mask)
{
  guint64 n = 0;
  for (guint y = 0; y < mask->height; y++) {
    const guint8 *m = ds_image_row (mask, y);
    for (guint x = 0; x < mask->width; x++)
      n += (m[x] & DS_MASK_SATURATED) != 0;
  }
  return n;
}

typedef struct {
  const DsStudyPlan *plan;
  const DsScene *scene;
  const DsRenderer *renderer;
  const char *scene_name;
  const DsImage *truth_t, *truth_g;
  double exposure, exposure_factor;
} PointContext;

static void
runs_free (EstimatorRun *runs, guint n)
{
  for (guint r = 0; r < n; r++)
    ds_phase_set_free (runs[r].set);
}

/* One (N, M, exposure, seed): renders the frames once and folds them into one phase set per
 * estimator. */
static gboolean
run_point (const PointContext *c, guint n, guint m, guint64 seed, DsStudyPointFunc emit,
           gpointer user_data, GError **error)
{
  guint w = ds_scene_width (c->scene), h = ds_scene_height (c->scene);
  EstimatorRun runs[4] = { 0 };
  guint n_runs = 0;
  gboolean ok = FALSE;
  for (guint k = 0; k < c->plan->n_estimators && n_runs < G_N_ELEMENTS (runs); k++) {
    DsSeparationParams p;
    ds_separation_params_init (&p, n);
    p.estimator = c->plan->estimators[k];
    p.pattern = ds_scene_pattern_is_sine (c->scene) ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
    p.duty = ds_scene_duty (c->scene);
    p.black_level = ds_scene_black_level (c->scene);
    p.system_gain = ds_scene_system_gain (c->scene);
    p.read_noise_dn = ds_scene_read_noise_dn (c->scene);
    if (!ds_separation_params_validate (&p, NULL))
      continue; /* e.g. sine with N < 3: not a point of the study */
    runs[n_runs].set = ds_phase_set_new (&p, w, h, error);
    if (!runs[n_runs].set)
      goto out;
    runs[n_runs].estimator = p.estimator;
    n_runs++;
  }
  if (n_runs == 0)
    return TRUE;
  {
    /* Dark frame: M frames with the illuminator off, averaged in float. */
    g_autoptr (DsImage) dark = ds_image_new (DS_SAMPLE_F32, w, h, error);
    if (!dark)
      goto out;
    guint64 frame_seed = seed * 1000003u + (guint64) n * 101u + m;
    for (guint j = 0; j < m; j++) {
      DsRenderRequest req = { .phase = 0, .n_phases = n, .illuminator_on = FALSE,
                              .exposure_us = c->exposure, .gain_db = 0, .seed = frame_seed++ };
      g_autoptr (DsImage) f = ds_renderer_render (c->renderer, &req, error);
      if (!f)
        goto out;
      for (guint y = 0; y < h; y++) {
        const guint16 *src = ds_image_row (f, y);
        float *dst = ds_image_row (dark, y);
        for (guint x = 0; x < w; x++)
          dst[x] += (float) src[x] / (float) m;
      }
    }
    /* The accumulator subtracts like from like: the averaged dark frame as rounded u16. */
    g_autoptr (DsImage) dark16 = ds_image_convert_f32_clamped (dark, DS_SAMPLE_U16, 65535.0, error);
    if (!dark16)
      goto out;
    dark16->bit_depth = ds_scene_bit_depth (c->scene);
    for (guint r = 0; r < n_runs; r++)
      if (!ds_phase_set_set_dark (runs[r].set, dark16, error))
        goto out;
    for (guint k = 0; k < n; k++)
      for (guint j = 0; j < m; j++) {
        DsRenderRequest req = { .phase = k, .n_phases = n, .illuminator_on = TRUE,
                                .exposure_us = c->exposure, .gain_db = 0, .seed = frame_seed++ };
        g_autoptr (DsImage) f = ds_renderer_render (c->renderer, &req, error);
        if (!f)
          goto out;
        for (guint r = 0; r < n_runs; r++) {
          gint64 t0 = g_get_monotonic_time ();
          if (!ds_phase_set_accumulate (runs[r].set, k, f, error))
            goto out;
          runs[r].compute_us += (double) (g_get_monotonic_time () - t0);
        }
      }
  }
  for (guint r = 0; r < n_runs; r++) {
    gint64 t0 = g_get_monotonic_time ();
    g_autoptr (DsSeparation) sep = ds_phase_set_finalize (runs[r].set, error);
    if (!sep)
      goto out;
    runs[r].compute_us += (double) (g_get_monotonic_time () - t0);
    DsStudyPoint pt = { .scene = c->scene_name, .estimator = runs[r].estimator, .phases = n,
                        .averages = m, .exposure_factor = c->exposure_factor,
                        .exposure_us = c->exposure, .seed = seed };
    DsErrorStats et, eg;
    /* Saturated, non-finite and dark-exceeds pixels carry no usable number; the others
     * (including low modulation and slightly negative ones) are scored as they are. */
    guint8 ignore = DS_MASK_SATURATED | DS_MASK_NONFINITE | DS_MASK_DARK_EXCEEDS;
    if (!ds_metrics_error (sep->transmissive, c->truth_t, sep->mask, ignore, &et, error) ||
        !ds_metrics_error (sep->scattered, c->truth_g, sep->mask, ignore, &eg, error) ||
        !ds_metrics_stripe_residue (sep->transmissive, ds_scene_period_px (c->scene),
                                    &pt.stripe_residue, error))
      goto out;
    if (c->plan->examples_dir && seed == 1 && m == 1 && c->exposure_factor == 1.0 &&
        (n == c->plan->phases[0] || n == c->plan->phases[c->plan->n_phases - 1])) {
      const DsImage *imgs[] = { sep->transmissive, sep->scattered };
      const char *names[] = { "transmissive", "scattered" };
      for (guint i = 0; i < 2; i++) {
        g_autoptr (DsImage) pv = ds_preview_u8 (imgs[i], 0.5, 99.5, error);
        g_autofree char *stem = g_strndup (c->scene_name, strcspn (c->scene_name, "."));
        g_autofree char *path = g_strdup_printf ("%s/%s-%s-N%u-%s.png", c->plan->examples_dir, stem,
                                                 ds_estimator_name (runs[r].estimator), n, names[i]);
        if (!pv || !ds_image_write (pv, path, error))
          goto out;
      }
    }
    pt.rel_rmse_transmissive = et.relative_rmse;
    pt.rel_rmse_scattered = eg.relative_rmse;
    pt.valid = et.valid;
    pt.masked = et.masked;
    pt.saturated = count_saturated (sep->mask);
    {
      double st = 0, sg = 0;
      for (guint y = 0; y < h; y++) {
        const float *a = ds_image_row (c->truth_t, y), *b = ds_image_row (c->truth_g, y);
        for (guint x = 0; x < w; x++) {
          st += a[x];
          sg += b[x];
        }
      }
      pt.signal_dn = (st + sg) / ((double) w * h);
      pt.direct_fraction = st + sg > 0 ? st / (st + sg) : 0;
    }
    pt.acquisition_ms = ds_rig_timing_set_ms (&c->plan->timing, w, h, n, m, c->exposure,
                                              c->plan->dark_frame);
    pt.compute_ms = runs[r].compute_us / 1000.0;
    emit (&pt, user_data);
  }
  ok = TRUE;
out:
  runs_free (runs, n_runs);
  return ok;
}

gboolean
ds_study_run_scene (const char *scene_path, const DsStudyPlan *plan, DsStudyPointFunc emit,
                    gpointer user_data, GError **error)
{
  g_autoptr (DsScene) scene = ds_scene_load (scene_path, error);
  if (!scene)
    return FALSE;
  g_autoptr (DsRenderer) renderer = ds_renderer_new (scene, NULL, error);
  if (!renderer)
    return FALSE;
  g_autofree char *scene_name = g_path_get_basename (scene_path);
  for (guint ie = 0; ie < plan->n_exposures; ie++) {
    PointContext c = { .plan = plan, .scene = scene, .renderer = renderer, .scene_name = scene_name,
                       .exposure_factor = plan->exposure_factors[ie] };
    c.exposure = ds_scene_default_exposure_us (scene) * c.exposure_factor;
    DsImage *tt = NULL, *tg = NULL;
    if (!ds_renderer_truth (renderer, c.exposure, 0.0, &tt, &tg, error))
      return FALSE;
    g_autoptr (DsImage) truth_t = tt;
    g_autoptr (DsImage) truth_g = tg;
    c.truth_t = truth_t;
    c.truth_g = truth_g;
    for (guint in = 0; in < plan->n_phases; in++)
      for (guint im = 0; im < plan->n_averages; im++)
        for (guint seed = 1; seed <= plan->n_seeds; seed++)
          if (!run_point (&c, plan->phases[in], plan->averages[im], seed, emit, user_data, error)) {
            g_prefix_error (error, "%s: ", scene_name);
            return FALSE;
          }
  }
  return TRUE;
}
