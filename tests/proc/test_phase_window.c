/* The sliding phase window against its definition: a fresh DsPhaseSet over the window's frames
 * in arrival order, compared bit for bit, for every estimator and sample type, across breaks;
 * each case also feeds a second window through ds_phase_window_push_finalize_into (push and
 * finalize fused row block by row block), which must give the same. */
#include <math.h>
#include <string.h>

#include "proc/phase_window.h"
#include "proc/proc_error.h"

#define W 61
#define H 17

/* Frame t of a stripe sequence: phase t mod N over a scene whose transmission varies in x and
 * y, with pseudo-random noise, so that max, min and sums differ at every pixel. */
/* gain 1: no sample reaches full scale; above, the brightest saturate (extremes tie there). */
static DsImage *
make_frame_sized (DsSampleType type, guint bits, guint n, guint64 t, GRand *r, guint width,
                  guint height, double gain, double noise)
{
  DsImage *img = ds_image_new (type, width, height, NULL);
  img->bit_depth = bits;
  /* float frames: the range of a 12-bit camera (a shift by 32 bits is undefined) */
  double full = type == DS_SAMPLE_F32 ? 4095.0 : (double) ((1u << bits) - 1);
  guint k = (guint) (t % n);
  for (guint y = 0; y < height; y++)
    for (guint x = 0; x < width; x++) {
      double ld = 0.5 + 0.4 * sin (0.3 * x + 0.7 * y);
      double lit = fmod (x / 8.0 + (double) k / n, 1.0) < 0.5 ? 1.0 : 0.05;
      double v = (0.2 + 0.5 * ld * lit) * full * 0.8 * gain + g_rand_double_range (r, -noise, noise);
      v = CLAMP (v, 0, full);
      void *row = ds_image_row (img, y);
      if (type == DS_SAMPLE_U8)
        ((guint8 *) row)[x] = (guint8) v;
      else if (type == DS_SAMPLE_U16)
        ((guint16 *) row)[x] = (guint16) v;
      else
        ((float *) row)[x] = (float) v;
    }
  return img;
}

static DsImage *
make_frame (DsSampleType type, guint bits, guint n, guint64 t, GRand *r)
{
  return make_frame_sized (type, bits, n, t, r, W, H, 1.0, 3.0);
}

static void
assert_same_plane (const DsImage *a, const DsImage *b, const char *what)
{
  if (!a && !b)
    return;
  g_assert_nonnull (a);
  g_assert_nonnull (b);
  g_assert_cmpuint (a->type, ==, b->type);
  gsize row = (gsize) a->width * ds_sample_size (a->type);
  for (guint y = 0; y < a->height; y++)
    if (memcmp (ds_image_row (a, y), ds_image_row (b, y), row) != 0)
      g_error ("%s differs from the fresh set's in row %u", what, y);
}

static void
assert_same_result (const DsSeparation *a, const DsSeparation *b)
{
  assert_same_plane (a->transmissive, b->transmissive, "transmissive");
  assert_same_plane (a->scattered, b->scattered, "scattered");
  assert_same_plane (a->mask, b->mask, "mask");
  assert_same_plane (a->max, b->max, "max");
  assert_same_plane (a->min, b->min, "min");
  assert_same_plane (a->mean, b->mean, "mean");
  for (guint bit = 0; bit < DS_MASK_N_BITS; bit++)
    g_assert_cmpuint (a->meta.flagged[bit], ==, b->meta.flagged[bit]);
}

