/* Separation core, hard numerical cases (issue 2): saturation, darkness, a dark frame brighter
 * than the phases, tiny direct under huge global, 1024 full-scale frames, b near 1, NaN/Inf,
 * odd widths and padded strides, 1x1 and 8192x8192, bad input. Each expectation is a closed
 * form or a naive reference computed here. */
#include <glib.h>
#include <math.h>
#include <string.h>

#include "proc/proc_error.h"
#include "proc/separation.h"
#include "tests/proc/separation_scene.h"

static DsImage *
const_frame (DsSampleType type, guint w, guint h, guint bits, double v)
{
  DsImage *img = ds_image_new (type, w, h, NULL);
  if (type != DS_SAMPLE_F32)
    img->bit_depth = bits;
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
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

static void
set_u16 (DsImage *img, guint x, guint y, guint16 v)
{
  ((guint16 *) ds_image_row (img, y))[x] = v;
}

static void
set_f32 (DsImage *img, guint x, guint y, float v)
{
  ((float *) ds_image_row (img, y))[x] = v;
}

/* Every pixel at full scale in every phase: all SATURATED (16 and 12 bits, default level). */
static void
test_all_saturated (void)
{
  const guint bits[] = { 16, 12 };
  for (guint i = 0; i < 2; i++) {
    DsSeparationParams p;
    ds_separation_params_init (&p, 4);
    g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, 6, 5, NULL);
    g_autoptr (DsImage) f = const_frame (DS_SAMPLE_U16, 6, 5, bits[i], (1u << bits[i]) - 1);
    for (guint k = 0; k < 4; k++)
      g_assert_true (ds_phase_set_accumulate (set, k, f, NULL));
    g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, NULL);
    g_assert_cmpuint (sep->meta.flagged[0], ==, 30); /* bit 0: SATURATED */
    g_assert_cmpuint (sep->meta.valid_pixels, ==, 0);
    g_assert_cmpfloat (sep->meta.saturation_level, ==, (1u << bits[i]) - 1);
    for (guint y = 0; y < 5; y++)
      for (guint x = 0; x < 6; x++) {
        g_assert_true (test_pixel_u8 (sep->mask, x, y) & DS_MASK_SATURATED);
        g_assert_cmpfloat (test_pixel_f32 (sep->transmissive, x, y), ==, 0);
        g_assert_cmpfloat (test_pixel_f32 (sep->scattered, x, y), ==, 2.0 * ((1u << bits[i]) - 1));
      }
  }
}

/* 12-bit frames; a few pixels reach 4095 in one phase only: exactly those are flagged, and
 * their values are still the closed form. An explicit level applies too. */
static void
test_partly_saturated (void)
{
  const guint w = 9, h = 4, n = 3;
  for (guint round = 0; round < 2; round++) {
    DsSeparationParams p;
    ds_separation_params_init (&p, n);
    if (round == 1)
      p.saturation_level = 3000;
    g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, NULL);
    for (guint k = 0; k < n; k++) {
      g_autoptr (DsImage) f = const_frame (DS_SAMPLE_U16, w, h, 12, 1000 + 100 * k);
      if (k == 1) {
        set_u16 (f, 2, 1, 4095);
        set_u16 (f, 8, 3, 4095);
        set_u16 (f, 0, 0, 3000);
      }
      g_assert_true (ds_phase_set_accumulate (set, k, f, NULL));
    }
    g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, NULL);
    for (guint y = 0; y < h; y++)
      for (guint x = 0; x < w; x++) {
        gboolean hot = (x == 2 && y == 1) || (x == 8 && y == 3);
        gboolean expect = hot || (round == 1 && x == 0 && y == 0);
        g_assert_cmpint (!!(test_pixel_u8 (sep->mask, x, y) & DS_MASK_SATURATED), ==, expect);
        double mx = hot ? 4095 : (x == 0 && y == 0) ? 3000 : 1200;
        g_assert_cmpfloat (test_pixel_f32 (sep->transmissive, x, y), ==, mx - 1000);
      }
    g_assert_cmpuint (sep->meta.flagged[0], ==, round == 0 ? 2 : 3);
  }
}

/* All frames black (and: all equal to a dark pedestal that is subtracted): zero components,
 * every pixel DARK and LOW_MODULATION, nothing NEGATIVE or DARK_EXCEEDS. */
