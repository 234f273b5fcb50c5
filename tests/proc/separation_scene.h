/* Test helpers for the separation tests: synthetic phase sets with known Ld and Lg, written
 * from the project's pattern convention independently of proc/ (no proc/ function is used to
 * make the expectation). Header-only, static. */
#pragma once
#include <glib.h>
#include <math.h>
#include <string.h>

#include "proc/image.h"
#include "proc/separation.h"

typedef struct {
  DsPatternKind kind;
  double period; /* pixels */
  double duty;   /* a (square only) */
  double black;  /* b */
} TestPattern;

/* value of the pattern (0..1 with black level b) at pixel x for phase k of n */
static inline double
test_pattern_value (const TestPattern *p, double x, guint k, guint n)
{
  double u = x / p->period - (double) k / n;
  u -= floor (u + 0.5); /* [-1/2, 1/2) */
  double on = p->kind == DS_PATTERN_SQUARE ? (fabs (u) < p->duty / 2 ? 1.0 : 0.0)
                                           : 0.5 * (1.0 + cos (2 * G_PI * u));
  return p->black + (1.0 - p->black) * on;
}

/* pattern mean m, from the definition (not from proc/) */
static inline double
test_pattern_mean (const TestPattern *p)
{
  return p->kind == DS_PATTERN_SQUARE ? p->duty + p->black * (1 - p->duty)
                                      : p->black + (1 - p->black) * 0.5;
}

static inline double
test_gauss (GRand *r)
{
  double u1 = g_rand_double_range (r, 1e-300, 1.0), u2 = g_rand_double (r);
  return sqrt (-2 * log (u1)) * cos (2 * G_PI * u2);
}

/* Frame k of n: Ld * pattern + Lg * m + offset (+ sigma * noise), per pixel from arrays of
 * w*h doubles (NULL: 0). Integer types are rounded (and clamped to the type's range).
 * stride 0: the tightest. */
static inline DsImage *
test_make_frame (DsSampleType type, guint w, guint h, gsize stride, const TestPattern *p, guint k,
                 guint n, const double *ld, const double *lg, double offset, double sigma, GRand *r)
{
  g_autoptr (GError) error = NULL;
  DsImage *img = stride ? ds_image_new_with_stride (type, w, h, stride, &error)
                        : ds_image_new (type, w, h, &error);
  g_assert_no_error (error);
  /* padding gets garbage so that reading it would show */
  memset (img->data, 0xA5, img->stride * h);
  double m = test_pattern_mean (p);
  for (guint y = 0; y < h; y++) {
    void *row = ds_image_row (img, y);
    for (guint x = 0; x < w; x++) {
      gsize i = (gsize) y * w + x;
      double v = (ld ? ld[i] : 0) * test_pattern_value (p, x, k, n) + (lg ? lg[i] : 0) * m + offset;
      if (sigma > 0)
        v += sigma * test_gauss (r);
      if (type == DS_SAMPLE_U8)
        ((guint8 *) row)[x] = (guint8) CLAMP (lround (v), 0, 255);
      else if (type == DS_SAMPLE_U16)
        ((guint16 *) row)[x] = (guint16) CLAMP (lround (v), 0, 65535);
      else
        ((float *) row)[x] = (float) v;
    }
  }
  return img;
}

static inline float
test_pixel_f32 (const DsImage *img, guint x, guint y)
{
  return ((const float *) ds_image_row (img, y))[x];
}

static inline guint8
test_pixel_u8 (const DsImage *img, guint x, guint y)
{
  return ((const guint8 *) ds_image_row (img, y))[x];
}

/* Folds frames 0..n-1 made by test_make_frame and finalizes. */
static inline DsSeparation *
test_separate (const DsSeparationParams *params, DsSampleType type, guint w, guint h, gsize stride,
               const TestPattern *p, const double *ld, const double *lg, double offset,
               double sigma, GRand *r, GError **error)
{
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (params, w, h, error);
  if (!set)
    return NULL;
  for (guint k = 0; k < params->n_phases; k++) {
    g_autoptr (DsImage) f = test_make_frame (type, w, h, stride, p, k, params->n_phases, ld, lg,
                                             offset, sigma, r);
    if (!ds_phase_set_accumulate (set, k, f, error))
      return NULL;
  }
  return ds_phase_set_finalize (set, error);
}
