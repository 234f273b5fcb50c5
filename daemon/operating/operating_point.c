#include "daemon/operating/operating_point.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "daemon/protocol/protocol.h"

static const DsEstimator all_estimators[] = { DS_ESTIMATOR_MAXMIN, DS_ESTIMATOR_SINE, DS_ESTIMATOR_ROBUST };

void
ds_operating_model_init (DsOperatingModel *m)
{
  static const guint phases[] = { 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64 };
  static const guint averages[] = { 1, 2, 4, 8, 16 };
  static const double factors[] = { 0.25, 0.5, 1, 2, 4 };
  memset (m, 0, sizeof *m);
  m->scale = 1.0;
  m->n_phases = G_N_ELEMENTS (phases);
  memcpy (m->phases, phases, sizeof phases);
  m->n_averages = G_N_ELEMENTS (averages);
  memcpy (m->averages, averages, sizeof averages);
  m->n_exposure_factors = G_N_ELEMENTS (factors);
  memcpy (m->exposure_factors, factors, sizeof factors);
  g_strlcpy (m->fitted_on, "nothing (built-in)", sizeof m->fitted_on);
}

#define GROUP "operating-model"

static gboolean
load_uints (GKeyFile *kf, const char *path, const char *key, guint lo, guint hi, guint *out, guint *n,
            GError **error)
{
  if (!g_key_file_has_key (kf, GROUP, key, NULL))
    return TRUE;
  gsize len = 0;
  g_autoptr (GError) e = NULL;
  g_autofree gint *v = g_key_file_get_integer_list (kf, GROUP, key, &len, &e);
  if (!v || len == 0 || len > DS_OPERATING_MAX_CANDIDATES) {
    g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_INVALID_VALUE,
                 "%s: [" GROUP "] %s: 1 to %u integers separated by ';' expected", path, key,
                 DS_OPERATING_MAX_CANDIDATES);
    return FALSE;
  }
  for (gsize i = 0; i < len; i++) {
    if (v[i] < (gint) lo || v[i] > (gint) hi) {
      g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_INVALID_VALUE,
                   "%s: [" GROUP "] %s: %d is outside [%u, %u]", path, key, v[i], lo, hi);
      return FALSE;
    }
    out[i] = (guint) v[i];
  }
  *n = (guint) len;
  return TRUE;
}

void
ds_operating_model_free (DsOperatingModel *m)
{
  g_free (m);
}

static gboolean load_into (DsOperatingModel *m, const char *path, GError **error);

DsOperatingModel *
ds_operating_model_load (const char *path, GError **error)
{
  g_autoptr (DsOperatingModel) m = g_new0 (DsOperatingModel, 1);
  if (!load_into (m, path, error))
    return NULL;
  return g_steal_pointer (&m);
}

