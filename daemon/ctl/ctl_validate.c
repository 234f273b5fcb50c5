/* `descatterctl validate` and `descatterctl generate-scenes`: the automatic operating point
 * against the simulator's truth on scenes it was never fitted to (docs/accuracy.md,
 * "Validation").
 *
 * For every scene: the pilot frames and the probe as descatterd makes them, then one automatic
 * capture per request (targets, budgets): the choice is run and its achieved error compared with
 * the prediction; a refused target is checked by running the best reachable point. --fit
 * measures the one fitted number, the scale of the predictions, leave-one-scene-out on the
 * given scenes and writes the operating model; generated scenes are never part of a fit. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <glib/gstdio.h>

#include "daemon/ctl/csv.h"
#include "daemon/ctl/ctl_commands.h"
#include "daemon/ctl/scene_gen.h"
#include "daemon/ctl/validate.h"
#include "daemon/operating/data_dir.h"
#include "daemon/operating/operating_error.h"
#include "proc/proc_error.h"

typedef struct {
  char *name;           /* file name */
  char *path;
  gboolean generated;
  DsValidateScene probe;
  gboolean probed;
  char *failure;        /* the probe's or the pilot's error */
  GArray *outcomes;     /* DsValidateOutcome */
  double loso_scale;    /* the scale it was validated with */
} SceneRun;

static void
scene_run_free (SceneRun *s)
{
  for (guint i = 0; s->outcomes && i < s->outcomes->len; i++)
    ds_validate_outcome_clear (&g_array_index (s->outcomes, DsValidateOutcome, i));
  if (s->outcomes)
    g_array_unref (s->outcomes);
  g_free (s->name);
  g_free (s->path);
  g_free (s->failure);
  g_free (s);
}

typedef struct {
  DsEstimator estimator;
  guint phases, averages;
  double factor;
} Config;

typedef struct {
  DsValidateOptions options;
  Config *configs;
  guint n_configs;
  DsOperatingModel model;
  DsRigTiming timing;
  double *targets, *budgets;
  guint n_targets, n_budgets;
  gboolean quiet;
} Plan;

static gboolean
parse_list (const char *text, double **out, guint *n)
{
  if (strcmp (text, "none") == 0) {
    *n = 0;
    *out = g_new0 (double, 1);
    return TRUE;
  }
  g_auto (GStrv) parts = g_strsplit (text, ",", -1);
  *n = g_strv_length (parts);
  *out = g_new0 (double, *n + 1);
  for (guint i = 0; i < *n; i++) {
    char *end = NULL;
    (*out)[i] = g_ascii_strtod (parts[i], &end);
    if (!end || *end || !((*out)[i] > 0) || !isfinite ((*out)[i]))
      return FALSE;
  }
  return TRUE;
}

/* Whether a fixed configuration failed because its estimator refuses the scene's sampling (its
 * precondition fails everywhere, too few phases, an ill-conditioned inversion) rather than
 * because something broke. */
static gboolean
estimator_refuses (const GError *e)
{
  if (e->domain == DS_OPERATING_ERROR)
    return e->code == DS_OPERATING_ERROR_CONFIGURATION; /* the error model's words for the same */
  return e->domain == DS_PROC_ERROR &&
         (e->code == DS_PROC_ERROR_PRECONDITION || e->code == DS_PROC_ERROR_NOT_ENOUGH_PHASES ||
          e->code == DS_PROC_ERROR_ILL_CONDITIONED || e->code == DS_PROC_ERROR_INVALID_ARGUMENT);
}

