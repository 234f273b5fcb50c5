#include "daemon/ctl/study.h"

#include <math.h>
#include <string.h>

#include "daemon/ctl/sim_rig.h"
#include "daemon/operating/motion_term.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"
#include "proc/metrics.h"
#include "proc/preview.h"
#include "proc/proc_error.h"

#define MAX_EST 4

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
  const DsSimRig *rig;
  const char *scene_name;
  gboolean own_period;
  const DsImage *truth_t, *truth_g;
  double exposure, exposure_factor;
  double signal_dn, direct_fraction;
  DsSeparationParams params[MAX_EST];
  guint n_params;
  double sys_t[MAX_EST], sys_g[MAX_EST];
  double speed_px_s;
  gboolean moving;           /* frames at their times, truth at the set's middle */
  gboolean examples;         /* this pass may write the example previews */
  const double *frame_time_s;/* moving: frame j of phase k at [k M + j] */
} PointContext;

/* Saturated and non-finite pixels carry no usable number; every other pixel is scored as it is.
 * Dark-exceeds is scored too: the separation sets it wherever the dark frame is above the
 * darkest phase by any amount, which read noise alone does in about half the pixels of a scene
 * without scattering (the darkest phase of a clear pixel is the dark level plus noise). Leaving
 * them out dropped 37-64 % of clear-grid's pixels, exactly those whose noise pushed max/min's
 * minimum down, and so understated its noise error. */
static const guint8 ignore_bits = DS_MASK_SATURATED | DS_MASK_NONFINITE;

/* Why a separation left no pixel to score: what its mask says of the pixels, and the sampling
 * precondition's verdict on the configuration (proc/separation.h). */
static char *
no_pixel_reason (const DsSeparationParams *p, const DsImage *mask)
{
  guint64 n = 0, clipped = 0, nonfinite = 0, under = 0;
  for (guint y = 0; y < mask->height; y++) {
    const guint8 *m = ds_image_row (mask, y);
    for (guint x = 0; x < mask->width; x++, n++) {
      clipped += (m[x] & DS_MASK_SATURATED) != 0;
      nonfinite += (m[x] & DS_MASK_NONFINITE) != 0;
      under += (m[x] & DS_MASK_UNDERSAMPLED) != 0;
    }
  }
  DsSamplingCheck check;
  gboolean accepted = ds_separation_check_sampling (p, &check, NULL);
  GString *r = g_string_new (NULL);
  g_string_append_printf (r, "no pixel left to score: %.0f %% clipped, %.0f %% not finite, %.0f %% undersampled",
                          100.0 * clipped / MAX (n, 1), 100.0 * nonfinite / MAX (n, 1), 100.0 * under / MAX (n, 1));
  if (!accepted && check.refusal[0])
    g_string_append_printf (r, "; %s", check.refusal);
  else if (check.applies && isfinite (check.affected_fraction))
    g_string_append_printf (r, "; the sampling precondition: %.0f %% of positions undersampled, lit phases %.2f, "
                               "unlit %.2f", 100 * check.affected_fraction, check.lit_phases, check.unlit_phases);
  return g_string_free (r, FALSE);
}

/* The errors against the truth; a set that left no pixel to score gives NAN and *reason (the
 * configuration cannot separate the scene), any other failure fails. */
static gboolean
errors_of (const PointContext *c, const DsSeparationParams *p, const DsSeparation *sep, double *t, double *g,
           DsErrorStats *st, char **reason, GError **error)
{
  DsErrorStats et = { 0 }, eg = { 0 };
  g_autoptr (GError) local = NULL;
  if (!ds_metrics_error (sep->transmissive, c->truth_t, sep->mask, ignore_bits, &et, &local) ||
      !ds_metrics_error (sep->scattered, c->truth_g, sep->mask, ignore_bits, &eg, &local)) {
    if (!g_error_matches (local, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY)) {
      g_propagate_error (error, g_steal_pointer (&local));
      return FALSE;
    }
    *t = *g = NAN;
    if (st) {
      memset (st, 0, sizeof *st);
      st->masked = (guint64) sep->mask->width * sep->mask->height;
    }
    if (reason)
      *reason = no_pixel_reason (p, sep->mask);
    return TRUE;
  }
  *t = et.relative_rmse;
  *g = eg.relative_rmse;
  if (st)
    *st = et;
  return TRUE;
}