static void
test_all_dark (void)
{
  for (guint with_dark = 0; with_dark < 2; with_dark++) {
    const guint w = 16, h = 8;
    double level = with_dark ? 100 : 0;
    DsSeparationParams p;
    ds_separation_params_init (&p, 4);
    g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, NULL);
    g_autoptr (DsImage) f = const_frame (DS_SAMPLE_U16, w, h, 16, level);
    if (with_dark)
      g_assert_true (ds_phase_set_set_dark (set, f, NULL));
    for (guint k = 0; k < 4; k++)
      g_assert_true (ds_phase_set_accumulate (set, k, f, NULL));
    g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, NULL);
    g_assert_cmpint (sep->meta.dark_subtracted, ==, with_dark);
    for (guint y = 0; y < h; y++)
      for (guint x = 0; x < w; x++) {
        guint8 m = test_pixel_u8 (sep->mask, x, y);
        g_assert_cmpuint (m, ==, DS_MASK_DARK | DS_MASK_LOW_MODULATION);
        g_assert_cmpfloat (test_pixel_f32 (sep->transmissive, x, y), ==, 0);
        g_assert_cmpfloat (test_pixel_f32 (sep->scattered, x, y), ==, 0);
      }
    g_assert_cmpuint (sep->meta.flagged[1], ==, w * h);
    g_assert_cmpuint (sep->meta.flagged[2], ==, w * h);
  }
}

/* The dark frame is brighter than the phase frames on some pixels: signed subtraction (a
 * negative Lg, never an unsigned wrap), DARK_EXCEEDS and NEGATIVE there, untouched elsewhere. */
static void
test_dark_exceeds (void)
{
  const guint w = 7, h = 3;
  DsSeparationParams p;
  ds_separation_params_init (&p, 2);
  p.keep_extrema = TRUE;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, NULL);
  g_autoptr (DsImage) dark = const_frame (DS_SAMPLE_U16, w, h, 16, 50);
  set_u16 (dark, 3, 1, 5000);
  set_u16 (dark, 6, 2, 65535);
  g_autoptr (DsImage) f0 = const_frame (DS_SAMPLE_U16, w, h, 16, 1050);
  g_autoptr (DsImage) f1 = const_frame (DS_SAMPLE_U16, w, h, 16, 250);
  g_assert_true (ds_phase_set_accumulate (set, 0, f0, NULL));
  g_assert_true (ds_phase_set_accumulate (set, 1, f1, NULL));
  /* the dark frame may come after the phases */
  g_assert_true (ds_phase_set_set_dark (set, dark, NULL));
  g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, NULL);
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      double d = (x == 3 && y == 1) ? 5000 : (x == 6 && y == 2) ? 65535 : 50;
      guint8 m = test_pixel_u8 (sep->mask, x, y);
      g_assert_cmpfloat (test_pixel_f32 (sep->transmissive, x, y), ==, 800);
      g_assert_cmpfloat (test_pixel_f32 (sep->scattered, x, y), ==, 2 * (250 - d));
      g_assert_cmpfloat (test_pixel_f32 (sep->min, x, y), ==, 250 - d);
      g_assert_cmpfloat (test_pixel_f32 (sep->mean, x, y), ==, 650 - d);
      if (d > 250)
        g_assert_cmpuint (m & (DS_MASK_DARK_EXCEEDS | DS_MASK_NEGATIVE), ==, DS_MASK_DARK_EXCEEDS | DS_MASK_NEGATIVE);
      else
        g_assert_cmpuint (m, ==, 0);
    }
  g_assert_cmpuint (sep->meta.flagged[5], ==, 2);
  g_assert_cmpuint (sep->meta.flagged[4], ==, 2);
}

/* Direct 1e-4 of global at 16 bits: lit 60006, unlit 60000 DN. Exact without noise model; with
 * a model whose shot noise (K = 1: sigma 245 DN) swamps 6 DN, LOW_MODULATION says so. */
