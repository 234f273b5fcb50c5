/* `descatterctl study`: the accuracy-versus-time sweep (docs/accuracy.md). Writes
 * OUT/study.csv (one row per point) and OUT/pareto.md (per scene: the points no other point
 * beats in both acquisition time and transmissive error, seeds averaged, clipped points flagged;
 * and the best error at each stripe period with its noise and systematic parts) and the figures
 * drawn from the CSV (study_figures.h: error against time with the front marked, against the
 * stripe period and against N, the example previews labelled; PNG and SVG). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <glib/gstdio.h>

#include "daemon/ctl/ctl_commands.h"
#include "daemon/ctl/ctl_progress.h"
#include "daemon/ctl/csv.h"
#include "daemon/ctl/study.h"
#include "daemon/ctl/study_figures.h"
#include "daemon/operating/data_dir.h"

typedef struct {
  FILE *csv;
  GArray *points;   /* DsStudyPoint (scene pointer not kept: index into names) */
  GPtrArray *names;
  guint done;
  DsCtlProgress *progress; /* one item per rendered set: (scene, exposure, N, M, seed) */
  const char *last_scene;
  DsStudyPoint last;
} StudyOut;

/* The noise part of an error whose systematic part is known: what noise adds in quadrature (0
 * when noise's bias cancels part of the systematic error instead). */
static double
noise_part (double total, double systematic)
{
  if (!isfinite (total) || !isfinite (systematic))
    return NAN;
  return sqrt (MAX (0.0, total * total - systematic * systematic));
}

/* A relative error against a truth of zero (the scattered image of a scene without scattering)
 * is no number: "nan" in the CSV, "–" in tables. */
static const char *
md_err (char *buf, gsize n, double total, double systematic)
{
  if (!isfinite (total) || !isfinite (systematic))
    return "–";
  g_snprintf (buf, n, "%.4f (%.4f + %.4f)", total, noise_part (total, systematic), systematic);
  return buf;
}

/* Kept for the fronts, its scene name owned by o->names. */
static DsStudyPoint
remember_point (StudyOut *o, const DsStudyPoint *p)
{
  DsStudyPoint copy = *p;
  guint idx = 0;
  while (idx < o->names->len && strcmp (g_ptr_array_index (o->names, idx), p->scene) != 0)
    idx++;
  if (idx == o->names->len)
    g_ptr_array_add (o->names, g_strdup (p->scene));
  copy.scene = g_ptr_array_index (o->names, idx);
  g_array_append_val (o->points, copy);
  o->done++;
  return copy;
}

static void
on_point (const DsStudyPoint *p, gpointer data)
{
  StudyOut *o = data;
  /* The scene is a file name, which may hold a comma or a quote: written quoted (RFC 4180).
   * Non-finite (a truth of zero) reads back as nan in every CSV reader. */
  g_autoptr (GString) row = g_string_new (NULL);
  ds_csv_append_field (row, p->scene);
  g_string_append_c (row, ',');
  ds_csv_append_field (row, ds_estimator_name (p->estimator));
#define F(v) (isfinite (v) ? (v) : NAN)
  g_string_append_printf (row, ",%u,%u,%g,%g,%.1f,%" G_GUINT64_FORMAT ",%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%" G_GUINT64_FORMAT ",%" G_GUINT64_FORMAT ",%" G_GUINT64_FORMAT ",%.3f,%.3f,%.2f,%.5f,%d,%g\n",
                          p->phases, p->averages, p->period_px, p->exposure_factor,
                          p->exposure_us, p->seed, F (p->rel_rmse_transmissive), F (p->rel_rmse_scattered),
                          F (p->systematic_transmissive), F (p->systematic_scattered),
                          F (noise_part (p->rel_rmse_transmissive, p->systematic_transmissive)),
                          F (noise_part (p->rel_rmse_scattered, p->systematic_scattered)), p->stripe_residue, p->valid,
                          p->masked, p->saturated, p->acquisition_ms, p->compute_ms, p->signal_dn, p->direct_fraction,
                          p->edge_blur_known ? 1 : 0, p->speed_px_s);
#undef F
  /* status and reason: a configuration that cannot separate the scene says so and why. */
  g_string_truncate (row, row->len - 1);
  g_string_append_c (row, ',');
  ds_csv_append_field (row, p->status ? p->status : "ok");
  g_string_append_c (row, ',');
  ds_csv_append_field (row, p->reason ? p->reason : "");
  g_string_append_c (row, '\n');
  fputs (row->str, o->csv);
  fflush (o->csv);
  if (p->status && strcmp (p->status, "ok") != 0) {
    o->done++; /* no error to rank: not among the fronts */
    return;
  }
  DsStudyPoint copy = remember_point (o, p);
  /* A set's points (one per estimator) come together once the set is done: the first of them
   * marks the set's end. Its cost is its frame count. */
  if (copy.scene != o->last_scene || p->phases != o->last.phases || p->averages != o->last.averages ||
      p->exposure_factor != o->last.exposure_factor || p->seed != o->last.seed || p->period_px != o->last.period_px ||
      p->speed_px_s != o->last.speed_px_s) {
    g_autofree char *extra = g_strdup_printf ("%u points", o->done);
    ds_ctl_progress_advance (o->progress, (double) p->phases * p->averages, extra);
  }
  o->last_scene = copy.scene;
  o->last = *p;
}

