/* Shared by the renderer tests (tests/sim/renderer_*.c): a 64 x 48 scene with a known photon
 * budget, and helpers to read frames and truth. */
#pragma once
#include <math.h>
#include <string.h>

#include "drivers/sim/renderer.h"

/* 64x48 px, 0.1 mm pixels (5 um / 0.05): 1 photon/um^2/ms is 1e4 photons/px/ms. */
#define PX_PHOTONS_PER_MS 1e4
#define EXPOSURE_US 1000.0
#define QE 0.5
#define K 0.25

static G_GNUC_UNUSED DsScene *
scene_from (const char *extra, const char *illum)
{
  g_autofree char *text = g_strdup_printf (
    "[sensor]\nwidth=64\nheight=48\nbit-depth=16\nquantum-efficiency=%g\nsystem-gain=%g\nread-noise-e=3\n"
    "dark-current-e-per-s=1000\nfull-well-e=1e6\nexposure-us=%g\n"
    "[illuminator]\nperiod-px=8\nirradiance=1\n%s\n%s", QE, K, EXPOSURE_US, illum ? illum : "", extra);
  g_autoptr (GError) error = NULL;
  DsScene *s = ds_scene_load_data (text, strlen (text), "renderer-test.scene", &error);
  g_assert_no_error (error);
  return s;
}

/* DN of the "on" level with no medium: photons x QE x K. */
static G_GNUC_UNUSED double
open_dn (void)
{
  return PX_PHOTONS_PER_MS * EXPOSURE_US / 1000 * QE * K;
}

static G_GNUC_UNUSED float
px (const DsImage *im, guint x, guint y)
{
  return ((const float *) ds_image_row (im, y))[x];
}

static G_GNUC_UNUSED void
truth (const DsRenderer *r, DsImage **t, DsImage **s)
{
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_renderer_truth (r, EXPOSURE_US, 0, t, s, &error));
  g_assert_no_error (error);
}

static G_GNUC_UNUSED void
assert_uniform (const DsImage *im, double expect, double rel)
{
  for (guint y = 0; y < im->height; y++)
    for (guint x = 0; x < im->width; x++)
      if (fabs (px (im, x, y) - expect) > rel * fabs (expect) + 1e-6)
        g_error ("pixel (%u, %u) = %g, expected %g", x, y, px (im, x, y), expect);
}

static G_GNUC_UNUSED double
square_lit (double x, guint k, guint n, double period, double duty)
{
  double u = x / period - (double) k / n;
  u -= floor (u + 0.5); /* [-1/2, 1/2) */
  double edge = fabs (fabs (u) - duty / 2) * period;
  if (edge < 0.6)
    return -1;
  return fabs (u) < duty / 2 ? 1 : 0;
}

static G_GNUC_UNUSED DsImage *
gaussian_kernel (guint radius, double sigma, double total)
{
  g_autoptr (GError) error = NULL;
  DsImage *k = ds_image_new (DS_SAMPLE_F32, 2 * radius + 1, 2 * radius + 1, &error);
  double sum = 0;
  for (guint y = 0; y < k->height; y++)
    for (guint x = 0; x < k->width; x++) {
      double dx = (double) x - radius, dy = (double) y - radius;
      sum += ((float *) ds_image_row (k, y))[x] = (float) exp (-(dx * dx + dy * dy) / (2 * sigma * sigma));
    }
  for (guint y = 0; y < k->height; y++)
    for (guint x = 0; x < k->width; x++)
      ((float *) ds_image_row (k, y))[x] *= (float) (total / sum);
  return k;
}