/* Probes the scene and runs every request with `model`. */
static gboolean
run_scene (SceneRun *s, const Plan *plan, const DsOperatingModel *model, GError **error)
{
  g_autoptr (DsSimRig) rig = ds_sim_rig_new (s->path, error);
  if (!rig)
    return FALSE;
  if (!s->probed) {
    g_autoptr (GError) local = NULL;
    if (!ds_validate_probe (rig, &plan->options, &s->probe, &local)) {
      /* A scene the pilot cannot measure (no modulation, everything clipped) is a result too:
       * every automatic capture on it is refused with this message. */
      s->failure = g_strdup (local->message);
      return TRUE;
    }
    s->probed = TRUE;
    const DsCalibration *cal = &s->probe.calibration;
    if (!plan->quiet && s->probe.calibrated)
      fprintf (stderr, "validate: %s: calibrated: %s stripes, black level %.4f (%s%s), harmonic gain %.4f, "
                       "edge blur %.2f px; the probe's blur %.2f px (%s)\n",
               s->name, cal->pattern == DS_PATTERN_SINE ? "sine" : "square", cal->black_level,
               cal->pattern != DS_PATTERN_SINE ? "measured"
               : cal->black_level_measured     ? "measured at two periods"
                                               : "configured, assumed: ",
               cal->pattern == DS_PATTERN_SINE && !cal->black_level_measured ? s->probe.second_period_note : "",
               cal->harmonic_gain, cal->edge_blur_px, s->probe.probe.geometry.blur_px,
               ds_blur_source_name (s->probe.probe.blur.source));
  }
  if (s->outcomes) {
    for (guint i = 0; i < s->outcomes->len; i++)
      ds_validate_outcome_clear (&g_array_index (s->outcomes, DsValidateOutcome, i));
    g_array_set_size (s->outcomes, 0);
  } else
    s->outcomes = g_array_new (FALSE, TRUE, sizeof (DsValidateOutcome));
  s->loso_scale = model->scale;
  g_autoptr (DsErrorModel) errors = ds_error_model_new (&s->probe.probe, &s->probe.params);
  guint n_req = plan->n_targets + plan->n_budgets;
  for (guint i = 0; i < n_req; i++) {
    double target = i < plan->n_targets ? plan->targets[i] : 0;
    double budget = i < plan->n_targets ? 0 : plan->budgets[i - plan->n_targets];
    DsValidateOutcome o;
    if (!ds_validate_request (rig, &s->probe, errors, model, &plan->timing, target, budget,
                              plan->options.seed * 7919 + i * 101 + 17, &o, error)) {
      g_prefix_error (error, "%s: ", s->name);
      return FALSE;
    }
    if (!plan->quiet)
      fprintf (stderr, "validate: %s: target %g budget %g: %s N=%u M=%u predicted %.4f achieved %.4f (%s)\n",
               s->name, target, budget, ds_estimator_name (o.point.estimator), o.point.phases, o.point.averages,
               o.point.predicted_error, o.achieved, ds_verdict_name (o.verdict));
    g_array_append_val (s->outcomes, o);
  }
  for (guint i = 0; i < plan->n_configs; i++) {
    const Config *c = &plan->configs[i];
    DsValidateOutcome o;
    g_autoptr (GError) local = NULL;
    if (!ds_validate_config (rig, &s->probe, errors, model, &plan->timing, c->estimator, c->phases, c->averages,
                             c->factor, plan->options.seed * 7919 + (n_req + i) * 101 + 17, &o, &local)) {
      if (!estimator_refuses (local)) {
        g_propagate_prefixed_error (error, g_steal_pointer (&local), "%s: ", s->name);
        return FALSE;
      }
      /* A configuration the estimator refuses on this scene (fine periods defeat max/min and
       * robust) is a result: the row says so, the other configurations still run. */
      memset (&o, 0, sizeof o);
      o.refused = TRUE;
      o.refusal = g_strdup (local->message);
      o.verdict = DS_VERDICT_NONE;
      o.point.estimator = c->estimator;
      o.point.phases = c->phases;
      o.point.averages = c->averages;
      o.point.predicted_error = INFINITY;
      if (!plan->quiet)
        fprintf (stderr, "validate: %s: %s N=%u M=%u x%g: refused: %s\n", s->name, ds_estimator_name (c->estimator),
                 c->phases, c->averages, c->factor, local->message);
      g_array_append_val (s->outcomes, o);
      continue;
    }
    if (!plan->quiet)
      fprintf (stderr, "validate: %s: %s N=%u M=%u x%g: predicted %.4f (noise %.4f, sampling %.4f, stripes %+.4f) "
                       "achieved %.4f (systematic %.4f)\n",
               s->name, ds_estimator_name (c->estimator), c->phases, c->averages, c->factor, o.point.predicted_error,
               o.point.parts.noise, o.point.parts.sampling, o.point.parts.scattered_stripes, o.achieved,
               o.achieved_systematic);
    g_array_append_val (s->outcomes, o);
  }
  return TRUE;
}

/* Geometric mean of achieved / predicted over the chosen points that are not lower bounds. */
static double
fit_scale (GPtrArray *scenes, const SceneRun *leave_out)
{
  double sum = 0;
  guint n = 0;
  for (guint i = 0; i < scenes->len; i++) {
    const SceneRun *s = g_ptr_array_index (scenes, i);
    if (s == leave_out || !s->outcomes)
      continue;
    for (guint j = 0; j < s->outcomes->len; j++) {
      const DsValidateOutcome *o = &g_array_index (s->outcomes, DsValidateOutcome, j);
      if (o->refused || o->point.lower_bound || !(o->achieved > 0) || !(o->point.predicted_error > 0))
        continue;
      /* The prediction without the scale it was made with. */
      sum += log (o->achieved / (o->point.predicted_error / s->loso_scale));
      n++;
    }
  }
  return n ? CLAMP (exp (sum / n), 0.5, 2.0) : 1.0;
}