static void
test_tiny_direct_huge_global (void)
{
  const guint w = 20, h = 6, n = 8;
  static double ld[20 * 6], lg[20 * 6];
  for (guint i = 0; i < w * h; i++) {
    ld[i] = 6;
    lg[i] = 120000; /* Lg * m = 60000 */
  }
  TestPattern pat = { DS_PATTERN_SQUARE, 10.0, 0.5, 0.0 };
  const DsEstimator est[] = { DS_ESTIMATOR_MAXMIN, DS_ESTIMATOR_ROBUST };
  for (guint e = 0; e < 2; e++)
    for (guint model = 0; model < 2; model++) {
      DsSeparationParams p;
      ds_separation_params_init (&p, n);
      p.estimator = est[e];
      if (model) {
        p.system_gain = 1.0;
        p.read_noise_dn = 2.0;
      }
      g_autoptr (GError) error = NULL;
      g_autoptr (DsSeparation) sep = test_separate (&p, DS_SAMPLE_U16, w, h, 0, &pat, ld, lg, 0, 0, NULL, &error);
      g_assert_no_error (error);
      for (guint y = 0; y < h; y++)
        for (guint x = 0; x < w; x++) {
          g_assert_cmpfloat (test_pixel_f32 (sep->transmissive, x, y), ==, 6);
          g_assert_cmpfloat (test_pixel_f32 (sep->scattered, x, y), ==, 120000);
          g_assert_cmpuint (test_pixel_u8 (sep->mask, x, y), ==, model ? DS_MASK_LOW_MODULATION : 0);
        }
      if (model) /* sigma of one frame at the mean signal 60003 DN */
        g_assert_cmpfloat_with_epsilon (sep->meta.noise_dn, sqrt (4 + 1.0 / 12 + 60003), 1e-3);
    }
}

/* 1024 full-scale 16-bit frames: the sums are exact. Pixel A is 65535 in every frame, B
 * alternates 65535/0, C is 64k in frame k; means from a naive long-double reference here. */
static void
test_1024_full_scale (void)
{
  const guint n = 1024, w = 3, h = 1;
  DsSeparationParams p;
  ds_separation_params_init (&p, n);
  p.keep_extrema = TRUE;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, NULL);
  long double ref[3] = { 0, 0, 0 };
  g_autoptr (DsImage) f = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
  for (guint k = 0; k < n; k++) {
    guint16 v[3] = { 65535, (guint16) (k % 2 ? 0 : 65535), (guint16) (64 * k) };
    for (guint x = 0; x < w; x++) {
      set_u16 (f, x, 0, v[x]);
      ref[x] += v[x];
    }
    g_assert_true (ds_phase_set_accumulate (set, k, f, NULL));
  }
  g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, NULL);
  for (guint x = 0; x < w; x++)
    g_assert_cmpfloat (test_pixel_f32 (sep->mean, x, 0), ==, (float) (ref[x] / n));
  g_assert_cmpfloat (test_pixel_f32 (sep->mean, 0, 0), ==, 65535.0f);
  g_assert_cmpfloat (test_pixel_f32 (sep->mean, 1, 0), ==, 32767.5f);
  g_assert_cmpfloat (test_pixel_f32 (sep->max, 2, 0), ==, 64.0f * 1023);
  g_assert_cmpfloat (test_pixel_f32 (sep->transmissive, 1, 0), ==, 65535.0f);

  /* the same 1024 frames as 2 phases of 512 averages, and through the sine estimator */
  for (guint round = 0; round < 2; round++) {
    DsSeparationParams q;
    ds_separation_params_init (&q, round ? 4 : 2);
    q.keep_extrema = TRUE;
    q.estimator = round ? DS_ESTIMATOR_SINE : DS_ESTIMATOR_MAXMIN;
    g_autoptr (DsPhaseSet) s2 = ds_phase_set_new (&q, 1, 1, NULL);
    g_autoptr (DsImage) full = const_frame (DS_SAMPLE_U16, 1, 1, 16, 65535);
    for (guint k = 0; k < q.n_phases; k++)
      for (guint j = 0; j < n / q.n_phases; j++)
        g_assert_true (ds_phase_set_accumulate (s2, k, full, NULL));
    g_autoptr (DsSeparation) r = ds_phase_set_finalize (s2, NULL);
    g_assert_cmpuint (r->meta.frames_per_phase, ==, n / q.n_phases);
    g_assert_cmpfloat (test_pixel_f32 (r->mean, 0, 0), ==, 65535.0f);
    g_assert_cmpfloat (test_pixel_f32 (r->max, 0, 0), ==, 65535.0f);
    g_assert_cmpfloat (fabsf (test_pixel_f32 (r->transmissive, 0, 0)), <, 1e-6f);
  }
}

