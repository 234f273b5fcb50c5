/* Result planes and payloads: one copy of the pixels (docs/design.md). Payloads of f32 and u8
 * planes are the planes themselves, they stay valid after the result is gone, and the planes
 * go back to their pool only when the last payload is released; a pool hands them out again
 * for the next result of that size. Expected values are written here, not computed by the code
 * under test. */
#include <math.h>
#include <string.h>

#include "daemon/acquire/result.h"
#include "daemon/acquire/result_planes.h"

static DsSeparation *
filled (DsPlanePool *pool, guint w, guint h)
{
  g_autoptr (GError) error = NULL;
  DsSeparation *sep = ds_plane_pool_take (pool, w, h, &error);
  g_assert_no_error (error);
  for (guint y = 0; y < h; y++) {
    float *t = ds_image_row (sep->transmissive, y), *g = ds_image_row (sep->scattered, y);
    guint8 *m = ds_image_row (sep->mask, y);
    for (guint x = 0; x < w; x++) {
      t[x] = (float) (x + 1000 * y) + 0.25f;
      g[x] = -1.5f + (float) x;     /* negative and beyond u16 ranges below */
      m[x] = (guint8) (x & 7);
    }
  }
  return sep;
}

static DsResult *
result_of (DsSeparation *sep, DsPlanePool *pool)
{
  DsCaptureSettings s;
  memset (&s, 0, sizeof s);
  s.phases = 8;
  DsFrameCounters c = { 0 };
  return ds_result_new (1, sep, pool, &s, &c, 0, 0, 0);
}

static void
test_payloads_are_the_planes (void)
{
  const guint w = 1000, h = 3; /* a width whose rows a 64-byte stride would pad */
  g_autoptr (DsPlanePool) pool = ds_plane_pool_new (2);
  DsSeparation *sep = filled (pool, w, h);
  const void *t_pixels = sep->transmissive->data, *m_pixels = sep->mask->data;
  DsResult *r = result_of (sep, pool);
  const DsPayloadInfo *infos;
  GBytes *const *bytes;
  guint n = ds_result_payloads (r, DS_OUTPUT_F32, FALSE, &infos, &bytes);
  g_assert_cmpuint (n, ==, 3);
  g_assert_cmpstr (infos[0].dtype, ==, "f32");
  g_assert_cmpstr (infos[2].dtype, ==, "u8");
  gsize size = 0;
  g_assert_true (g_bytes_get_data (bytes[0], &size) == t_pixels); /* no copy */
  g_assert_cmpuint (size, ==, (gsize) w * h * 4);
  g_assert_true (g_bytes_get_data (bytes[2], NULL) == m_pixels);
  /* A client still sending the payloads when the result goes. */
  GBytes *t = g_bytes_ref (bytes[0]), *m = g_bytes_ref (bytes[2]);
  ds_result_unref (r);
  g_assert_cmpuint (ds_plane_pool_n_free (pool), ==, 0);
  const float *tv = g_bytes_get_data (t, NULL);
  g_assert_cmpfloat (tv[2 * w + 7], ==, 2007.25f);
  g_assert_cmpuint (((const guint8 *) g_bytes_get_data (m, NULL))[w + 13], ==, 5);
  g_bytes_unref (t);
  g_assert_cmpuint (ds_plane_pool_n_free (pool), ==, 0);
  g_bytes_unref (m);
  g_assert_cmpuint (ds_plane_pool_n_free (pool), ==, 1);
  /* The next result of that size gets the same planes; another size gets new ones. */
  g_autoptr (GError) error = NULL;
  DsSeparation *again = ds_plane_pool_take (pool, w, h, &error);
  g_assert_true (again->transmissive->data == t_pixels);
  ds_plane_pool_give (pool, again);
  DsSeparation *other = ds_plane_pool_take (pool, 64, h, &error);
  g_assert_true (other->transmissive->width == 64);
  g_assert_cmpuint (other->transmissive->stride, ==, 64 * 4);
  ds_plane_pool_give (pool, other);
}

/* u16 payloads: rounded to nearest, clamped to 0..65535 (values chosen so each rule shows). */
static void
test_u16_payloads (void)
{
  const guint w = 70000 / 1000, h = 2;
  g_autoptr (DsPlanePool) pool = ds_plane_pool_new (1);
  DsSeparation *sep = filled (pool, w, h);
  g_autoptr (DsResult) r = result_of (sep, pool);
  const DsPayloadInfo *infos;
  GBytes *const *bytes;
  g_assert_cmpuint (ds_result_payloads (r, DS_OUTPUT_U16, FALSE, &infos, &bytes), ==, 3);
  g_assert_cmpstr (infos[0].dtype, ==, "u16");
  g_assert_cmpstr (infos[2].dtype, ==, "u8");
  gsize size = 0;
  const guint16 *t = g_bytes_get_data (bytes[0], &size);
  g_assert_cmpuint (size, ==, (gsize) w * h * 2);
  g_assert_cmpuint (t[5], ==, 5);                  /* 5.25 -> 5 */
  g_assert_cmpuint (t[w + 3], ==, 1003);           /* 1003.25 -> 1003 */
  const guint16 *g = g_bytes_get_data (bytes[1], NULL);
  g_assert_cmpuint (g[0], ==, 0);                  /* -1.5 clamps to 0 */
  g_assert_cmpuint (g[3], ==, 2);                  /* 1.5 rounds to 2 */
  /* Asking again returns the same bytes: built once per format. */
  GBytes *const *again;
  ds_result_payloads (r, DS_OUTPUT_U16, FALSE, &infos, &again);
  g_assert_true (again[0] == bytes[0]);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/result-planes/payloads-are-the-planes", test_payloads_are_the_planes);
  g_test_add_func ("/result-planes/u16", test_u16_payloads);
  return g_test_run ();
}
