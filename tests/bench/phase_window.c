/* Benchmark: the sliding phase window (proc/phase_window.h, issue 37's per-frame results)
 * against baselines measured in the same run, on N phases of WxH u16 and u8 frames, one frame
 * per phase in cyclic order, for each estimator:
 *   window   ds_phase_window_push of the newest frame, then ds_phase_window_finalize_into a
 *            pooled result: what a per-frame result costs once the window is full (median and
 *            worst over the pushes, per megapixel, and its two halves);
 *   fused    ds_phase_window_push_finalize_into, the same on a second window fed the same
 *            frames (what descatterd calls): each block of rows pushed and finalized at once;
 *   fold     ds_phase_set_accumulate of one frame (what a per-set result costs per frame);
 *   refold   a fresh set over the window's N frames and its finalize (the window's
 *            definition, and what a window without incremental state would cost);
 *   floor    a streaming pass over the bytes per pixel the estimator's push + finalize must
 *            move at least with its present state and result (layout_of below), with the kept
 *            planes when its push reads them, and any result's floor (the frame read, the
 *            9 bytes of t, g and mask written): how far each is from memory speed.
 * It also prints the share of pixels whose extremes a push rebuilt from the kept frames, and
 * the memory the window holds against one set's state (the kept frames counted). Times are
 * the process's CPU time (below); the fused line also gives the wall-clock median (the
 * latency, shorter than the CPU time with 2 threads); runs and baselines take turns within
 * each repetition. It
 * asserts no timing; it checks its results (exit status 1 on a mismatch): both windows' last
 * results equal the fresh set's bit for bit. It prints a hash of that result, the same for
 * two builds whose outputs are the same bit for bit. Without --threads it runs on 1 and on 2 threads.
 *
 *   bench_phase_window [--quick] [--case NxWxH]... [--reps R] [--threads T] [--estimator E]
 * Full run (docs/benchmarks.md): build/tests/bench/bench_phase_window */
#include <glib.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "proc/phase_window.h"
#include "proc/separation.h"

typedef struct {
  guint n, w, h;
} Case;

/* CPU seconds of the process (every thread): on a machine shared with other work a wall
 * clock counts the time the scheduler gave to others; CPU time does not. With one thread it is
 * the latency on an idle machine; with more, the CPU a result costs. */