/* How far a prediction is off on a scene the scale was not fitted on: the RMS of log (achieved /
 * predicted) over the chosen points that are not lower bounds, each scene predicted with the scale
 * fitted without it (the outcomes of the leave-one-scene-out pass). 0 when there are none. */
static double
fit_spread (GPtrArray *scenes, guint n_given)
{
  double sum = 0;
  guint n = 0;
  for (guint i = 0; i < n_given; i++) {
    const SceneRun *s = g_ptr_array_index (scenes, i);
    for (guint j = 0; s->outcomes && j < s->outcomes->len; j++) {
      const DsValidateOutcome *o = &g_array_index (s->outcomes, DsValidateOutcome, j);
      if (o->refused || o->point.lower_bound || !(o->achieved > 0) || !(o->point.predicted_error > 0))
        continue;
      double r = log (o->achieved / o->point.predicted_error);
      sum += r * r;
      n++;
    }
  }
  return n ? MIN (1.0, sqrt (sum / n)) : 0;
}

static void
write_csv (GString *csv, const SceneRun *s)
{
  /* The scene is a file name: quoted when it holds a comma or a quote (RFC 4180). */
  if (!s->outcomes) {
    ds_csv_append_field (csv, s->name);
    g_string_append_printf (csv, ",%s,,,refused,,,,,,,,,,,,,pilot failed,,\n", s->generated ? "generated" : "shipped");
    return;
  }
  for (guint j = 0; j < s->outcomes->len; j++) {
    const DsValidateOutcome *o = &g_array_index (s->outcomes, DsValidateOutcome, j);
    const DsOperatingPoint *p = &o->point;
    ds_csv_append_field (csv, s->name);
    g_string_append_printf (csv, ",%s,%g,%g,%s,%s,%u,%u,%.0f,%.4g,%.4g,%.4g,%.4g,%.4g,%d,%.4g,%.4g,%s,%d,%.4g\n",
                            s->generated ? "generated" : "shipped", o->target_error, o->time_budget_ms,
                            o->refused ? "refused" : o->target_error > 0 || o->time_budget_ms > 0 ? "chosen" : "fixed", ds_estimator_name (p->estimator), p->phases, p->averages,
                            p->exposure_us, p->predicted_error, p->parts.noise, p->parts.sampling,
                            p->parts.scattered_stripes, s->loso_scale, p->lower_bound, o->achieved,
                            o->achieved_systematic, ds_verdict_name (o->verdict), p->target_may_be_missed,
                            p->uncertainty);
  }
}

typedef struct {
  guint total, good, refused_right, refused_wrong, off, none;
  guint lower, lower_off;  /* predictions marked as lower bounds; of them outside the factor */
  guint margin, margin_missed; /* chosen on the margin (target_may_be_missed); of them missing the target */
  double worst_ratio;      /* furthest from 1, as max(r, 1/r) */
  const SceneRun *worst_scene;
  const DsValidateOutcome *worst;
} Summary;

static void
summarise (const SceneRun *s, Summary *sum)
{
  if (!s->outcomes) {
    sum->total++;
    sum->none++;
    sum->good++; /* refused with the pilot's reason: no separation is possible */
    return;
  }
  for (guint j = 0; j < s->outcomes->len; j++) {
    const DsValidateOutcome *o = &g_array_index (s->outcomes, DsValidateOutcome, j);
    if (o->refused && o->target_error <= 0 && o->time_budget_ms <= 0)
      continue; /* a fixed configuration its estimator refuses: no prediction was tested */
    sum->total++;
    if (o->point.lower_bound && o->verdict != DS_VERDICT_NONE) {
      sum->lower++;
      sum->lower_off += o->verdict == DS_VERDICT_OFF || o->verdict == DS_VERDICT_REFUSED_WRONG;
    }
    if (o->point.target_may_be_missed && o->verdict != DS_VERDICT_NONE) {
      sum->margin++;
      sum->margin_missed += o->achieved > o->target_error;
    }
    switch (o->verdict) {
    case DS_VERDICT_WITHIN:
      sum->good++;
      break;
    case DS_VERDICT_REFUSED_RIGHT:
      sum->good++;
      sum->refused_right++;
      break;
    case DS_VERDICT_REFUSED_WRONG:
      sum->refused_wrong++;
      break;
    case DS_VERDICT_OFF:
      sum->off++;
      break;
    case DS_VERDICT_NONE:
      sum->none++;
      sum->good++;
      break;
    }
    if (o->achieved > 0 && o->point.predicted_error > 0 && isfinite (o->point.predicted_error)) {
      double r = o->achieved / o->point.predicted_error, far = MAX (r, 1 / r);
      if (far > sum->worst_ratio) {
        sum->worst_ratio = far;
        sum->worst_scene = s;
        sum->worst = o;
      }
    }
  }
}