static gboolean
load_into (DsOperatingModel *m, const char *path, GError **error)
{
  ds_operating_model_init (m);
  g_autoptr (GKeyFile) kf = g_key_file_new ();
  if (!g_key_file_load_from_file (kf, path, G_KEY_FILE_NONE, error)) {
    g_prefix_error (error, "operating model %s: ", path);
    return FALSE;
  }
  if (!g_key_file_has_group (kf, GROUP)) {
    g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_GROUP_NOT_FOUND,
                 "%s: no [" GROUP "] group (an operating model from before the error model? "
                 "regenerate it with `descatterctl validate --fit`)", path);
    return FALSE;
  }
  g_auto (GStrv) keys = g_key_file_get_keys (kf, GROUP, NULL, NULL);
  static const char *const known[] = { "scale", "phases", "averages", "exposure-factors", "fitted-on", NULL };
  for (guint i = 0; keys && keys[i]; i++)
    if (!g_strv_contains (known, keys[i])) {
      g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_KEY_NOT_FOUND,
                   "%s: [" GROUP "] unknown key %s (known: scale, phases, averages, exposure-factors, fitted-on)",
                   path, keys[i]);
      return FALSE;
    }
  if (g_key_file_has_key (kf, GROUP, "scale", NULL)) {
    g_autoptr (GError) e = NULL;
    double v = g_key_file_get_double (kf, GROUP, "scale", &e);
    if (e || !(v >= 0.5 && v <= 2.0)) {
      g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_INVALID_VALUE,
                   "%s: [" GROUP "] scale: a number in [0.5, 2] expected", path);
      return FALSE;
    }
    m->scale = v;
  }
  if (!load_uints (kf, path, "phases", 2, DS_MAX_PHASES, m->phases, &m->n_phases, error) ||
      !load_uints (kf, path, "averages", 1, DS_MAX_PHASES, m->averages, &m->n_averages, error))
    return FALSE;
  if (g_key_file_has_key (kf, GROUP, "exposure-factors", NULL)) {
    gsize len = 0;
    g_autoptr (GError) e = NULL;
    g_autofree double *v = g_key_file_get_double_list (kf, GROUP, "exposure-factors", &len, &e);
    gboolean ok = v && len > 0 && len <= DS_OPERATING_MAX_CANDIDATES;
    for (gsize i = 0; ok && i < len; i++)
      ok = v[i] > 0 && v[i] <= 1000;
    if (!ok) {
      g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_INVALID_VALUE,
                   "%s: [" GROUP "] exposure-factors: 1 to %u numbers in (0, 1000] separated by ';' expected",
                   path, DS_OPERATING_MAX_CANDIDATES);
      return FALSE;
    }
    memcpy (m->exposure_factors, v, len * sizeof *v);
    m->n_exposure_factors = (guint) len;
  }
  g_autofree char *fitted = g_key_file_get_string (kf, GROUP, "fitted-on", NULL);
  if (fitted)
    g_strlcpy (m->fitted_on, fitted, sizeof m->fitted_on);
  return TRUE;
}

gboolean
ds_operating_model_write (const DsOperatingModel *m, const char *path, GError **error)
{
  g_autoptr (GKeyFile) kf = g_key_file_new ();
  gint phases[DS_OPERATING_MAX_CANDIDATES], averages[DS_OPERATING_MAX_CANDIDATES];
  for (guint i = 0; i < m->n_phases; i++)
    phases[i] = (gint) m->phases[i];
  for (guint i = 0; i < m->n_averages; i++)
    averages[i] = (gint) m->averages[i];
  g_key_file_set_double (kf, GROUP, "scale", m->scale);
  g_key_file_set_integer_list (kf, GROUP, "phases", phases, m->n_phases);
  g_key_file_set_integer_list (kf, GROUP, "averages", averages, m->n_averages);
  g_key_file_set_double_list (kf, GROUP, "exposure-factors", (double *) m->exposure_factors,
                              m->n_exposure_factors);
  g_key_file_set_string (kf, GROUP, "fitted-on", m->fitted_on);
  g_key_file_set_comment (kf, NULL, NULL,
                          " descatter operating model (docs/accuracy.md): the candidates the automatic\n"
                          " operating point searches, and the scale its predictions are multiplied by.\n"
                          " Written by `descatterctl validate --fit`.",
                          NULL);
  g_autofree char *text = g_key_file_to_data (kf, NULL, NULL);
  return g_file_set_contents_full (path, text, -1,
                                   G_FILE_SET_CONTENTS_CONSISTENT | G_FILE_SET_CONTENTS_DURABLE, 0644, error);
}

double
ds_scene_probe_max_exposure (const DsSceneProbe *p)
{
  if (!(p->saturation_dn > 0) || !(p->bright_dn > 0))
    return 16 * p->exposure_us;
  double room = 0.9 * p->saturation_dn - p->dark_dn;
  return room > 0 ? p->exposure_us * room / p->bright_dn : 0;
}

