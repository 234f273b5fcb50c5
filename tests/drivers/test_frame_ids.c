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

/* A frame lost with its loss counted (a grab that timed out): the next frame's id shows the
 * lost one missing, and that is no gap. Counted by hand: 100 seen, 101 lost, 102 arrives. */
static void
test_counted_loss_is_not_a_gap (void)
{
  DsFrameIdTracker t;
  ds_frame_id_tracker_init (&t, 16);
  guint32 skipped;
  guint64 a = ds_frame_id_tracker_update (&t, 100, &skipped);
  ds_frame_id_tracker_note_lost (&t);
  guint64 b = ds_frame_id_tracker_update (&t, 102, &skipped);
  g_assert_cmpuint (skipped, ==, 0);
  g_assert_cmpuint (b, ==, a + 2); /* the extended id still skips the lost one */
  /* Two losses counted, three ids missing (103..105; 106 arrives): one is unaccounted. */
  ds_frame_id_tracker_note_lost (&t);
  ds_frame_id_tracker_note_lost (&t);
  ds_frame_id_tracker_update (&t, 106, &skipped);
  g_assert_cmpuint (skipped, ==, 1);
  /* The notes were used up by 106: a later gap (107 missing, 108 arrives) is a gap again. */
  ds_frame_id_tracker_update (&t, 108, &skipped);
  g_assert_cmpuint (skipped, ==, 1);
}

/* A lost trigger makes no id: its note is used up by the next frame (contiguous), and a frame
 * that goes missing afterwards, unaccounted, is still a gap. */
static void
test_note_does_not_outlive_the_next_frame (void)
{
  DsFrameIdTracker t;
  ds_frame_id_tracker_init (&t, 16);
  guint32 skipped;
  ds_frame_id_tracker_update (&t, 500, &skipped);
  ds_frame_id_tracker_note_lost (&t); /* the trigger was lost: 501 is the retry's frame */
  ds_frame_id_tracker_update (&t, 501, &skipped);
  g_assert_cmpuint (skipped, ==, 0);
  ds_frame_id_tracker_update (&t, 503, &skipped); /* 502 vanished, nobody counted it */
  g_assert_cmpuint (skipped, ==, 1);
  /* The lost frame arrives late after all (its id follows the last one): the note is used up
   * by it, so the retry's frame after it is judged on its own id. */
  ds_frame_id_tracker_note_lost (&t);
  ds_frame_id_tracker_update (&t, 504, &skipped); /* the late frame */
  g_assert_cmpuint (skipped, ==, 0);
  ds_frame_id_tracker_update (&t, 506, &skipped); /* 505 missing: the note is gone */
  g_assert_cmpuint (skipped, ==, 1);
}

/* Counted losses across the 16-bit wrap, where id 0 does not exist: 65534 seen, 65535 and 1
 * lost (two timeouts), 2 arrives: two ids missing, both accounted. With one loss counted, one
 * of them is a gap. */
static void
test_counted_loss_across_wrap (void)
{
  DsFrameIdTracker t;
  ds_frame_id_tracker_init (&t, 16);
  guint32 skipped;
  guint64 a = ds_frame_id_tracker_update (&t, 65534, &skipped);
  ds_frame_id_tracker_note_lost (&t);
  ds_frame_id_tracker_note_lost (&t);
  guint64 b = ds_frame_id_tracker_update (&t, 2, &skipped);
  g_assert_cmpuint (skipped, ==, 0);
  g_assert_cmpuint (b, ==, a + 3);
  /* 65535 lost alone: 65534 -> 1 is one id missing. */
  ds_frame_id_tracker_init (&t, 16);
  ds_frame_id_tracker_update (&t, 65534, &skipped);
  ds_frame_id_tracker_note_lost (&t);
  ds_frame_id_tracker_update (&t, 1, &skipped);
  g_assert_cmpuint (skipped, ==, 0);
  /* 65535 and 1 missing, one loss counted: one gap. */
  ds_frame_id_tracker_init (&t, 16);
  ds_frame_id_tracker_update (&t, 65534, &skipped);
  ds_frame_id_tracker_note_lost (&t);
  ds_frame_id_tracker_update (&t, 2, &skipped);
  g_assert_cmpuint (skipped, ==, 1);
}

static void
test_counted_loss_64_bit (void)
{
  DsFrameIdTracker t;
  ds_frame_id_tracker_init (&t, 64);
  guint32 skipped;
  ds_frame_id_tracker_update (&t, 1000000, &skipped);
  ds_frame_id_tracker_note_lost (&t);
  ds_frame_id_tracker_update (&t, 1000002, &skipped);
  g_assert_cmpuint (skipped, ==, 0);
  ds_frame_id_tracker_update (&t, 1000004, &skipped);
  g_assert_cmpuint (skipped, ==, 1);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/frame-ids/wrap", test_wrap_without_gap);
  g_test_add_func ("/frame-ids/gap-across-wrap", test_gap_across_wrap);
  g_test_add_func ("/frame-ids/duplicate", test_duplicate_is_not_a_gap);
  g_test_add_func ("/frame-ids/64-bit", test_64_bit_ids);
  g_test_add_func ("/frame-ids/counted-loss", test_counted_loss_is_not_a_gap);
  g_test_add_func ("/frame-ids/note-used-by-next-frame", test_note_does_not_outlive_the_next_frame);
  g_test_add_func ("/frame-ids/counted-loss-across-wrap", test_counted_loss_across_wrap);
  g_test_add_func ("/frame-ids/counted-loss-64-bit", test_counted_loss_64_bit);
  return g_test_run ();
}
