/* Benchmark: the separation of N phases of WxH u16 frames against baselines measured in the same
 * run, at the sizes of issue 13 (4 x 1 MP, 8 x 4 MP, 32 x 4 MP):
 *   ours     what descatterd does: ds_phase_set_accumulate per frame as frames arrive, the last
 *            one with ds_phase_set_accumulate_finalize_into pooled planes (the daemon's steady
 *            state: planes reused, faulted in by an untimed first set); one thread and the
 *            set's threads (0: one per processor, as descatterd);
 *   numpy    the ICCP 2013 authors' loop, np.maximum/np.minimum per frame
 *            (tests/bench/separation_numpy.py, run with /usr/bin/python3);
 *   OpenCV   cv::max/cv::min per frame, subtract, scale (ds_cv_separate_maxmin_u16);
 *   memcpy   the same input bytes copied into distinct, pre-faulted buffers.
 * It also times sine and robust against maxmin, each estimator with the motion mask bit against
 * itself without it, the per-set noise estimate against folding one frame, the single-frame
 * estimator (one frame into pooled planes, P = 16) against folding one frame on as many threads
 * (1, and the set's threads), and unpacking packed pixel formats into a pooled image against a memcpy of the
 * unpacked frame. Best of R repetitions each; ours, OpenCV and memcpy take turns within each
 * repetition, so that on a shared machine they see the same load. It prints times and ratios
 * and asserts no timing.
 * It checks its results (exit status 1 on a mismatch): ours equals OpenCV on every pixel, every
 * thread count gives the bits of one thread (all estimators), the fused last frame gives the
 * bits of the two calls, unpacking inverts ds_pixfmt_pack.
 *
 *   bench_separation [--quick] [--case NxWxH]... [--reps R] [--threads T]
 * Full run (docs/benchmarks.md): build/tests/bench/bench_separation */
#include <glib.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proc/cv_bridge.h"
#include "proc/pixfmt.h"
#include "proc/separation.h"
#include "proc/separation_internal.h" /* ds_separation_frame_noise, timed alone */
#include "proc/single_frame.h"

static double
now (void)
{
  return g_get_monotonic_time () / 1e6;
}

typedef struct {
  guint n, w, h;
} Case;

static double
run_numpy (const Case *c, guint reps)
{
  g_autofree char *w = g_strdup_printf ("%u", c->w), *h = g_strdup_printf ("%u", c->h),
                  *f = g_strdup_printf ("%u", c->n), *r = g_strdup_printf ("%u", reps);
  char *argv[] = { (char *) DS_BENCH_PYTHON, (char *) DS_BENCH_NUMPY_SCRIPT, (char *) "--width", w,
                   (char *) "--height", h, (char *) "--frames", f, (char *) "--reps", r, NULL };
  g_autofree char *out = NULL, *err = NULL;
  int status = 0;
  g_autoptr (GError) error = NULL;
  if (!g_spawn_sync (NULL, argv, NULL, G_SPAWN_DEFAULT, NULL, NULL, &out, &err, &status, &error) ||
      !g_spawn_check_wait_status (status, NULL)) {
    fprintf (stderr, "numpy baseline failed: %s%s\n", error ? error->message : "", err ? err : "");
    return NAN;
  }
  const char *p = strstr (out, "numpy_seconds ");
  return p ? g_ascii_strtod (p + strlen ("numpy_seconds "), NULL) : NAN;
}

typedef struct {
  double total, accumulate, finalize; /* best of the repetitions, each */
} Timing;

/* One estimator on its own phase set and pooled result, timed one set at a time so that the
 * runs and the baselines can take turns (on a busy machine all then see the same load). */
typedef struct {
  DsPhaseSet *set;
  DsSeparation *sep;  /* a pool of one, as the daemon's result-plane pool reuses planes */
  gboolean two_calls;
  Timing t;           /* best of the timed sets */
} Runner;