static void
write_md (GString *md, const char *title, GPtrArray *scenes, gboolean generated)
{
  Summary sum = { 0 };
  g_string_append_printf (md, "\n## %s\n\n| scene | probe: Ld (truth), Lg (truth), blur, scattered stripes at P | request | choice | predicted (noise, sampling, stripes) | achieved | verdict |\n|---|---|---|---|---|---|---|\n", title);
  for (guint i = 0; i < scenes->len; i++) {
    const SceneRun *s = g_ptr_array_index (scenes, i);
    if (s->generated != generated)
      continue;
    summarise (s, &sum);
    if (!s->outcomes) {
      g_string_append_printf (md, "| %s | pilot refused: %s | all | – | – | – | refused |\n", s->name, s->failure);
      continue;
    }
    const DsSceneProbe *p = &s->probe.probe;
    for (guint j = 0; j < s->outcomes->len; j++) {
      const DsValidateOutcome *o = &g_array_index (s->outcomes, DsValidateOutcome, j);
      if (j == 0) {
        /* Where the probe bounds Ld from below too (scene_probe.h): its lower end. */
        g_autofree char *interval = !p->interval.set ? g_strdup ("")
                                    : p->interval.unbounded ? g_strdup (", Ld not bounded below")
                                    : p->interval.ld_lower < p->light.ld_mean ? g_strdup_printf (", Ld ≥ %.0f", p->interval.ld_lower)
                                    : g_strdup ("");
        g_string_append_printf (md, "| %s | %.0f (%.0f), %.0f (%.0f), %.2f px %s, %.1f %%%s%s |", s->name, p->light.ld_mean,
                                s->probe.truth_ld_mean, p->light.lg_mean, s->probe.truth_lg_mean, p->geometry.blur_px,
                                ds_blur_source_name (p->blur.source), 100 * ds_scene_probe_leak (p, p->geometry.period_px, 1),
                                p->leak.measured ? "" : " (not measured)", interval);
      } else
        g_string_append (md, "| | |");
      if (o->target_error > 0)
        g_string_append_printf (md, " target %g |", o->target_error);
      else if (o->time_budget_ms > 0)
        g_string_append_printf (md, " budget %g ms |", o->time_budget_ms);
      else
        g_string_append (md, " fixed |");
      if (o->verdict == DS_VERDICT_NONE && o->target_error <= 0 && o->time_budget_ms <= 0) {
        g_string_append_printf (md, " %s N=%u M=%u | – | – | the estimator refuses it |\n",
                                ds_estimator_name (o->point.estimator), o->point.phases, o->point.averages);
        continue;
      }
      if (o->verdict == DS_VERDICT_NONE) {
        g_string_append (md, " nothing fits | – | – | nothing fits |\n");
        continue;
      }
      g_string_append_printf (md, " %s%s N=%u M=%u %.0f µs |",
                              o->refused                        ? "refused; best: "
                              : o->point.target_may_be_missed ? "on the margin: "
                                                              : "",
                              ds_estimator_name (o->point.estimator), o->point.phases, o->point.averages,
                              o->point.exposure_us);
      /* A lower bound's upper end, where the probe bounds the direct light (scene_probe.h). */
      g_autofree char *upper = !o->point.lower_bound ? g_strdup ("")
                               : isinf (o->point.predicted_error_upper) ? g_strdup (" to unbounded")
                               : o->point.predicted_error_upper > o->point.predicted_error
                                 ? g_strdup_printf (" to %.4f", o->point.predicted_error_upper)
                                 : g_strdup ("");
      g_string_append_printf (md, " %.4f%s%s (%.4f, %.4f, %+.4f) | %.4f | %s |\n", o->point.predicted_error,
                              o->point.lower_bound ? " ≥" : "", upper, o->point.parts.noise, o->point.parts.sampling,
                              o->point.parts.scattered_stripes, o->achieved, ds_verdict_name (o->verdict));
    }
  }
  g_string_append_printf (md, "\n%u requests: %u (%.0f %%) within a factor 1.5 or correctly refused "
                              "(%u refused and the best reachable point indeed misses the target; %u with nothing "
                              "to run); %u outside the factor, %u refused wrongly.",
                          sum.total, sum.good, sum.total ? 100.0 * sum.good / sum.total : 0, sum.refused_right,
                          sum.none, sum.off, sum.refused_wrong);
  /* A lower bound that misses is a miss like any other (counted above); how many there are: */
  if (sum.lower)
    g_string_append_printf (md, " %u predictions are lower bounds (≥), %u of them outside the factor.", sum.lower,
                            sum.lower_off);
  /* Judged on the prediction as any chosen point; whether they met the target is told too. */
  if (sum.margin)
    g_string_append_printf (md, " %u targets chosen on the margin (not predicted to be met, within the prediction's "
                                "uncertainty), %u of them missed.",
                            sum.margin, sum.margin_missed);
  if (sum.worst)
    g_string_append_printf (md, " Worst: %s, %s %g: predicted %.4f, achieved %.4f (x%.2f).\n", sum.worst_scene->name,
                            sum.worst->target_error > 0 ? "target" : "budget",
                            sum.worst->target_error > 0 ? sum.worst->target_error : sum.worst->time_budget_ms,
                            sum.worst->point.predicted_error, sum.worst->achieved,
                            sum.worst->achieved / sum.worst->point.predicted_error);
  else
    g_string_append (md, "\n");
}