typedef struct {
  const char *scene;
  DsEstimator estimator;
  guint phases, averages;
  double period, exposure_factor, speed;
  double err_t, err_g, sys_t, sys_g, residue, time_ms;
  guint64 saturated, pixels;
  gboolean blur_unknown; /* some seed's sets ran without the edge blur (the precondition refused it) */
  guint n;
} Aggregate;

static int
compare_time (const void *a, const void *b)
{
  const Aggregate *x = a, *y = b;
  if (x->time_ms != y->time_ms)
    return x->time_ms < y->time_ms ? -1 : 1;
  return x->err_t < y->err_t ? -1 : x->err_t > y->err_t;
}

/* The scene's points at one speed, seeds averaged, one aggregate per configuration. */
static GArray *
aggregate (const StudyOut *o, const char *scene, double speed)
{
  GArray *agg = g_array_new (FALSE, TRUE, sizeof (Aggregate));
  for (guint i = 0; i < o->points->len; i++) {
    const DsStudyPoint *p = &g_array_index (o->points, DsStudyPoint, i);
    if (p->scene != scene || p->speed_px_s != speed)
      continue;
    guint j = 0;
    for (; j < agg->len; j++) {
      Aggregate *a = &g_array_index (agg, Aggregate, j);
      if (a->estimator == p->estimator && a->phases == p->phases && a->averages == p->averages &&
          a->exposure_factor == p->exposure_factor && a->period == p->period_px)
        break;
    }
    if (j == agg->len) {
      Aggregate a = { .scene = scene, .estimator = p->estimator, .phases = p->phases, .averages = p->averages,
                      .period = p->period_px, .exposure_factor = p->exposure_factor, .speed = p->speed_px_s,
                      .time_ms = p->acquisition_ms,
                      .sys_t = p->systematic_transmissive, .sys_g = p->systematic_scattered,
                      .pixels = p->valid + p->masked };
      g_array_append_val (agg, a);
    }
    Aggregate *a = &g_array_index (agg, Aggregate, j);
    a->err_t += p->rel_rmse_transmissive;
    a->err_g += p->rel_rmse_scattered;
    a->residue += p->stripe_residue;
    a->saturated = MAX (a->saturated, p->saturated);
    a->blur_unknown = a->blur_unknown || !p->edge_blur_known;
    a->n++;
  }
  for (guint j = 0; j < agg->len; j++) {
    Aggregate *a = &g_array_index (agg, Aggregate, j);
    a->err_t /= a->n;
    a->err_g /= a->n;
    a->residue /= a->n;
  }
  g_array_sort (agg, compare_time);
  return agg;
}