static gboolean
predict (const DsOperatingModel *m, DsErrorModel *errors, const DsSceneProbe *probe, const DsRigTiming *t,
         guint w, guint h, DsEstimator e, guint n, guint mm, double factor, double period,
         DsOperatingPoint *p)
{
  memset (p, 0, sizeof *p);
  if (!ds_error_model_predict (errors, e, n, mm, factor, period, &p->parts, NULL))
    return FALSE;
  p->estimator = e;
  p->phases = n;
  p->averages = mm;
  p->exposure_us = probe->exposure_us * factor;
  p->period_px = period > 0 ? period : probe->geometry.period_px;
  p->predicted_error = m->scale * p->parts.total;
  p->predicted_time_ms = ds_rig_timing_set_ms (t, w, h, n, mm, p->exposure_us, TRUE);
  p->lower_bound = !probe->leak_measured || probe->blur_source == DS_BLUR_ASSUMED_SHARP;
  return TRUE;
}

typedef struct {
  gboolean found;
  DsOperatingPoint p;
} Best;

/* The rule: with a target, the fastest point meeting it (ties: the more accurate); otherwise the
 * most accurate (ties: the faster). */
static void
consider (Best *b, const DsOperatingPoint *p, double target)
{
  gboolean better;
  if (!b->found)
    better = TRUE;
  else if (target > 0)
    better = p->predicted_time_ms < b->p.predicted_time_ms ||
             (p->predicted_time_ms == b->p.predicted_time_ms && p->predicted_error < b->p.predicted_error);
  else
    better = p->predicted_error < b->p.predicted_error ||
             (p->predicted_error == b->p.predicted_error && p->predicted_time_ms < b->p.predicted_time_ms);
  if (better) {
    b->p = *p;
    b->found = TRUE;
  }
}

/* The exposure factors that keep the brightest pixels below the clip level; when none does,
 * the largest exposure that does. */
static guint
usable_factors (const DsOperatingModel *m, const DsSceneProbe *probe, double *out)
{
  double max_f = ds_scene_probe_max_exposure (probe) / probe->exposure_us;
  guint n = 0;
  for (guint i = 0; i < m->n_exposure_factors; i++)
    if (m->exposure_factors[i] <= max_f * (1 + 1e-9))
      out[n++] = m->exposure_factors[i];
  if (n == 0 && max_f > 0)
    out[n++] = max_f;
  return n;
}

typedef struct {
  Best in_budget_meeting;   /* the choice */
  Best least_in_budget;     /* the most accurate within the budget */
  Best meeting_any_time;    /* the fastest meeting the target, whatever the budget */
} Search;

static void
search (const DsOperatingModel *m, DsErrorModel *errors, const DsSceneProbe *probe, const DsRigTiming *t,
        guint w, guint h, const guint *phases, guint n_phases, const guint *averages, guint n_averages,
        const double *factors, guint n_factors, double period, double target, double budget, Search *s)
{
  for (guint ie = 0; ie < G_N_ELEMENTS (all_estimators); ie++)
    for (guint in = 0; in < n_phases; in++)
      for (guint im = 0; im < n_averages; im++)
        for (guint iff = 0; iff < n_factors; iff++) {
          DsOperatingPoint p;
          if (!predict (m, errors, probe, t, w, h, all_estimators[ie], phases[in], averages[im], factors[iff],
                        period, &p))
            continue;
          gboolean in_budget = budget <= 0 || p.predicted_time_ms <= budget;
          gboolean meets = target <= 0 || p.predicted_error <= target;
          if (in_budget)
            consider (&s->least_in_budget, &p, 0);
          if (meets)
            consider (&s->meeting_any_time, &p, 1);
          if (in_budget && meets)
            consider (&s->in_budget_meeting, &p, target);
        }
}