static gboolean
write_file (const char *dir, const char *name, const GString *text, GError **error)
{
  g_autofree char *path = g_build_filename (dir, name, NULL);
  return g_file_set_contents_full (path, text->str, (gssize) text->len, G_FILE_SET_CONTENTS_CONSISTENT, 0644, error);
}

/* g_ptr_array_sort hands the comparison pointers to the elements, not the elements: comparing
 * those as strings ordered the shipped scenes by where their names happened to be allocated. */
static gint
compare_names (gconstpointer a, gconstpointer b)
{
  return g_strcmp0 (*(const char *const *) a, *(const char *const *) b);
}

/* --configs: ESTIMATOR:N:M:EXPOSURE-FACTOR,... into *list (the caller's), *n_configs of them.
 * FALSE with the message printed. */
static gboolean
parse_configs (const char *configs, Config **list, guint *n_configs)
{
  g_auto (GStrv) cfg = configs ? g_strsplit (configs, ",", -1) : NULL;
  *list = g_new0 (Config, cfg ? g_strv_length (cfg) + 1 : 1);
  for (guint i = 0; cfg && cfg[i]; i++) {
    g_auto (GStrv) f = g_strsplit (cfg[i], ":", -1);
    guint64 n = 0, m = 0;
    char *end = NULL;
    Config *c = &(*list)[(*n_configs)++];
    if (g_strv_length (f) != 4 || !ds_estimator_from_name (f[0], &c->estimator) ||
        !g_ascii_string_to_unsigned (f[1], 10, 2, DS_MAX_PHASES, &n, NULL) ||
        !g_ascii_string_to_unsigned (f[2], 10, 1, DS_MAX_PHASES, &m, NULL) ||
        !((c->factor = g_ascii_strtod (f[3], &end)) > 0) || *end) {
      fprintf (stderr, "descatterctl validate: --configs: \"%s\" is not ESTIMATOR:N:M:EXPOSURE-FACTOR\n", cfg[i]);
      return FALSE;
    }
    c->phases = (guint) n;
    c->averages = (guint) m;
  }
  return TRUE;
}

/* The scenes to run: the given files, the shipped ones in name order, then the generated ones
 * (written to scene_dir); *n_given counts the first two. FALSE with the message printed. */
static gboolean
collect_scenes (GPtrArray *runs, char **scene_files, gboolean shipped, gint generate, gint64 seed,
                guint generator, const char *scene_dir, guint *n_given)
{
  g_autoptr (GError) error = NULL;
  for (guint i = 0; scene_files && scene_files[i]; i++) {
    SceneRun *s = g_new0 (SceneRun, 1);
    s->path = g_strdup (scene_files[i]);
    s->name = g_path_get_basename (scene_files[i]);
    g_ptr_array_add (runs, s);
  }
  if (shipped) {
    g_autofree char *sd = ds_data_path ("scenes");
    g_autoptr (GDir) d = g_dir_open (sd, 0, &error);
    if (!d) {
      fprintf (stderr, "descatterctl validate: %s\n", error->message);
      return FALSE;
    }
    g_autoptr (GPtrArray) names = g_ptr_array_new_with_free_func (g_free);
    const char *n;
    while ((n = g_dir_read_name (d)))
      if (g_str_has_suffix (n, ".scene") && !strstr (n, "1024"))
        g_ptr_array_add (names, g_strdup (n));
    g_ptr_array_sort (names, compare_names);
    for (guint i = 0; i < names->len; i++) {
      SceneRun *s = g_new0 (SceneRun, 1);
      s->name = g_strdup (g_ptr_array_index (names, i));
      s->path = g_build_filename (sd, s->name, NULL);
      g_ptr_array_add (runs, s);
    }
  }
  *n_given = runs->len;
  for (gint i = 0; i < generate; i++) {
    g_autofree char *text = ds_scene_generate ((guint64) seed, (guint) i, generator, &error);
    SceneRun *s = g_new0 (SceneRun, 1);
    s->generated = TRUE;
    s->name = g_strdup_printf ("gen-%" G_GINT64_FORMAT "-%02d.scene", seed, i);
    s->path = g_build_filename (scene_dir, s->name, NULL);
    g_ptr_array_add (runs, s);
    if (!text || !g_file_set_contents (s->path, text, -1, &error)) {
      fprintf (stderr, "descatterctl validate: %s: %s\n", s->name, error->message);
      return FALSE;
    }
  }
  return TRUE;
}

