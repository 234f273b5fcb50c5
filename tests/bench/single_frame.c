/* Benchmark: the single-frame estimator (ds_single_frame_separate_into, maxmin and sine, one
 * frame into pooled planes as descatterd runs it) against one fold (ds_phase_set_accumulate of
 * one frame into a maxmin phase set), both measured in the same run on the same frames, on
 * as many threads each (1 and 2), for u8 and u16 frames at 1 MP and 4 MP. Goal (issue 37):
 * single-frame / fold <= 1.
 * Each repetition times the fold (frames 1..N-1 of a set, per frame) and each estimator once,
 * in turn, so that on a shared machine they see the same load; each figure is the best of R.
 * It prints times and ratios and asserts no timing.
 * It checks its results (exit status 1 on a mismatch): two threads give the bits of one, and
 * sampled rows of each result equal a direct per-pixel reference (max and min scanned over
 * the pixel's window; the sine fit by solving the window's normal equations in double).
 *
 *   bench_single_frame [--quick] [--reps R] [--period P] [--size WxH]
 * Full run (docs/benchmarks.md): build/tests/bench/bench_single_frame */
#include <glib.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proc/separation.h"
#include "proc/single_frame.h"

#define N_FOLD 8u

static double
now (void)
{
  return g_get_monotonic_time () / 1e6;
}

/* Frames as the rig makes them: stripes of period P on a smooth scene, with noise; under the
 * type's full scale, so that nothing is saturated. */
static DsImage *
make_frame (DsSampleType type, guint w, guint h, double period, guint phase, guint64 *state)
{
  DsImage *img = ds_image_new (type, w, h, NULL);
  double full = type == DS_SAMPLE_U8 ? 250 : 4000;
  img->bit_depth = type == DS_SAMPLE_U8 ? 8 : 12;
  for (guint y = 0; y < h; y++) {
    void *row = ds_image_row (img, y);
    for (guint x = 0; x < w; x++) {
      *state = *state * 6364136223846793005ull + 1442695040888963407ull;
      double scene = 0.5 + 0.3 * sin (x * 0.003 + y * 0.002);
      double lit = fmod (x + phase * period / N_FOLD, period) < period / 2 ? 1 : 0.1;
      double v = full * scene * (0.3 + 0.6 * lit) + (double) (*state >> 59) - 16;
      v = CLAMP (v, 0, full);
      if (type == DS_SAMPLE_U8)
        ((guint8 *) row)[x] = (guint8) v;
      else
        ((guint16 *) row)[x] = (guint16) v;
    }
  }
  return img;
}

static double
sample (const DsImage *img, guint x, guint y)
{
  const void *row = ds_image_row (img, y);
  return img->type == DS_SAMPLE_U8 ? ((const guint8 *) row)[x] : ((const guint16 *) row)[x];
}

/* The result at pixel (x, y) from its window alone, in double: Ld and Lg. */
static void
reference (const DsImage *f, guint x, guint y, DsEstimator e, double period, double b, double m, double hg,
           double out[2])
{
  guint l = ds_single_frame_window_px (period), s = x >= l / 2 ? x - l / 2 : 0;
  s = MIN (s, f->width - l);
  if (e == DS_ESTIMATOR_MAXMIN) {
    double mx = -INFINITY, mn = INFINITY;
    for (guint j = s; j < s + l; j++) {
      mx = fmax (mx, sample (f, j, y));
      mn = fmin (mn, sample (f, j, y));
    }
    out[0] = (mx - mn) / (1 - b);
    out[1] = (mn - b * out[0]) / m;
    return;
  }
  /* normal equations of M + a cos + b sin, by Gauss-Jordan */
  double a[3][4] = { { 0 } };
  for (guint j = s; j < s + l; j++) {
    double u = 2 * G_PI * fmod (j, period) / period, basis[3] = { 1, cos (u), sin (u) }, v = sample (f, j, y);
    for (guint i = 0; i < 3; i++) {
      for (guint k = 0; k < 3; k++)
        a[i][k] += basis[i] * basis[k];
      a[i][3] += basis[i] * v;
    }
  }
  for (guint i = 0; i < 3; i++) {
    double p = a[i][i];
    for (guint k = 0; k < 4; k++)
      a[i][k] /= p;
    for (guint r = 0; r < 3; r++)
      if (r != i) {
        double q = a[r][i];
        for (guint k = 0; k < 4; k++)
          a[r][k] -= q * a[i][k];
      }
  }
  out[0] = hypot (a[1][3], a[2][3]) / hg;
  out[1] = a[0][3] / m - out[0];
}

