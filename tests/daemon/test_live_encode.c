/* The live view's frame message (daemon/service/live_encode.h) read as a browser reads it: the
 * header's significant bits, full scale, histogram, clipped count, mean and percentiles, and the
 * full-resolution samples, each against what the test computes from the pixels it wrote. The
 * case the page depends on: 12-bit data in a 16-bit container spans 0..4095 once
 * [camera] saturation-dn names the sensor's top. */
#include <json-glib/json-glib.h>
#include <math.h>
#include <string.h>

#include "daemon/service/live_encode.h"

#define W 64
#define H 48

typedef struct {
  JsonParser *parser;
  JsonObject *header;
  const guint8 *pixels; /* after the header */
  gsize n_pixels;
} Message;

static void
message_parse (Message *m, GBytes *bytes)
{
  gsize size;
  const guint8 *data = g_bytes_get_data (bytes, &size);
  g_assert_cmpuint (size, >=, 4);
  guint32 len = (guint32) data[0] | (guint32) data[1] << 8 | (guint32) data[2] << 16 | (guint32) data[3] << 24;
  g_assert_cmpuint (4 + (gsize) len, <=, size);
  m->parser = json_parser_new ();
  g_assert_true (json_parser_load_from_data (m->parser, (const char *) data + 4, len, NULL));
  m->header = json_node_get_object (json_parser_get_root (m->parser));
  m->pixels = data + 4 + len;
  m->n_pixels = size - 4 - len;
}

/* 12-bit values, a ramp over the whole range with every 50th pixel at the top. */
static guint16
value_at (guint i)
{
  return i % 50 == 0 ? 4095 : (guint16) ((i * 37u) % 4096u);
}

static DsImage *
make_frame (guint bit_depth)
{
  DsImage *img = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  img->bit_depth = bit_depth;
  for (guint y = 0; y < H; y++) {
    guint16 *row = ds_image_row (img, y);
    for (guint x = 0; x < W; x++)
      row[x] = value_at (y * W + x);
  }
  return img;
}

static int
cmp_u16 (const void *a, const void *b)
{
  return (int) *(const guint16 *) a - (int) *(const guint16 *) b;
}

/* Checks a message against the values written, for a sensor whose top is full_scale. */
static void
check_frame (GBytes *bytes, guint expect_bits, double full_scale, guint container_bits)
{
  Message m;
  message_parse (&m, bytes);
  JsonObject *h = m.header;
  g_assert_cmpstr (json_object_get_string_member (h, "type"), ==, "frame");
  g_assert_cmpint (json_object_get_int_member (h, "bit_depth"), ==, container_bits);
  g_assert_cmpint (json_object_get_int_member (h, "significant_bits"), ==, expect_bits);
  g_assert_cmpfloat (json_object_get_double_member (h, "full_scale_dn"), ==, full_scale);
  guint32 bins[64] = { 0 };
  guint64 clipped = 0;
  double sum = 0;
  guint16 sorted[W * H];
  for (guint i = 0; i < W * H; i++) {
    guint16 v = value_at (i);
    sorted[i] = v;
    sum += v;
    if (v >= full_scale) {
      clipped++;
      bins[63]++;
    } else {
      bins[MIN (63u, (guint) floor (v / full_scale * 64))]++;
    }
  }
  JsonArray *hist = json_object_get_array_member (h, "histogram");
  g_assert_cmpuint (json_array_get_length (hist), ==, 64);
  for (guint i = 0; i < 64; i++)
    g_assert_cmpint (json_array_get_int_element (hist, i), ==, bins[i]);
  g_assert_cmpint (json_object_get_int_member (h, "at_full_scale"), ==, (gint64) clipped);
  g_assert_cmpfloat_with_epsilon (json_object_get_double_member (h, "mean"), sum / (W * H), 1e-9);
  qsort (sorted, W * H, sizeof sorted[0], cmp_u16);
  JsonObject *pc = json_object_get_object_member (h, "percentiles");
  /* Any rank convention lands within one sample of the nearest rank. */
  g_assert_cmpfloat (fabs (json_object_get_double_member (pc, "p50") - sorted[W * H / 2]), <=, 37);
  g_assert_cmpfloat (json_object_get_double_member (pc, "p99_9"), ==, 4095);
  /* The samples as written, little-endian, 4-byte aligned. */
  JsonObject *s = json_object_get_object_member (h, "sensor");
  g_assert_cmpstr (json_object_get_string_member (s, "sample"), ==, "u16");
  gint64 off = json_object_get_int_member (s, "offset");
  g_assert_cmpint (off % 4, ==, 0);
  g_assert_cmpint (json_object_get_int_member (s, "width"), ==, W);
  g_assert_cmpint (json_object_get_int_member (s, "height"), ==, H);
  g_assert_cmpuint ((gsize) off + 2 * W * H, <=, m.n_pixels);
  for (guint i = 0; i < W * H; i++)
    g_assert_cmpuint ((guint) m.pixels[off + 2 * i] | (guint) m.pixels[off + 2 * i + 1] << 8, ==, value_at (i));
  g_object_unref (m.parser);
}

static void
test_container (void)
{
  g_autoptr (DsImage) img = make_frame (16);
  DsLiveFrameInfo info = { .phase = 1, .n_phases = 4, .frame_id = 9, .period_px = 8, .saturation_dn = 4095 };
  g_autoptr (GBytes) with_top = ds_live_encode_frame (img, &info, 640);
  check_frame (with_top, 12, 4095, 16);
  /* Without it the container's 16 bits are all the daemon knows: 0..65535, nothing clipped. */
  info.saturation_dn = 0;
  g_autoptr (GBytes) container = ds_live_encode_frame (img, &info, 640);
  Message m;
  message_parse (&m, container);
  g_assert_cmpint (json_object_get_int_member (m.header, "significant_bits"), ==, 16);
  g_assert_cmpint (json_object_get_int_member (m.header, "at_full_scale"), ==, 0);
  g_object_unref (m.parser);
}

static void
test_significant_depth (void)
{
  g_autoptr (DsImage) img = make_frame (12);
  DsLiveFrameInfo info = { .n_phases = 4, .period_px = 8 };
  g_autoptr (GBytes) plain = ds_live_encode_frame (img, &info, 640);
  check_frame (plain, 12, 4095, 12);
  /* A full well below the ADC's top: full scale there, still 12 significant bits. */
  info.saturation_dn = 3000;
  g_autoptr (GBytes) well = ds_live_encode_frame (img, &info, 640);
  Message m;
  message_parse (&m, well);
  g_assert_cmpint (json_object_get_int_member (m.header, "significant_bits"), ==, 12);
  g_assert_cmpfloat (json_object_get_double_member (m.header, "full_scale_dn"), ==, 3000);
  guint64 clipped = 0;
  for (guint i = 0; i < W * H; i++)
    clipped += value_at (i) >= 3000;
  g_assert_cmpint (json_object_get_int_member (m.header, "at_full_scale"), ==, (gint64) clipped);
  g_object_unref (m.parser);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/live-encode/12-bit-in-16-bit-container", test_container);
  g_test_add_func ("/live-encode/significant-depth", test_significant_depth);
  return g_test_run ();
}