typedef struct {
  DsEstimator estimator;
  DsSampleType type;
  guint bits;
  guint n;
  gboolean dark;
  /* 0 or FALSE: the defaults (W x H, one thread, extrema kept, no model, gain 1) */
  guint width, height, threads;
  gboolean no_extrema, model;
  double gain;
  double noise;      /* DN either side; 0: 3. Below one DN few samples change, so few extremes
                        leave and a push rebuilds them pixel by pixel, not row by row */
  guint64 repeat_at; /* > 0: the frame at this push repeats the phase before it, out of turn */
  gboolean one_thread_calls; /* pushes and finalizes on one of the window's threads */
  /* Samples that come and go as the window slides: every third frame is 2.2x as bright (its
   * brightest samples saturate), and each frame drops a sparse grid of pixels, moving with t,
   * to 0 (below the dark frame, which is then dark_level + x mod 5): saturated and dark pixels
   * enter and leave the window at every push. The run must see SATURATED (and, with a dark
   * frame, DARK_EXCEEDS) set in some results and at other pixel counts in others. */
  gboolean come_and_go;
  guint dark_level;
  /* One pixel per row, moving with t, at full scale (even rows) or 0 (odd rows): an extreme no
   * other kept sample shares, which leaves with its frame at one pixel of a row, so that the
   * push rebuilds it from the other kept frames pixel by pixel. */
  gboolean spikes;
} Case;

static void
spike_frame (DsImage *img, guint64 t)
{
  guint full = img->type == DS_SAMPLE_U8 ? 255 : (1u << img->bit_depth) - 1;
  for (guint y = 0; y < img->height; y++) {
    guint x = (guint) ((t * 5 + y * 3) % img->width);
    guint v = y % 2 == 0 ? full : 0;
    void *row = ds_image_row (img, y);
    if (img->type == DS_SAMPLE_U8)
      ((guint8 *) row)[x] = (guint8) v;
    else
      ((guint16 *) row)[x] = (guint16) v;
  }
}

/* The frame of push t for come_and_go (above), over make_frame_sized's. */
static void
come_and_go_frame (DsImage *img, guint64 t)
{
  for (guint y = 0; y < img->height; y++)
    for (guint x = 0; x < img->width; x++)
      if ((x * 7 + y * 3 + t) % 11 == 0) {
        void *row = ds_image_row (img, y);
        if (img->type == DS_SAMPLE_U8)
          ((guint8 *) row)[x] = 0;
        else
          ((guint16 *) row)[x] = 0;
      }
}

static DsImage *
make_dark (const Case *c, guint width, guint height)
{
  DsImage *dark = ds_image_new (c->type, width, height, NULL);
  dark->bit_depth = c->bits;
  for (guint y = 0; y < height; y++)
    for (guint x = 0; x < width; x++) {
      void *row = ds_image_row (dark, y);
      if (c->type == DS_SAMPLE_U8)
        ((guint8 *) row)[x] = (guint8) (c->dark_level + x % 5);
      else if (c->type == DS_SAMPLE_U16)
        ((guint16 *) row)[x] = (guint16) (c->dark_level + x % 5);
      else
        ((float *) row)[x] = (float) (x % 5);
    }
  return dark;
}

/* Frames 0..T-1 in cyclic order (but for one repeated phase when asked), a lost frame (a
 * break) at `lost`: each window result must equal a fresh set over the newest frame of each
 * phase since the break, in arrival order (frames t-N+1..t in cyclic order), and no result
 * may come before every phase has a frame after the break. */
