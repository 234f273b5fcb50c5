/* Does a calibration reference scatter? (calibration_scatter.h) */
#include "proc/calibration_scatter.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Dim and bright thirds this far apart in brightness tell a black level (the same fraction on
 * both) from scattered light; a difference in the fraction already shows at 1.1. */
#define CONTRAST_TO_CLEAR 1.5
#define CONTRAST_TO_SEE 1.1
/* A difference in the off-stripe fraction above noise and pixel-to-pixel spread of a clear
 * reference (tests/proc/test_ctl_calibrate.c: < 0.005 on clear references). */
#define FRACTION_DIFFERENCE 0.02
/* The profile fit's rms residual over the profile's range that calls the shape not a blurred
 * square (and 5 times the profile's own noise): clear simulated references leave 0.01-0.18 %
 * (duty 0.3-0.67, black level 0-0.14, blur 0-1.5 px, low light), references in a forward-
 * scattering medium 0.8-7 % (tests/proc/test_ctl_calibrate.c, tests/daemon/test_calibrate.py).
 * A real projector's defocus is not exactly Gaussian: a residual from it would warn too, and the
 * warning names the residual. */
#define SHAPE_RESIDUAL 0.005

typedef struct {
  double rel, off;
} RelOff;

static int
compare_doubles (const void *a, const void *b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return x < y ? -1 : x > y;
}

static int
compare_rel (const void *a, const void *b)
{
  return compare_doubles (&((const RelOff *) a)->rel, &((const RelOff *) b)->rel);
}

static double
median_of (double *v, gsize n)
{
  qsort (v, n, sizeof (double), compare_doubles);
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void
ds_calibration_scatter_check (const double *brightness, const double *off, guint w, guint h, double period,
                              DsScatterCheck *out)
{
  memset (out, 0, sizeof *out);
  gsize stride = (gsize) w + 1;
  g_autofree double *integral = g_new0 (double, stride * (h + 1));
  g_autofree guint *counts = g_new0 (guint, stride * (h + 1));
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      double v = brightness[(gsize) y * w + x];
      gboolean use = v > 0 && isfinite (v);
      gsize k = (gsize) (y + 1) * stride + x + 1;
      integral[k] = (use ? v : 0) + integral[k - 1] + integral[k - stride] - integral[k - stride - 1];
      counts[k] = (use ? 1 : 0) + counts[k - 1] + counts[k - stride] - counts[k - stride - 1];
    }
  guint radius = (guint) MAX (4.0, ceil (period));
  g_autofree RelOff *v = g_new (RelOff, (gsize) w * h);
  gsize n = 0;
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      gsize i = (gsize) y * w + x;
      if (!(brightness[i] > 0) || !isfinite (brightness[i]) || !isfinite (off[i]))
        continue;
      guint x0 = x > radius ? x - radius : 0, x1 = MIN (w, x + radius + 1);
      guint y0 = y > radius ? y - radius : 0, y1 = MIN (h, y + radius + 1);
      gsize a = (gsize) y0 * stride + x0, b = (gsize) y0 * stride + x1;
      gsize c = (gsize) y1 * stride + x0, e = (gsize) y1 * stride + x1;
      guint count = counts[e] - counts[b] - counts[c] + counts[a];
      double local = (integral[e] - integral[b] - integral[c] + integral[a]) / MAX (count, 1u);
      if (count == 0 || !(local > 0))
        continue;
      v[n++] = (RelOff) { brightness[i] / local, off[i] };
    }
  if (n < 90)
    return;
  qsort (v, n, sizeof (RelOff), compare_rel);
  gsize third = n / 3;
  g_autofree double *dim = g_new (double, third), *bright = g_new (double, third);
  g_autofree double *rel_dim = g_new (double, third), *rel_bright = g_new (double, third);
  for (gsize i = 0; i < third; i++) {
    dim[i] = v[i].off;
    rel_dim[i] = v[i].rel;
    bright[i] = v[n - 1 - i].off;
    rel_bright[i] = v[n - 1 - i].rel;
  }
  out->off_dim = median_of (dim, third);
  out->off_bright = median_of (bright, third);
  double rd = median_of (rel_dim, third), rb = median_of (rel_bright, third);
  out->brightness_contrast = rd > 0 ? rb / rd : 0;
  double tolerance = MAX (FRACTION_DIFFERENCE, 0.15 * out->off_bright);
  out->spatial = out->brightness_contrast >= CONTRAST_TO_SEE && out->off_dim - out->off_bright > tolerance;
  out->measured = out->spatial || out->brightness_contrast >= CONTRAST_TO_CLEAR;
  out->scattering = out->spatial || out->shape_misfit;
}

gboolean
ds_calibration_shape_fits (double residual, double noise)
{
  return residual <= MAX (SHAPE_RESIDUAL, 5 * noise);
}

void
ds_calibration_scatter_shape (DsScatterCheck *c)
{
  c->shape_misfit = !ds_calibration_shape_fits (c->shape_residual, c->shape_noise);
  c->scattering = c->spatial || c->shape_misfit;
}