/* One set as descatterd folds it: frames 0..N-2 with ds_phase_set_accumulate as they arrive,
 * the last one with ds_phase_set_accumulate_finalize_into (folded on the finalize's pass), into
 * the runner's planes. `accumulate` is the first N-1 frames, `finalize` the last frame and the
 * finalize. two_calls: the last frame with ds_phase_set_accumulate, then
 * ds_phase_set_finalize_into (the reference for the fused path; `finalize` is then the
 * finalize alone). */
static gboolean
runner_once (Runner *rn, DsImage **frames, guint n, gboolean timed)
{
  g_autoptr (GError) error = NULL;
  ds_phase_set_reset (rn->set);
  double t0 = now ();
  guint folded = rn->two_calls ? n : n - 1;
  for (guint k = 0; k < folded; k++)
    if (!ds_phase_set_accumulate (rn->set, k, frames[k], &error)) {
      fprintf (stderr, "accumulate: %s\n", error->message);
      return FALSE;
    }
  double t1 = now ();
  gboolean ok = rn->two_calls ? ds_phase_set_finalize_into (rn->set, rn->sep, &error)
                              : ds_phase_set_accumulate_finalize_into (rn->set, n - 1, frames[n - 1], rn->sep, NULL,
                                                                       &error);
  if (!ok) {
    fprintf (stderr, "finalize: %s\n", error->message);
    return FALSE;
  }
  double t2 = now ();
  if (timed) {
    rn->t.total = MIN (rn->t.total, t2 - t0);
    rn->t.accumulate = MIN (rn->t.accumulate, t1 - t0);
    rn->t.finalize = MIN (rn->t.finalize, t2 - t1);
  }
  return TRUE;
}

/* A runner for estimator e at `threads`; a first set, not timed, faults its pooled planes in. */
static gboolean
runner_init_motion (Runner *rn, DsEstimator e, guint threads, gboolean two_calls, gboolean motion, DsImage **frames,
                    const Case *c)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, c->n);
  p.estimator = e;
  p.detect_motion = motion;
  p.threads = threads;
  p.saturation_level = 65536.0; /* random data touches 65535: do not count it saturated */
  g_autoptr (GError) error = NULL;
  *rn = (Runner) { .two_calls = two_calls, .t = { INFINITY, INFINITY, INFINITY } };
  rn->set = ds_phase_set_new (&p, c->w, c->h, &error);
  if (!rn->set) {
    fprintf (stderr, "ds_phase_set_new: %s\n", error->message);
    return FALSE;
  }
  rn->sep = ds_separation_new ();
  return runner_once (rn, frames, c->n, FALSE);
}

static gboolean
runner_init (Runner *rn, DsEstimator e, guint threads, gboolean two_calls, DsImage **frames, const Case *c)
{
  return runner_init_motion (rn, e, threads, two_calls, FALSE, frames, c);
}

static void
runner_clear (Runner *rn)
{
  g_clear_pointer (&rn->set, ds_phase_set_free);
  g_clear_pointer (&rn->sep, ds_separation_free);
}

static gboolean
same_planes (const DsImage *a, const DsImage *b)
{
  if (!a || !b)
    return a == b;
  gsize row = (gsize) a->width * ds_sample_size (a->type);
  for (guint y = 0; y < a->height; y++)
    if (memcmp (ds_image_row (a, y), ds_image_row (b, y), row) != 0)
      return FALSE;
  return TRUE;
}

static gboolean
same_result (const DsSeparation *a, const DsSeparation *b)
{
  return same_planes (a->transmissive, b->transmissive) && same_planes (a->scattered, b->scattered) &&
         same_planes (a->mask, b->mask) && memcmp (&a->meta, &b->meta, sizeof a->meta) == 0;
}