static void
run_case (const Case *c)
{
  guint width = c->width ? c->width : W, height = c->height ? c->height : H;
  DsSeparationParams p;
  ds_separation_params_init (&p, c->n);
  p.estimator = c->estimator;
  p.pattern = DS_PATTERN_SQUARE;
  p.keep_extrema = !c->no_extrema;
  p.threads = c->threads ? c->threads : 1;
  if (c->model) {
    p.system_gain = 0.5;
    p.read_noise_dn = 2.0;
  }
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseWindow) win = ds_phase_window_new (&p, width, height, &error);
  g_assert_no_error (error);
  g_autoptr (DsPhaseWindow) fwin = ds_phase_window_new (&p, width, height, &error);
  g_assert_no_error (error);
  if (c->one_thread_calls) {
    ds_phase_window_set_push_threads (win, 1);
    ds_phase_window_set_finalize_threads (win, 1);
    ds_phase_window_set_push_threads (fwin, 1);
    ds_phase_window_set_finalize_threads (fwin, 1);
  }
  g_autoptr (GRand) r = g_rand_new_with_seed (7 + c->n + c->estimator);
  g_autoptr (DsImage) dark = c->dark ? make_dark (c, width, height) : NULL;
  if (dark) {
    g_assert_true (ds_phase_window_set_dark (win, dark, &error));
    g_assert_true (ds_phase_window_set_dark (fwin, dark, &error));
  }
  const guint64 total = 4 * c->n + 3, lost = 2 * c->n + 1;
  GPtrArray *frames = g_ptr_array_new_with_free_func ((GDestroyNotify) ds_image_free);
  g_autofree gint64 *newest = g_new (gint64, c->n); /* frame of each phase since the break */
  for (guint k = 0; k < c->n; k++)
    newest[k] = -1;
  guint64 good_since_break = 0;
  g_autoptr (DsSeparation) got = ds_separation_new ();
  g_autoptr (DsSeparation) fgot = ds_separation_new ();
  /* come_and_go: the fewest and most pixels flagged SATURATED and DARK_EXCEEDS over results */
  guint64 sat_lo = G_MAXUINT64, sat_hi = 0, exc_lo = G_MAXUINT64, exc_hi = 0;
  for (guint64 t = 0; t < total; t++) {
    guint phase = (guint) ((c->repeat_at && t == c->repeat_at ? t - 1 : t) % c->n);
    double gain = c->gain > 0 ? c->gain : 1.0;
    if (c->come_and_go && t % 3 == 0)
      gain *= 2.2;
    g_ptr_array_add (frames, make_frame_sized (c->type, c->bits, c->n, phase, r, width, height,
                                               gain, c->noise > 0 ? c->noise : 3.0));
    if (c->come_and_go)
      come_and_go_frame (frames->pdata[t], t);
    if (c->spikes)
      spike_frame (frames->pdata[t], t);
    if (t == lost) {
      ds_phase_window_break (win);
      ds_phase_window_break (fwin);
      good_since_break = 0;
      for (guint k = 0; k < c->n; k++)
        newest[k] = -1;
      continue;
    }
    gboolean complete = FALSE;
    g_assert_true (ds_phase_window_push (win, phase, frames->pdata[t], &complete, &error));
    g_assert_no_error (error);
    gboolean fcomplete = FALSE, pushed = FALSE;
    g_assert_true (ds_phase_window_push_finalize_into (fwin, phase, frames->pdata[t], fgot, &fcomplete,
                                                       &pushed, &error));
    g_assert_no_error (error);
    g_assert_true (pushed);
    g_assert_cmpint (fcomplete, ==, complete);
    g_assert_cmpuint (ds_phase_window_fill (fwin), ==, ds_phase_window_fill (win));
    good_since_break++;
    newest[phase] = (gint64) t;
    guint have = 0;
    gint64 oldest = G_MAXINT64;
    for (guint k = 0; k < c->n; k++)
      if (newest[k] >= 0) {
        have++;
        oldest = MIN (oldest, newest[k]);
      }
    g_assert_cmpint (complete, ==, have == c->n);
    g_assert_cmpuint (ds_phase_window_fill (win), ==, have);
    g_assert_cmpuint (ds_phase_window_frames_since_break (win), ==, good_since_break);
    if (!complete) {
      g_assert_false (ds_phase_window_finalize_into (win, got, &error));
      g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_NOT_ENOUGH_PHASES);
      g_clear_error (&error);
      continue;
    }
    g_assert_cmpuint (ds_phase_window_span (win), ==, (guint64) ((gint64) t - oldest + 1));
    g_assert_true (ds_phase_window_finalize_into (win, got, &error));
    g_assert_no_error (error);
    g_autoptr (DsPhaseSet) fresh = ds_phase_set_new (&p, width, height, &error);
    if (dark)
      g_assert_true (ds_phase_set_set_dark (fresh, dark, &error));
    for (guint64 u = (guint64) oldest; u <= t; u++) {
      guint ku = (guint) ((c->repeat_at && u == c->repeat_at ? u - 1 : u) % c->n);
      if (newest[ku] == (gint64) u)
        g_assert_true (ds_phase_set_accumulate (fresh, ku, frames->pdata[u], &error));
    }
    g_autoptr (DsSeparation) want = ds_phase_set_finalize (fresh, &error);
    g_assert_no_error (error);
    assert_same_result (got, want);
    assert_same_result (fgot, want);
    sat_lo = MIN (sat_lo, want->meta.flagged[0]);
    sat_hi = MAX (sat_hi, want->meta.flagged[0]);
    exc_lo = MIN (exc_lo, want->meta.flagged[5]);
    exc_hi = MAX (exc_hi, want->meta.flagged[5]);
    g_assert_cmpmem (&fgot->meta, sizeof fgot->meta, &want->meta, sizeof want->meta);
    g_assert_cmpuint (ds_phase_window_rebuilt_pixels (fwin), ==, ds_phase_window_rebuilt_pixels (win));
  }
  g_ptr_array_unref (frames);
  G_STATIC_ASSERT (DS_MASK_SATURATED == 1 << 0 && DS_MASK_DARK_EXCEEDS == 1 << 5);
  if (c->come_and_go) {
    g_assert_cmpuint (sat_hi, >, 0);
    g_assert_cmpuint (sat_lo, <, sat_hi);
    if (c->dark) {
      g_assert_cmpuint (exc_hi, >, 0);
      g_assert_cmpuint (exc_lo, <, exc_hi);
    }
  }
}