static void
append_row (GString *md, const Aggregate *a)
{
  char t[64], g[64];
  g_string_append_printf (md, "| %s%s | %u | %u | %g | %g× | %.1f | %s | %s | %.4f |", ds_estimator_name (a->estimator),
                          a->blur_unknown ? " †" : "", a->phases, a->averages, a->period, a->exposure_factor, a->time_ms,
                          md_err (t, sizeof t, a->err_t, a->sys_t), md_err (g, sizeof g, a->err_g, a->sys_g),
                          a->residue);
  /* A clipped point's error leaves its saturated pixels out: it is not comparable with the
   * others, and says so wherever it appears. */
  if (a->saturated)
    g_string_append_printf (md, " **clipped**: %" G_GUINT64_FORMAT " px (%.1f %%) excluded |\n", a->saturated,
                            a->pixels ? 100.0 * a->saturated / a->pixels : 0);
  else
    g_string_append (md, " |\n");
}

static gint
compare_double (gconstpointer a, gconstpointer b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return (x > y) - (x < y);
}

static gboolean
write_pareto (StudyOut *o, const char *path, GError **error)
{
  GString *md = g_string_new ("# Pareto fronts: acquisition time against transmissive error\n\n"
                              "Made by `descatterctl study`; seeds averaged. A point is on the front when no other "
                              "point is both faster and more accurate. Errors are relative RMSEs against the "
                              "simulator's truth, written total (noise part + systematic part): the systematic part "
                              "is the same configuration on noise-free frames, the noise part what noise adds in "
                              "quadrature (0 where max/min's noise bias cancels part of the systematic error). "
                              "Points whose frames clip are flagged **clipped** in the last column: their error "
                              "leaves the clipped pixels out, so they are not comparable with the others. The sets "
                              "know the scene's edge blur, as descatterd's with `[illuminator] edge-blur-px`; † "
                              "marks a point whose configuration the sampling precondition refuses with the blur "
                              "known (no pixel fully lit in one phase and fully dark in another), run with the "
                              "period alone (the blur unknown), as descatterd runs it without edge-blur-px: its "
                              "error includes the pixels the precondition would refuse.\n");
  /* One section per scene and speed: a moving scene's front is its own (its error is against
   * the truth at each set's middle). */
  g_autoptr (GArray) sections = g_array_new (FALSE, FALSE, sizeof (DsStudyPoint));
  for (guint i = 0; i < o->points->len; i++) {
    const DsStudyPoint *p = &g_array_index (o->points, DsStudyPoint, i);
    gboolean seen = FALSE;
    for (guint k = 0; k < sections->len && !seen; k++) {
      const DsStudyPoint *q = &g_array_index (sections, DsStudyPoint, k);
      seen = q->scene == p->scene && q->speed_px_s == p->speed_px_s;
    }
    if (!seen)
      g_array_append_val (sections, *p);
  }
  for (guint s = 0; s < sections->len; s++) {
    const DsStudyPoint *sec = &g_array_index (sections, DsStudyPoint, s);
    const char *scene = sec->scene;
    GArray *agg = aggregate (o, scene, sec->speed_px_s);
    g_autofree char *moving = sec->speed_px_s > 0 ? g_strdup_printf (", objects moving at %g px/s", sec->speed_px_s)
                                                  : g_strdup ("");
    g_string_append_printf (md, "\n## %s%s\n\n| estimator | N | M | period (px) | exposure | time (ms) | transmissive "
                                "(noise + systematic) | scattered (noise + systematic) | stripe residue | |\n"
                                "|---|---|---|---|---|---|---|---|---|---|\n", scene, moving);
    double best = INFINITY;
    for (guint j = 0; j < agg->len; j++) {
      Aggregate *a = &g_array_index (agg, Aggregate, j);
      if (a->err_t >= best)
        continue;
      best = a->err_t;
      append_row (md, a);
    }
    /* Which period this medium needs: the best configuration at each period, and the best
     * within 100 ms. */
    g_string_append (md, "\nBest at each stripe period:\n\n| estimator | N | M | period (px) | exposure | time (ms) | "
                         "transmissive (noise + systematic) | scattered (noise + systematic) | stripe residue | |\n"
                         "|---|---|---|---|---|---|---|---|---|---|\n");
    GArray *periods = g_array_new (FALSE, FALSE, sizeof (double));
    for (guint j = 0; j < agg->len; j++) {
      double p = g_array_index (agg, Aggregate, j).period;
      gboolean seen = FALSE;
      for (guint k = 0; k < periods->len && !seen; k++)
        seen = g_array_index (periods, double, k) == p;
      if (!seen)
        g_array_append_val (periods, p);
    }
    g_array_sort (periods, (GCompareFunc) compare_double);
    for (guint k = 0; k < periods->len; k++) {
      const Aggregate *bst = NULL;
      for (guint j = 0; j < agg->len; j++) {
        const Aggregate *a = &g_array_index (agg, Aggregate, j);
        if (a->period == g_array_index (periods, double, k) && (!bst || a->err_t < bst->err_t))
          bst = a;
      }
      if (bst)
        append_row (md, bst);
    }
    g_array_unref (periods);
    g_array_unref (agg);
  }
  gboolean ok = g_file_set_contents_full (path, md->str, -1, G_FILE_SET_CONTENTS_CONSISTENT, 0644, error);
  g_string_free (md, TRUE);
  return ok;
}

