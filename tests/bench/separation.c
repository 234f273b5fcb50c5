/* Benchmark: accumulate + finalize of N phases of SxS u16 frames on one thread, against
 * baselines measured in the same run: the straightforward numpy script
 * (tests/bench/separation_numpy.py, run as a subprocess), OpenCV's max/min/subtract path
 * (ds_cv_separate_maxmin_u16), and memcpy of the same input bytes. Prints times and ratios;
 * asserts no timing. It does check that our direct/global equal OpenCV's (exit 1 if not).
 *
 *   bench_separation [--quick] [--size S] [--frames N] [--reps R]
 * Full run (docs/benchmarks.md): build/tests/bench/bench_separation */
#include <glib.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proc/cv_bridge.h"
#include "proc/separation.h"

static double
now (void)
{
  return g_get_monotonic_time () / 1e6;
}

static double
run_numpy (guint size, guint frames, guint reps)
{
  g_autofree char *s = g_strdup_printf ("%u", size), *f = g_strdup_printf ("%u", frames),
                  *r = g_strdup_printf ("%u", reps);
  char *argv[] = { (char *) DS_BENCH_PYTHON, (char *) DS_BENCH_NUMPY_SCRIPT, (char *) "--size", s,
                   (char *) "--frames", f, (char *) "--reps", r, NULL };
  g_autofree char *out = NULL, *err = NULL;
  int status = 0;
  g_autoptr (GError) error = NULL;
  if (!g_spawn_sync (NULL, argv, NULL, G_SPAWN_DEFAULT, NULL, NULL, &out, &err, &status, &error) ||
      !g_spawn_check_wait_status (status, NULL)) {
    fprintf (stderr, "numpy baseline unavailable: %s%s\n", error ? error->message : "", err ? err : "");
    return NAN;
  }
  const char *p = strstr (out, "numpy_seconds ");
  return p ? g_ascii_strtod (p + strlen ("numpy_seconds "), NULL) : NAN;
}

typedef struct {
  double total, accumulate, finalize; /* best of the repetitions, each */
} Timing;

/* Times accumulate + finalize `reps` times; *sep keeps the last result. */
static gboolean
time_ours (DsPhaseSet *set, DsImage **frames, guint nframes, guint reps, gboolean reuse, Timing *t,
           DsSeparation **sep)
{
  *t = (Timing) { INFINITY, INFINITY, INFINITY };
  g_autoptr (GError) error = NULL;
  for (guint r = 0; r < reps; r++) {
    if (!reuse)
      g_clear_pointer (sep, ds_separation_free);
    ds_phase_set_reset (set);
    double t0 = now ();
    for (guint k = 0; k < nframes; k++)
      if (!ds_phase_set_accumulate (set, k, frames[k], &error)) {
        fprintf (stderr, "accumulate: %s\n", error->message);
        return FALSE;
      }
    double t1 = now ();
    *sep = reuse ? ds_phase_set_finalize_reusing (set, g_steal_pointer (sep), &error)
                 : ds_phase_set_finalize (set, &error);
    double t2 = now ();
    if (!*sep) {
      fprintf (stderr, "finalize: %s\n", error->message);
      return FALSE;
    }
    t->total = MIN (t->total, t2 - t0);
    t->accumulate = MIN (t->accumulate, t1 - t0);
    t->finalize = MIN (t->finalize, t2 - t1);
  }
  return TRUE;
}