static void
test_fresh_set_equality (void)
{
  const Case cases[] = {
    { .estimator = DS_ESTIMATOR_MAXMIN, .type = DS_SAMPLE_U16, .bits = 12, .n = 4, .dark = FALSE },
    { .estimator = DS_ESTIMATOR_MAXMIN, .type = DS_SAMPLE_U8, .bits = 8, .n = 8, .dark = TRUE },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U16, .bits = 16, .n = 8, .dark = FALSE },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U16, .bits = 12, .n = 5, .dark = TRUE },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_F32, .bits = 32, .n = 6, .dark = FALSE },
    { .estimator = DS_ESTIMATOR_ROBUST, .type = DS_SAMPLE_U16, .bits = 12, .n = 16, .dark = FALSE },
    { .estimator = DS_ESTIMATOR_ROBUST, .type = DS_SAMPLE_U8, .bits = 8, .n = 8, .dark = TRUE },
    /* the finalize's integer maxmin path (no extrema, no model), saturated pixels whose
     * extremes tie, a noise model, and a phase repeated out of turn while the window slides */
    { .estimator = DS_ESTIMATOR_MAXMIN, .type = DS_SAMPLE_U8, .bits = 8, .n = 6, .dark = TRUE,
      .no_extrema = TRUE, .gain = 2.5 },
    { .estimator = DS_ESTIMATOR_MAXMIN, .type = DS_SAMPLE_U16, .bits = 10, .n = 3, .dark = FALSE,
      .model = TRUE, .repeat_at = 5 },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U8, .bits = 8, .n = 4, .dark = FALSE,
      .gain = 1.6, .repeat_at = 6 },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U16, .bits = 12, .n = 3, .dark = TRUE,
      .model = TRUE, .no_extrema = TRUE },
    { .estimator = DS_ESTIMATOR_ROBUST, .type = DS_SAMPLE_U16, .bits = 12, .n = 6, .dark = FALSE,
      .repeat_at = 8 },
    { .estimator = DS_ESTIMATOR_MAXMIN, .type = DS_SAMPLE_U16, .bits = 12, .n = 5, .dark = FALSE,
      .noise = 0.1 },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U8, .bits = 8, .n = 4, .dark = TRUE,
      .noise = 0.1 },
    /* extremes that leave at few pixels of a row (N = 40, samples rarely tied), rebuilt pixel
     * by pixel; spikes no other sample shares. With sine's counts the window keeps the minimum
     * for DARK_EXCEEDS alone: a dark level of 12000 DN is above the flag's threshold over a 0
     * spike and below it over the other samples' minimum, so a minimum kept after its spike
     * left the window shows in the mask. */
    { .estimator = DS_ESTIMATOR_MAXMIN, .type = DS_SAMPLE_U16, .bits = 16, .n = 40, .noise = 900,
      .spikes = TRUE },
    { .estimator = DS_ESTIMATOR_MAXMIN, .type = DS_SAMPLE_U8, .bits = 8, .n = 40, .dark = TRUE,
      .noise = 60, .spikes = TRUE },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U16, .bits = 16, .n = 40, .dark = TRUE,
      .noise = 900, .spikes = TRUE, .no_extrema = TRUE, .dark_level = 12000 },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U8, .bits = 8, .n = 40, .dark = TRUE,
      .noise = 20, .spikes = TRUE, .no_extrema = TRUE, .dark_level = 12 },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U16, .bits = 16, .n = 40, .noise = 900,
      .spikes = TRUE },
    /* the finalize's integer sine path (no extrema, no model), with saturated pixels */
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U16, .bits = 12, .n = 8, .dark = TRUE,
      .no_extrema = TRUE, .gain = 1.6 },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U8, .bits = 8, .n = 5, .dark = FALSE,
      .no_extrema = TRUE, .repeat_at = 7 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++)
    run_case (&cases[i]);
}