static gboolean
write_examples (const PointContext *c, const DsSeparation *sep, DsEstimator est, guint n, GError **error)
{
  const DsImage *imgs[] = { sep->transmissive, sep->scattered };
  const char *names[] = { "transmissive", "scattered" };
  for (guint i = 0; i < 2; i++) {
    g_autoptr (DsImage) pv = ds_preview_u8 (imgs[i], 0.5, 99.5, error);
    g_autofree char *stem = g_strndup (c->scene_name, strcspn (c->scene_name, "."));
    g_autofree char *path = g_strdup_printf ("%s/%s-%s-N%u-%s.png", c->plan->examples_dir, stem,
                                             ds_estimator_name (est), n, names[i]);
    if (!pv || !ds_image_write (pv, path, error))
      return FALSE;
  }
  return TRUE;
}

/* One (N, M, seed) at the context's period and exposure: renders once, one set per estimator. */
static gboolean
run_point (const PointContext *c, guint n, guint m, guint64 seed, DsStudyPointFunc emit, gpointer user_data,
           GError **error)
{
  DsSeparation *seps[MAX_EST] = { NULL };
  double compute_us[MAX_EST] = { 0 };
  DsSeparationParams params[MAX_EST];
  for (guint i = 0; i < c->n_params; i++) {
    params[i] = c->params[i];
    params[i].n_phases = n;
  }
  guint64 frame_seed = seed * 1000003u + (guint64) n * 101u + m * 7u;
  if (!ds_sim_rig_separate_at (c->rig, params, c->n_params, m, c->exposure, frame_seed, FALSE, c->frame_time_s,
                               seps, compute_us, error))
    return FALSE;
  gboolean ok = TRUE;
  const DsScene *scene = ds_sim_rig_scene (c->rig);
  guint w = ds_scene_width (scene), h = ds_scene_height (scene);
  for (guint r = 0; r < c->n_params && ok; r++) {
    const DsSeparation *sep = seps[r];
    DsStudyPoint pt = { .scene = c->scene_name, .estimator = params[r].estimator, .phases = n, .averages = m,
                        .period_px = ds_scene_period_px (scene), .exposure_factor = c->exposure_factor,
                        .exposure_us = c->exposure, .seed = seed,
                        .systematic_transmissive = c->sys_t[r], .systematic_scattered = c->sys_g[r],
                        .signal_dn = c->signal_dn, .direct_fraction = c->direct_fraction,
                        .edge_blur_known = params[r].geometry.edge_blur_known, .speed_px_s = c->speed_px_s,
                        .status = "ok", .reason = "" };
    DsErrorStats et;
    g_autofree char *reason = NULL;
    ok = errors_of (c, &params[r], sep, &pt.rel_rmse_transmissive, &pt.rel_rmse_scattered, &et, &reason, error);
    if (ok && reason) {
      pt.status = "cannot-separate";
      pt.reason = reason;
      pt.stripe_residue = NAN;
    } else
      ok = ok && ds_metrics_stripe_residue (sep->transmissive, ds_scene_period_px (scene), &pt.stripe_residue, error);
    if (ok && c->plan->examples_dir && c->examples && c->own_period && seed == 1 && m == 1 && c->exposure_factor == 1.0 &&
        (n == c->plan->phases[0] || n == c->plan->phases[c->plan->n_phases - 1]))
      ok = write_examples (c, sep, params[r].estimator, n, error);
    if (!ok)
      break;
    pt.valid = et.valid;
    pt.masked = et.masked;
    pt.saturated = count_saturated (sep->mask);
    pt.acquisition_ms = ds_rig_timing_set_ms (&c->plan->timing, w, h, n, m, c->exposure, c->plan->dark_frame);
    pt.compute_ms = compute_us[r] / 1000.0;
    emit (&pt, user_data);
  }
  for (guint r = 0; r < c->n_params; r++)
    ds_separation_free (seps[r]);
  return ok;
}

/* A configuration proc refuses on this scene: one point per M and seed, nothing run, the
 * refusal as its reason, so that the sweep says which configurations cannot separate the scene
 * and why instead of leaving them out. */
static void
emit_refused (const PointContext *c, const DsSeparationParams *p, const char *why, DsStudyPointFunc emit,
              gpointer user_data)
{
  const DsScene *scene = ds_sim_rig_scene (c->rig);
  for (guint im = 0; im < c->plan->n_averages; im++)
    for (guint seed = 1; seed <= c->plan->n_seeds; seed++) {
      DsStudyPoint pt = { .scene = c->scene_name, .estimator = p->estimator, .phases = p->n_phases,
                          .averages = c->plan->averages[im], .period_px = ds_scene_period_px (scene),
                          .exposure_factor = c->exposure_factor, .exposure_us = c->exposure, .seed = seed,
                          .rel_rmse_transmissive = NAN, .rel_rmse_scattered = NAN,
                          .systematic_transmissive = NAN, .systematic_scattered = NAN, .stripe_residue = NAN,
                          .signal_dn = c->signal_dn, .direct_fraction = c->direct_fraction,
                          .edge_blur_known = p->geometry.edge_blur_known, .speed_px_s = c->speed_px_s,
                          .status = "refused", .reason = why };
      pt.masked = (guint64) ds_scene_width (scene) * ds_scene_height (scene);
      emit (&pt, user_data);
    }
}