/* A point as on_point wrote it into study.csv (columns by name): for --fronts-from, which
 * writes pareto.md from an earlier run's CSV without running the sweep again. */
static gboolean
point_from_csv (GStrv header, GStrv cells, DsStudyPoint *p, const char **bad_column)
{
  static const char *const wanted[] = { "scene", "estimator", "phases", "averages", "period_px", "exposure_factor",
                                        "exposure_us", "seed", "rel_rmse_transmissive", "rel_rmse_scattered",
                                        "systematic_transmissive", "systematic_scattered", "stripe_residue", "valid",
                                        "masked", "saturated", "acquisition_ms", "edge_blur_known" };
  memset (p, 0, sizeof *p);
  for (guint w = 0; w < G_N_ELEMENTS (wanted); w++) {
    const char *v = NULL;
    for (guint i = 0; header[i] && !v; i++)
      if (strcmp (header[i], wanted[w]) == 0)
        v = i < g_strv_length (cells) ? cells[i] : NULL;
    *bad_column = wanted[w];
    if (!v || !*v)
      return FALSE;
    char *end = NULL;
    double d = g_ascii_strtod (v, &end);
    gboolean number = end && *end == '\0';
    switch (w) {
    case 0: p->scene = v; continue;
    case 1: if (!ds_estimator_from_name (v, &p->estimator)) return FALSE; continue;
    default: if (!number) return FALSE; break;
    }
    switch (w) {
    case 2: p->phases = (guint) d; break;
    case 3: p->averages = (guint) d; break;
    case 4: p->period_px = d; break;
    case 5: p->exposure_factor = d; break;
    case 6: p->exposure_us = d; break;
    case 7: p->seed = (guint64) d; break;
    case 8: p->rel_rmse_transmissive = d; break;
    case 9: p->rel_rmse_scattered = d; break;
    case 10: p->systematic_transmissive = d; break;
    case 11: p->systematic_scattered = d; break;
    case 12: p->stripe_residue = d; break;
    case 13: p->valid = (guint64) d; break;
    case 14: p->masked = (guint64) d; break;
    case 15: p->saturated = (guint64) d; break;
    case 16: p->acquisition_ms = d; break;
    case 17: p->edge_blur_known = d != 0; break;
    }
  }
  /* Optional: a study.csv written before the speed axis is of still scenes. */
  for (guint i = 0; header[i]; i++)
    if (strcmp (header[i], "speed_px_s") == 0 && i < g_strv_length (cells)) {
      char *end = NULL;
      p->speed_px_s = g_ascii_strtod (cells[i], &end);
      *bad_column = "speed_px_s";
      if (!end || *end || !(p->speed_px_s >= 0))
        return FALSE;
    }
  return TRUE;
}

