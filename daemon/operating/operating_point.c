#include "daemon/operating/operating_point.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "daemon/protocol/protocol.h"
#include "proc/stripe_phase.h"

struct DsOperatingModel {
  GArray *rows; /* DsModelRow */
  double safety;
};

DsOperatingModel *
ds_operating_model_new (const DsModelRow *rows, guint n, double safety)
{
  DsOperatingModel *m = g_new0 (DsOperatingModel, 1);
  m->rows = g_array_sized_new (FALSE, FALSE, sizeof (DsModelRow), n);
  g_array_append_vals (m->rows, rows, n);
  m->safety = MAX (1.0, safety);
  return m;
}

void
ds_operating_model_free (DsOperatingModel *m)
{
  if (!m)
    return;
  g_array_unref (m->rows);
  g_free (m);
}

double
ds_operating_model_safety (const DsOperatingModel *m)
{
  return m->safety;
}

#define HEADER "scene,estimator,phases,averages,a,b,signal_dn,direct_fraction,base_exposure_us"

gboolean
ds_operating_model_write (const DsModelRow *rows, guint n, double safety, const char *path,
                          GError **error)
{
  GString *s = g_string_new (NULL);
  g_string_append_printf (s, "# descatter operating model (descatterctl study); safety=%.4f\n" HEADER "\n",
                          safety);
  for (guint i = 0; i < n; i++) {
    char a[G_ASCII_DTOSTR_BUF_SIZE], b[G_ASCII_DTOSTR_BUF_SIZE], sig[G_ASCII_DTOSTR_BUF_SIZE],
        f[G_ASCII_DTOSTR_BUF_SIZE], e[G_ASCII_DTOSTR_BUF_SIZE];
    g_string_append_printf (s, "%s,%s,%u,%u,%s,%s,%s,%s,%s\n", rows[i].scene,
                            ds_estimator_name (rows[i].estimator), rows[i].phases, rows[i].averages,
                            g_ascii_dtostr (a, sizeof a, rows[i].a), g_ascii_dtostr (b, sizeof b, rows[i].b),
                            g_ascii_dtostr (sig, sizeof sig, rows[i].signal_dn),
                            g_ascii_dtostr (f, sizeof f, rows[i].direct_fraction),
                            g_ascii_dtostr (e, sizeof e, rows[i].base_exposure_us));
  }
  gboolean ok = g_file_set_contents_full (path, s->str, (gssize) s->len,
                                          G_FILE_SET_CONTENTS_CONSISTENT | G_FILE_SET_CONTENTS_DURABLE,
                                          0644, error);
  g_string_free (s, TRUE);
  return ok;
}

static gboolean
parse_double (const char *text, double *out)
{
  char *end = NULL;
  errno = 0;
  *out = g_ascii_strtod (text, &end);
  return errno == 0 && end && end != text && *end == 0 && isfinite (*out);
}

DsOperatingModel *
ds_operating_model_load (const char *path, GError **error)
{
  g_autofree char *text = NULL;
  if (!g_file_get_contents (path, &text, NULL, error)) {
    g_prefix_error (error, "operating model: ");
    return NULL;
  }
  g_auto (GStrv) lines = g_strsplit (text, "\n", -1);
  g_autoptr (GArray) rows = g_array_new (FALSE, FALSE, sizeof (DsModelRow));
  double safety = 1.0;
  gboolean header = FALSE;
  for (guint i = 0; lines[i]; i++) {
    const char *l = lines[i];
    if (!*l)
      continue;
    if (l[0] == '#') {
      const char *p = strstr (l, "safety=");
      if (p && !parse_double (p + 7, &safety)) {
        g_set_error (error, G_FILE_ERROR, G_FILE_ERROR_INVAL, "%s:%u: bad safety factor", path, i + 1);
        return NULL;
      }
      continue;
    }
    if (!header) {
      if (strcmp (l, HEADER) != 0) {
        g_set_error (error, G_FILE_ERROR, G_FILE_ERROR_INVAL,
                     "%s:%u: expected the header \"" HEADER "\"", path, i + 1);
        return NULL;
      }
      header = TRUE;
      continue;
    }
    g_auto (GStrv) f = g_strsplit (l, ",", -1);
    DsModelRow r = { 0 };
    guint64 n, m;
    if (g_strv_length (f) != 9 || strlen (f[0]) >= sizeof r.scene ||
        !ds_estimator_from_name (f[1], &r.estimator) ||
        !g_ascii_string_to_unsigned (f[2], 10, 2, 1024, &n, NULL) ||
        !g_ascii_string_to_unsigned (f[3], 10, 1, 1024, &m, NULL) || !parse_double (f[4], &r.a) ||
        !parse_double (f[5], &r.b) || !parse_double (f[6], &r.signal_dn) ||
        !parse_double (f[7], &r.direct_fraction) || !parse_double (f[8], &r.base_exposure_us) ||
        r.a < 0 || r.b < 0 || r.signal_dn <= 0 || r.direct_fraction <= 0 || r.base_exposure_us <= 0) {
      g_set_error (error, G_FILE_ERROR, G_FILE_ERROR_INVAL,
                   "%s:%u: expected scene,estimator,N>=2,M>=1,a>=0,b>=0,signal>0,fraction>0,exposure>0",
                   path, i + 1);
      return NULL;
    }
    g_strlcpy (r.scene, f[0], sizeof r.scene);
    r.phases = (guint) n;
    r.averages = (guint) m;
    g_array_append_val (rows, r);
  }
  if (rows->len == 0) {
    g_set_error (error, G_FILE_ERROR, G_FILE_ERROR_INVAL, "%s: no model rows", path);
    return NULL;
  }
  return ds_operating_model_new ((const DsModelRow *) rows->data, rows->len, safety);
}