/* b close to 1 but accepted (condition 50): the closed form with b holds on u16 frames. */
static void
test_black_level_high (void)
{
  const guint w = 10, h = 2, n = 4;
  static double ld[20], lg[20];
  for (guint i = 0; i < w * h; i++) {
    ld[i] = 5000;
    lg[i] = 1000;
  }
  TestPattern pat = { DS_PATTERN_SQUARE, 10.0, 0.5, 0.98 };
  DsSeparationParams p;
  ds_separation_params_init (&p, n);
  p.black_level = 0.98;
  g_autoptr (GError) error = NULL;
  g_autoptr (DsSeparation) sep = test_separate (&p, DS_SAMPLE_F32, w, h, 0, &pat, ld, lg, 0, 0, NULL, &error);
  g_assert_no_error (error);
  for (guint i = 0; i < w * h; i++) {
    g_assert_cmpfloat (fabs (test_pixel_f32 (sep->transmissive, i % w, i / w) - 5000), <, 0.05);
    g_assert_cmpfloat (fabs (test_pixel_f32 (sep->scattered, i % w, i / w) - 1000), <, 0.05);
  }
}

/* NaN and Inf in float input (frames and dark): those pixels are NONFINITE with finite zero
 * outputs; the others are untouched, for every estimator and with averaging. */
static void
test_nonfinite (void)
{
  const guint w = 6, h = 3, n = 4;
  const DsEstimator est[] = { DS_ESTIMATOR_MAXMIN, DS_ESTIMATOR_SINE, DS_ESTIMATOR_ROBUST };
  for (guint e = 0; e < 3; e++)
    for (guint m = 1; m <= 2; m++) {
      DsSeparationParams p;
      ds_separation_params_init (&p, n);
      p.estimator = est[e];
      p.pattern = est[e] == DS_ESTIMATOR_SINE ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
      p.keep_extrema = TRUE;
      p.system_gain = 0.1;
      g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, NULL);
      g_autoptr (DsImage) dark = const_frame (DS_SAMPLE_F32, w, h, 32, 10);
      set_f32 (dark, 4, 1, NAN);
      g_assert_true (ds_phase_set_set_dark (set, dark, NULL));
      for (guint k = 0; k < n; k++)
        for (guint j = 0; j < m; j++) {
          g_autoptr (DsImage) f = const_frame (DS_SAMPLE_F32, w, h, 32, k == 0 ? 510 : 110);
          if (k == 0 && j == 0)
            set_f32 (f, 1, 1, NAN);
          if (k == 2)
            set_f32 (f, 2, 1, INFINITY);
          if (k == 3)
            set_f32 (f, 3, 1, -INFINITY);
          g_assert_true (ds_phase_set_accumulate (set, k, f, NULL));
        }
      g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, NULL);
      g_assert_cmpuint (sep->meta.flagged[3], ==, 4);
      for (guint y = 0; y < h; y++)
        for (guint x = 0; x < w; x++) {
          gboolean bad = y == 1 && x >= 1 && x <= 4;
          guint8 mk = test_pixel_u8 (sep->mask, x, y);
          g_assert_cmpint (!!(mk & DS_MASK_NONFINITE), ==, bad);
          const DsImage *outs[] = { sep->transmissive, sep->scattered, sep->max, sep->min, sep->mean,
                                    sep->sigma_transmissive, sep->sigma_scattered };
          for (guint o = 0; o < G_N_ELEMENTS (outs); o++) {
            float v = test_pixel_f32 (outs[o], x, y);
            g_assert_true (isfinite (v));
            if (bad)
              g_assert_cmpfloat (v, ==, 0);
          }
          if (!bad && est[e] != DS_ESTIMATOR_SINE) {
            g_assert_cmpfloat (test_pixel_f32 (sep->transmissive, x, y), ==, 400);
            g_assert_cmpfloat (test_pixel_f32 (sep->scattered, x, y), ==, 200);
          }
        }
    }
}

/* Finite inputs near the float range: lit +3e38 and unlit -3e38 give Ld = 6e38, which float32
 * cannot hold; such pixels are NONFINITE with zero outputs, never a silent Inf. Pixels whose
 * results fit (1e38 lit, 0 unlit) are exact. All estimators, with extrema and a noise model. */