static gboolean
load_csv (StudyOut *o, const char *path, GError **error)
{
  g_autofree char *text = NULL;
  if (!g_file_get_contents (path, &text, NULL, error))
    return FALSE;
  g_autoptr (GArray) records = ds_csv_parse (text, path, error);
  if (!records)
    return FALSE;
  GStrv header = records->len ? g_array_index (records, DsCsvRecord, 0).fields : NULL;
  for (guint i = 1; i < records->len; i++) {
    const DsCsvRecord *r = &g_array_index (records, DsCsvRecord, i);
    /* Rows of configurations that could not separate the scene have no error to rank. */
    guint status_col = 0;
    while (header[status_col] && strcmp (header[status_col], "status") != 0)
      status_col++;
    if (header[status_col] && status_col < g_strv_length (r->fields) && strcmp (r->fields[status_col], "ok") != 0)
      continue;
    DsStudyPoint p;
    const char *bad = NULL;
    if (!point_from_csv (header, r->fields, &p, &bad)) {
      g_set_error (error, G_FILE_ERROR, G_FILE_ERROR_INVAL,
                   "%s:%u: column %s is missing or not a %s (a study.csv written by descatterctl study)", path,
                   r->line, bad ? bad : "?", bad && strcmp (bad, "estimator") == 0 ? "known estimator" : "number");
      return FALSE;
    }
    /* remember_point copies the scene name: the record's cells may go. */
    remember_point (o, &p);
  }
  if (o->points->len == 0) {
    g_set_error (error, G_FILE_ERROR, G_FILE_ERROR_INVAL, "%s: no points", path);
    return FALSE;
  }
  return TRUE;
}

/* descatterctl study --fronts-from CSV --out DIR: pareto.md (and the figures) again from a
 * study's points. */
static int
fronts_from (const char *csv_path, const char *dir, gboolean figures)
{
  g_autoptr (GError) error = NULL;
  StudyOut o = { .points = g_array_new (FALSE, FALSE, sizeof (DsStudyPoint)),
                 .names = g_ptr_array_new_with_free_func (g_free) };
  g_autofree char *md = g_build_filename (dir, "pareto.md", NULL);
  gboolean ok = load_csv (&o, csv_path, &error);
  if (ok && g_mkdir_with_parents (dir, 0755) != 0) {
    int e = errno;
    g_set_error (&error, G_FILE_ERROR, g_file_error_from_errno (e), "%s: %s", dir, g_strerror (e));
    ok = FALSE;
  }
  ok = ok && write_pareto (&o, md, &error) && (!figures || ds_study_draw_figures (csv_path, dir, &error));
  if (!ok)
    fprintf (stderr, "descatterctl study: %s\n", error->message);
  else
    fprintf (stderr, "study: fronts of %u points from %s in %s\n", o.done, csv_path, md);
  g_array_unref (o.points);
  g_ptr_array_unref (o.names);
  return ok ? 0 : 1;
}

static gboolean
parse_uint_list (const char *text, guint **out, guint *n)
{
  g_auto (GStrv) parts = g_strsplit (text, ",", -1);
  *n = g_strv_length (parts);
  *out = g_new0 (guint, *n);
  for (guint i = 0; i < *n; i++) {
    guint64 v;
    if (!g_ascii_string_to_unsigned (parts[i], 10, 1, 1024, &v, NULL))
      return FALSE;
    (*out)[i] = (guint) v;
  }
  return *n > 0;
}

static gboolean
parse_double_list (const char *text, double **out, guint *n)
{
  g_auto (GStrv) parts = g_strsplit (text, ",", -1);
  *n = g_strv_length (parts);
  *out = g_new0 (double, *n);
  for (guint i = 0; i < *n; i++) {
    char *end = NULL;
    (*out)[i] = g_ascii_strtod (parts[i], &end);
    if (!end || *end || !((*out)[i] > 0))
      return FALSE;
  }
  return *n > 0;
}