int
main (int argc, char **argv)
{
  guint size = 2048, nframes = 8, reps = 5;
  for (int i = 1; i < argc; i++) {
    if (strcmp (argv[i], "--quick") == 0) {
      size = 256;
      reps = 2;
    } else if (strcmp (argv[i], "--size") == 0 && i + 1 < argc) {
      size = (guint) atoi (argv[++i]);
    } else if (strcmp (argv[i], "--frames") == 0 && i + 1 < argc) {
      nframes = (guint) atoi (argv[++i]);
    } else if (strcmp (argv[i], "--reps") == 0 && i + 1 < argc) {
      reps = (guint) atoi (argv[++i]);
    } else {
      fprintf (stderr, "usage: %s [--quick] [--size S] [--frames N] [--reps R]\n", argv[0]);
      return 2;
    }
  }
  if (size < 1 || nframes < 2 || reps < 1)
    return 2;

  /* Frames: deterministic pseudo-random 16-bit data (xorshift), all bits used. */
  DsImage **frames = g_new0 (DsImage *, nframes);
  const guint16 **planes = g_new0 (const guint16 *, nframes);
  guint64 state = 0x9E3779B97F4A7C15ull;
  for (guint k = 0; k < nframes; k++) {
    frames[k] = ds_image_new (DS_SAMPLE_U16, size, size, NULL);
    for (guint y = 0; y < size; y++) {
      guint16 *row = ds_image_row (frames[k], y);
      for (guint x = 0; x < size; x++) {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        row[x] = (guint16) (state >> 24);
      }
    }
    planes[k] = (const guint16 *) frames[k]->data;
  }
  gsize frame_bytes = frames[0]->stride * size;

  /* Ours. */
  DsSeparationParams params;
  ds_separation_params_init (&params, nframes);
  params.saturation_level = 65536.0; /* random data touches 65535: do not count it saturated */
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&params, size, size, &error);
  if (!set) {
    fprintf (stderr, "ds_phase_set_new: %s\n", error->message);
    return 1;
  }
  /* Fresh result images per set (ds_phase_set_finalize), then the steady state of continuous
   * acquisition, where the previous result's planes are reused (finalize_reusing). */
  Timing fresh, reused;
  DsSeparation *sep = NULL;
  if (!time_ours (set, frames, nframes, reps, FALSE, &fresh, &sep) ||
      !time_ours (set, frames, nframes, reps, TRUE, &reused, &sep))
    return 1;
  double best_ours = reused.total;

  /* OpenCV. */
  float *cv_direct = g_malloc ((gsize) size * size * sizeof (float));
  float *cv_global = g_malloc ((gsize) size * size * sizeof (float));
  double best_cv = INFINITY;
  char err[256];
  for (guint r = 0; r < reps; r++) {
    double t0 = now ();
    if (ds_cv_separate_maxmin_u16 (planes, (int) nframes, (int) size, (int) size, frames[0]->stride,
                                   cv_direct, cv_global, err, sizeof err) != 0) {
      fprintf (stderr, "opencv: %s\n", err);
      return 1;
    }
    best_cv = MIN (best_cv, now () - t0);
  }

  /* memcpy of the same input bytes into distinct, pre-faulted destinations. */
  guint8 *dst = g_malloc (frame_bytes * nframes);
  memset (dst, 1, frame_bytes * nframes);
  double best_copy = INFINITY;
  for (guint r = 0; r < reps; r++) {
    double t0 = now ();
    for (guint k = 0; k < nframes; k++)
      memcpy (dst + k * frame_bytes, frames[k]->data, frame_bytes);
    best_copy = MIN (best_copy, now () - t0);
  }

  /* Same answer as OpenCV (a correctness check, not a timing one). */
  guint64 mismatches = 0;
  for (guint y = 0; y < size; y++) {
    const float *t = ds_image_row (sep->transmissive, y), *s = ds_image_row (sep->scattered, y);
    for (guint x = 0; x < size; x++) {
      gsize i = (gsize) y * size + x;
      if (fabsf (t[x] - cv_direct[i]) > 1e-3f || fabsf (s[x] - cv_global[i]) > 1e-3f)
        mismatches++;
    }
  }

  double numpy = run_numpy (size, nframes, reps);

  double mib = frame_bytes * nframes / (1024.0 * 1024.0);
  printf ("separation benchmark: %u phases of %ux%u u16 (%.1f MiB in), one thread, best of %u\n", nframes,
          size, size, mib, reps);
  printf ("  ours, fresh result images:  accumulate %7.2f ms, finalize %7.2f ms, total %7.2f ms\n",
          fresh.accumulate * 1e3, fresh.finalize * 1e3, fresh.total * 1e3);
  printf ("  ours, reused result images: accumulate %7.2f ms, finalize %7.2f ms, total %7.2f ms\n",
          reused.accumulate * 1e3, reused.finalize * 1e3, reused.total * 1e3);
  printf ("  (finalize = last frame in -> result; reused total %.0f MiB/s)\n", mib / best_ours);
  printf ("  numpy (stack, max, min)      %8.2f ms  numpy/ours   %5.2fx reused, %5.2fx fresh (target >= 5)\n",
          numpy * 1e3, numpy / best_ours, numpy / fresh.total);
  printf ("  OpenCV (max, min, subtract)  %8.2f ms  opencv/ours  %5.2fx reused, %5.2fx fresh (target >= 2.5)\n",
          best_cv * 1e3, best_cv / best_ours, best_cv / fresh.total);
  printf ("  memcpy of the input          %8.2f ms  ours/memcpy  %5.2fx reused, %5.2fx fresh (target <= 3)\n",
          best_copy * 1e3, best_ours / best_copy, fresh.total / best_copy);
  printf ("  pixels differing from OpenCV: %" G_GUINT64_FORMAT "\n", mismatches);

  ds_separation_free (sep);
  g_free (dst);
  g_free (cv_direct);
  g_free (cv_global);
  for (guint k = 0; k < nframes; k++)
    ds_image_free (frames[k]);
  g_free (frames);
  g_free (planes);
  return mismatches ? 1 : 0;
}