/* The main comparison at one size; returns FALSE on a wrong result. */
static gboolean
bench_case (const Case *c, guint reps, guint threads, gboolean estimators)
{
  gsize npix = (gsize) c->w * c->h;
  DsImage **frames = g_new0 (DsImage *, c->n);
  const guint16 **planes = g_new0 (const guint16 *, c->n);
  guint64 state = 0x9E3779B97F4A7C15ull;
  for (guint k = 0; k < c->n; k++) {
    frames[k] = ds_image_new (DS_SAMPLE_U16, c->w, c->h, NULL);
    for (guint y = 0; y < c->h; y++) {
      guint16 *row = ds_image_row (frames[k], y);
      for (guint x = 0; x < c->w; x++) {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        row[x] = (guint16) (state >> 24);
      }
    }
    planes[k] = (const guint16 *) frames[k]->data;
  }
  gsize frame_bytes = frames[0]->stride * c->h;
  gboolean ok = TRUE;

  /* ours (1 thread, the set's threads, the two calls), OpenCV and memcpy take turns in every
   * repetition; best of each */
  Runner r1, rt, r2;
  if (!runner_init (&r1, DS_ESTIMATOR_MAXMIN, 1, FALSE, frames, c) ||
      !runner_init (&rt, DS_ESTIMATOR_MAXMIN, threads, FALSE, frames, c) ||
      !runner_init (&r2, DS_ESTIMATOR_MAXMIN, 1, TRUE, frames, c))
    return FALSE;
  float *cv_direct = g_malloc (npix * sizeof (float)), *cv_global = g_malloc (npix * sizeof (float));
  guint8 *dst = g_malloc (frame_bytes * c->n);
  memset (dst, 1, frame_bytes * c->n);
  double best_cv = INFINITY, best_copy = INFINITY;
  char err[256];
  for (guint r = 0; r < reps; r++) {
    if (!runner_once (&r1, frames, c->n, TRUE) || !runner_once (&rt, frames, c->n, TRUE) ||
        !runner_once (&r2, frames, c->n, TRUE))
      return FALSE;
    double t0 = now ();
    if (ds_cv_separate_maxmin_u16 (planes, (int) c->n, (int) c->w, (int) c->h, frames[0]->stride,
                                   cv_direct, cv_global, err, sizeof err) != 0) {
      fprintf (stderr, "opencv: %s\n", err);
      return FALSE;
    }
    best_cv = MIN (best_cv, now () - t0);
    t0 = now ();
    for (guint k = 0; k < c->n; k++)
      memcpy (dst + k * frame_bytes, frames[k]->data, frame_bytes);
    best_copy = MIN (best_copy, now () - t0);
  }
  Timing one = r1.t, many = rt.t, two = r2.t;
  const DsSeparation *sep1 = r1.sep;
  if (!same_result (sep1, rt.sep)) {
    fprintf (stderr, "%u threads differ from one thread\n", threads);
    ok = FALSE;
  }
  if (!same_result (sep1, r2.sep)) {
    fprintf (stderr, "the last frame folded on the finalize's pass differs from the two calls\n");
    ok = FALSE;
  }
  guint64 mismatches = 0;
  for (guint y = 0; y < c->h; y++) {
    const float *t = ds_image_row (sep1->transmissive, y), *s = ds_image_row (sep1->scattered, y);
    for (guint x = 0; x < c->w; x++) {
      gsize i = (gsize) y * c->w + x;
      mismatches += t[x] != cv_direct[i] || s[x] != cv_global[i];
    }
  }
  if (mismatches) {
    fprintf (stderr, "%" G_GUINT64_FORMAT " pixels differ from OpenCV\n", mismatches);
    ok = FALSE;
  }
  double numpy = run_numpy (c, reps);

  double mib = frame_bytes * c->n / (1024.0 * 1024.0);
  printf ("\n%u phases of %ux%u u16 (%.1f MiB in), maxmin, best of %u\n", c->n, c->w, c->h, mib, reps);
  printf ("  ours, 1 thread:   %u frames %8.2f ms  last + finalize %6.2f ms  total %8.2f ms\n", c->n - 1,
          one.accumulate * 1e3, one.finalize * 1e3, one.total * 1e3);
  printf ("  ours, %u threads:  %u frames %8.2f ms  last + finalize %6.2f ms  total %8.2f ms\n", threads,
          c->n - 1, many.accumulate * 1e3, many.finalize * 1e3, many.total * 1e3);
  printf ("  (two calls, 1 thread: %u frames %.2f ms, finalize %.2f ms, total %.2f ms: %.2fx the fused)\n", c->n,
          two.accumulate * 1e3, two.finalize * 1e3, two.total * 1e3, two.total / one.total);
  printf ("  numpy loop  %8.2f ms   numpy/ours   %5.2fx (1 thread)  %5.2fx (%u)   target > 1\n",
          numpy * 1e3, numpy / one.total, numpy / many.total, threads);
  printf ("  OpenCV      %8.2f ms   opencv/ours  %5.2fx (1 thread)  %5.2fx (%u)   target > 1\n",
          best_cv * 1e3, best_cv / one.total, best_cv / many.total, threads);
  printf ("  memcpy      %8.2f ms   ours/memcpy  %5.2fx (1 thread)  %5.2fx (%u)   target <= 1.5 at 4 MP\n",
          best_copy * 1e3, one.total / best_copy, many.total / best_copy, threads);

  if (estimators) {
    Timing base[3] = { one };
    for (DsEstimator e = DS_ESTIMATOR_SINE; e <= DS_ESTIMATOR_ROBUST; e++) {
      Runner a, b;
      gboolean ran = runner_init (&a, e, 1, FALSE, frames, c) && runner_init (&b, e, threads, FALSE, frames, c);
      for (guint r = 0; ran && r < reps; r++)
        ran = runner_once (&a, frames, c->n, TRUE) && runner_once (&b, frames, c->n, TRUE);
      gboolean same = ran && same_result (a.sep, b.sep);
      Timing te1 = a.t, tet = b.t;
      runner_clear (&a);
      runner_clear (&b);
      if (!same) {
        fprintf (stderr, "%s: %u threads differ from one thread\n", ds_estimator_name (e), threads);
        ok = FALSE;
        continue;
      }
      printf ("  %-6s total %8.2f ms (1 thread, %5.2fx maxmin: accumulate %5.2fx, finalize %5.2fx)  "
              "%8.2f ms (%u threads)\n",
              ds_estimator_name (e), te1.total * 1e3, te1.total / one.total, te1.accumulate / one.accumulate,
              te1.finalize / one.finalize, tet.total * 1e3, threads);
      base[e] = te1;
    }
    /* the motion mask bit (detect_motion) against the same estimator without it */
    for (DsEstimator e = DS_ESTIMATOR_MAXMIN; e <= DS_ESTIMATOR_ROBUST; e++) {
      Runner a, b;
      gboolean ran = runner_init_motion (&a, e, 1, FALSE, TRUE, frames, c) &&
                     runner_init_motion (&b, e, threads, FALSE, TRUE, frames, c);
      for (guint r = 0; ran && r < reps; r++)
        ran = runner_once (&a, frames, c->n, TRUE) && runner_once (&b, frames, c->n, TRUE);
      gboolean same = ran && same_result (a.sep, b.sep);
      Timing tm1 = a.t, tmt = b.t;
      runner_clear (&a);
      runner_clear (&b);
      if (!same) {
        fprintf (stderr, "%s with motion: %u threads differ from one thread\n", ds_estimator_name (e), threads);
        ok = FALSE;
        continue;
      }
      printf ("  %-6s +motion total %8.2f ms (1 thread, %5.2fx without: accumulate %5.2fx, finalize %5.2fx)  "
              "%8.2f ms (%u threads)\n",
              ds_estimator_name (e), tm1.total * 1e3, tm1.total / base[e].total,
              tm1.accumulate / base[e].accumulate, tm1.finalize / base[e].finalize, tmt.total * 1e3, threads);
    }
    /* the noise estimate of a set's first frame, against folding one frame */
    double best_noise = INFINITY;
    volatile double sink = 0;
    for (guint r = 0; r < reps; r++) {
      double t0 = now ();
      sink += ds_separation_frame_noise (frames[0]);
      best_noise = MIN (best_noise, now () - t0);
    }
    (void) sink;
    printf ("  noise estimate %6.3f ms per set (%.2f of one frame's fold at 1 thread)\n", best_noise * 1e3,
            best_noise / (one.accumulate / (c->n - 1)));
    /* the single-frame estimator (one frame, P = 16, into a pooled result as descatterd
     * reuses its planes) against folding one frame, on one thread and on the set's threads
     * each: target <= 1 */
    for (DsEstimator e = DS_ESTIMATOR_MAXMIN; e <= DS_ESTIMATOR_SINE; e++) {
      double best_single[2] = { INFINITY, INFINITY };
      for (guint i = 0; i < 2; i++) {
        DsSeparationParams sp;
        ds_separation_params_init (&sp, 8);
        sp.estimator = e;
        sp.geometry.period_px = 16;
        sp.threads = i == 0 ? 1 : threads;
        g_autoptr (GError) error = NULL;
        g_autoptr (DsSingleFrame) sf = ds_single_frame_new (&sp, c->w, c->h, &error);
        g_autoptr (DsSeparation) single = ds_separation_new ();
        for (guint r = 0; sf && r <= reps; r++) {
          double t0 = now ();
          if (!ds_single_frame_separate_into (sf, frames[0], NULL, single, &error))
            break;
          if (r > 0) /* the first faults the pooled planes in */
            best_single[i] = MIN (best_single[i], now () - t0);
        }
        if (error) {
          fprintf (stderr, "single-frame %s: %s\n", ds_estimator_name (e), error->message);
          ok = FALSE;
        }
      }
      printf ("  single-frame %-6s %6.3f ms per frame (%.2fx one frame's fold, 1 thread each)  %6.3f ms "
              "(%.2fx, %u threads each; target <= 1)\n",
              ds_estimator_name (e), best_single[0] * 1e3, best_single[0] / (one.accumulate / (c->n - 1)),
              best_single[1] * 1e3, best_single[1] / (many.accumulate / (c->n - 1)), threads);
    }
  }

  runner_clear (&r1);
  runner_clear (&rt);
  runner_clear (&r2);
  g_free (dst);
  g_free (cv_direct);
  g_free (cv_global);
  for (guint k = 0; k < c->n; k++)
    ds_image_free (frames[k]);
  g_free (frames);
  g_free (planes);
  return ok;
}

