/* Pixel formats against byte patterns worked out by hand from the PFNC / GigE Vision layouts
 * (the expected bytes are written literally; see the comments for the bit arithmetic). */
#include <glib.h>
#include <string.h>

#include "proc/pixfmt.h"
#include "proc/proc_error.h"

static DsImage *
image_u16 (guint w, guint h, const guint16 *px, guint depth)
{
  DsImage *img = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
  g_assert_nonnull (img);
  img->bit_depth = depth;
  for (guint y = 0; y < h; y++)
    memcpy (ds_image_row (img, y), px + (gsize) y * w, w * 2u);
  return img;
}

/* Unpacks from an exactly sized heap copy (so ASan sees any overread) and compares. */
static void
check_unpack (DsPixelFormat fmt, const guint8 *bytes, gsize n, guint w, guint h, gsize stride,
              const guint16 *expect)
{
  guint8 *copy = g_memdup2 (bytes, n);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsImage) img = ds_pixfmt_unpack (fmt, copy, n, w, h, stride, &error);
  g_assert_no_error (error);
  g_assert_nonnull (img);
  g_assert_cmpuint (img->width, ==, w);
  g_assert_cmpuint (img->height, ==, h);
  g_assert_cmpuint (img->bit_depth, ==, ds_pixfmt_bit_depth (fmt));
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      guint got = fmt == DS_PIXFMT_MONO8 ? ((guint8 *) ds_image_row (img, y))[x]
                                         : ((guint16 *) ds_image_row (img, y))[x];
      g_assert_cmphex (got, ==, expect[y * w + x]);
    }
  g_free (copy);
}

static void
check_pack (DsPixelFormat fmt, const guint16 *px, guint w, guint h, gsize stride, const guint8 *expect,
            gsize n)
{
  g_autoptr (DsImage) img = NULL;
  if (fmt == DS_PIXFMT_MONO8) {
    img = ds_image_new (DS_SAMPLE_U8, w, h, NULL);
    for (guint i = 0; i < w * h; i++)
      ((guint8 *) ds_image_row (img, i / w))[i % w] = (guint8) px[i];
  } else {
    img = image_u16 (w, h, px, ds_pixfmt_bit_depth (fmt));
  }
  g_autoptr (GError) error = NULL;
  g_autoptr (GBytes) b = ds_pixfmt_pack (fmt, img, stride, &error);
  g_assert_no_error (error);
  gsize got_n;
  const guint8 *got = g_bytes_get_data (b, &got_n);
  g_assert_cmpmem (got, got_n, expect, n);
}

static void
test_names_codes (void)
{
  /* PFNC 2.x codes; the non-"p" ones also match Aravis's ARV_PIXEL_FORMAT_MONO_* constants. */
  static const struct { const char *name; guint32 code; guint depth; } table[] = {
    { "Mono8", 0x01080001u, 8 },   { "Mono10", 0x01100003u, 10 }, { "Mono12", 0x01100005u, 12 },
    { "Mono16", 0x01100007u, 16 }, { "Mono10p", 0x010A0046u, 10 }, { "Mono12p", 0x010C0047u, 12 },
    { "Mono12Packed", 0x010C0006u, 12 },
  };
  for (gsize i = 0; i < G_N_ELEMENTS (table); i++) {
    DsPixelFormat f, g;
    g_assert_true (ds_pixfmt_from_name (table[i].name, &f));
    g_assert_cmpstr (ds_pixfmt_name (f), ==, table[i].name);
    g_assert_cmphex (ds_pixfmt_to_pfnc (f), ==, table[i].code);
    g_assert_true (ds_pixfmt_from_pfnc (table[i].code, &g));
    g_assert_cmpint (f, ==, g);
    g_assert_cmpuint (ds_pixfmt_bit_depth (f), ==, table[i].depth);
    /* held in the smallest sample that fits the depth: u8 for 8 bits, u16 above */
    g_assert_cmpint (ds_pixfmt_sample_type (f), ==, table[i].depth <= 8 ? DS_SAMPLE_U8 : DS_SAMPLE_U16);
  }
  DsPixelFormat f = DS_PIXFMT_MONO8;
  g_assert_false (ds_pixfmt_from_name ("Mono14", &f));
  g_assert_false (ds_pixfmt_from_name ("", &f));
  g_assert_false (ds_pixfmt_from_pfnc (0x010C0004u /* Mono10Packed: not supported */, &f));
  g_assert_cmpstr (ds_pixfmt_name ((DsPixelFormat) 99), ==, "invalid");
  /* Row sizes: ceil(width * bits / 8). */
  g_assert_cmpuint (ds_pixfmt_row_bytes (DS_PIXFMT_MONO10P, 3), ==, 4);   /* 30 bits */
  g_assert_cmpuint (ds_pixfmt_row_bytes (DS_PIXFMT_MONO12P, 3), ==, 5);   /* 36 bits */
  g_assert_cmpuint (ds_pixfmt_row_bytes (DS_PIXFMT_MONO12PACKED, 1), ==, 2);
  g_assert_cmpuint (ds_pixfmt_row_bytes (DS_PIXFMT_MONO12, 3), ==, 6);
  g_assert_cmpuint (ds_pixfmt_image_bytes (DS_PIXFMT_MONO10P, 3, 2, 0), ==, 8); /* 60 bits */
  g_assert_cmpuint (ds_pixfmt_image_bytes (DS_PIXFMT_MONO10P, 3, 2, 7), ==, 11);
}

