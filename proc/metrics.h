/* Accuracy metrics against a known truth (the simulator's), for the accuracy study and the
 * tests: per-pixel work, so it lives in proc/. */
#pragma once
#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  double relative_rmse;   /* sqrt(sum (est - truth)^2 / sum truth^2) over valid pixels */
  double rmse;            /* in the images' units */
  double bias;            /* mean (est - truth) */
  guint64 valid;          /* pixels compared */
  guint64 masked;         /* pixels left out by the mask */
} DsErrorStats;

/* est and truth f32 of one size; mask u8 or NULL; pixels with (mask & ignore_bits) != 0 or a
 * non-finite value are left out. Fails on size/type mismatch or when no pixel is valid. */
gboolean ds_metrics_error (const DsImage *est, const DsImage *truth, const DsImage *mask,
                           guint8 ignore_bits, DsErrorStats *out, GError **error);

/* Stripe residue: the amplitude of the first harmonic at the pattern period left in an image
 * that should not carry the pattern (the transmissive image), relative to its mean. */
gboolean ds_metrics_stripe_residue (const DsImage *image, double period_px, double *residue,
                                    GError **error);

G_END_DECLS