/* sine's fast row, where the window keeps a count of saturated samples for SATURATED and the
 * minimum only with a dark frame (for DARK_EXCEEDS): saturated and dark samples entering and
 * leaving the window at every push, with and without a dark frame, u8 and u16, a phase
 * repeated out of turn, and rows split over threads. */
static void
test_counts (void)
{
  const Case cases[] = {
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U16, .bits = 12, .n = 8, .dark = TRUE,
      .no_extrema = TRUE, .come_and_go = TRUE, .dark_level = 600 },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U8, .bits = 8, .n = 5, .dark = TRUE,
      .no_extrema = TRUE, .come_and_go = TRUE, .dark_level = 33, .repeat_at = 7 },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U16, .bits = 10, .n = 6, .dark = FALSE,
      .no_extrema = TRUE, .come_and_go = TRUE },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U8, .bits = 8, .n = 3, .dark = FALSE,
      .no_extrema = TRUE, .come_and_go = TRUE, .repeat_at = 4 },
    /* low noise: few minima leave, each rescanned alone rather than its row rebuilt */
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U16, .bits = 12, .n = 4, .dark = TRUE,
      .no_extrema = TRUE, .come_and_go = TRUE, .dark_level = 600, .noise = 0.1 },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U16, .bits = 12, .n = 8, .dark = TRUE,
      .no_extrema = TRUE, .come_and_go = TRUE, .dark_level = 600, .width = 509, .height = 331,
      .threads = 2 },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U8, .bits = 8, .n = 8, .dark = FALSE,
      .no_extrema = TRUE, .come_and_go = TRUE, .width = 4100, .height = 150, .threads = 2 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++)
    run_case (&cases[i]);
}

/* A dark frame set, changed and taken away while the window slides: each result is still a
 * fresh set's with the dark frame of the moment (with counts the minimum is kept only while
 * a dark frame is set). */