static void
test_mono8_16 (void)
{
  static const guint8 m8[] = { 0x00, 0x7F, 0xFF, 0x10, 0x20, 0x30 };
  static const guint16 m8px[] = { 0x00, 0x7F, 0xFF, 0x10, 0x20, 0x30 };
  check_unpack (DS_PIXFMT_MONO8, m8, sizeof m8, 3, 2, 0, m8px);
  check_pack (DS_PIXFMT_MONO8, m8px, 3, 2, 0, m8, sizeof m8);
  /* Stride 4: one padding byte per row; the last row has none. */
  static const guint8 m8s[] = { 0x00, 0x7F, 0xFF, 0xEE, 0x10, 0x20, 0x30 };
  check_unpack (DS_PIXFMT_MONO8, m8s, sizeof m8s, 3, 2, 4, m8px);

  /* Little-endian words: 0xBEEF -> EF BE. */
  static const guint8 m16[] = { 0xEF, 0xBE, 0x01, 0x00, 0xFF, 0xFF };
  static const guint16 m16px[] = { 0xBEEF, 0x0001, 0xFFFF };
  check_unpack (DS_PIXFMT_MONO16, m16, sizeof m16, 3, 1, 0, m16px);
  check_pack (DS_PIXFMT_MONO16, m16px, 3, 1, 0, m16, sizeof m16);

  static const guint8 m10[] = { 0x23, 0x01, 0xFF, 0x03, 0x00, 0x00 };
  static const guint16 m10px[] = { 0x123, 0x3FF, 0x000 };
  check_unpack (DS_PIXFMT_MONO10, m10, sizeof m10, 3, 1, 0, m10px);
  check_pack (DS_PIXFMT_MONO10, m10px, 3, 1, 0, m10, sizeof m10);
  static const guint8 m12[] = { 0xFF, 0x0F, 0x34, 0x02 };
  static const guint16 m12px[] = { 0xFFF, 0x234 };
  check_unpack (DS_PIXFMT_MONO12, m12, sizeof m12, 2, 1, 0, m12px);

  /* A Mono10 word with bit 10 set is not Mono10: refused, naming the pixel. */
  static const guint8 bad[] = { 0x00, 0x00, 0x00, 0x04 };
  g_autoptr (GError) error = NULL;
  DsImage *img = ds_pixfmt_unpack (DS_PIXFMT_MONO10, bad, sizeof bad, 2, 1, 0, &error);
  g_assert_null (img);
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT);
  g_assert_nonnull (strstr (error->message, "(1, 0)"));
}