gboolean
ds_scene_stats_from_frame (const DsImage *frame, double dark_dn, double period_px, double pattern_mean,
                           double harmonic_gain, double exposure_us, DsSceneStats *out, GError **error)
{
  DsStripePhase sp;
  if (!ds_stripe_phase_measure (frame, period_px, NULL, &sp, error))
    return FALSE;
  double mean = sp.mean - dark_dn;
  if (!(mean > 0) || !(pattern_mean > 0) || !(harmonic_gain > 0)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_DEVICE,
                 "preview frame: no signal above the dark level (mean %.1f DN, dark %.1f DN)", sp.mean, dark_dn);
    return FALSE;
  }
  out->signal_dn = mean / pattern_mean;
  double ld = sp.amplitude / harmonic_gain;
  out->direct_fraction = CLAMP (ld / out->signal_dn, 0.001, 1.0);
  out->exposure_us = exposure_us;
  return TRUE;
}

/* The model rows of one configuration; the one whose scene is closest in direct fraction
 * (in log: fractions span decades in heavy scattering) gives the systematic part. */
static const DsModelRow *
closest_row (const DsOperatingModel *m, const DsSceneStats *st, DsEstimator est, guint n, guint mm)
{
  const DsModelRow *best = NULL;
  double best_d = INFINITY;
  for (guint i = 0; i < m->rows->len; i++) {
    const DsModelRow *r = &g_array_index (m->rows, DsModelRow, i);
    if (r->estimator != est || r->phases != n || r->averages != mm)
      continue;
    double d = fabs (log (r->direct_fraction / st->direct_fraction));
    if (d < best_d) {
      best_d = d;
      best = r;
    }
  }
  return best;
}

double
ds_operating_model_predict (const DsOperatingModel *m, const DsSceneStats *st, DsEstimator est,
                            guint n, guint mm, double exposure_us)
{
  const DsModelRow *r = closest_row (m, st, est, n, mm);
  if (!r)
    return INFINITY;
  double signal = st->signal_dn * exposure_us / st->exposure_us;
  double noise2 = r->a * (r->direct_fraction * r->direct_fraction * r->signal_dn) /
                  (st->direct_fraction * st->direct_fraction * signal);
  return m->safety * sqrt (noise2 + r->b);
}

gboolean
ds_operating_point_choose (const DsOperatingModel *m, const DsSceneStats *st, const DsRigTiming *timing,
                           guint width, guint height, double max_exposure_us, double target_error,
                           double time_budget_ms, DsOperatingPoint *out, GError **error)
{
  static const double factors[] = { 0.5, 1, 2, 4 };
  gboolean found = FALSE;
  DsOperatingPoint best = { 0 }, least_error = { .predicted_error = INFINITY };
  for (guint i = 0; i < m->rows->len; i++) {
    const DsModelRow *r = &g_array_index (m->rows, DsModelRow, i);
    /* Each configuration once (rows repeat it per study scene). */
    gboolean seen = FALSE;
    for (guint j = 0; j < i && !seen; j++) {
      const DsModelRow *q = &g_array_index (m->rows, DsModelRow, j);
      seen = q->estimator == r->estimator && q->phases == r->phases && q->averages == r->averages;
    }
    if (seen)
      continue;
    for (guint k = 0; k < G_N_ELEMENTS (factors); k++) {
      double e = MIN (st->exposure_us * factors[k], max_exposure_us);
      DsOperatingPoint p = { .estimator = r->estimator, .phases = r->phases, .averages = r->averages,
                             .exposure_us = e };
      p.predicted_error = ds_operating_model_predict (m, st, r->estimator, r->phases, r->averages, e);
      p.predicted_time_ms = ds_rig_timing_set_ms (timing, width, height, r->phases, r->averages, e, TRUE);
      gboolean in_budget = time_budget_ms <= 0 || p.predicted_time_ms <= time_budget_ms;
      if (in_budget && p.predicted_error < least_error.predicted_error)
        least_error = p;
      if (!in_budget || (target_error > 0 && p.predicted_error > target_error))
        continue;
      /* With a target: the fastest point meeting it. Budget only: the most accurate. */
      gboolean better = !found ||
                        (target_error > 0 ? p.predicted_time_ms < best.predicted_time_ms ||
                                                (p.predicted_time_ms == best.predicted_time_ms &&
                                                 p.predicted_error < best.predicted_error)
                                          : p.predicted_error < best.predicted_error);
      if (better) {
        best = p;
        found = TRUE;
      }
    }
  }
  if (!found) {
    if (isfinite (least_error.predicted_error))
      g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                   "no operating point reaches a relative error of %.4f within %.0f ms; the best "
                   "within the budget is %.4f (%s, N=%u, M=%u, %.0f µs: %.0f ms)",
                   target_error, time_budget_ms, least_error.predicted_error,
                   ds_estimator_name (least_error.estimator), least_error.phases,
                   least_error.averages, least_error.exposure_us, least_error.predicted_time_ms);
    else
      g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                   "no operating point fits a time budget of %.0f ms", time_budget_ms);
    return FALSE;
  }
  *out = best;
  return TRUE;
}