/* The systematic part of each estimator's error: the same set on noise-free frames (M of them
 * per phase when the scene moves, each at its time; one stands for all M of a still scene). */
static gboolean
systematic_parts (PointContext *c, guint m, GError **error)
{
  DsSeparation *seps[MAX_EST] = { NULL };
  if (!ds_sim_rig_separate_at (c->rig, c->params, c->n_params, m, c->exposure, 0, TRUE, c->frame_time_s, seps, NULL,
                               error))
    return FALSE;
  gboolean ok = TRUE;
  for (guint r = 0; r < c->n_params; r++) {
    ok = ok && errors_of (c, &c->params[r], seps[r], &c->sys_t[r], &c->sys_g[r], NULL, NULL, error);
    ds_separation_free (seps[r]);
  }
  return ok;
}

/* Every seed of one (N, M). A moving scene's frames are timed, its truth is taken at the set's
 * middle (halfway between the first and the last frame) and its systematic part is made with
 * the same times. */
static gboolean
run_averages (const PointContext *cn, guint n, guint m, DsStudyPointFunc emit, gpointer user_data, GError **error)
{
  PointContext c = *cn;
  g_autofree double *times = NULL;
  g_autoptr (DsImage) truth_t = NULL;
  g_autoptr (DsImage) truth_g = NULL;
  if (c.moving) {
    const DsScene *scene = ds_sim_rig_scene (c.rig);
    times = g_new (double, (gsize) n * m);
    ds_motion_frame_times (&c.plan->timing, ds_scene_width (scene), ds_scene_height (scene), n, m, c.exposure, times);
    double mid = (times[0] + times[(gsize) n * m - 1]) / 2;
    DsImage *tt = NULL, *tg = NULL;
    if (!ds_renderer_truth_at (ds_sim_rig_renderer (c.rig), c.exposure, 0.0, mid, &tt, &tg, error))
      return FALSE;
    truth_t = tt;
    truth_g = tg;
    c.truth_t = truth_t;
    c.truth_g = truth_g;
    c.frame_time_s = times;
    if (!systematic_parts (&c, m, error))
      return FALSE;
  }
  for (guint seed = 1; seed <= c.plan->n_seeds; seed++)
    if (!run_point (&c, n, m, seed, emit, user_data, error))
      return FALSE;
  return TRUE;
}

/* The fastest object of a scene (px/s). */
static double
scene_speed (const DsScene *scene)
{
  const DsSceneSpec *s = ds_scene_spec (scene);
  double v = 0;
  for (guint i = 0; i < s->n_objects; i++)
    v = MAX (v, hypot (s->objects[i].vx, s->objects[i].vy));
  return v;
}