static void
test_dark_changes (void)
{
  const guint n = 4;
  DsSeparationParams p;
  ds_separation_params_init (&p, n);
  p.estimator = DS_ESTIMATOR_SINE;
  p.pattern = DS_PATTERN_SQUARE;
  p.keep_extrema = FALSE;
  p.threads = 1;
  const Case c = { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U16, .bits = 12, .n = n,
                   .dark = TRUE, .dark_level = 600 };
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseWindow) win = ds_phase_window_new (&p, W, H, &error);
  g_assert_no_error (error);
  g_autoptr (DsImage) dark = make_dark (&c, W, H);
  g_autoptr (GRand) r = g_rand_new_with_seed (5);
  GPtrArray *frames = g_ptr_array_new_with_free_func ((GDestroyNotify) ds_image_free);
  g_autoptr (DsSeparation) got = ds_separation_new ();
  guint64 exceeds = 0;
  for (guint64 t = 0; t < 6 * n; t++) {
    DsImage *f = make_frame_sized (DS_SAMPLE_U16, 12, n, t, r, W, H, t % 3 == 0 ? 2.2 : 1.0, 3.0);
    come_and_go_frame (f, t);
    g_ptr_array_add (frames, f);
    /* no dark, then one, then none, then one again, each for some pushes */
    gboolean use_dark = (t / 5) % 2 == 1;
    if (t % 5 == 0)
      g_assert_true (ds_phase_window_set_dark (win, use_dark ? dark : NULL, &error));
    gboolean complete = FALSE;
    g_assert_true (ds_phase_window_push_finalize_into (win, (guint) (t % n), f, got, &complete, NULL, &error));
    g_assert_no_error (error);
    if (!complete)
      continue;
    g_autoptr (DsPhaseSet) fresh = ds_phase_set_new (&p, W, H, &error);
    if (use_dark)
      g_assert_true (ds_phase_set_set_dark (fresh, dark, &error));
    for (guint64 u = t + 1 - n; u <= t; u++)
      g_assert_true (ds_phase_set_accumulate (fresh, (guint) (u % n), frames->pdata[u], &error));
    g_autoptr (DsSeparation) want = ds_phase_set_finalize (fresh, &error);
    g_assert_no_error (error);
    assert_same_result (got, want);
    g_assert_cmpmem (&got->meta, sizeof got->meta, &want->meta, sizeof want->meta);
    exceeds += want->meta.flagged[5];
  }
  g_assert_cmpuint (exceeds, >, 0);
  g_ptr_array_unref (frames);
}

/* Frames large enough that the set splits rows over worker threads: the pushes' rows too, and
 * the same bits when the window is told to push and finalize on one of them. */
static void
test_threaded (void)
{
  const Case cases[] = {
    { .estimator = DS_ESTIMATOR_MAXMIN, .type = DS_SAMPLE_U16, .bits = 12, .n = 4, .dark = TRUE,
      .width = 512, .height = 320, .threads = 2, .no_extrema = TRUE },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U8, .bits = 8, .n = 3, .dark = FALSE,
      .width = 512, .height = 320, .threads = 2 },
    { .estimator = DS_ESTIMATOR_MAXMIN, .type = DS_SAMPLE_U8, .bits = 8, .n = 3, .dark = FALSE,
      .width = 512, .height = 320, .threads = 2, .one_thread_calls = TRUE },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U16, .bits = 12, .n = 8, .dark = TRUE,
      .width = 509, .height = 331, .threads = 3, .no_extrema = TRUE },
    /* rows wide enough that a fused push and finalize takes each band in several blocks (of
     * 256 KiB of a kept plane: 63 rows here) and a last short one */
    { .estimator = DS_ESTIMATOR_MAXMIN, .type = DS_SAMPLE_U16, .bits = 12, .n = 3, .dark = TRUE,
      .width = 2050, .height = 203, .threads = 1, .no_extrema = TRUE },
    { .estimator = DS_ESTIMATOR_SINE, .type = DS_SAMPLE_U8, .bits = 8, .n = 4, .dark = FALSE,
      .width = 4100, .height = 150, .threads = 2, .no_extrema = TRUE, .gain = 1.6 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++)
    run_case (&cases[i]);
}