static void
test_mono10p (void)
{
  /* P = 0x123, 0x2AB, 0x3C5, 0x3FE, LSB-first 10-bit stream:
   *  b0 = P0[7:0] = 0x23
   *  b1 = P1[5:0] << 2 | P0[9:8] = 0x2B << 2 | 1 = 0xAD
   *  b2 = P2[3:0] << 4 | P1[9:6] = 0x5 << 4 | 0xA = 0x5A
   *  b3 = P3[1:0] << 6 | P2[9:4] = 2 << 6 | 0x3C = 0xBC
   *  b4 = P3[9:2] = 0xFF */
  static const guint8 four[] = { 0x23, 0xAD, 0x5A, 0xBC, 0xFF };
  static const guint16 px4[] = { 0x123, 0x2AB, 0x3C5, 0x3FE };
  check_unpack (DS_PIXFMT_MONO10P, four, sizeof four, 4, 1, 0, px4);
  check_pack (DS_PIXFMT_MONO10P, px4, 4, 1, 0, four, sizeof four);

  /* Width 3, two rows, continuous: the second row starts at bit 30, mid-byte. Pixels 4 and 5
   * are 0x000 and 0x155: b5 = 0x00, b6 = P5[5:0] << 2 = 0x15 << 2 = 0x54, b7 = P5[9:6] = 0x5.
   * 60 bits -> 8 bytes. */
  static const guint8 cont[] = { 0x23, 0xAD, 0x5A, 0xBC, 0xFF, 0x00, 0x54, 0x05 };
  static const guint16 px6[] = { 0x123, 0x2AB, 0x3C5, 0x3FE, 0x000, 0x155 };
  check_unpack (DS_PIXFMT_MONO10P, cont, sizeof cont, 3, 2, 0, px6);
  check_pack (DS_PIXFMT_MONO10P, px6, 3, 2, 0, cont, sizeof cont);

  /* Same pixels with stride 5: each row restarts the stream. Row 0: 0x123, 0x2AB, 0x3C5 ->
   * 23 AD 5A 3C(P2[9:4] only) + 1 pad; row 1: 0x3FE, 0x000, 0x155 -> b0 = 0xFE, b1 = P0[9:8] = 3,
   * b2 = P2[3:0] << 4 = 0x50, b3 = P2[9:4] = 0x15. */
  static const guint8 strided[] = { 0x23, 0xAD, 0x5A, 0x3C, 0x00, 0xFE, 0x03, 0x50, 0x15 };
  check_unpack (DS_PIXFMT_MONO10P, strided, sizeof strided, 3, 2, 5, px6);
  static const guint8 strided_packed[] = { 0x23, 0xAD, 0x5A, 0x3C, 0x00, 0xFE, 0x03, 0x50, 0x15 };
  check_pack (DS_PIXFMT_MONO10P, px6, 3, 2, 5, strided_packed, sizeof strided_packed);
}

static void
test_mono12p (void)
{
  /* P = 0x123, 0x456, 0x789: b0 = 0x23, b1 = P1[3:0] << 4 | P0[11:8] = 0x61, b2 = P1[11:4] =
   * 0x45, b3 = P2[7:0] = 0x89, b4 = P2[11:8] = 0x07 (36 bits -> 5 bytes). */
  static const guint8 row3[] = { 0x23, 0x61, 0x45, 0x89, 0x07 };
  static const guint16 px3[] = { 0x123, 0x456, 0x789 };
  check_unpack (DS_PIXFMT_MONO12P, row3, sizeof row3, 3, 1, 0, px3);
  check_pack (DS_PIXFMT_MONO12P, px3, 3, 1, 0, row3, sizeof row3);

  /* Continuous 3x2: pixels 2,3 = 0x789, 0xABC -> 89 C7 AB; 4,5 = 0xDEF, 0x001 -> EF 1D 00. */
  static const guint8 cont[] = { 0x23, 0x61, 0x45, 0x89, 0xC7, 0xAB, 0xEF, 0x1D, 0x00 };
  static const guint16 px6[] = { 0x123, 0x456, 0x789, 0xABC, 0xDEF, 0x001 };
  check_unpack (DS_PIXFMT_MONO12P, cont, sizeof cont, 3, 2, 0, px6);
  check_pack (DS_PIXFMT_MONO12P, px6, 3, 2, 0, cont, sizeof cont);
}