static void
append_point (GString *s, const DsOperatingPoint *p)
{
  g_string_append_printf (s, "%.4f (%s, N=%u, M=%u, %.0f µs", p->predicted_error, ds_estimator_name (p->estimator),
                          p->phases, p->averages, p->exposure_us);
  g_string_append_printf (s, ", period %g px: %.0f ms; noise %.4f, sampling %.4f, scattered stripes %+.4f)",
                          p->period_px, p->predicted_time_ms, p->parts.noise, p->parts.sampling,
                          p->parts.scattered_stripes);
}

gboolean
ds_operating_point_choose (const DsOperatingModel *m, DsErrorModel *errors, const DsSceneProbe *probe,
                           const DsRigTiming *t, guint w, guint h, double target, double budget,
                           DsOperatingPoint *out, GError **error)
{
  double factors[DS_OPERATING_MAX_CANDIDATES];
  guint n_factors = usable_factors (m, probe, factors);
  Search s = { 0 };
  search (m, errors, probe, t, w, h, m->phases, m->n_phases, m->averages, m->n_averages, factors, n_factors,
          0, target, budget, &s);
  if (s.in_budget_meeting.found) {
    *out = s.in_budget_meeting.p;
    return TRUE;
  }
  *out = s.least_in_budget.p;
  if (!s.least_in_budget.found)
    out->predicted_error = INFINITY;
  GString *msg = g_string_new (NULL);
  if (target > 0)
    g_string_append_printf (msg, "no operating point reaches a relative error of %.4f", target);
  else
    g_string_append (msg, "no operating point");
  if (budget > 0)
    g_string_append_printf (msg, " within %.0f ms", budget);
  if (s.least_in_budget.found) {
    g_string_append (msg, "; the best reachable is ");
    append_point (msg, &s.least_in_budget.p);
    if (s.least_in_budget.p.lower_bound)
      g_string_append (msg, ", a lower bound");
  } else
    g_string_append_printf (msg, "; the fastest candidate does not fit a budget of %.0f ms", budget);
  if (target > 0 && s.meeting_any_time.found) {
    g_string_append_printf (msg, ". A time budget of %.0f ms would reach it: ", ceil (s.meeting_any_time.p.predicted_time_ms));
    append_point (msg, &s.meeting_any_time.p);
  } else if (target > 0) {
    /* What else would: more frames than the candidates hold, then more light (which the clip
     * level may forbid), then another stripe period. */
    static const guint more_m[] = { 32, 64 };
    static const double more_f[] = { 8, 16 };
    Search more = { 0 };
    search (m, errors, probe, t, w, h, m->phases, m->n_phases, more_m, G_N_ELEMENTS (more_m), factors, n_factors,
            0, target, 0, &more);
    if (!more.meeting_any_time.found)
      search (m, errors, probe, t, w, h, m->phases, m->n_phases, m->averages, m->n_averages, more_f,
              G_N_ELEMENTS (more_f), 0, target, 0, &more);
    if (more.meeting_any_time.found) {
      g_string_append (msg, ". More frames or light would reach it: ");
      append_point (msg, &more.meeting_any_time.p);
      if (more.meeting_any_time.p.exposure_us > ds_scene_probe_max_exposure (probe))
        g_string_append_printf (msg, ", but exposures above %.0f µs clip the brightest pixels: "
                                     "more illumination or a lower gain",
                                ds_scene_probe_max_exposure (probe));
    }
    static const double period_factors[] = { 0.5, 0.67, 0.75, 1.5, 2 };
    Best other = { 0 };
    for (guint i = 0; i < G_N_ELEMENTS (period_factors); i++) {
      double q = probe->geometry.period_px * period_factors[i];
      if (q < 3)
        continue;
      Search ps = { 0 };
      search (m, errors, probe, t, w, h, m->phases, m->n_phases, m->averages, m->n_averages, factors, n_factors, q,
              target, budget, &ps);
      if (ps.in_budget_meeting.found)
        consider (&other, &ps.in_budget_meeting.p, 1);
    }
    if (other.found) {
      g_string_append_printf (msg, ". A stripe period of %g px would reach it: ", other.p.period_px);
      append_point (msg, &other.p);
    } else if (!more.meeting_any_time.found)
      g_string_append (msg, ". Neither more time, more light nor another stripe period reaches it");
    if (!probe->leak_measured)
      g_string_append_printf (msg, " (scattered light that keeps the stripes: %s)", probe->leak_note);
  }
  g_set_error_literal (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT, msg->str);
  g_string_free (msg, TRUE);
  return FALSE;
}