/* The window holds one set's state and its N kept frames, nothing per pixel besides: maxmin
 * with extrema on u16 keeps max and min (2 + 2 bytes) and a 32-bit sum; four u16 frames add
 * 4 x 2 bytes (and their padding, at most a page and five cache lines each). */
static void
test_memory (void)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, 4);
  p.keep_extrema = TRUE;
  g_autoptr (DsPhaseWindow) win = ds_phase_window_new (&p, W, H, NULL);
  g_autoptr (GRand) r = g_rand_new_with_seed (11);
  g_autoptr (DsSeparation) sep = ds_separation_new ();
  for (guint k = 0; k < 4; k++) {
    g_autoptr (DsImage) f = make_frame (DS_SAMPLE_U16, 12, 4, k, r);
    g_assert_true (ds_phase_window_push (win, k, f, NULL, NULL));
  }
  g_assert_true (ds_phase_window_finalize_into (win, sep, NULL));
  gsize window_bytes = 0, set_bytes = 0;
  ds_phase_window_memory (win, &window_bytes, &set_bytes);
  g_assert_cmpuint (set_bytes, ==, (gsize) W * H * (2 + 2 + 4));
  /* each kept plane may be padded by up to a page and five cache lines (phase_window.c) */
  g_assert_cmpuint (window_bytes, >=, (gsize) W * H * (2 + 2 + 4 + 4 * 2));
  g_assert_cmpuint (window_bytes, <=, (gsize) W * H * (2 + 2 + 4 + 4 * 2) + 4 * (4096 + 5 * 64));
}

/* A phase repeated out of turn replaces that phase's frame: the window then spans more pushes
 * than N, and its result is the fresh set over the newest frame of each phase. */
static void
test_repeated_phase (void)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, 4);
  p.threads = 1;
  g_autoptr (DsPhaseWindow) win = ds_phase_window_new (&p, W, H, NULL);
  g_autoptr (GRand) r = g_rand_new_with_seed (3);
  const guint phases[] = { 0, 1, 2, 1, 3 };
  DsImage *f[5];
  for (guint i = 0; i < 5; i++) {
    f[i] = make_frame (DS_SAMPLE_U16, 12, 4, phases[i], r);
    gboolean complete;
    g_assert_true (ds_phase_window_push (win, phases[i], f[i], &complete, NULL));
    g_assert_cmpint (complete, ==, i == 4);
  }
  g_assert_cmpuint (ds_phase_window_span (win), ==, 5);
  g_autoptr (DsSeparation) got = ds_separation_new ();
  g_assert_true (ds_phase_window_finalize_into (win, got, NULL));
  g_autoptr (DsPhaseSet) fresh = ds_phase_set_new (&p, W, H, NULL);
  const guint used[] = { 0, 2, 3, 4 }; /* arrival order of the newest frame of each phase */
  for (guint i = 0; i < 4; i++)
    g_assert_true (ds_phase_set_accumulate (fresh, phases[used[i]], f[used[i]], NULL));
  g_autoptr (DsSeparation) want = ds_phase_set_finalize (fresh, NULL);
  assert_same_result (got, want);
  for (guint i = 0; i < 5; i++)
    ds_image_free (f[i]);
}

