#include "proc/metrics.h"

#include <math.h>

#include "proc/proc_error.h"
#include "proc/stripe_phase.h"

gboolean
ds_metrics_error (const DsImage *est, const DsImage *truth, const DsImage *mask, guint8 ignore_bits,
                  DsErrorStats *out, GError **error)
{
  if (est->type != DS_SAMPLE_F32 || truth->type != DS_SAMPLE_F32 || !ds_image_same_shape (est, truth) ||
      (mask && (mask->type != DS_SAMPLE_U8 || mask->width != est->width || mask->height != est->height))) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "metrics: estimate %ux%u, truth %ux%u and mask must be f32, f32 and u8 of one size",
                 est->width, est->height, truth->width, truth->height);
    return FALSE;
  }
  double se = 0, st = 0, sb = 0;
  guint64 valid = 0, masked = 0;
  for (guint y = 0; y < est->height; y++) {
    const float *e = ds_image_row (est, y), *t = ds_image_row (truth, y);
    const guint8 *m = mask ? ds_image_row (mask, y) : NULL;
    for (guint x = 0; x < est->width; x++) {
      if ((m && (m[x] & ignore_bits)) || !isfinite (e[x]) || !isfinite (t[x])) {
        masked++;
        continue;
      }
      double d = (double) e[x] - t[x];
      se += d * d;
      sb += d;
      st += (double) t[x] * t[x];
      valid++;
    }
  }
  if (!valid) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY, "metrics: no valid pixel to compare");
    return FALSE;
  }
  out->rmse = sqrt (se / valid);
  out->relative_rmse = st > 0 ? sqrt (se / st) : INFINITY;
  out->bias = sb / valid;
  out->valid = valid;
  out->masked = masked;
  return TRUE;
}

gboolean
ds_metrics_stripe_residue (const DsImage *image, double period_px, double *residue, GError **error)
{
  DsStripePhase sp;
  if (!ds_stripe_phase_measure (image, period_px, NULL, &sp, error))
    return FALSE;
  *residue = sp.mean > 0 ? sp.amplitude / sp.mean : 0.0;
  return TRUE;
}