static void
test_near_float_range (void)
{
  const guint w = 4, h = 1, n = 4;
  const DsEstimator est[] = { DS_ESTIMATOR_MAXMIN, DS_ESTIMATOR_SINE, DS_ESTIMATOR_ROBUST };
  /* column 0: +-3e38; 1: 1e38 / 0; 2: 3e38 everywhere (Lg = 2 * 3e38); 3: ordinary */
  const float lit[] = { 3e38f, 1e38f, 3e38f, 300 }, unlit[] = { -3e38f, 0, 3e38f, 100 };
  const gboolean overflow[] = { TRUE, FALSE, TRUE, FALSE };
  for (guint e = 0; e < 3; e++) {
    DsSeparationParams p;
    ds_separation_params_init (&p, n);
    p.estimator = est[e];
    p.keep_extrema = TRUE;
    p.system_gain = 0.5;
    if (est[e] == DS_ESTIMATOR_SINE)
      p.harmonic_gain = 0.5; /* any h: the point is the range */
    g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, NULL);
    for (guint k = 0; k < n; k++) {
      g_autoptr (DsImage) f = const_frame (DS_SAMPLE_F32, w, h, 32, 0);
      for (guint x = 0; x < w; x++) /* P = N = 4 pixels: phases 0 and 1 light x = 0, 1 ... */
        set_f32 (f, x, 0, k < 2 ? lit[x] : unlit[x]);
      g_assert_true (ds_phase_set_accumulate (set, k, f, NULL));
    }
    g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, NULL);
    g_assert_nonnull (sep);
    const DsImage *outs[] = { sep->transmissive, sep->scattered, sep->max, sep->min, sep->mean,
                              sep->sigma_transmissive, sep->sigma_scattered };
    for (guint x = 0; x < w; x++) {
      guint8 mk = test_pixel_u8 (sep->mask, x, 0);
      g_assert_cmpint (!!(mk & DS_MASK_NONFINITE), ==, overflow[x]);
      for (guint o = 0; o < G_N_ELEMENTS (outs); o++) {
        float v = test_pixel_f32 (outs[o], x, 0);
        g_assert_true (isfinite (v));
        if (overflow[x])
          g_assert_cmpfloat (v, ==, 0);
      }
    }
    if (est[e] != DS_ESTIMATOR_SINE)
      g_assert_cmpfloat (test_pixel_f32 (sep->transmissive, 1, 0), ==, 1e38f);
    g_assert_true (isfinite (sep->meta.noise_dn));
  }
}

/* Odd widths and padded strides (garbage in the padding) give what tight frames give, for u8,
 * u16 and f32 phases and a padded dark frame. */
static void
test_strides (void)
{
  const guint w = 13, h = 5, n = 5;
  static double ld[13 * 5], lg[13 * 5];
  for (guint i = 0; i < w * h; i++) {
    ld[i] = 40 + (i * 7) % 50;
    lg[i] = 2 * (10 + (i * 3) % 40);
  }
  TestPattern pat = { DS_PATTERN_SQUARE, 6.0, 0.5, 0.0 };
  const DsSampleType types[] = { DS_SAMPLE_U8, DS_SAMPLE_U16, DS_SAMPLE_F32 };
  const gsize strides[] = { 17, 64, 13 * 4 + 12 };
  for (guint t = 0; t < 3; t++) {
    DsSeparation *results[2] = { NULL, NULL };
    for (guint padded = 0; padded < 2; padded++) {
      DsSeparationParams p;
      ds_separation_params_init (&p, n);
      p.keep_extrema = TRUE;
      gsize stride = padded ? strides[t] : 0;
      g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, NULL);
      g_autoptr (DsImage) dark = test_make_frame (types[t], w, h, stride, &pat, 0, n, NULL, NULL, 3, 0, NULL);
      g_assert_true (ds_phase_set_set_dark (set, dark, NULL));
      for (guint k = 0; k < n; k++) {
        g_autoptr (DsImage) f = test_make_frame (types[t], w, h, stride, &pat, k, n, ld, lg, 3, 0, NULL);
        g_assert_true (ds_phase_set_accumulate (set, k, f, NULL));
      }
      results[padded] = ds_phase_set_finalize (set, NULL);
    }
    for (guint y = 0; y < h; y++)
      for (guint x = 0; x < w; x++) {
        gsize i = (gsize) y * w + x;
        g_assert_cmpfloat (test_pixel_f32 (results[1]->transmissive, x, y), ==, test_pixel_f32 (results[0]->transmissive, x, y));
        g_assert_cmpfloat (test_pixel_f32 (results[1]->scattered, x, y), ==, test_pixel_f32 (results[0]->scattered, x, y));
        g_assert_cmpfloat (test_pixel_f32 (results[1]->mean, x, y), ==, test_pixel_f32 (results[0]->mean, x, y));
        g_assert_cmpfloat (test_pixel_f32 (results[1]->transmissive, x, y), ==, ld[i]);
        g_assert_cmpfloat (test_pixel_f32 (results[1]->scattered, x, y), ==, lg[i]);
      }
    ds_separation_free (results[0]);
    ds_separation_free (results[1]);
  }
}