static void
test_mono12packed (void)
{
  /* GigE Vision: b0 = P0[11:4], b1 = P1[3:0] << 4 | P0[3:0], b2 = P1[11:4].
   * 0x123, 0x456 -> 12 63 45; unpaired 0x789 -> 78 09. */
  static const guint8 row3[] = { 0x12, 0x63, 0x45, 0x78, 0x09 };
  static const guint16 px3[] = { 0x123, 0x456, 0x789 };
  check_unpack (DS_PIXFMT_MONO12PACKED, row3, sizeof row3, 3, 1, 0, px3);
  check_pack (DS_PIXFMT_MONO12PACKED, px3, 3, 1, 0, row3, sizeof row3);

  /* Continuous 3x2: the pair (0x789, 0xABC) straddles the rows -> 78 C9 AB; (0xDEF, 0x001) ->
   * DE 1F 00. */
  static const guint8 cont[] = { 0x12, 0x63, 0x45, 0x78, 0xC9, 0xAB, 0xDE, 0x1F, 0x00 };
  static const guint16 px6[] = { 0x123, 0x456, 0x789, 0xABC, 0xDEF, 0x001 };
  check_unpack (DS_PIXFMT_MONO12PACKED, cont, sizeof cont, 3, 2, 0, px6);
  check_pack (DS_PIXFMT_MONO12PACKED, px6, 3, 2, 0, cont, sizeof cont);

  /* Stride 6: row 1 restarts pairing: (0xABC, 0xDEF) -> AB FC DE, 0x001 -> 00 01. The last
   * row carries no padding. */
  static const guint8 strided[] = { 0x12, 0x63, 0x45, 0x78, 0x09, 0x00,
                                    0xAB, 0xFC, 0xDE, 0x00, 0x01 };
  check_unpack (DS_PIXFMT_MONO12PACKED, strided, sizeof strided, 3, 2, 6, px6);
  check_pack (DS_PIXFMT_MONO12PACKED, px6, 3, 2, 6, strided, sizeof strided);
}

