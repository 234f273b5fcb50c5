/* The operating model file (operating_point.h): the candidates the automatic operating point
 * searches and the scale its predictions are multiplied by. */
#include "daemon/operating/operating_point.h"

#include <string.h>

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
  static const char *const known[] = { "scale", "scale-spread", "phases", "averages", "exposure-factors", "fitted-on",
                                       NULL };
  for (guint i = 0; keys && keys[i]; i++)
    if (!g_strv_contains (known, keys[i])) {
      g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_KEY_NOT_FOUND,
                   "%s: [" GROUP "] unknown key %s (known: scale, scale-spread, phases, averages, exposure-factors, "
                   "fitted-on)",
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
  if (g_key_file_has_key (kf, GROUP, "scale-spread", NULL)) {
    g_autoptr (GError) e = NULL;
    double v = g_key_file_get_double (kf, GROUP, "scale-spread", &e);
    if (e || !(v >= 0 && v <= 1)) {
      g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_INVALID_VALUE,
                   "%s: [" GROUP "] scale-spread: a number in [0, 1] expected", path);
      return FALSE;
    }
    m->scale_spread = v;
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
  g_key_file_set_double (kf, GROUP, "scale-spread", m->scale_spread);
  g_key_file_set_integer_list (kf, GROUP, "phases", phases, m->n_phases);
  g_key_file_set_integer_list (kf, GROUP, "averages", averages, m->n_averages);
  g_key_file_set_double_list (kf, GROUP, "exposure-factors", (double *) m->exposure_factors,
                              m->n_exposure_factors);
  g_key_file_set_string (kf, GROUP, "fitted-on", m->fitted_on);
  g_key_file_set_comment (kf, NULL, NULL,
                          " descatter operating model (docs/accuracy.md): the candidates the automatic\n"
                          " operating point searches, the scale its predictions are multiplied by, and how far\n"
                          " they are off on a scene left out of the fit (scale-spread).\n"
                          " Written by `descatterctl validate --fit`.",
                          NULL);
  g_autofree char *text = g_key_file_to_data (kf, NULL, NULL);
  return g_file_set_contents_full (path, text, -1,
                                   G_FILE_SET_CONTENTS_CONSISTENT | G_FILE_SET_CONTENTS_DURABLE, 0644, error);
}