/* Leave one scene out: each given scene is validated again with the scale fitted on the others;
 * the model written to DIR/operating-model.conf is fitted on all of them. */
static gboolean
fit_model (GPtrArray *runs, guint n_given, Plan *plan, const char *dir, GError **error)
{
  double scales[64];
  guint n_s = MIN (n_given, G_N_ELEMENTS (scales));
  for (guint i = 0; i < n_s; i++)
    scales[i] = fit_scale (runs, g_ptr_array_index (runs, i));
  plan->model.scale = fit_scale (runs, NULL);
  GString *fitted = g_string_new (NULL);
  for (guint i = 0; i < n_given; i++)
    g_string_append_printf (fitted, "%s%s", i ? ";" : "", ((SceneRun *) g_ptr_array_index (runs, i))->name);
  g_strlcpy (plan->model.fitted_on, fitted->str, sizeof plan->model.fitted_on);
  g_string_free (fitted, TRUE);
  for (guint i = 0; i < n_s; i++) {
    DsOperatingModel loso = plan->model;
    loso.scale = scales[i];
    if (!run_scene (g_ptr_array_index (runs, i), plan, &loso, error))
      return FALSE;
  }
  /* Measured with a spread of 0 (the model being fitted has none yet), so that no target was
   * taken on the margin by the spread being measured. */
  plan->model.scale_spread = fit_spread (runs, n_s);
  g_autofree char *mp = g_build_filename (dir, "operating-model.conf", NULL);
  return ds_operating_model_write (&plan->model, mp, error);
}

/* DIR/validation.csv and DIR/validation.md: every scene's outcome, the given and the generated
 * scenes in tables of their own. */
static gboolean
write_reports (GPtrArray *runs, guint n_given, gint generate, const Plan *plan, gboolean fit, gint64 seed,
               const char *dir, GError **error)
{
  GString *csv = g_string_new ("scene,kind,target_error,time_budget_ms,outcome,estimator,phases,averages,exposure_us,"
                               "predicted,noise,sampling,scattered_stripes,scale,lower_bound,achieved,"
                               "achieved_systematic,verdict,target_may_be_missed,uncertainty\n");
  for (guint i = 0; i < runs->len; i++)
    write_csv (csv, g_ptr_array_index (runs, i));
  GString *md = g_string_new ("# Validation of the automatic operating point\n\nMade by `descatterctl validate`");
  g_string_append_printf (md, " (rig: %s, %s, %s; seed %" G_GINT64_FORMAT "; scale %.3f, spread %.3f, fitted on %s).\n",
                          plan->options.calibrated  ? "calibrated harmonic gain"
                          : plan->options.simulated ? "simulated illuminator known"
                                                    : "uncalibrated",
                          plan->options.fixed_period ? "fixed stripe period" : "stripe period can change",
                          plan->options.saturation_known ? "clip level configured"
                                                         : "clip level unknown below the format's top",
                          seed, plan->model.scale, plan->model.scale_spread, plan->model.fitted_on);
  if (n_given)
    write_md (md, fit ? "Given scenes, leave one scene out" : "Given scenes", runs, FALSE);
  if ((guint) generate > 0)
    write_md (md, "Generated scenes (never fitted to)", runs, TRUE);
  gboolean ok = write_file (dir, "validation.csv", csv, error) && write_file (dir, "validation.md", md, error);
  g_string_free (csv, TRUE);
  g_string_free (md, TRUE);
  return ok;
}