/* Unpacking a WxH frame of each packed format into a pooled image, against a memcpy of the
 * unpacked frame; checked against the packed original. */
static gboolean
bench_unpack (guint w, guint h, guint reps)
{
  const DsPixelFormat fmts[] = { DS_PIXFMT_MONO12, DS_PIXFMT_MONO12P, DS_PIXFMT_MONO12PACKED,
                                 DS_PIXFMT_MONO10P };
  g_autoptr (DsImage) src = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
  g_autoptr (DsImage) pooled = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
  g_autoptr (DsImage) copy = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
  memset (copy->data, 1, copy->stride * h);
  memset (pooled->data, 1, pooled->stride * h);
  guint64 state = 12345;
  gboolean ok = TRUE;
  double best_copy = INFINITY;
  for (guint r = 0; r < reps; r++) {
    double t0 = now ();
    memcpy (copy->data, src->data, src->stride * h);
    best_copy = MIN (best_copy, now () - t0);
  }
  printf ("\nunpacking a %ux%u frame into a pooled image (memcpy of the unpacked frame: %.2f ms)\n", w, h,
          best_copy * 1e3);
  for (guint f = 0; f < G_N_ELEMENTS (fmts); f++) {
    guint depth = ds_pixfmt_bit_depth (fmts[f]);
    for (guint y = 0; y < h; y++) {
      guint16 *row = ds_image_row (src, y);
      for (guint x = 0; x < w; x++) {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        row[x] = (guint16) ((state >> 33) & ((1u << depth) - 1u));
      }
    }
    g_autoptr (GBytes) payload = ds_pixfmt_pack (fmts[f], src, 0, NULL);
    gsize size;
    const void *data = g_bytes_get_data (payload, &size);
    double best = INFINITY;
    g_autoptr (GError) error = NULL;
    for (guint r = 0; r < reps; r++) {
      double t0 = now ();
      if (!ds_pixfmt_unpack_into (fmts[f], data, size, 0, pooled, &error)) {
        fprintf (stderr, "unpack %s: %s\n", ds_pixfmt_name (fmts[f]), error->message);
        return FALSE;
      }
      best = MIN (best, now () - t0);
    }
    gboolean same = same_planes (src, pooled);
    ok = ok && same;
    printf ("  %-13s %6.2f ms  %5.2fx memcpy%s\n", ds_pixfmt_name (fmts[f]), best * 1e3, best / best_copy,
            same ? "" : "  WRONG PIXELS");
  }
  return ok;
}