/* 1x1 frames: maxmin N = 2 (u16) and sine N = 3 (f32). No data noise estimate is possible. */
static void
test_one_pixel (void)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, 2);
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, 1, 1, NULL);
  g_autoptr (DsImage) a = const_frame (DS_SAMPLE_U16, 1, 1, 16, 700);
  g_autoptr (DsImage) b = const_frame (DS_SAMPLE_U16, 1, 1, 16, 300);
  g_assert_true (ds_phase_set_accumulate (set, 0, a, NULL));
  g_assert_true (ds_phase_set_accumulate (set, 1, b, NULL));
  g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, NULL);
  g_assert_cmpfloat (test_pixel_f32 (sep->transmissive, 0, 0), ==, 400);
  g_assert_cmpfloat (test_pixel_f32 (sep->scattered, 0, 0), ==, 600);
  g_assert_cmpuint (test_pixel_u8 (sep->mask, 0, 0), ==, 0);
  g_assert_true (isnan (sep->meta.noise_dn));

  ds_separation_params_init (&p, 3);
  p.estimator = DS_ESTIMATOR_SINE;
  p.pattern = DS_PATTERN_SINE;
  g_autoptr (DsPhaseSet) s3 = ds_phase_set_new (&p, 1, 1, NULL);
  /* pixel at x = 0: pattern 0.5 (1 + cos(2 pi k / 3)) = 1, 1/4, 1/4; Ld = 80, Lg = 20 */
  const double v[3] = { 80 + 10, 20 + 10, 20 + 10 };
  for (guint k = 0; k < 3; k++) {
    g_autoptr (DsImage) f = const_frame (DS_SAMPLE_F32, 1, 1, 32, v[k]);
    g_assert_true (ds_phase_set_accumulate (s3, k, f, NULL));
  }
  g_autoptr (DsSeparation) s = ds_phase_set_finalize (s3, NULL);
  g_assert_cmpfloat_with_epsilon (test_pixel_f32 (s->transmissive, 0, 0), 80, 1e-4);
  g_assert_cmpfloat_with_epsilon (test_pixel_f32 (s->scattered, 0, 0), 20, 1e-4);
}

/* 8192 x 8192, 2 phases of u16: Ld = |a - b| and Lg = 2 min(a, b) at every pixel. */
static void
test_8192 (void)
{
  const guint s = 8192;
  g_autoptr (DsImage) f0 = ds_image_new (DS_SAMPLE_U16, s, s, NULL);
  g_autoptr (DsImage) f1 = ds_image_new (DS_SAMPLE_U16, s, s, NULL);
  g_assert_nonnull (f0);
  g_assert_nonnull (f1);
  for (guint y = 0; y < s; y++) {
    guint16 *r0 = ds_image_row (f0, y), *r1 = ds_image_row (f1, y);
    for (guint x = 0; x < s; x++) {
      r0[x] = (guint16) ((x * 3 + y) & 0x7FFF);
      r1[x] = (guint16) ((x ^ y) & 0x7FFF);
    }
  }
  DsSeparationParams p;
  ds_separation_params_init (&p, 2);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, s, s, &error);
  g_assert_no_error (error);
  g_assert_true (ds_phase_set_accumulate (set, 0, f0, &error));
  g_assert_true (ds_phase_set_accumulate (set, 1, f1, &error));
  g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, &error);
  g_assert_no_error (error);
  guint64 wrong = 0;
  for (guint y = 0; y < s; y++) {
    const float *t = ds_image_row (sep->transmissive, y), *g = ds_image_row (sep->scattered, y);
    const guint16 *r0 = ds_image_row (f0, y), *r1 = ds_image_row (f1, y);
    for (guint x = 0; x < s; x++) {
      int a = r0[x], b = r1[x];
      wrong += t[x] != (float) abs (a - b) || g[x] != (float) (2 * MIN (a, b));
    }
  }
  g_assert_cmpuint (wrong, ==, 0);
}