void
ds_operating_report_to_json (const DsOperatingReport *r, JsonBuilder *b)
{
#define DBL(k, v) (json_builder_set_member_name (b, k), json_builder_add_double_value (b, v))
#define STR(k, v) (json_builder_set_member_name (b, k), json_builder_add_string_value (b, v))
#define BOOL(k, v) (json_builder_set_member_name (b, k), json_builder_add_boolean_value (b, v))
  const DsOperatingPoint *p = &r->point;
  const DsSceneProbe *pr = &r->probe;
  DBL ("target_error", r->target_error);
  DBL ("time_budget_ms", r->time_budget_ms);
  DBL ("predicted_error", p->predicted_error);
  DBL ("predicted_time_ms", p->predicted_time_ms);
  DBL ("scale", r->scale);
  json_builder_set_member_name (b, "parts");
  json_builder_begin_object (b);
  DBL ("noise", p->parts.noise);
  DBL ("systematic", p->parts.systematic);
  DBL ("sampling", p->parts.sampling);
  DBL ("scattered_stripes", p->parts.scattered_stripes);
  json_builder_end_object (b);
  /* What the prediction contains: noise and the pattern's sampling always; the blur when it was
   * calibrated or measured; the scattered stripes when measured at two periods. Saturated
   * pixels are excluded from the error (and from the result's valid pixels), never chosen into. */
  json_builder_set_member_name (b, "contains");
  json_builder_begin_array (b);
  json_builder_add_string_value (b, "noise");
  json_builder_add_string_value (b, "sampling");
  if (pr->blur_source != DS_BLUR_ASSUMED_SHARP)
    json_builder_add_string_value (b, "blur");
  if (pr->leak_measured)
    json_builder_add_string_value (b, "scattered_stripes");
  json_builder_add_string_value (b, "saturation");
  json_builder_end_array (b);
  BOOL ("lower_bound", p->lower_bound);
  json_builder_set_member_name (b, "lower_bound_reasons");
  json_builder_begin_array (b);
  if (!pr->leak_measured)
    json_builder_add_string_value (b, pr->leak_note);
  if (pr->blur_source == DS_BLUR_ASSUMED_SHARP)
    json_builder_add_string_value (b, "stripe blur neither calibrated nor measurable from the pilot frames: "
                                      "assumed sharp");
  json_builder_end_array (b);
  json_builder_set_member_name (b, "scene");
  json_builder_begin_object (b);
  DBL ("direct_dn", pr->ld_mean);
  DBL ("direct_spread", pr->ld_spread);
  DBL ("scattered_dn", pr->lg_mean);
  DBL ("noise_dn", sqrt (pr->noise_var0 + pr->noise_gain * (pr->ld_mean + pr->lg_mean)));
  DBL ("blur_px", pr->geometry.blur_px);
  STR ("blur_source", ds_blur_source_name (pr->blur_source));
  DBL ("scattered_stripes_at_period", ds_scene_probe_leak (pr, pr->geometry.period_px, 1));
  STR ("scattered_stripes_note", pr->leak_note);
  DBL ("clip_dn", pr->saturation_dn);
  DBL ("saturated_fraction", pr->saturated_fraction);
  DBL ("exposure_us", pr->exposure_us);
  json_builder_end_object (b);
  json_builder_set_member_name (b, "pilot_frames");
  json_builder_add_int_value (b, r->pilot_frames);
  DBL ("pilot_ms", r->pilot_ms);
#undef DBL
#undef STR
#undef BOOL
}