static gboolean
check_rows (const DsImage *f, const DsSeparation *sep, DsEstimator e, double period)
{
  guint rows[] = { 0, f->height / 2, f->height - 1 };
  guint64 bad = 0;
  for (guint i = 0; i < G_N_ELEMENTS (rows); i++) {
    guint y = rows[i];
    const float *t = ds_image_row (sep->transmissive, y), *g = ds_image_row (sep->scattered, y);
    for (guint x = 0; x < f->width; x++) {
      double want[2];
      reference (f, x, y, e, period, sep->meta.black_level, sep->meta.pattern_mean, sep->meta.harmonic_gain, want);
      /* float arithmetic on sums of at most 16 samples of at most 4095 */
      double tol = 1e-3 * (1 + fabs (want[0]) + fabs (want[1]));
      if (fabs (t[x] - want[0]) > tol || fabs (g[x] - want[1]) > tol) {
        if (bad++ == 0)
          fprintf (stderr, "%s pixel (%u, %u): %g %g, the reference %g %g\n", ds_estimator_name (e), x, y, t[x],
                   g[x], want[0], want[1]);
      }
    }
  }
  return bad == 0;
}

static gboolean
same_bits (const DsSeparation *a, const DsSeparation *b)
{
  guint h = a->transmissive->height, w = a->transmissive->width;
  for (guint y = 0; y < h; y++)
    if (memcmp (ds_image_row (a->transmissive, y), ds_image_row (b->transmissive, y), w * 4) ||
        memcmp (ds_image_row (a->scattered, y), ds_image_row (b->scattered, y), w * 4) ||
        memcmp (ds_image_row (a->mask, y), ds_image_row (b->mask, y), w))
      return FALSE;
  return TRUE;
}

static gboolean
run_case (DsSampleType type, guint w, guint h, guint reps, double period)
{
  guint64 state = 0x9E3779B97F4A7C15ull;
  DsImage *frames[N_FOLD];
  for (guint k = 0; k < N_FOLD; k++)
    frames[k] = make_frame (type, w, h, period, k, &state);
  gboolean ok = TRUE;
  printf ("\n%ux%u %s, P = %g, best of %u\n", w, h, ds_sample_type_name (type), period, reps);
  DsSeparation *first[2] = { NULL, NULL }; /* each estimator's result on one thread */
  for (guint threads = 1; threads <= 2; threads++) {
    DsSeparationParams p;
    ds_separation_params_init (&p, N_FOLD);
    p.threads = threads;
    g_autoptr (GError) error = NULL;
    g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, &error);
    DsSingleFrame *sf[2] = { NULL, NULL };
    DsSeparation *sep[2] = { ds_separation_new (), ds_separation_new () };
    for (guint i = 0; set && i < 2; i++) {
      DsSeparationParams sp = p;
      sp.estimator = i == 0 ? DS_ESTIMATOR_MAXMIN : DS_ESTIMATOR_SINE;
      sp.geometry.period_px = period;
      sf[i] = ds_single_frame_new (&sp, w, h, &error);
      if (!sf[i])
        break;
    }
    double fold = INFINITY, single[2] = { INFINITY, INFINITY }, floor_ = INFINITY;
    g_autofree guint8 *floor_bytes = g_malloc0 ((gsize) w * h * 9);
    for (guint r = 0; !error && r <= reps; r++) {
      ds_phase_set_reset (set);
      if (!ds_phase_set_accumulate (set, 0, frames[0], &error))
        break;
      double t0 = now ();
      for (guint k = 1; k < N_FOLD && !error; k++)
        ds_phase_set_accumulate (set, k, frames[k], &error);
      double t1 = now ();
      for (guint i = 0; i < 2 && !error; i++) {
        double s0 = now ();
        if (ds_single_frame_separate_into (sf[i], frames[0], NULL, sep[i], &error) && r > 0)
          single[i] = MIN (single[i], now () - s0); /* the first faults the pooled planes in */
      }
      /* the floor: writing the bytes of a result (two float planes and the mask), one thread */
      double f0 = now ();
      memset (floor_bytes, (int) r, (gsize) w * h * 9);
      double f1 = now ();
      if (r > 0) {
        fold = MIN (fold, (t1 - t0) / (N_FOLD - 1));
        floor_ = MIN (floor_, f1 - f0);
      }
    }
    if (error) {
      fprintf (stderr, "%s\n", error->message);
      ok = FALSE;
    } else if (threads == 1) {
      printf ("  (writing a result's 9 bytes per pixel alone, memset on 1 thread: %.3f ms, %.2fx one fold)\n",
              floor_ * 1e3, floor_ / fold);
    }
    for (guint i = 0; i < 2 && ok; i++) {
      DsEstimator e = i == 0 ? DS_ESTIMATOR_MAXMIN : DS_ESTIMATOR_SINE;
      printf ("  %u thread%s  fold %7.3f ms  single-frame %-6s %7.3f ms  %5.2fx one fold (target <= 1)\n",
              threads, threads > 1 ? "s" : " ", fold * 1e3, ds_estimator_name (e), single[i] * 1e3,
              single[i] / fold);
      if (threads == 1) {
        if (!check_rows (frames[0], sep[i], e, period))
          ok = FALSE;
        first[i] = g_steal_pointer (&sep[i]);
      } else if (!same_bits (first[i], sep[i])) {
        fprintf (stderr, "%s: 2 threads differ from 1\n", ds_estimator_name (e));
        ok = FALSE;
      }
    }
    for (guint i = 0; i < 2; i++) {
      g_clear_pointer (&sf[i], ds_single_frame_free);
      g_clear_pointer (&sep[i], ds_separation_free);
    }
  }
  for (guint i = 0; i < 2; i++)
    g_clear_pointer (&first[i], ds_separation_free);
  for (guint k = 0; k < N_FOLD; k++)
    ds_image_free (frames[k]);
  return ok;
}