int
ds_ctl_validate (int argc, char **argv)
{
  g_auto (GStrv) scene_files = NULL;
  g_autofree char *out = NULL, *targets = NULL, *budgets = NULL, *model_path = NULL, *configs = NULL;
  gboolean uncalibrated = FALSE, simulated = FALSE, fixed_period = FALSE, shipped = FALSE, fit = FALSE, quiet = FALSE,
           saturation_known = FALSE;
  gint generate = 0, generator = DS_SCENE_GENERATOR_LATEST;
  gint64 seed = 1;
  GOptionEntry entries[] = {
    { "scene", 's', 0, G_OPTION_ARG_FILENAME_ARRAY, &scene_files, "Scene file (repeat)", "FILE" },
    { "shipped", 0, 0, G_OPTION_ARG_NONE, &shipped, "The example scenes (etc/scenes)", NULL },
    { "generate", 0, 0, G_OPTION_ARG_INT, &generate, "Also K generated scenes (never fitted to)", "K" },
    { "seed", 0, 0, G_OPTION_ARG_INT64, &seed, "Generator and noise seed (default 1)", "S" },
    { "generator", 0, 0, G_OPTION_ARG_INT, &generator, "Version of the scene generator (default 2; 1: the draw of the records' seeds 1 to 24)", "V" },
    { "targets", 0, 0, G_OPTION_ARG_STRING, &targets, "Target errors requested (default 0.03,0.1,0.3; none)", "LIST" },
    { "budgets", 0, 0, G_OPTION_ARG_STRING, &budgets, "Time budgets requested alone, ms (default 60; none)", "LIST" },
    { "configs", 0, 0, G_OPTION_ARG_STRING, &configs, "Also these fixed configurations, ESTIMATOR:N:M:EXPOSURE-FACTOR,...", "LIST" },
    { "fit", 0, 0, G_OPTION_ARG_NONE, &fit, "Fit the prediction's scale leave-one-scene-out on the given (not generated) scenes; write OUT/operating-model.conf", NULL },
    { "model", 0, 0, G_OPTION_ARG_FILENAME, &model_path, "Operating model (default: the installed one)", "FILE" },
    { "uncalibrated", 0, 0, G_OPTION_ARG_NONE, &uncalibrated, "The rig has no calibrated harmonic gain", NULL },
    { "simulated", 0, 0, G_OPTION_ARG_NONE, &simulated, "The rig knows the simulated illuminator as descatterd --sim does (its exact geometry, not a calibration)", NULL },
    { "fixed-period", 0, 0, G_OPTION_ARG_NONE, &fixed_period, "The illuminator cannot change its period", NULL },
    { "saturation-known", 0, 0, G_OPTION_ARG_NONE, &saturation_known, "The rig is configured with the sensor's clip level ([camera] saturation-dn)", NULL },
    { "out", 'o', 0, G_OPTION_ARG_FILENAME, &out, "Output folder (default validation/)", "DIR" },
    { "quiet", 'q', 0, G_OPTION_ARG_NONE, &quiet, "No progress", NULL },
    { NULL },
  };
  g_autoptr (GOptionContext) ctx = g_option_context_new (NULL);
  g_option_context_set_summary (ctx, "The automatic operating point against the simulator's truth: predicted "
                                     "against achieved error on the given and on generated scenes "
                                     "(docs/accuracy.md). Writes OUT/validation.csv and OUT/validation.md.");
  g_option_context_add_main_entries (ctx, entries, NULL);
  ds_ctl_describe_globals (ctx);
  g_autoptr (GError) error = NULL;
  if (!g_option_context_parse (ctx, &argc, &argv, &error)) {
    fprintf (stderr, "descatterctl validate: %s\n", error->message);
    return 2;
  }
  Plan plan = { .options = { .calibrated = !uncalibrated && !simulated, .simulated = simulated, .fixed_period = fixed_period,
                             .saturation_known = saturation_known, .seed = (guint64) seed },
                .quiet = quiet };
  ds_rig_timing_init (&plan.timing);
  g_autofree double *t_list = NULL, *b_list = NULL;
  if (!parse_list (targets ? targets : "0.03,0.1,0.3", &t_list, &plan.n_targets) ||
      !parse_list (budgets ? budgets : "60", &b_list, &plan.n_budgets) || generate < 0) {
    fprintf (stderr, "descatterctl validate: --targets/--budgets take comma-separated positive numbers\n");
    return 2;
  }
  if (generator < DS_SCENE_GENERATOR_OLDEST || generator > DS_SCENE_GENERATOR_LATEST) {
    fprintf (stderr, "descatterctl validate: --generator %d: there are versions %d to %d\n", generator,
             DS_SCENE_GENERATOR_OLDEST, DS_SCENE_GENERATOR_LATEST);
    return 2;
  }
  plan.targets = t_list;
  plan.budgets = b_list;
  g_autofree Config *c_list = NULL;
  if (!parse_configs (configs, &c_list, &plan.n_configs))
    return 2;
  plan.configs = c_list;
  g_autofree char *default_model = ds_data_path ("operating-model.conf");
  if (fit)
    ds_operating_model_init (&plan.model);
  else {
    g_autoptr (DsOperatingModel) m = ds_operating_model_load (model_path ? model_path : default_model, &error);
    if (!m) {
      fprintf (stderr, "descatterctl validate: %s\n", error->message);
      return 1;
    }
    plan.model = *m;
  }
  const char *dir = out ? out : "validation";
  g_autofree char *scene_dir = g_build_filename (dir, "scenes", NULL);
  if (g_mkdir_with_parents (scene_dir, 0755) != 0) {
    fprintf (stderr, "descatterctl validate: cannot create %s\n", scene_dir);
    return 1;
  }
  g_autoptr (GPtrArray) runs = g_ptr_array_new_with_free_func ((GDestroyNotify) scene_run_free);
  guint n_given = 0;
  if (!collect_scenes (runs, scene_files, shipped, generate, seed, (guint) generator, scene_dir, &n_given))
    return 1;
  if (runs->len == 0) {
    fprintf (stderr, "descatterctl validate: no scenes (--scene, --shipped, --generate)\n");
    return 2;
  }
  /* Pass 1: the given scenes with the model as it is (scale 1 when fitting). */
  for (guint i = 0; i < n_given; i++)
    if (!run_scene (g_ptr_array_index (runs, i), &plan, &plan.model, &error)) {
      fprintf (stderr, "descatterctl validate: %s\n", error->message);
      return 1;
    }
  if (fit && !fit_model (runs, n_given, &plan, dir, &error)) {
    fprintf (stderr, "descatterctl validate: %s\n", error->message);
    return 1;
  }
  for (guint i = n_given; i < runs->len; i++)
    if (!run_scene (g_ptr_array_index (runs, i), &plan, &plan.model, &error)) {
      fprintf (stderr, "descatterctl validate: %s\n", error->message);
      return 1;
    }
  if (!write_reports (runs, n_given, generate, &plan, fit, seed, dir, &error)) {
    fprintf (stderr, "descatterctl validate: %s\n", error->message);
    return 1;
  }
  if (!quiet)
    fprintf (stderr, "validate: %u scenes; %s/validation.md\n", runs->len, dir);
  return 0;
}