static gboolean
run_period (const DsSimRig *rig, const char *scene_name, gboolean own_period, gboolean examples,
            const DsStudyPlan *plan, DsStudyPointFunc emit, gpointer user_data, GError **error)
{
  const DsScene *scene = ds_sim_rig_scene (rig);
  PointContext c = { .plan = plan, .rig = rig, .scene_name = scene_name, .own_period = own_period,
                     .examples = examples, .moving = ds_scene_has_motion (scene), .speed_px_s = scene_speed (scene) };
  for (guint k = 0; k < plan->n_estimators && c.n_params < MAX_EST; k++) {
    DsSeparationParams *p = &c.params[c.n_params];
    ds_separation_params_init (p, 4);
    p->estimator = plan->estimators[k];
    p->pattern = ds_scene_pattern_is_sine (scene) ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
    p->duty = ds_scene_duty (scene);
    p->black_level = ds_scene_black_level (scene);
    p->system_gain = ds_scene_system_gain (scene);
    p->read_noise_dn = ds_scene_read_noise_dn (scene);
    /* As descatterd's sets with [illuminator] edge-blur-px calibrated: the period and the
     * blur are known (robust's margin follows them), the sensor integrates over whole pixels. */
    p->geometry.period_px = ds_scene_period_px (scene);
    p->geometry.edge_blur_px = ds_scene_spec (scene)->edge_blur_px;
    p->geometry.edge_blur_known = TRUE;
    p->geometry.pixel_aperture = 1;
    c.n_params++;
  }
  for (guint ie = 0; ie < plan->n_exposures; ie++) {
    c.exposure_factor = plan->exposure_factors[ie];
    c.exposure = ds_scene_default_exposure_us (scene) * c.exposure_factor;
    DsImage *tt = NULL, *tg = NULL;
    if (!ds_renderer_truth (ds_sim_rig_renderer (rig), c.exposure, 0.0, &tt, &tg, error))
      return FALSE;
    g_autoptr (DsImage) truth_t = tt;
    g_autoptr (DsImage) truth_g = tg;
    c.truth_t = truth_t;
    c.truth_g = truth_g;
    double st = 0, sg = 0;
    for (guint y = 0; y < truth_t->height; y++) {
      const float *a = ds_image_row (truth_t, y), *b = ds_image_row (truth_g, y);
      for (guint x = 0; x < truth_t->width; x++) {
        st += a[x];
        sg += b[x];
      }
    }
    c.signal_dn = (st + sg) / ((double) truth_t->width * truth_t->height);
    c.direct_fraction = st + sg > 0 ? st / (st + sg) : 0;
    for (guint in = 0; in < plan->n_phases; in++) {
      guint n = plan->phases[in];
      /* Estimators that cannot run this N (sine below 3) are left out of its points. Where
       * the sampling precondition refuses the blur known (no pixel fully lit in any phase),
       * the point is what descatterd does without the blur configured, marked as such. */
      PointContext cn = c;
      cn.n_params = 0;
      for (guint k = 0; k < c.n_params; k++) {
        DsSeparationParams p = c.params[k];
        p.n_phases = n;
        if (!ds_separation_params_validate (&p, NULL)) {
          p.geometry.edge_blur_px = 0;
          p.geometry.edge_blur_known = FALSE;
        }
        g_autoptr (GError) refused = NULL;
        if (ds_separation_params_validate (&p, &refused))
          cn.params[cn.n_params++] = p;
        else if (g_error_matches (refused, DS_PROC_ERROR, DS_PROC_ERROR_PRECONDITION))
          emit_refused (&c, &p, refused->message, emit, user_data); /* this scene's period; an N no
                                                                       scene takes stays out */
      }
      if (cn.n_params == 0)
        continue;
      if (!c.moving && !systematic_parts (&cn, 1, error))
        return FALSE;
      for (guint im = 0; im < plan->n_averages; im++)
        if (!run_averages (&cn, n, plan->averages[im], emit, user_data, error))
          return FALSE;
    }
  }
  return TRUE;
}

/* One speed: every period of the plan on the rig (the scene's own period run once). */
static gboolean
run_periods (const DsSimRig *rig, const char *scene_name, gboolean examples, const DsStudyPlan *plan,
             DsStudyPointFunc emit, gpointer user_data, GError **error)
{
  double own = ds_scene_period_px (ds_sim_rig_scene (rig));
  g_autoptr (GArray) done = g_array_new (FALSE, FALSE, sizeof (double));
  for (guint ip = 0; ip < MAX (plan->n_periods, 1u); ip++) {
    double period = plan->n_periods ? plan->periods[ip] : 0;
    period = period > 0 ? period : period < 0 ? -period * own : own;
    gboolean seen = FALSE;
    for (guint k = 0; k < done->len && !seen; k++)
      seen = fabs (g_array_index (done, double, k) - period) < 1e-9;
    if (seen)
      continue;
    g_array_append_val (done, period);
    gboolean is_own = fabs (period - own) < 1e-9;
    g_autoptr (DsSimRig) variant = is_own ? NULL : ds_sim_rig_with_period (rig, period, error);
    if ((!is_own && !variant) ||
        !run_period (is_own ? rig : variant, scene_name, is_own, examples, plan, emit, user_data, error))
      return FALSE;
  }
  return TRUE;
}

gboolean
ds_study_run_scene (const char *scene_path, const DsStudyPlan *plan, DsStudyPointFunc emit,
                    gpointer user_data, GError **error)
{
  g_autoptr (DsSimRig) rig = ds_sim_rig_new (scene_path, error);
  if (!rig)
    return FALSE;
  g_autofree char *scene_name = g_path_get_basename (scene_path);
  for (guint is = 0; is < MAX (plan->n_speeds, 1u); is++) {
    g_autoptr (DsSimRig) moved = NULL;
    if (plan->n_speeds && !(moved = ds_sim_rig_with_speed (rig, plan->speeds[is], plan->moving_object, error))) {
      g_prefix_error (error, "%s: speed %g px/s: ", scene_name, plan->speeds[is]);
      return FALSE;
    }
    if (!run_periods (moved ? moved : rig, scene_name, is == 0, plan, emit, user_data, error)) {
      g_prefix_error (error, "%s: ", scene_name);
      return FALSE;
    }
  }
  return TRUE;
}