/* Speeds in px/s: 0 (still) up to the scene format's limit. */
static gboolean
parse_speed_list (const char *text, double **out, guint *n)
{
  g_auto (GStrv) parts = g_strsplit (text, ",", -1);
  *n = g_strv_length (parts);
  *out = g_new0 (double, MAX (*n, 1u));
  for (guint i = 0; i < *n; i++) {
    char *end = NULL;
    (*out)[i] = g_ascii_strtod (parts[i], &end);
    if (!end || end == parts[i] || *end || !((*out)[i] >= 0 && (*out)[i] <= 1e6))
      return FALSE;
  }
  return *n > 0;
}

/* The stripe periods and object speeds of the plan (their lists stay owned by the caller). */
static gboolean
plan_axes (DsStudyPlan *plan, const char *periods, const char *speeds, const char *moving_object, double **p_out,
           double **v_out)
{
  g_auto (GStrv) period_items = g_strsplit (periods, ",", -1);
  double *p_list = *p_out = g_new0 (double, g_strv_length (period_items) + 1);
  for (guint i = 0; period_items[i]; i++) {
    const char *t = period_items[i];
    char *end = NULL;
    double v = strcmp (t, "scene") == 0 ? 0 : t[0] == 'x' ? -g_ascii_strtod (t + 1, &end) : g_ascii_strtod (t, &end);
    if (strcmp (t, "scene") != 0 && (!end || *end || !(fabs (v) > 0) || (v > 0 && v < 2))) {
      fprintf (stderr, "descatterctl study: --periods: \"%s\" is not a period >= 2 px, xF or scene\n", t);
      return FALSE;
    }
    p_list[plan->n_periods++] = v;
  }
  plan->periods = p_list;
  if (speeds && !parse_speed_list (speeds, v_out, &plan->n_speeds)) {
    fprintf (stderr, "descatterctl study: --speeds takes comma-separated speeds in px/s, each in [0, 1e6]\n");
    return FALSE;
  }
  if (moving_object && !speeds) {
    fprintf (stderr, "descatterctl study: --moving names the object --speeds moves: give --speeds\n");
    return FALSE;
  }
  plan->speeds = *v_out;
  plan->moving_object = moving_object;
  return TRUE;
}

/* g_ptr_array_sort hands the comparison pointers to the elements, not the elements. */
static gint
compare_paths (gconstpointer a, gconstpointer b)
{
  return g_strcmp0 (*(char *const *) a, *(char *const *) b);
}