/* Bad frames are refused with an error that names them, and leave the window as it was. */
static void
test_bad_frames (void)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, 4);
  g_autoptr (DsPhaseWindow) win = ds_phase_window_new (&p, W, H, NULL);
  g_autoptr (GRand) r = g_rand_new_with_seed (5);
  g_autoptr (DsImage) a = make_frame (DS_SAMPLE_U16, 12, 4, 0, r);
  g_autoptr (DsImage) b8 = make_frame (DS_SAMPLE_U8, 8, 4, 1, r);
  g_autoptr (DsImage) small = ds_image_new (DS_SAMPLE_U16, W - 1, H, NULL);
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_phase_window_push (win, 0, a, NULL, &error));
  g_assert_false (ds_phase_window_push (win, 1, b8, NULL, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_assert_nonnull (strstr (error->message, "phase 1"));
  g_clear_error (&error);
  g_assert_false (ds_phase_window_push (win, 2, small, NULL, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_clear_error (&error);
  g_assert_false (ds_phase_window_push (win, 4, a, NULL, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_clear_error (&error);
  g_assert_cmpuint (ds_phase_window_fill (win), ==, 1);
  g_assert_cmpuint (ds_phase_window_frames_since_break (win), ==, 1);
  /* After a break the sample type may change: the old frames are gone. */
  ds_phase_window_break (win);
  g_assert_true (ds_phase_window_push (win, 1, b8, NULL, &error));
  g_assert_cmpuint (ds_phase_window_fill (win), ==, 1);
}

/* The fused call when no result can be made (a plane of the wrong shape): it fails as the
 * finalize would, but the frame went in, as after the push of the two calls; the next result
 * is the fresh set's. */
static void
test_fused_errors (void)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, 4);
  p.threads = 1;
  p.estimator = DS_ESTIMATOR_SINE;
  g_autoptr (DsPhaseWindow) win = ds_phase_window_new (&p, W, H, NULL);
  g_autoptr (GRand) r = g_rand_new_with_seed (9);
  DsImage *f[6];
  g_autoptr (DsSeparation) sep = ds_separation_new ();
  g_autoptr (GError) error = NULL;
  for (guint t = 0; t < 6; t++) {
    f[t] = make_frame (DS_SAMPLE_U16, 12, 4, t, r);
    gboolean complete = FALSE, pushed = FALSE;
    if (t == 5) {
      /* a transmissive plane of another size */
      g_clear_pointer (&sep->transmissive, ds_image_free);
      sep->transmissive = ds_image_new (DS_SAMPLE_F32, W + 1, H, NULL);
      g_assert_false (ds_phase_window_push_finalize_into (win, t % 4, f[t], sep, &complete, &pushed, &error));
      g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
      g_clear_error (&error);
      g_assert_true (pushed);
      g_assert_true (complete);
      continue;
    }
    g_assert_true (ds_phase_window_push_finalize_into (win, t % 4, f[t], sep, &complete, &pushed, &error));
    g_assert_no_error (error);
    g_assert_true (pushed);
    g_assert_cmpint (complete, ==, t >= 3);
  }
  /* a bad frame: nothing pushed, nothing changed */
  g_autoptr (DsImage) small = ds_image_new (DS_SAMPLE_U16, W - 1, H, NULL);
  gboolean pushed = TRUE;
  g_assert_false (ds_phase_window_push_finalize_into (win, 0, small, sep, NULL, &pushed, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_assert_false (pushed);
  g_autoptr (DsSeparation) got = ds_separation_new ();
  g_assert_true (ds_phase_window_finalize_into (win, got, NULL));
  g_autoptr (DsPhaseSet) fresh = ds_phase_set_new (&p, W, H, NULL);
  for (guint t = 2; t < 6; t++)
    g_assert_true (ds_phase_set_accumulate (fresh, t % 4, f[t], NULL));
  g_autoptr (DsSeparation) want = ds_phase_set_finalize (fresh, NULL);
  assert_same_result (got, want);
  for (guint t = 0; t < 6; t++)
    ds_image_free (f[t]);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/phase-window/fresh-set-equality", test_fresh_set_equality);
  g_test_add_func ("/phase-window/threaded", test_threaded);
  g_test_add_func ("/phase-window/counts", test_counts);
  g_test_add_func ("/phase-window/dark-changes", test_dark_changes);
  g_test_add_func ("/phase-window/memory", test_memory);
  g_test_add_func ("/phase-window/repeated-phase", test_repeated_phase);
  g_test_add_func ("/phase-window/bad-frames", test_bad_frames);
  g_test_add_func ("/phase-window/fused-errors", test_fused_errors);
  return g_test_run ();
}