int
ds_ctl_generate_scenes (int argc, char **argv)
{
  g_autofree char *out = NULL;
  gint count = 1, generator = DS_SCENE_GENERATOR_LATEST;
  gint64 seed = 1;
  GOptionEntry entries[] = {
    { "count", 0, 0, G_OPTION_ARG_INT, &count, "How many (default 1)", "K" },
    { "seed", 0, 0, G_OPTION_ARG_INT64, &seed, "Seed (default 1)", "S" },
    { "generator", 0, 0, G_OPTION_ARG_INT, &generator, "Version of the draw (default 2; 1: the draw of the records' seeds 1 to 24)", "V" },
    { "out", 'o', 0, G_OPTION_ARG_FILENAME, &out, "Output folder (default .)", "DIR" },
    { NULL },
  };
  g_autoptr (GOptionContext) ctx = g_option_context_new (NULL);
  g_option_context_set_summary (ctx, "Random scene files (docs/scene-format.md) for validation: medium, g, "
                                     "thickness, pattern, duty, black level, period, blur, objects, ambient "
                                     "light and sensor drawn from wide ranges; the same generator version and "
                                     "seed give the same scenes.");
  g_option_context_add_main_entries (ctx, entries, NULL);
  ds_ctl_describe_globals (ctx);
  g_autoptr (GError) error = NULL;
  if (!g_option_context_parse (ctx, &argc, &argv, &error) || count < 1) {
    fprintf (stderr, "descatterctl generate-scenes: %s\n", error ? error->message : "--count must be >= 1");
    return 2;
  }
  if (generator < DS_SCENE_GENERATOR_OLDEST || generator > DS_SCENE_GENERATOR_LATEST) {
    fprintf (stderr, "descatterctl generate-scenes: --generator %d: there are versions %d to %d\n", generator,
             DS_SCENE_GENERATOR_OLDEST, DS_SCENE_GENERATOR_LATEST);
    return 2;
  }
  const char *dir = out ? out : ".";
  if (g_mkdir_with_parents (dir, 0755) != 0) {
    fprintf (stderr, "descatterctl generate-scenes: cannot create %s\n", dir);
    return 1;
  }
  for (gint i = 0; i < count; i++) {
    g_autofree char *text = ds_scene_generate ((guint64) seed, (guint) i, (guint) generator, &error);
    g_autofree char *path = g_strdup_printf ("%s/gen-%" G_GINT64_FORMAT "-%02d.scene", dir, seed, i);
    if (!text || !g_file_set_contents (path, text, -1, &error)) {
      fprintf (stderr, "descatterctl generate-scenes: %s\n", error->message);
      return 1;
    }
    printf ("%s\n", path);
  }
  return 0;
}