static double
now (void)
{
  struct timespec ts;
  clock_gettime (CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + ts.tv_nsec / 1e9;
}

/* Frame `t` of a stripe sequence: period 16 px, half lit, over a scene whose transmission
 * varies, with noise of a few DN (a 12-bit camera, or an 8-bit one), so that every pixel's
 * extremes are decided by noise as a camera's are. */
static DsImage *
make_frame (DsSampleType type, const Case *c, guint64 t)
{
  DsImage *img = ds_image_new (type, c->w, c->h, NULL);
  img->bit_depth = type == DS_SAMPLE_U8 ? 8 : 12;
  double full = type == DS_SAMPLE_U8 ? 255.0 : 4095.0, noise = type == DS_SAMPLE_U8 ? 1.5 : 6.0;
  guint32 state = 2463534242u + (guint32) t * 7919u;
  guint k = (guint) (t % c->n);
  for (guint y = 0; y < c->h; y++) {
    void *row = ds_image_row (img, y);
    for (guint x = 0; x < c->w; x++) {
      state ^= state << 13;
      state ^= state >> 17;
      state ^= state << 5;
      double u = (state & 0xffff) / 65536.0 + ((state >> 16) & 0xffff) / 65536.0 - 1.0;
      double ld = 0.5 + 0.4 * sin (0.01 * x + 0.013 * y);
      double lit = fmod (x / 16.0 + (double) k / c->n, 1.0) < 0.5 ? 1.0 : 0.1;
      double v = CLAMP ((0.15 + 0.6 * ld * lit) * full + noise * 2.45 * u, 0, full);
      if (type == DS_SAMPLE_U8)
        ((guint8 *) row)[x] = (guint8) v;
      else
        ((guint16 *) row)[x] = (guint16) v;
    }
  }
  return img;
}

/* Wall-clock seconds: the latency of a result, which with several threads is less than its
 * CPU time; on a loaded machine it also counts the time the scheduler gave to others. */
static double
wall (void)
{
  struct timespec ts;
  clock_gettime (CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + ts.tv_nsec / 1e9;
}

static int
cmp_double (const void *a, const void *b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return (x > y) - (x < y);
}

/* The median: on a shared machine a preempted push would drag a mean. Reorders v. */
static double
median (double *v, guint64 n)
{
  qsort (v, n, sizeof *v, cmp_double);
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* A hash of a plane's bytes (FNV-1a over 8-byte words, the tail bytewise): printed with the
 * results, so that two builds' outputs can be compared bit for bit on the same frames. */
static guint64
plane_hash (const DsImage *a, guint64 h)
{
  if (!a)
    return h;
  gsize row = (gsize) a->width * ds_sample_size (a->type);
  for (guint y = 0; y < a->height; y++) {
    const guint8 *p = ds_image_row (a, y);
    gsize x = 0;
    for (; x + 8 <= row; x += 8) {
      guint64 v;
      memcpy (&v, p + x, 8);
      h = (h ^ v) * 0x100000001b3ull;
    }
    for (; x < row; x++)
      h = (h ^ p[x]) * 0x100000001b3ull;
  }
  return h;
}

static gboolean
same_plane (const DsImage *a, const DsImage *b)
{
  if (!a || !b)
    return a == b;
  gsize row = (gsize) a->width * ds_sample_size (a->type);
  for (guint y = 0; y < a->height; y++)
    if (memcmp (ds_image_row (a, y), ds_image_row (b, y), row) != 0)
      return FALSE;
  return TRUE;
}

/* The memory-bandwidth floor of a push + finalize: one streaming pass over the bytes per pixel
 * that an estimator must at least move with its present state and result, on one thread. The
 * bytes are three kinds, each in its own buffer and each streamed once, block by block side by
 * side as the window's rows are:
 *   ro   read only: the new frame, and the kept planes a rebuild or robust's finalize reads;
 *   rmw  read and written in place: the kept slot (the retired sample out, the new one in) and
 *        the state the push updates;
 *   wo   written only: the result planes, t and g as float and the mask (9 bytes), and
 *        robust's phase plane of the new frame.
 * A write to memory not in cache first reads the line (as the result's stores do), so wo
 * costs what the real stores cost. The pass does no arithmetic worth the name: its time is
 * what moving the bytes costs on this machine, below which no code with this layout goes. */
typedef struct {
  guint ro, rmw, wo;    /* bytes per pixel of each kind, without kept planes */
  guint kept;           /* bytes per pixel more read when the push reads every kept plane */
  const char *what;
} Layout;

/* The layout of each estimator with the bench's parameters (no dark, model, extrema or motion),
 * s bytes per sample, N phases. */
static Layout
layout_of (DsEstimator e, guint s, guint n)
{
  const guint result = 4 + 4 + 1;
  switch (e) {
  case DS_ESTIMATOR_MAXMIN:
    /* u16 max and min; a push that loses an extreme rebuilds it from the N kept planes, which
     * under noise touches every line of them (the "rebuilt" share) */
    return (Layout) { s, s + 4, result, (n - 1) * s, "frame; slot + max/min u16; result" };
  case DS_ESTIMATOR_SINE:
    /* u32 sum, i64 cos and sin, a u8 count of saturated samples (for SATURATED); no minimum
     * without a dark frame (proc/phase_window.c), so no kept plane but the slot is read */
    return (Layout) { s, s + 4 + 16 + 1, result, 0,
                      "frame; slot + sum u32 + harmonic 2 i64 + saturated count u8; result" };
  default:
    /* robust: the finalize reads its N u16 phase planes (the new one among them, written by
     * the push), the kept slot gets the frame, nothing is retired but by overwriting */
    return (Layout) { s + 2 * (n - 1), s, result + 2, 0,
                      "frame + N-1 u16 planes; slot; result + new u16 plane" };
  }
}

typedef guint64 Vec __attribute__ ((vector_size (16)));

/* One pass: ro summed, rmw incremented in place, wo stored; 64 KiB of each per block. */
static guint64
stream_pass (const guint8 *ro, gsize ro_bytes, guint8 *rmw, gsize rmw_bytes, guint8 *wo,
             gsize wo_bytes, guint64 salt)
{
  const gsize block = 65536;
  Vec acc = { 0, 0 }, one = { 1, 1 }, fill = { salt, salt };
  gsize nb = MAX (MAX (ro_bytes, rmw_bytes), wo_bytes) / block + 1;
  for (gsize b = 0; b < nb; b++) {
    gsize r0 = ro_bytes * b / nb, r1 = ro_bytes * (b + 1) / nb;
    gsize m0 = rmw_bytes * b / nb, m1 = rmw_bytes * (b + 1) / nb;
    gsize w0 = wo_bytes * b / nb, w1 = wo_bytes * (b + 1) / nb;
    for (gsize i = r0 & ~(gsize) 15; i + 16 <= r1; i += 16) {
      Vec v;
      memcpy (&v, ro + i, 16);
      acc += v;
    }
    for (gsize i = m0 & ~(gsize) 15; i + 16 <= m1; i += 16) {
      Vec v;
      memcpy (&v, rmw + i, 16);
      v += one;
      memcpy (rmw + i, &v, 16);
    }
    for (gsize i = w0 & ~(gsize) 15; i + 16 <= w1; i += 16)
      memcpy (wo + i, &fill, 16);
  }
  return acc[0] ^ acc[1];
}

typedef struct {
  guint8 *ro, *rmw, *wo;
  gsize ro_bytes, rmw_bytes, wo_bytes;
} Floor;

static void
floor_init (Floor *f, gsize npix, guint ro, guint rmw, guint wo)
{
  f->ro_bytes = npix * ro;
  f->rmw_bytes = npix * rmw;
  f->wo_bytes = npix * wo;
  /* calloc'd and touched once, so that the timed passes find every page mapped */
  f->ro = g_malloc0 (f->ro_bytes + 16);
  f->rmw = g_malloc0 (f->rmw_bytes + 16);
  f->wo = g_malloc0 (f->wo_bytes + 16);
  memset (f->ro, 1, f->ro_bytes);
  memset (f->rmw, 1, f->rmw_bytes);
  memset (f->wo, 1, f->wo_bytes);
}

static void
floor_clear (Floor *f)
{
  g_clear_pointer (&f->ro, g_free);
  g_clear_pointer (&f->rmw, g_free);
  g_clear_pointer (&f->wo, g_free);
}

G_DEFINE_AUTO_CLEANUP_CLEAR_FUNC (Floor, floor_clear)

static volatile guint64 floor_sink;

/* CPU seconds of one pass. */
static double
floor_time (Floor *f, guint64 salt)
{
  double t0 = now ();
  floor_sink ^= stream_pass (f->ro, f->ro_bytes, f->rmw, f->rmw_bytes, f->wo, f->wo_bytes, salt);
  return now () - t0;
}

static gboolean
bench_one (const Case *c, DsSampleType type, DsEstimator estimator, guint reps, guint threads,
           DsImage **frames)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, c->n);
  p.estimator = estimator;
  p.threads = threads;
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseWindow) win = ds_phase_window_new (&p, c->w, c->h, &error);
  g_autoptr (DsPhaseWindow) fwin = win ? ds_phase_window_new (&p, c->w, c->h, &error) : NULL;
  g_autoptr (DsPhaseSet) set = fwin ? ds_phase_set_new (&p, c->w, c->h, &error) : NULL;
  g_autoptr (DsSeparation) got = ds_separation_new (), want = ds_separation_new ();
  g_autoptr (DsSeparation) fgot = ds_separation_new ();
  if (!win || !fwin || !set) {
    fprintf (stderr, "%s\n", error->message);
    return FALSE;
  }
  /* fill the window and fault every plane in (untimed, as the daemon's first results) */
  guint64 t = 0;
  for (; t < c->n; t++)
    if (!ds_phase_window_push (win, (guint) (t % c->n), frames[t % (2 * c->n)], NULL, &error) ||
        !ds_phase_window_push (fwin, (guint) (t % c->n), frames[t % (2 * c->n)], NULL, &error))
      break;
  if (error || !ds_phase_window_finalize_into (win, got, &error) ||
      !ds_phase_window_finalize_into (fwin, fgot, &error)) {
    fprintf (stderr, "%s\n", error->message);
    return FALSE;
  }
  gsize pushes = (gsize) reps * c->n;
  g_autofree double *total = g_new (double, pushes), *push = g_new (double, pushes),
                    *fin = g_new (double, pushes), *fused = g_new (double, pushes),
                    *fwall = g_new (double, pushes);
  double fworst = 0;
  /* the floors (above): the estimator's layout, with its kept planes read (when a push reads
   * them), and any result's (the frame read, the 9 result bytes written) */
  guint s = (guint) ds_sample_size (type);
  Layout lay = layout_of (estimator, s, c->n);
  gsize npix = (gsize) c->w * c->h;
  g_auto (Floor) fl_state = { 0 };
  g_auto (Floor) fl_kept = { 0 };
  g_auto (Floor) fl_result = { 0 };
  floor_init (&fl_state, npix, lay.ro, lay.rmw, lay.wo);
  floor_init (&fl_kept, npix, lay.ro + lay.kept, lay.rmw, lay.wo);
  floor_init (&fl_result, npix, s, 0, 9);
  const guint passes = 2;
  gsize n_floor = (gsize) reps * passes;
  g_autofree double *t_state = g_new (double, n_floor), *t_kept = g_new (double, n_floor),
                    *t_result = g_new (double, n_floor);
  guint floored = 0;
  double worst = 0, best_fold = INFINITY, best_refold = INFINITY;
  guint64 rebuilt0 = ds_phase_window_rebuilt_pixels (win);
  guint timed = 0;
  for (guint r = 0; r < reps; r++) {
    /* the two windows take turns by cycles of N pushes, not push by push, so that each finds
     * its kept frames in cache as it would alone */
    guint64 t_cycle = t;
    for (guint i = 0; i < c->n; i++, t++) {
      const DsImage *f = frames[t % (2 * c->n)];
      double t0 = now ();
      gboolean ok = ds_phase_window_push (win, (guint) (t % c->n), f, NULL, &error);
      double t1 = now ();
      ok = ok && ds_phase_window_finalize_into (win, got, &error);
      double t2 = now ();
      if (!ok) {
        fprintf (stderr, "%s\n", error->message);
        return FALSE;
      }
      total[timed + i] = t2 - t0;
      push[timed + i] = t1 - t0;
      fin[timed + i] = t2 - t1;
      worst = MAX (worst, t2 - t0);
    }
    for (guint i = 0; i < c->n; i++) {
      guint64 u = t_cycle + i;
      gboolean complete = FALSE;
      double w3 = wall (), t3 = now ();
      gboolean ok = ds_phase_window_push_finalize_into (fwin, (guint) (u % c->n), frames[u % (2 * c->n)], fgot,
                                                        &complete, NULL, &error);
      double t4 = now (), w4 = wall ();
      if (!ok || !complete) {
        fprintf (stderr, "fused: %s\n", error ? error->message : "no result");
        return FALSE;
      }
      fused[timed + i] = t4 - t3;
      fwall[timed + i] = w4 - w3;
      fworst = MAX (fworst, t4 - t3);
    }
    timed += c->n;
    /* the floors take their turn after the pushes, as the baselines do */
    for (guint i = 0; i < passes; i++, floored++) {
      t_state[floored] = floor_time (&fl_state, t + i);
      t_kept[floored] = lay.kept ? floor_time (&fl_kept, t + i) : t_state[floored];
      t_result[floored] = floor_time (&fl_result, t + i);
    }
    /* the baselines over the window's current frames */
    ds_phase_set_reset (set);
    double t0 = now ();
    for (guint64 u = t - c->n; u < t; u++)
      if (!ds_phase_set_accumulate (set, (guint) (u % c->n), frames[u % (2 * c->n)], &error))
        return FALSE;
    double t1 = now ();
    if (!ds_phase_set_finalize_into (set, want, &error))
      return FALSE;
    double t2 = now ();
    best_fold = MIN (best_fold, (t1 - t0) / c->n);
    best_refold = MIN (best_refold, t2 - t0);
  }
  gboolean same = same_plane (got->transmissive, want->transmissive) &&
                  same_plane (got->scattered, want->scattered) && same_plane (got->mask, want->mask) &&
                  same_plane (fgot->transmissive, want->transmissive) &&
                  same_plane (fgot->scattered, want->scattered) && same_plane (fgot->mask, want->mask) &&
                  memcmp (&fgot->meta, &want->meta, sizeof want->meta) == 0 &&
                  memcmp (&got->meta, &want->meta, sizeof want->meta) == 0;
  double mp = (double) c->w * c->h / 1e6, mean = median (total, timed);
  gsize window_bytes = 0, set_bytes = 0;
  ds_phase_window_memory (win, &window_bytes, &set_bytes);
  double rebuilt = (double) (ds_phase_window_rebuilt_pixels (win) - rebuilt0) / ((double) timed * c->w * c->h);
  printf ("  %-3s %-6s push+finalize %7.2f ms (worst %7.2f) = %6.2f ms/MP  [push %6.2f, finalize %7.2f]"
          "  %5.2fx one fold  %5.2fx the refold  rebuilt %5.1f%%  memory %4.1f B/px = %4.2fx one set%s\n",
          type == DS_SAMPLE_U8 ? "u8" : "u16", ds_estimator_name (estimator), mean * 1e3, worst * 1e3,
          mean * 1e3 / mp, median (push, timed) * 1e3, median (fin, timed) * 1e3, mean / best_fold,
          mean / best_refold, 100 * rebuilt, (double) window_bytes / (c->w * (double) c->h),
          (double) window_bytes / set_bytes, same ? "" : "  WRONG: differs from a fresh set");
  double fmed = median (fused, timed), fw = median (fwall, timed);
  printf ("  %-3s %-6s fused         %7.2f ms (worst %7.2f) = %6.2f ms/MP  %5.2fx push+finalize"
          "  wall %6.2f ms/MP\n",
          type == DS_SAMPLE_U8 ? "u8" : "u16", ds_estimator_name (estimator), fmed * 1e3, fworst * 1e3,
          fmed * 1e3 / mp, fmed / mean, fw * 1e3 / mp);
  guint64 hash = plane_hash (want->transmissive, 0xcbf29ce484222325ull);
  hash = plane_hash (want->mask, plane_hash (want->scattered, hash));
  printf ("  %-3s %-6s result hash   %016" G_GINT64_MODIFIER "x (t, g and mask of the last result)\n",
          type == DS_SAMPLE_U8 ? "u8" : "u16", ds_estimator_name (estimator), hash);
  double fs = median (t_state, floored), fk = median (t_kept, floored), fr = median (t_result, floored);
  printf ("  %-3s %-6s floor         %6.2f ms/MP (%u B/px: %u read, %u read+written, %u written;"
          " %s)  fused %5.2fx it\n",
          type == DS_SAMPLE_U8 ? "u8" : "u16", ds_estimator_name (estimator), fs * 1e3 / mp,
          lay.ro + lay.rmw + lay.wo, lay.ro, lay.rmw, lay.wo, lay.what, fmed / fs);
  if (lay.kept)
    printf ("  %-3s %-6s floor + kept  %6.2f ms/MP (%u B/px more read: the other N - 1 kept planes,"
            " as a rebuild of every line)  fused %5.2fx it\n",
            type == DS_SAMPLE_U8 ? "u8" : "u16", ds_estimator_name (estimator), fk * 1e3 / mp,
            lay.kept, fmed / fk);
  printf ("  %-3s %-6s any result    %6.2f ms/MP (%u B/px: the frame read, t, g and mask written)"
          "  fused %5.2fx it\n",
          type == DS_SAMPLE_U8 ? "u8" : "u16", ds_estimator_name (estimator), fr * 1e3 / mp, s + 9,
          fmed / fr);
  return same;
}