int
ds_ctl_study (int argc, char **argv)
{
  g_autofree char *out = NULL, *fronts_csv = NULL, *phases = NULL, *averages = NULL, *exposures = NULL,
                  *estimators = NULL, *periods = NULL, *speeds = NULL, *moving_object = NULL;
  g_auto (GStrv) scenes = NULL;
  int seeds = 0;
  gboolean quick = FALSE, quiet = FALSE, no_figures = FALSE;
  DsStudyPlan plan = { 0 };
  ds_rig_timing_init (&plan.timing);
  GOptionEntry entries[] = {
    { "scene", 's', 0, G_OPTION_ARG_FILENAME_ARRAY, &scenes, "Scene file (repeat; default: every etc/scenes/*.scene)", "FILE" },
    { "out", 'o', 0, G_OPTION_ARG_FILENAME, &out, "Output folder (default study/)", "DIR" },
    { "phases", 0, 0, G_OPTION_ARG_STRING, &phases, "N values (default 2,3,4,6,8,12,16,24,32)", "LIST" },
    { "averages", 0, 0, G_OPTION_ARG_STRING, &averages, "M values (default 1,2,4,8)", "LIST" },
    { "exposures", 0, 0, G_OPTION_ARG_STRING, &exposures, "exposure factors of the scene's base (default 1,2,4)", "LIST" },
    { "periods", 0, 0, G_OPTION_ARG_STRING, &periods, "stripe periods: px, xF (F times the scene's) or scene (default scene,4,6,8,12,16,24)", "LIST" },
    { "estimators", 0, 0, G_OPTION_ARG_STRING, &estimators, "default maxmin,sine,robust", "LIST" },
    { "seeds", 0, 0, G_OPTION_ARG_INT, &seeds, "noise seeds per point (default 3)", "K" },
    { "speeds", 0, 0, G_OPTION_ARG_STRING, &speeds, "object speeds in px/s across the stripes, e.g. 0,50,200 (default: as the scene declares)", "LIST" },
    { "moving", 0, 0, G_OPTION_ARG_STRING, &moving_object, "the [object.NAME] --speeds moves (default: every object but masks)", "NAME" },
    { "quick", 0, 0, G_OPTION_ARG_NONE, &quick, "Reduced sweep (CI): N 4,8; M 1,2; exposure 1; periods scene,x2; 1 seed", NULL },
    { "settle-ms", 0, 0, G_OPTION_ARG_DOUBLE, &plan.timing.settle_ms, "illuminator settle time (default 3)", "MS" },
    { "trigger-us", 0, 0, G_OPTION_ARG_DOUBLE, &plan.timing.trigger_overhead_us, "trigger overhead (default 200)", "US" },
    { "link-mbit", 0, 0, G_OPTION_ARG_DOUBLE, &plan.timing.link_mbit_s, "camera link (default 1000)", "MBIT" },
    { "quiet", 'q', 0, G_OPTION_ARG_NONE, &quiet, "No progress", NULL },
    { "fronts-from", 0, 0, G_OPTION_ARG_FILENAME, &fronts_csv, "Write OUT/pareto.md and the figures from an earlier run's study.csv (no sweep)", "CSV" },
    { "no-figures", 0, 0, G_OPTION_ARG_NONE, &no_figures, "Write no figures (they need python3-matplotlib)", NULL },
    { NULL },
  };
  g_autoptr (GOptionContext) ctx = g_option_context_new (NULL);
  g_option_context_set_summary (ctx, "Sweeps estimator, N, M, exposure, stripe period and seeds over simulated "
                                     "scenes; writes study.csv, pareto.md and the figures, PNG and SVG (docs/accuracy.md, "
                                     "docs/operations.md).");
  g_option_context_add_main_entries (ctx, entries, NULL);
  ds_ctl_describe_globals (ctx);
  g_autoptr (GError) error = NULL;
  if (!g_option_context_parse (ctx, &argc, &argv, &error)) {
    fprintf (stderr, "descatterctl study: %s\n", error->message);
    return 2;
  }
  if (fronts_csv)
    return fronts_from (fronts_csv, out ? out : "study", !no_figures);
  const char *def_n = quick ? "4,8" : "2,3,4,6,8,12,16,24,32";
  const char *def_m = quick ? "1,2" : "1,2,4,8";
  const char *def_e = quick ? "1" : "1,2,4";
  g_autofree guint *n_list = NULL, *m_list = NULL;
  g_autofree double *e_list = NULL;
  if (!parse_uint_list (phases ? phases : def_n, &n_list, &plan.n_phases) ||
      !parse_uint_list (averages ? averages : def_m, &m_list, &plan.n_averages) ||
      !parse_double_list (exposures ? exposures : def_e, &e_list, &plan.n_exposures)) {
    fprintf (stderr, "descatterctl study: --phases/--averages/--exposures take comma-separated positive numbers\n");
    return 2;
  }
  plan.phases = n_list;
  plan.averages = m_list;
  plan.exposure_factors = e_list;
  g_autofree double *p_list = NULL;
  g_autofree double *v_list = NULL;
  if (!plan_axes (&plan, periods ? periods : quick ? "scene,x2" : "scene,4,6,8,12,16,24", speeds, moving_object,
                  &p_list, &v_list))
    return 2;
  plan.n_seeds = seeds > 0 ? (guint) seeds : quick ? 1 : 3;
  plan.dark_frame = TRUE;
  g_auto (GStrv) est_names = g_strsplit (estimators ? estimators : "maxmin,sine,robust", ",", -1);
  DsEstimator est[4];
  plan.n_estimators = 0;
  for (guint i = 0; est_names[i] && plan.n_estimators < 4; i++)
    if (!ds_estimator_from_name (est_names[i], &est[plan.n_estimators++])) {
      fprintf (stderr, "descatterctl study: unknown estimator \"%s\"\n", est_names[i]);
      return 2;
    }
  plan.estimators = est;
  g_autoptr (GPtrArray) files = g_ptr_array_new_with_free_func (g_free);
  if (scenes)
    for (guint i = 0; scenes[i]; i++)
      g_ptr_array_add (files, g_strdup (scenes[i]));
  else {
    g_autofree char *scene_dir = ds_data_path ("scenes");
    g_autoptr (GDir) dir = g_dir_open (scene_dir, 0, &error);
    if (!dir) {
      fprintf (stderr, "descatterctl study: %s (give --scene)\n", error->message);
      return 1;
    }
    const char *name;
    while ((name = g_dir_read_name (dir)))
      if (g_str_has_suffix (name, ".scene") && !strstr (name, "1024"))
        g_ptr_array_add (files, g_build_filename (scene_dir, name, NULL));
    g_ptr_array_sort (files, compare_paths);
  }
  const char *dir = out ? out : "study";
  g_mkdir_with_parents (dir, 0755);
  g_autofree char *examples = g_build_filename (dir, "examples", NULL);
  g_mkdir_with_parents (examples, 0755);
  plan.examples_dir = examples;
  g_autofree char *csv_path = g_build_filename (dir, "study.csv", NULL);
  g_autofree char *tmp_path = g_strconcat (csv_path, ".tmp", NULL);
  guint sum_n = 0, sum_m = 0;
  for (guint i = 0; i < plan.n_phases; i++)
    sum_n += plan.phases[i];
  for (guint i = 0; i < plan.n_averages; i++)
    sum_m += plan.averages[i];
  guint n_speeds = MAX (plan.n_speeds, 1u);
  guint n_sets = files->len * n_speeds * plan.n_periods * plan.n_exposures * plan.n_phases * plan.n_averages *
                 plan.n_seeds;
  double frames = (double) files->len * n_speeds * plan.n_periods * plan.n_exposures * plan.n_seeds * sum_n * sum_m;
  g_autoptr (DsCtlProgress) progress = ds_ctl_progress_new ("study", "sets", n_sets, frames, quiet);
  StudyOut o = { .csv = fopen (tmp_path, "w"), .points = g_array_new (FALSE, FALSE, sizeof (DsStudyPoint)),
                 .names = g_ptr_array_new_with_free_func (g_free), .progress = progress };
  if (!o.csv) {
    fprintf (stderr, "descatterctl study: cannot write %s\n", tmp_path);
    return 1;
  }
  fprintf (o.csv, "scene,estimator,phases,averages,period_px,exposure_factor,exposure_us,seed,rel_rmse_transmissive,"
                  "rel_rmse_scattered,systematic_transmissive,systematic_scattered,noise_transmissive,noise_scattered,"
                  "stripe_residue,valid,masked,saturated,acquisition_ms,compute_ms,signal_dn,direct_fraction,edge_blur_known,"
                  "speed_px_s,status,reason\n");
  int status = 0;
  for (guint i = 0; i < files->len && status == 0; i++)
    if (!ds_study_run_scene (g_ptr_array_index (files, i), &plan, on_point, &o, &error))
      status = 1;
  g_clear_pointer (&progress, ds_ctl_progress_free); /* ends the progress line */
  o.progress = NULL;
  if (status != 0)
    fprintf (stderr, "descatterctl study: %s\n", error->message);
  /* The CSV appears whole or not at all. */
  if (fclose (o.csv) != 0 || (status == 0 && g_rename (tmp_path, csv_path) != 0))
    status = 1;
  if (status == 0) {
    g_autofree char *md = g_build_filename (dir, "pareto.md", NULL);
    if (!write_pareto (&o, md, &error) || (!no_figures && !ds_study_draw_figures (csv_path, dir, &error))) {
      fprintf (stderr, "descatterctl study: %s\n", error->message);
      status = 1;
    } else if (!quiet)
      fprintf (stderr, "study: %u points in %s, fronts in %s%s\n", o.done, csv_path, md,
               no_figures ? "" : ", figures (PNG, SVG) beside them");
  } else
    g_unlink (tmp_path);
  g_array_unref (o.points);
  g_ptr_array_unref (o.names);
  return status;
}