static void
test_short_buffers (void)
{
  for (int f = 0; f < DS_PIXFMT_COUNT; f++)
    for (guint w = 1; w <= 9; w++)
      for (int s = 0; s < 2; s++) {
        guint h = 3;
        gsize stride = s ? ds_pixfmt_row_bytes ((DsPixelFormat) f, w) + 3 : 0;
        gsize need = ds_pixfmt_image_bytes ((DsPixelFormat) f, w, h, stride);
        g_assert_cmpuint (need, >, 0);
        /* One byte short, from an exactly sized heap block: must fail without reading it. */
        guint8 *buf = g_malloc0 (need - 1);
        g_autoptr (GError) error = NULL;
        DsImage *img = ds_pixfmt_unpack ((DsPixelFormat) f, buf, need - 1, w, h, stride, &error);
        g_assert_null (img);
        g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
        g_autofree char *want = g_strdup_printf ("needs %zu bytes, got %zu", need, need - 1);
        g_assert_nonnull (strstr (error->message, want));
        g_free (buf);
      }
  /* Stride below the row size, zero width, NULL data. */
  guint8 b[16] = { 0 };
  g_autoptr (GError) e1 = NULL, e2 = NULL, e3 = NULL;
  g_assert_null (ds_pixfmt_unpack (DS_PIXFMT_MONO12P, b, sizeof b, 3, 2, 4, &e1));
  g_assert_error (e1, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_assert_null (ds_pixfmt_unpack (DS_PIXFMT_MONO8, b, sizeof b, 0, 2, 0, &e2));
  g_assert_error (e2, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_assert_null (ds_pixfmt_unpack (DS_PIXFMT_MONO8, NULL, 0, 2, 2, 0, &e3));
  g_assert_error (e3, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
}

/* Round trip through pack and unpack: random values, every width 1..17, strides 0 / tight /
 * padded. The unpacked image must equal the original; independent of the layout details. */
static void
test_round_trip (void)
{
  GRand *rand = g_rand_new_with_seed (20261122);
  for (int f = 0; f < DS_PIXFMT_COUNT; f++) {
    DsPixelFormat fmt = (DsPixelFormat) f;
    guint depth = ds_pixfmt_bit_depth (fmt);
    for (guint w = 1; w <= 17; w++)
      for (guint h = 1; h <= 4; h += 3)
        for (int s = 0; s < 3; s++) {
          gsize stride = s == 0 ? 0 : ds_pixfmt_row_bytes (fmt, w) + (s == 2 ? 5 : 0);
          g_autoptr (DsImage) img =
            ds_image_new (fmt == DS_PIXFMT_MONO8 ? DS_SAMPLE_U8 : DS_SAMPLE_U16, w, h, NULL);
          for (guint y = 0; y < h; y++)
            for (guint x = 0; x < w; x++) {
              guint v = (guint) g_rand_int_range (rand, 0, 1 << depth);
              if (fmt == DS_PIXFMT_MONO8)
                ((guint8 *) ds_image_row (img, y))[x] = (guint8) v;
              else
                ((guint16 *) ds_image_row (img, y))[x] = (guint16) v;
            }
          g_autoptr (GError) error = NULL;
          g_autoptr (GBytes) bytes = ds_pixfmt_pack (fmt, img, stride, &error);
          g_assert_no_error (error);
          g_assert_cmpuint (g_bytes_get_size (bytes), ==, ds_pixfmt_image_bytes (fmt, w, h, stride));
          gsize n;
          const void *p = g_bytes_get_data (bytes, &n);
          g_autoptr (DsImage) back = ds_pixfmt_unpack (fmt, p, n, w, h, stride, &error);
          g_assert_no_error (error);
          for (guint y = 0; y < h; y++)
            g_assert_cmpmem (ds_image_row (back, y), w * ds_sample_size (back->type),
                             ds_image_row (img, y), w * ds_sample_size (img->type));
        }
  }
  g_rand_free (rand);

  /* pack refuses values beyond the depth and the wrong sample type. */
  static const guint16 over[] = { 0x1000 };
  g_autoptr (DsImage) img = image_u16 (1, 1, over, 16);
  g_autoptr (GError) e1 = NULL, e2 = NULL;
  g_assert_null (ds_pixfmt_pack (DS_PIXFMT_MONO12P, img, 0, &e1));
  g_assert_error (e1, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT);
  g_assert_null (ds_pixfmt_pack (DS_PIXFMT_MONO8, img, 0, &e2));
  g_assert_error (e2, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT);
}

/* Unpacking into a provided (pooled) image: the pixels of the hand-derived Mono12p example,
 * into an image that held other pixels before; a mismatched sample type is refused. */
static void
test_unpack_into_pooled (void)
{
  static const guint8 cont[] = { 0x23, 0x61, 0x45, 0x89, 0xC7, 0xAB, 0xEF, 0x1D, 0x00 };
  static const guint16 px6[] = { 0x123, 0x456, 0x789, 0xABC, 0xDEF, 0x001 };
  g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_U16, 3, 2, NULL);
  for (guint y = 0; y < 2; y++)
    memset (ds_image_row (img, y), 0xff, 6);
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_pixfmt_unpack_into (DS_PIXFMT_MONO12P, cont, sizeof cont, 0, img, &error));
  g_assert_no_error (error);
  g_assert_cmpuint (img->bit_depth, ==, 12);
  for (guint y = 0; y < 2; y++)
    for (guint x = 0; x < 3; x++)
      g_assert_cmphex (((guint16 *) ds_image_row (img, y))[x], ==, px6[y * 3 + x]);
  g_autoptr (DsImage) u8 = ds_image_new (DS_SAMPLE_U8, 3, 2, NULL);
  g_assert_false (ds_pixfmt_unpack_into (DS_PIXFMT_MONO12P, cont, sizeof cont, 0, u8, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
}

static gboolean
bits_are_words (DsPixelFormat fmt)
{
  return fmt == DS_PIXFMT_MONO10 || fmt == DS_PIXFMT_MONO12 || fmt == DS_PIXFMT_MONO16;
}

/* Pixel x of row y as the layouts define it, one bit at a time (independent of proc/). */
static guint
reference_pixel (DsPixelFormat fmt, const guint8 *p, guint w, gsize stride, guint x, guint y)
{
  guint bits = ds_pixfmt_bits_per_pixel (fmt);
  guint64 q = stride ? x : (guint64) y * w + x;   /* pixel index in its bitstream */
  const guint8 *base = stride ? p + y * stride : p;
  if (fmt == DS_PIXFMT_MONO12PACKED) {
    const guint8 *b = base + (q / 2) * 3;
    return q % 2 == 0 ? (guint) (b[0] << 4) | (b[1] & 0xF) : (guint) (b[2] << 4) | (b[1] >> 4);
  }
  if (bits == 16)
    return base[2 * q] | (guint) base[2 * q + 1] << 8;
  guint v = 0;
  for (guint i = 0; i < bits; i++) {
    guint64 bit = q * bits + i;
    v |= (guint) ((base[bit / 8] >> (bit % 8)) & 1u) << i;
  }
  return v;
}

/* unpack_into a caller's image (padded rows, garbage in them) against the bit-by-bit
 * reference, for widths that start packed rows mid-byte and mid-pair in a continuous stream. */
static void
test_unpack_into (void)
{
  GRand *rand = g_rand_new_with_seed (77);
  for (int f = 0; f < DS_PIXFMT_COUNT; f++) {
    DsPixelFormat fmt = (DsPixelFormat) f;
    guint depth = ds_pixfmt_bit_depth (fmt);
    for (guint w = 1; w <= 41; w += (w < 12 ? 1 : 7))
      for (int s = 0; s < 2; s++) {
        guint h = 5;
        gsize stride = s ? ds_pixfmt_row_bytes (fmt, w) + 3 : 0;
        gsize n = ds_pixfmt_image_bytes (fmt, w, h, stride);
        guint8 *payload = g_malloc (n);
        for (gsize i = 0; i < n; i++)
          payload[i] = (guint8) g_rand_int (rand);
        if (bits_are_words (fmt)) /* 16-bit words: keep the bits above the depth clear */
          for (guint y = 0; y < h; y++)
            for (guint x = 0; x < w; x++) {
              gsize hi = stride ? y * stride + 2 * x + 1 : 2 * ((gsize) y * w + x) + 1;
              payload[hi] &= (guint8) ((1u << (depth - 8)) - 1u);
            }
        DsSampleType type = fmt == DS_PIXFMT_MONO8 ? DS_SAMPLE_U8 : DS_SAMPLE_U16;
        g_autoptr (DsImage) dst = ds_image_new_with_stride (type, w, h, w * 2 + 64, NULL);
        memset (dst->data, 0xA5, dst->stride * h);
        g_autoptr (GError) error = NULL;
        g_assert_true (ds_pixfmt_unpack_into (fmt, payload, n, stride, dst, &error));
        g_assert_no_error (error);
        g_assert_cmpuint (dst->bit_depth, ==, depth);
        for (guint y = 0; y < h; y++)
          for (guint x = 0; x < w; x++) {
            guint got = type == DS_SAMPLE_U8 ? ((guint8 *) ds_image_row (dst, y))[x]
                                             : ((guint16 *) ds_image_row (dst, y))[x];
            if (got != reference_pixel (fmt, payload, w, stride, x, y))
              g_error ("%s w=%u stride=%zu pixel (%u,%u): got %u, expected %u", ds_pixfmt_name (fmt), w,
                       stride, x, y, got, reference_pixel (fmt, payload, w, stride, x, y));
          }
        g_free (payload);
      }
  }
  g_rand_free (rand);

  /* a payload too short for the image; a Mono12 word above 12 bits names its pixel */
  guint8 words[8] = { 0x01, 0x00, 0xFF, 0x0F, 0x00, 0x10, 0x00, 0x00 };
  g_autoptr (DsImage) big = ds_image_new (DS_SAMPLE_U16, 5, 1, NULL);
  g_autoptr (DsImage) ok = ds_image_new (DS_SAMPLE_U16, 4, 1, NULL);
  g_autoptr (GError) e1 = NULL, e3 = NULL;
  g_assert_false (ds_pixfmt_unpack_into (DS_PIXFMT_MONO12, words, 8, 0, big, &e1));
  g_assert_error (e1, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_assert_false (ds_pixfmt_unpack_into (DS_PIXFMT_MONO12, words, 8, 0, ok, &e3));
  g_assert_error (e3, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT);
  g_assert_nonnull (strstr (e3->message, "pixel (2, 0)"));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/pixfmt/names-codes", test_names_codes);
  g_test_add_func ("/pixfmt/mono8-16", test_mono8_16);
  g_test_add_func ("/pixfmt/mono10p", test_mono10p);
  g_test_add_func ("/pixfmt/mono12p", test_mono12p);
  g_test_add_func ("/pixfmt/mono12packed", test_mono12packed);
  g_test_add_func ("/pixfmt/short-buffers", test_short_buffers);
  g_test_add_func ("/pixfmt/round-trip", test_round_trip);
  g_test_add_func ("/pixfmt/unpack-into-pooled", test_unpack_into_pooled);
  g_test_add_func ("/pixfmt/unpack-into", test_unpack_into);
  return g_test_run ();
}
