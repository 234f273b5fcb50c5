#include "daemon/service/live_encode.h"

#include <math.h>
#include <string.h>

#include "proc/live_image.h"
#include "proc/stripe_period.h"
#include "proc/stripe_phase.h"

#define HISTOGRAM_BINS 64

typedef struct {
  GString *header; /* the "images" array being built */
  GByteArray *pixels;
} Packer;

static void
add_picture (Packer *p, const char *name, const DsImage *pic, double lo, double hi)
{
  char a[G_ASCII_DTOSTR_BUF_SIZE], b[G_ASCII_DTOSTR_BUF_SIZE];
  g_string_append_printf (p->header, "%s{\"name\":\"%s\",\"width\":%u,\"height\":%u,\"offset\":%u,\"lo\":%s,\"hi\":%s}",
                          p->header->len > 1 ? "," : "", name, pic->width, pic->height, p->pixels->len,
                          isfinite (lo) ? g_ascii_dtostr (a, sizeof a, lo) : "null",
                          isfinite (hi) ? g_ascii_dtostr (b, sizeof b, hi) : "null");
  for (guint y = 0; y < pic->height; y++)
    g_byte_array_append (p->pixels, ds_image_row (pic, y), pic->width);
}

/* A plane scaled between two percentiles. */
static void
add_plane (Packer *p, const char *name, const DsImage *plane, double lo_p, double hi_p, guint max_side)
{
  double lo, hi;
  ds_image_levels (plane, lo_p, hi_p, &lo, &hi);
  g_autoptr (DsImage) pic = ds_live_downscale_u8 (plane, max_side, lo, hi, NULL);
  if (pic)
    add_picture (p, name, pic, lo, hi);
}

static GBytes *
pack (const char *header_head, Packer *p, const char *header_tail)
{
  g_autofree char *header = g_strdup_printf ("%s,\"images\":[%s]%s}", header_head, p->header->str + 1,
                                             header_tail ? header_tail : "");
  guint32 len = GUINT32_TO_LE ((guint32) strlen (header));
  GByteArray *out = g_byte_array_sized_new (4 + strlen (header) + p->pixels->len);
  g_byte_array_append (out, (const guint8 *) &len, 4);
  g_byte_array_append (out, (const guint8 *) header, (guint) strlen (header));
  g_byte_array_append (out, p->pixels->data, p->pixels->len);
  g_string_free (p->header, TRUE);
  g_byte_array_unref (p->pixels);
  return g_byte_array_free_to_bytes (out);
}

static void
append_double (GString *s, const char *key, double v)
{
  char buf[G_ASCII_DTOSTR_BUF_SIZE];
  g_string_append_printf (s, ",\"%s\":%s", key, isfinite (v) ? g_ascii_dtostr (buf, sizeof buf, v) : "null");
}

GBytes *
ds_live_encode_frame (const DsImage *frame, guint phase, guint n_phases, guint64 frame_id, double period_px,
                      guint max_side)
{
  GString *head = g_string_new ("{\"type\":\"frame\"");
  g_string_append_printf (head, ",\"phase\":%u,\"phases\":%u,\"frame_id\":%" G_GUINT64_FORMAT
                                ",\"width\":%u,\"height\":%u,\"bit_depth\":%u",
                          phase, n_phases, frame_id, frame->width, frame->height, frame->bit_depth);
  append_double (head, "period_configured_px", period_px);
  /* The period the camera sees, then the phase at that period. */
  DsStripePeriod sp = { .period_px = NAN };
  double lo_px = MAX (2.5, period_px / 2), hi_px = MIN (frame->width / 2.0, period_px * 2);
  if (isfinite (period_px) && hi_px > lo_px)
    ds_stripe_period_measure (frame, lo_px, hi_px, &sp, NULL);
  append_double (head, "period_px", sp.period_px);
  append_double (head, "period_peak_ratio", sp.peak_ratio);
  double at = sp.reliable ? sp.period_px : period_px;
  DsStripePhase ph = { .phase = NAN, .modulation = NAN, .snr = NAN };
  if (isfinite (at) && at > 2 && at <= frame->width)
    ds_stripe_phase_measure (frame, at, NULL, &ph, NULL);
  append_double (head, "stripe_phase", ph.phase);
  append_double (head, "modulation", ph.modulation);
  append_double (head, "snr", ph.snr);
  g_string_append_printf (head, ",\"phase_reliable\":%s", ph.reliable ? "true" : "false");
  /* Histogram over the ADC's range; the top bin also counts what is at full scale. */
  double fmin, fmax;
  ds_image_levels (frame, 0, 100, &fmin, &fmax);
  double top = frame->type == DS_SAMPLE_F32 ? fmax + 1 : (double) (1u << frame->bit_depth);
  guint32 bins[HISTOGRAM_BINS];
  guint64 full = 0;
  ds_image_histogram (frame, frame->type == DS_SAMPLE_F32 ? top : top - 1, HISTOGRAM_BINS, bins, &full);
  append_double (head, "histogram_top", top);
  g_string_append (head, ",\"histogram\":[");
  for (guint i = 0; i < HISTOGRAM_BINS; i++)
    g_string_append_printf (head, "%s%u", i ? "," : "", bins[i]);
  g_string_append_printf (head, "],\"at_full_scale\":%" G_GUINT64_FORMAT, full);
  Packer p = { g_string_new ("["), g_byte_array_new () };
  add_plane (&p, "raw", frame, 0.1, 99.9, max_side);
  GBytes *out = pack (head->str, &p, NULL);
  g_string_free (head, TRUE);
  return out;
}

GBytes *
ds_live_encode_result (const DsSeparation *sep, const char *meta_json, guint max_side)
{
  Packer p = { g_string_new ("["), g_byte_array_new () };
  add_plane (&p, "transmissive", sep->transmissive, 0.5, 99.5, max_side);
  add_plane (&p, "scattered", sep->scattered, 0.5, 99.5, max_side);
  /* What a camera under the same light without stripes would give: the phases' mean. */
  g_autoptr (DsImage) average = NULL;
  if (!sep->mean && isfinite (sep->meta.pattern_mean))
    average = ds_image_weighted_sum (sep->transmissive, sep->meta.pattern_mean, sep->scattered,
                                     sep->meta.pattern_mean, NULL);
  const DsImage *avg = sep->mean ? sep->mean : average;
  if (avg)
    add_plane (&p, "average", avg, 0.5, 99.5, max_side);
  g_autoptr (DsImage) mask = ds_live_downscale_u8 (sep->mask, max_side, NAN, NAN, NULL);
  if (mask)
    add_picture (&p, "mask", mask, NAN, NAN);
  g_autofree char *tail = g_strdup_printf (",\"meta\":%s", meta_json ? meta_json : "null");
  return pack ("{\"type\":\"result\"", &p, tail);
}