/* Bad input fails with an error naming what and where, and folds nothing. */
static void
test_errors (void)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, 3);
  g_autoptr (GError) error = NULL;
  g_assert_null (ds_phase_set_new (&p, 0, 4, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_clear_error (&error);

  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, 8, 4, NULL);
  g_assert_null (ds_phase_set_finalize (set, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY);
  g_clear_error (&error);

  g_autoptr (DsImage) ok = const_frame (DS_SAMPLE_U16, 8, 4, 12, 100);
  g_autoptr (DsImage) small = const_frame (DS_SAMPLE_U16, 7, 4, 12, 100);
  g_autoptr (DsImage) byte = const_frame (DS_SAMPLE_U8, 8, 4, 8, 100);
  g_autoptr (DsImage) deep = const_frame (DS_SAMPLE_U16, 8, 4, 16, 100);

  g_assert_false (ds_phase_set_accumulate (set, 3, ok, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_assert_nonnull (strstr (error->message, "phase 3"));
  g_clear_error (&error);

  g_assert_false (ds_phase_set_accumulate (set, 0, small, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_assert_nonnull (strstr (error->message, "phase 0"));
  g_assert_nonnull (strstr (error->message, "7x4"));
  g_assert_nonnull (strstr (error->message, "8x4"));
  g_clear_error (&error);

  g_assert_true (ds_phase_set_accumulate (set, 0, ok, NULL));
  g_assert_false (ds_phase_set_accumulate (set, 1, byte, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_assert_nonnull (strstr (error->message, "phase 1"));
  g_clear_error (&error);
  g_assert_false (ds_phase_set_accumulate (set, 1, deep, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_assert_nonnull (strstr (error->message, "12 bits"));
  g_clear_error (&error);
  g_assert_cmpuint (ds_phase_set_frames_folded (set), ==, 1);

  g_assert_false (ds_phase_set_set_dark (set, byte, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_clear_error (&error);
  g_assert_false (ds_phase_set_set_dark (set, small, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_assert_nonnull (strstr (error->message, "dark"));
  g_clear_error (&error);

  g_assert_true (ds_phase_set_accumulate (set, 1, ok, NULL));
  g_assert_false (ds_phase_set_accumulate (set, 0, ok, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_assert_nonnull (strstr (error->message, "revisited"));
  g_clear_error (&error);

  g_assert_null (ds_phase_set_finalize (set, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_NOT_ENOUGH_PHASES);
  g_assert_nonnull (strstr (error->message, "phase 2"));
  g_clear_error (&error);

  g_assert_true (ds_phase_set_accumulate (set, 2, ok, NULL));
  g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, &error);
  g_assert_no_error (error);
  g_assert_cmpfloat (sep->meta.saturation_level, ==, 4095);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/separation-hard/all-saturated", test_all_saturated);
  g_test_add_func ("/separation-hard/partly-saturated", test_partly_saturated);
  g_test_add_func ("/separation-hard/all-dark", test_all_dark);
  g_test_add_func ("/separation-hard/dark-exceeds", test_dark_exceeds);
  g_test_add_func ("/separation-hard/tiny-direct-huge-global", test_tiny_direct_huge_global);
  g_test_add_func ("/separation-hard/1024-full-scale", test_1024_full_scale);
  g_test_add_func ("/separation-hard/black-level-high", test_black_level_high);
  g_test_add_func ("/separation-hard/nonfinite", test_nonfinite);
  g_test_add_func ("/separation-hard/near-float-range", test_near_float_range);
  g_test_add_func ("/separation-hard/strides", test_strides);
  g_test_add_func ("/separation-hard/one-pixel", test_one_pixel);
  g_test_add_func ("/separation-hard/8192", test_8192);
  g_test_add_func ("/separation-hard/errors", test_errors);
  return g_test_run ();
}
