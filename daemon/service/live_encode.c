#include "daemon/service/live_encode.h"

#include <math.h>
#include <string.h>

#include "proc/live_image.h"
#include "proc/stripe_period.h"
#include "proc/stripe_phase.h"

#define HISTOGRAM_BINS 64
/* Full-resolution samples for frames up to this size (32 MB of u16): a page zooms to single
 * pixels and reads their values only from these. */
#define LIVE_MAX_SENSOR_PIXELS (16u * 1024 * 1024)

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

static const char *
number_or_null (char buf[G_ASCII_DTOSTR_BUF_SIZE], double v)
{
  return isfinite (v) ? g_ascii_dtostr (buf, G_ASCII_DTOSTR_BUF_SIZE, v) : "null";
}

static void
append_double (GString *s, const char *key, double v)
{
  char buf[G_ASCII_DTOSTR_BUF_SIZE];
  g_string_append_printf (s, ",\"%s\":%s", key, number_or_null (buf, v));
}

/* The sensor's significant bits and its full scale: a configured saturation level names both
 * (12-bit data in a 16-bit container clips at 4095, not 65535); else the image's depth. */
static void
significant_range (const DsImage *frame, double saturation_dn, guint *bits, double *full_scale)
{
  guint depth = frame->type == DS_SAMPLE_F32 ? 32 : frame->bit_depth;
  if (frame->type != DS_SAMPLE_F32 && saturation_dn >= 1) {
    guint b = 1;
    while (b < depth && (double) (1u << b) - 1 < saturation_dn)
      b++;
    *bits = b;
    *full_scale = MIN (saturation_dn, (double) ((1u << b) - 1));
    return;
  }
  *bits = depth;
  if (frame->type == DS_SAMPLE_F32) {
    double lo, hi;
    ds_image_levels (frame, 0, 100, &lo, &hi);
    *full_scale = hi;
  } else {
    *full_scale = (double) ((1u << depth) - 1);
  }
}

static double
image_mean (const DsImage *frame)
{
  double sum = 0;
  guint64 n = 0;
  for (guint y = 0; y < frame->height; y++) {
    const void *row = ds_image_row (frame, y);
    for (guint x = 0; x < frame->width; x++) {
      double v = ds_image_sample (frame, row, x);
      if (isfinite (v)) {
        sum += v;
        n++;
      }
    }
  }
  return n ? sum / (double) n : NAN;
}

/* The samples at full resolution, rows back to back, little-endian, 4-byte aligned. */
static void
add_sensor (Packer *p, GString *head, const DsImage *frame)
{
  if ((guint64) frame->width * frame->height > LIVE_MAX_SENSOR_PIXELS)
    return;
  static const guint8 zeros[4] = { 0 };
  g_byte_array_append (p->pixels, zeros, (4 - p->pixels->len % 4) % 4);
  gsize size = ds_sample_size (frame->type);
  g_string_append_printf (head, ",\"sensor\":{\"offset\":%u,\"width\":%u,\"height\":%u,\"sample\":\"%s\"}",
                          p->pixels->len, frame->width, frame->height,
                          frame->type == DS_SAMPLE_U8 ? "u8" : frame->type == DS_SAMPLE_U16 ? "u16" : "f32");
  guint at = p->pixels->len;
  for (guint y = 0; y < frame->height; y++)
    g_byte_array_append (p->pixels, ds_image_row (frame, y), (guint) (frame->width * size));
#if G_BYTE_ORDER == G_BIG_ENDIAN
  for (guint i = at; i + size <= p->pixels->len; i += size)
    for (gsize a = 0, b = size - 1; a < b; a++, b--) {
      guint8 t = p->pixels->data[i + a];
      p->pixels->data[i + a] = p->pixels->data[i + b];
      p->pixels->data[i + b] = t;
    }
#else
  (void) at;
#endif
}

static void
append_stripes (GString *head, const DsImage *frame, double period_px)
{
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
}

static void
append_levels (GString *head, const DsImage *frame, double saturation_dn)
{
  guint bits;
  double full_scale;
  significant_range (frame, saturation_dn, &bits, &full_scale);
  g_string_append_printf (head, ",\"significant_bits\":%u", bits);
  append_double (head, "full_scale_dn", full_scale);
  /* Bins from 0 to full scale; the top bin also counts what is at full scale (clipped). */
  guint32 bins[HISTOGRAM_BINS];
  guint64 full = 0;
  ds_image_histogram (frame, full_scale, HISTOGRAM_BINS, bins, &full);
  append_double (head, "histogram_top", full_scale);
  g_string_append (head, ",\"histogram\":[");
  for (guint i = 0; i < HISTOGRAM_BINS; i++)
    g_string_append_printf (head, "%s%u", i ? "," : "", bins[i]);
  g_string_append_printf (head, "],\"at_full_scale\":%" G_GUINT64_FORMAT, full);
  double p1, p50, p99, p999;
  ds_image_levels (frame, 1, 99, &p1, &p99);
  ds_image_levels (frame, 50, 99.9, &p50, &p999);
  char b1[G_ASCII_DTOSTR_BUF_SIZE], b50[G_ASCII_DTOSTR_BUF_SIZE], b99[G_ASCII_DTOSTR_BUF_SIZE],
      b999[G_ASCII_DTOSTR_BUF_SIZE];
  g_string_append_printf (head, ",\"percentiles\":{\"p1\":%s,\"p50\":%s,\"p99\":%s,\"p99_9\":%s}",
                          number_or_null (b1, p1), number_or_null (b50, p50), number_or_null (b99, p99),
                          number_or_null (b999, p999));
  append_double (head, "mean", image_mean (frame));
}

GBytes *
ds_live_encode_frame (const DsImage *frame, const DsLiveFrameInfo *info, guint max_side)
{
  GString *head = g_string_new ("{\"type\":\"frame\"");
  g_string_append_printf (head, ",\"phase\":%u,\"phases\":%u,\"frame_id\":%" G_GUINT64_FORMAT
                                ",\"width\":%u,\"height\":%u,\"bit_depth\":%u,\"time_unix_ms\":%" G_GINT64_FORMAT,
                          info->phase, info->n_phases, info->frame_id, frame->width, frame->height,
                          frame->bit_depth, info->time_unix_ms);
  append_double (head, "exposure_us", info->exposure_us);
  append_double (head, "gain_db", info->gain_db);
  append_stripes (head, frame, info->period_px);
  append_levels (head, frame, info->saturation_dn);
  Packer p = { g_string_new ("["), g_byte_array_new () };
  add_plane (&p, "raw", frame, 0.1, 99.9, max_side);
  add_sensor (&p, head, frame);
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