static gboolean
bench_case (const Case *c, guint reps, guint threads, const char *only)
{
  printf ("\nN = %u, %ux%u (%.1f MP), %u thread%s, median of %u pushes per estimator\n", c->n, c->w, c->h,
          c->w * (double) c->h / 1e6, threads, threads == 1 ? "" : "s", reps * c->n);
  gboolean ok = TRUE;
  const DsSampleType types[] = { DS_SAMPLE_U16, DS_SAMPLE_U8 };
  for (guint ti = 0; ti < G_N_ELEMENTS (types); ti++) {
    /* two cycles of frames with different noise: every push changes every sample */
    DsImage **frames = g_new0 (DsImage *, 2 * c->n);
    for (guint i = 0; i < 2 * c->n; i++)
      frames[i] = make_frame (types[ti], c, i);
    const DsEstimator est[] = { DS_ESTIMATOR_MAXMIN, DS_ESTIMATOR_SINE, DS_ESTIMATOR_ROBUST };
    for (guint e = 0; e < G_N_ELEMENTS (est); e++)
      if (!only || strcmp (only, ds_estimator_name (est[e])) == 0)
        ok = bench_one (c, types[ti], est[e], reps, threads, frames) && ok;
    for (guint i = 0; i < 2 * c->n; i++)
      ds_image_free (frames[i]);
    g_free (frames);
  }
  return ok;
}