int
main (int argc, char **argv)
{
  gboolean quick = FALSE;
  gint reps = 7;
  double period = 16;
  g_autofree char *size = NULL;
  GOptionEntry entries[] = {
    { "quick", 0, 0, G_OPTION_ARG_NONE, &quick, "one small frame per type, 2 repetitions (ctest)", NULL },
    { "reps", 0, 0, G_OPTION_ARG_INT, &reps, "repetitions (best of)", "R" },
    { "period", 0, 0, G_OPTION_ARG_DOUBLE, &period, "stripe period in pixels", "P" },
    { "size", 0, 0, G_OPTION_ARG_STRING, &size, "one frame size instead of 1 MP and 4 MP", "WxH" },
    { NULL },
  };
  g_autoptr (GOptionContext) ctx = g_option_context_new ("- single-frame estimator against one fold");
  g_option_context_add_main_entries (ctx, entries, NULL);
  g_autoptr (GError) error = NULL;
  if (!g_option_context_parse (ctx, &argc, &argv, &error) || reps < 1 || !(period >= 3 && period <= 256)) {
    fprintf (stderr, "%s\n", error ? error->message : "--reps >= 1, --period in [3, 256]");
    return 2;
  }
  if (quick)
    reps = 2;
  guint sizes[][2] = { { 1024, 1024 }, { 2048, 2048 } }, quick_size[2] = { 640, 400 }, n_sizes = 2;
  if (size) {
    if (sscanf (size, "%ux%u", &sizes[0][0], &sizes[0][1]) != 2 || sizes[0][0] < 256 || sizes[0][1] < 4) {
      fprintf (stderr, "--size WxH, W >= 256, H >= 4\n");
      return 2;
    }
    n_sizes = 1;
  }
  gboolean ok = TRUE;
  for (guint s = 0; s < (quick ? 1u : n_sizes); s++)
    for (guint t = 0; t < 2; t++) {
      const guint *sz = quick ? quick_size : sizes[s];
      ok = run_case (t == 0 ? DS_SAMPLE_U8 : DS_SAMPLE_U16, sz[0], sz[1], (guint) reps, period) && ok;
    }
  printf ("\nresults checked: %s\n", ok ? "all correct" : "MISMATCH");
  return ok ? 0 : 1;
}
