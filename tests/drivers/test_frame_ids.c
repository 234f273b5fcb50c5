/* Frame-id continuity across the 16-bit wrap of GigE Vision 1.x (ids 1..65535, 0 skipped),
 * against ids counted by hand. */
#include "drivers/core/frame.h"

static void
test_wrap_without_gap (void)
{
  DsFrameIdTracker t;
  ds_frame_id_tracker_init (&t, 16);
  guint32 skipped;
  guint64 first = ds_frame_id_tracker_update (&t, 65400, &skipped);
  guint raw = 65400;
  for (guint i = 1; i <= 400; i++) {
    raw = raw == 65535 ? 1 : raw + 1; /* the camera's own sequence: 0 is never used */
    guint64 e = ds_frame_id_tracker_update (&t, raw, &skipped);
    g_assert_cmpuint (skipped, ==, 0);
    g_assert_cmpuint (e, ==, first + i);
  }
}

static void
test_gap_across_wrap (void)
{
  DsFrameIdTracker t;
  ds_frame_id_tracker_init (&t, 16);
  guint32 skipped;
  ds_frame_id_tracker_update (&t, 65533, &skipped);
  /* 65534, 65535, 1 lost; 2 arrives: three ids missing. */
  ds_frame_id_tracker_update (&t, 2, &skipped);
  g_assert_cmpuint (skipped, ==, 3);
}

static void
test_duplicate_is_not_a_gap (void)
{
  DsFrameIdTracker t;
  ds_frame_id_tracker_init (&t, 16);
  guint32 skipped;
  guint64 a = ds_frame_id_tracker_update (&t, 10, &skipped);
  guint64 b = ds_frame_id_tracker_update (&t, 10, &skipped);
  g_assert_cmpuint (skipped, ==, 0);
  g_assert_cmpuint (b, >, a); /* extended ids stay monotonic */
  guint64 c = ds_frame_id_tracker_update (&t, 11, &skipped);
  g_assert_cmpuint (skipped, ==, 0);
  g_assert_cmpuint (c, >, b);
}

static void
test_64_bit_ids (void)
{
  DsFrameIdTracker t;
  ds_frame_id_tracker_init (&t, 64);
  guint32 skipped;
  ds_frame_id_tracker_update (&t, 1000000, &skipped);
  g_assert_cmpuint (ds_frame_id_tracker_update (&t, 1000005, &skipped), ==, 1000005);
  g_assert_cmpuint (skipped, ==, 4);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/frame-ids/wrap", test_wrap_without_gap);
  g_test_add_func ("/frame-ids/gap-across-wrap", test_gap_across_wrap);
  g_test_add_func ("/frame-ids/duplicate", test_duplicate_is_not_a_gap);
  g_test_add_func ("/frame-ids/64-bit", test_64_bit_ids);
  return g_test_run ();
}