int
main (int argc, char **argv)
{
  GArray *cases = g_array_new (FALSE, FALSE, sizeof (Case));
  guint reps = 5, threads = MIN (g_get_num_processors (), DS_MAX_THREADS);
  gboolean quick = FALSE;
  for (int i = 1; i < argc; i++) {
    Case c;
    if (strcmp (argv[i], "--quick") == 0) {
      quick = TRUE;
    } else if (strcmp (argv[i], "--case") == 0 && i + 1 < argc &&
               sscanf (argv[++i], "%ux%ux%u", &c.n, &c.w, &c.h) == 3 && c.n >= 2 && c.w && c.h) {
      g_array_append_val (cases, c);
    } else if (strcmp (argv[i], "--reps") == 0 && i + 1 < argc) {
      reps = (guint) atoi (argv[++i]);
    } else if (strcmp (argv[i], "--threads") == 0 && i + 1 < argc) {
      threads = (guint) atoi (argv[++i]);
    } else {
      fprintf (stderr, "usage: %s [--quick] [--case NxWxH]... [--reps R] [--threads T]\n", argv[0]);
      return 2;
    }
  }
  if (reps < 1 || threads < 1)
    return 2;
  threads = MAX (threads, 2u); /* the threaded path is what is checked against one thread */
  if (cases->len == 0) {
    /* quick: small, but one case above the size where a set shares its rows with workers */
    const Case full[] = { { 4, 1024, 1024 }, { 8, 2048, 2048 }, { 32, 2048, 2048 } };
    const Case small[] = { { 4, 256, 256 }, { 8, 515, 301 } };
    g_array_append_vals (cases, quick ? small : full, quick ? G_N_ELEMENTS (small) : G_N_ELEMENTS (full));
  }
  if (quick)
    reps = MIN (reps, 2u);
  printf ("separation benchmark: %u repetitions, %u threads for the threaded runs\n", reps, threads);
  gboolean ok = TRUE;
  for (guint i = 0; i < cases->len; i++) {
    const Case *c = &g_array_index (cases, Case, i);
    ok = bench_case (c, reps, threads, quick || i < 2) && ok;
  }
  ok = bench_unpack (quick ? 301 : 2048, quick ? 97 : 2048, reps) && ok;
  g_array_free (cases, TRUE);
  printf ("\nresults %s\n", ok ? "checked: all correct" : "WRONG (see above)");
  return ok ? 0 : 1;
}