int
main (int argc, char **argv)
{
  GArray *cases = g_array_new (FALSE, FALSE, sizeof (Case));
  guint reps = 5, threads = 0;
  gboolean quick = FALSE;
  const char *only = NULL;
  for (int i = 1; i < argc; i++) {
    Case c;
    if (strcmp (argv[i], "--quick") == 0) {
      quick = TRUE;
    } else if (strcmp (argv[i], "--case") == 0 && i + 1 < argc &&
               sscanf (argv[++i], "%ux%ux%u", &c.n, &c.w, &c.h) == 3 && c.n >= 3 && c.w && c.h) {
      g_array_append_val (cases, c);
    } else if (strcmp (argv[i], "--reps") == 0 && i + 1 < argc) {
      reps = (guint) atoi (argv[++i]);
    } else if (strcmp (argv[i], "--threads") == 0 && i + 1 < argc) {
      threads = (guint) atoi (argv[++i]);
    } else if (strcmp (argv[i], "--estimator") == 0 && i + 1 < argc) {
      only = argv[++i];
    } else {
      fprintf (stderr, "usage: %s [--quick] [--case NxWxH]... [--reps R] [--threads T] [--estimator E]\n", argv[0]);
      return 2;
    }
  }
  if (reps < 1)
    return 2;
  if (cases->len == 0) {
    /* quick: small, but one case above the size where a set shares its rows with workers */
    const Case full[] = { { 8, 1024, 1024 }, { 8, 2048, 2048 } };
    const Case small[] = { { 4, 256, 256 }, { 8, 515, 301 } };
    g_array_append_vals (cases, quick ? small : full, quick ? G_N_ELEMENTS (small) : G_N_ELEMENTS (full));
  }
  /* 1 thread: the latency on an idle core; 2: what the daemon's finalize may share */
  guint thread_list[2] = { 1, 2 }, n_threads = 2;
  if (threads > 0) {
    thread_list[0] = threads;
    n_threads = 1;
  }
  if (quick) {
    reps = MIN (reps, 2u);
    thread_list[0] = MAX (thread_list[0], 2u);
    n_threads = 1;
  }
  printf ("sliding window benchmark: %u repetitions of N pushes\n", reps);
  gboolean ok = TRUE;
  for (guint ti = 0; ti < n_threads; ti++)
    for (guint i = 0; i < cases->len; i++)
      ok = bench_case (&g_array_index (cases, Case, i), reps, thread_list[ti], only) && ok;
  g_array_free (cases, TRUE);
  printf ("\nresults %s\n", ok ? "checked: all equal to a fresh set" : "WRONG (see above)");
  return ok ? 0 : 1;
}
