/* The illuminator moves to the next phase while a frame transfers (docs/design.md, "The
 * pipeline"): never during an exposure, and never a frame folded into a phase it was not lit
 * with. The camera here exposes in real time: a trigger opens an exposure of `exposure_us`,
 * the frame shows the light lit at the end of it (a move during the exposure shows as the next
 * phase: what a real frame would show in part), and only then does the camera report the frame
 * begun (frames_begun). Every frame's true phase is recorded by id, and every frame the
 * sequencer folds is checked against it through the frame hook: the truth is the camera's, not
 * the sequencer's. No timing is asserted: only which phase each exposure saw. */
#include <math.h>
#include <string.h>

#include "proc/phase_check.h"
#include "daemon/acquire/sequencer.h"
#include "scripted_lab.h"

#define W 64
#define H 16
#define N_TRUTH 4096

typedef struct {
  int lit;                  /* phase lit, -1 off */
  guint n_phases;
  gint64 exposure_us;
  /* The frame of the last trigger: exposing until exposure_end, then sent (begun) until grabbed. */
  gboolean exposing, sent, reported;
  gint64 exposure_end;
  int exposed_phase;        /* the light at the end of its exposure */
  guint64 begun, frame_id;
  int truth[N_TRUTH];       /* phase shown, by frame id */
  guint moves_during_exposure, moves_during_transfer, set_phases;
  guint moves_between_frames; /* to a phase other than 0 with no frame exposing or in transfer */
  guint zero_between_frames;  /* to phase 0 likewise */
  /* Faults, counted down (0 never): */
  guint report_early_in;    /* that frame is reported begun at its trigger, while it still exposes */
  gboolean report_early_always;
  guint lose_in;            /* that trigger's frame never comes */
  guint busy_in;            /* that set_phase fails BUSY (the retry policy) */
  guint lost_in;            /* that set_phase fails DISCONNECTED (the set fails, reconnect) */
  gboolean trusted;         /* [camera] sends-after-exposure */
  /* Written by the frame hook (fold thread). */
  GMutex lock;
  guint folded, folded_wrong;
} Lab;

static guint16
pixel_value (int phase, guint n, guint x)
{
  return stripe_scene_value (x, phase, n, SCRIPTED_PERIOD);
}

static void
finish_exposure (Lab *lab)
{
  if (!lab->exposing)
    return;
  gint64 left = lab->exposure_end - g_get_monotonic_time ();
  if (left > 0)
    g_usleep ((gulong) left);
  lab->exposing = FALSE;
  lab->sent = TRUE;
  if (!lab->reported)
    lab->begun++;
  lab->reported = TRUE;
}

static gboolean cam_configure (gpointer b, const DsCameraSettings *s, GError **e) { (void) b; (void) s; (void) e; return TRUE; }
static gboolean cam_start (gpointer b, GError **e) { (void) b; (void) e; return TRUE; }
static void cam_stop (gpointer b) { (void) b; }
static guint cam_flush (gpointer b) { (void) b; return 0; }
static gboolean cam_reconnect (gpointer b, GError **e) { (void) b; (void) e; return TRUE; }
static void cam_stats (gpointer b, DsCameraStats *s) { (void) b; memset (s, 0, sizeof *s); }
static void cam_close (gpointer b) { (void) b; }

static void
cam_info (gpointer b, DsCameraInfo *i)
{
  (void) b;
  memset (i, 0, sizeof *i);
  i->sensor_width = W;
  i->sensor_height = H;
  i->connected = TRUE;
}

static gboolean
cam_trigger (gpointer b, GError **e)
{
  (void) e;
  Lab *lab = b;
  finish_exposure (lab); /* a previous frame never grabbed is over by now */
  lab->sent = FALSE;
  if (scripted_fault_now (&lab->lose_in))
    return TRUE;
  lab->exposing = TRUE;
  lab->exposure_end = g_get_monotonic_time () + lab->exposure_us;
  lab->exposed_phase = lab->lit;
  /* A camera that sends rows while later rows still expose: the frame begins at once. */
  lab->reported = lab->report_early_always || scripted_fault_now (&lab->report_early_in);
  lab->begun += lab->reported;
  return TRUE;
}

static guint64
cam_frames_begun (gpointer b, guint64 after, guint timeout_ms)
{
  Lab *lab = b;
  if (lab->begun > after || timeout_ms == 0)
    return lab->begun;
  if (lab->exposing)
    finish_exposure (lab);
  else if (!lab->sent)
    g_usleep (timeout_ms * 1000); /* lost: nothing begins */
  return lab->begun;
}

static DsFrame *
cam_grab (gpointer b, guint timeout_ms, GError **e)
{
  Lab *lab = b;
  finish_exposure (lab);
  if (!lab->sent) {
    g_set_error (e, DS_CAMERA_ERROR, DS_DEVICE_ERROR_TIMEOUT, "no frame within %u ms", timeout_ms);
    return NULL;
  }
  lab->sent = FALSE;
  DsFrame *f = g_new0 (DsFrame, 1);
  f->image = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  f->image->bit_depth = 12;
  for (guint y = 0; y < H; y++) {
    guint16 *row = ds_image_row (f->image, y);
    for (guint x = 0; x < W; x++)
      row[x] = pixel_value (lab->exposed_phase, lab->n_phases, x);
  }
  f->frame_id = ++lab->frame_id;
  lab->truth[f->frame_id % N_TRUTH] = lab->exposed_phase;
  f->host_time_us = (guint64) g_get_monotonic_time ();
  return f;
}

static const DsCameraOps cam_ops = {
  .name = "exposing", .configure = cam_configure, .start = cam_start, .trigger = cam_trigger,
  .grab = cam_grab, .flush = cam_flush, .stop = cam_stop, .reconnect = cam_reconnect,
  .get_stats = cam_stats, .get_info = cam_info, .close = cam_close, .frames_begun = cam_frames_begun,
};

static void
light (Lab *lab, int phase)
{
  if (lab->exposing && g_get_monotonic_time () < lab->exposure_end) {
    lab->moves_during_exposure++;
    lab->exposed_phase = phase;
  } else if (lab->sent || lab->exposing) {
    lab->moves_during_transfer++;
  } else if (phase > 0) {
    lab->moves_between_frames++;
  } else if (phase == 0) {
    lab->zero_between_frames++;
  }
  lab->lit = phase;
}

static gboolean
ill_pattern (gpointer b, const DsStripePattern *p, GError **e)
{
  (void) e;
  ((Lab *) b)->n_phases = p->n_phases;
  return TRUE;
}

static gboolean
ill_phase (gpointer b, guint phase, guint timeout_ms, GError **e)
{
  (void) timeout_ms;
  Lab *lab = b;
  if (scripted_fault_now (&lab->busy_in)) {
    g_set_error (e, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_BUSY, "not ready");
    return FALSE;
  }
  if (scripted_fault_now (&lab->lost_in)) {
    g_set_error (e, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_DISCONNECTED, "illuminator gone");
    return FALSE;
  }
  lab->set_phases++;
  light (lab, (int) phase);
  return TRUE;
}

static gboolean
ill_off (gpointer b, guint t, GError **e)
{
  (void) t;
  (void) e;
  light (b, -1);
  return TRUE;
}

static gboolean
ill_status (gpointer b, DsIlluminatorStatus *s, GError **e)
{
  (void) e;
  memset (s, 0, sizeof *s);
  s->ready = TRUE;
  s->applied_phase = ((Lab *) b)->lit;
  s->temperature_c = NAN;
  return TRUE;
}

static gboolean ill_reconnect (gpointer b, GError **e) { (void) b; (void) e; return TRUE; }
static void ill_close (gpointer b) { (void) b; }

static const DsIlluminatorOps ill_ops = {
  .name = "exposing", .set_pattern = ill_pattern, .set_phase = ill_phase, .off = ill_off,
  .get_status = ill_status, .reconnect = ill_reconnect, .close = ill_close,
};

static DsDevices *
open_lab (gpointer data, GError **error)
{
  (void) error;
  Lab *lab = data;
  DsDevices *d = scripted_devices_new (&cam_ops, &ill_ops, lab, "exposing");
  d->sends_after_exposure = lab->trusted;
  return d;
}

/* Called on the fold thread for every frame verified and folded into `phase`. */
static void
on_folded (const DsFrame *frame, guint phase, const DsCaptureSettings *s, gpointer data)
{
  (void) s;
  Lab *lab = data;
  g_mutex_lock (&lab->lock);
  lab->folded++;
  lab->folded_wrong += lab->truth[frame->frame_id % N_TRUTH] != (int) phase;
  g_mutex_unlock (&lab->lock);
}

/* ---- harness ---- */

typedef struct {
  Lab lab;
  GMainLoop *loop;
  gboolean ready;
  DsResult *result;
  GError *failure;
  guint results;
  DsSequencer *seq;
} Fixture;

static void
on_event (const DsSequencerEvent *ev, gpointer data)
{
  Fixture *f = data;
  switch (ev->kind) {
  case DS_SEQUENCER_EVENT_READY:
    f->ready = ev->error == NULL;
    g_main_loop_quit (f->loop);
    break;
  case DS_SEQUENCER_EVENT_RESULT:
    g_clear_pointer (&f->result, ds_result_unref);
    f->result = ds_result_ref (ev->result);
    f->results++;
    g_main_loop_quit (f->loop);
    break;
  case DS_SEQUENCER_EVENT_FAILED:
    g_clear_error (&f->failure);
    f->failure = g_error_copy (ev->error);
    g_main_loop_quit (f->loop);
    break;
  default:
    break;
  }
}

static void
settings (DsCaptureSettings *s, guint n, guint m)
{
  memset (s, 0, sizeof *s);
  s->phases = n;
  s->averages = m;
  s->exposure_us = 2000;
  s->estimator = DS_ESTIMATOR_MAXMIN;
  s->pattern = DS_PATTERN_SQUARE;
  s->period_px = SCRIPTED_PERIOD;
  s->duty = 0.5;
  s->phase_retries = 3;
  s->verify_phase = TRUE;
  s->phase_tolerance_deg = ds_phase_check_default_tolerance_deg (n);
}

static void
setup (Fixture *f, gboolean trusted)
{
  memset (f, 0, sizeof *f);
  g_mutex_init (&f->lab.lock);
  f->lab.lit = -1;
  f->lab.exposure_us = 2000;
  f->lab.trusted = trusted;
  f->loop = g_main_loop_new (NULL, FALSE);
  DsCaptureSettings s;
  settings (&s, 8, 1);
  f->seq = ds_sequencer_new (open_lab, &f->lab, &s, g_main_context_default (), on_event, f);
  g_main_loop_run (f->loop);
  g_assert_true (f->ready);
  ds_sequencer_set_frame_hook (f->seq, on_folded, &f->lab);
}

static void
setup_trusted (Fixture *f, gconstpointer d)
{
  (void) d;
  setup (f, TRUE);
}

static void
setup_untrusted (Fixture *f, gconstpointer d)
{
  (void) d;
  setup (f, FALSE);
}

static void
teardown (Fixture *f, gconstpointer d)
{
  (void) d;
  ds_sequencer_free (f->seq);
  g_clear_pointer (&f->result, ds_result_unref);
  g_clear_error (&f->failure);
  g_main_loop_unref (f->loop);
  g_mutex_clear (&f->lab.lock);
}

static void
capture (Fixture *f, const DsCaptureSettings *s)
{
  g_clear_pointer (&f->result, ds_result_unref);
  g_clear_error (&f->failure);
  g_assert_true (ds_sequencer_capture (f->seq, s, 1));
  g_main_loop_run (f->loop);
}

static void
status (Fixture *f, DsSequencerStatus *st)
{
  ds_sequencer_get_status (f->seq, st);
  guint64 sum = 0;
  for (guint i = 0; i < DS_DROP_N_REASONS; i++)
    sum += st->frames.by_reason[i];
  g_assert_cmpuint (st->frames.dropped, ==, sum);
  g_assert_cmpuint (st->frames.acquired, ==, st->frames.folded + st->frames.dropped);
}

static guint
folded_wrong (Lab *lab)
{
  g_mutex_lock (&lab->lock);
  guint n = lab->folded_wrong;
  g_mutex_unlock (&lab->lock);
  return n;
}

/* A camera that sends each frame after its exposure: every phase after the first is applied
 * while the previous phase's frame transfers, none while a frame exposes, and every folded
 * frame was lit with its phase. Fails if set_phase went out before the exposure ended: that
 * frame shows the next phase (moves_during_exposure, a wrong-phase drop). */
static void
test_moves_during_transfer (Fixture *f, gconstpointer d)
{
  guint m = GPOINTER_TO_UINT (d);
  DsCaptureSettings s;
  settings (&s, 8, m);
  for (guint set = 0; set < 2; set++) {
    capture (f, &s);
    g_assert_no_error (f->failure);
    scripted_assert_scene_recovered (f->result);
  }
  g_assert_cmpuint (f->lab.moves_during_exposure, ==, 0);
  /* Phases 1..7 of each set, during the transfer of the last frame of the phase before. */
  g_assert_cmpuint (f->lab.moves_during_transfer, ==, 2 * 7);
  g_assert_cmpuint (f->lab.moves_between_frames, ==, 0);
  g_assert_cmpuint (f->lab.set_phases, ==, 2 * 8);
  DsSequencerStatus st;
  status (f, &st);
  g_assert_cmpuint (st.frames.dropped, ==, 0);
  g_assert_cmpuint (st.frames.folded, ==, 2 * 8 * m);
  g_assert_cmpuint (f->lab.folded, ==, 2 * 8 * m);
  g_assert_cmpuint (folded_wrong (&f->lab), ==, 0);
}

/* One frame is reported begun while it still exposes (a camera breaking the assumption): the
 * illuminator moves during that exposure, the frame shows the next phase, and phase
 * verification refuses it; the phase is acquired again and no frame is folded wrong. */
static void
test_camera_sends_while_exposing (Fixture *f, gconstpointer d)
{
  (void) d;
  DsCaptureSettings s;
  settings (&s, 8, 1);
  capture (f, &s); /* learn the stripe-phase offset on a clean set */
  g_assert_nonnull (f->result);
  DsSequencerStatus before, after;
  status (f, &before);
  f->lab.report_early_in = 3; /* phase 2's frame */
  capture (f, &s);
  g_assert_no_error (f->failure);
  scripted_assert_scene_recovered (f->result);
  status (f, &after);
  g_assert_cmpuint (f->lab.moves_during_exposure, ==, 1);
  g_assert_cmpuint (after.frames.by_reason[DS_DROP_WRONG_PHASE] - before.frames.by_reason[DS_DROP_WRONG_PHASE], ==, 1);
  g_assert_cmpuint (after.frames.folded - before.frames.folded, ==, 8);
  g_assert_cmpuint (folded_wrong (&f->lab), ==, 0);
}

/* Every frame reported begun at its trigger: every move lands in an exposure, and every frame
 * exposed across a move (it shows the next phase) is refused; not one is folded wrong. A phase
 * whose frame was refused is taken again without a move during its exposure (the frame grabbed
 * meanwhile is kept back, and nothing moves while one is: pipeline.c), so the sets
 * still complete, at one retry per phase. */
static void
test_camera_always_sends_while_exposing (Fixture *f, gconstpointer d)
{
  (void) d;
  DsCaptureSettings s;
  settings (&s, 8, 1);
  capture (f, &s);
  g_assert_nonnull (f->result);
  f->lab.report_early_always = TRUE;
  DsSequencerStatus before, after;
  status (f, &before);
  for (guint set = 0; set < 3; set++) {
    capture (f, &s);
    g_assert_no_error (f->failure);
    scripted_assert_scene_recovered (f->result);
  }
  status (f, &after);
  g_assert_cmpuint (f->lab.moves_during_exposure, >=, 3);
  g_assert_cmpuint (after.frames.by_reason[DS_DROP_WRONG_PHASE] - before.frames.by_reason[DS_DROP_WRONG_PHASE], ==,
                    f->lab.moves_during_exposure);
  g_assert_cmpuint (after.frames.folded - before.frames.folded, ==, 3 * 8);
  g_assert_cmpuint (folded_wrong (&f->lab), ==, 0);
}

/* [camera] sends-after-exposure=false, the remedy for such a camera: the illuminator moves
 * only once a frame arrived, never during an exposure or a transfer. */
static void
test_untrusted_camera (Fixture *f, gconstpointer d)
{
  (void) d;
  f->lab.report_early_always = TRUE;
  DsCaptureSettings s;
  settings (&s, 8, 1);
  capture (f, &s);
  g_assert_no_error (f->failure);
  scripted_assert_scene_recovered (f->result);
  g_assert_cmpuint (f->lab.moves_during_exposure, ==, 0);
  g_assert_cmpuint (f->lab.moves_during_transfer, ==, 0);
  g_assert_cmpuint (folded_wrong (&f->lab), ==, 0);
}

/* Applying the next phase fails (BUSY) while a frame transfers: that frame, exposed before,
 * is still folded; the failure costs a retry of the next phase, as if it had failed after the
 * grab. */
static void
test_set_phase_fails_during_transfer (Fixture *f, gconstpointer d)
{
  (void) d;
  DsCaptureSettings s;
  settings (&s, 8, 1);
  f->lab.busy_in = 2; /* phase 1, during phase 0's transfer */
  capture (f, &s);
  g_assert_no_error (f->failure);
  scripted_assert_scene_recovered (f->result);
  DsSequencerStatus st;
  status (f, &st);
  g_assert_cmpuint (st.frames.device_errors, ==, 1);
  g_assert_cmpuint (st.frames.retries, ==, 1);
  g_assert_cmpuint (st.frames.folded, ==, 8);
  g_assert_cmpuint (st.frames.dropped, ==, 0);
  g_assert_cmpuint (f->lab.moves_during_exposure, ==, 0);
  g_assert_cmpuint (folded_wrong (&f->lab), ==, 0);
}

/* The illuminator is lost while a frame transfers: the set fails naming the phase, the frames
 * taken are accounted (aborted), the devices reconnect and the next set is whole. */
static void
test_illuminator_lost_during_transfer (Fixture *f, gconstpointer d)
{
  (void) d;
  DsCaptureSettings s;
  settings (&s, 8, 1);
  f->lab.lost_in = 4; /* phase 3, during phase 2's transfer */
  capture (f, &s);
  g_assert_null (f->result);
  g_assert_nonnull (f->failure);
  g_assert_nonnull (strstr (f->failure->message, "phase 3"));
  g_assert_nonnull (strstr (f->failure->message, "illuminator gone"));
  DsSequencerStatus st;
  status (f, &st);
  g_assert_cmpuint (st.frames.by_reason[DS_DROP_ABORTED], ==, 3);
  capture (f, &s);
  g_assert_no_error (f->failure);
  scripted_assert_scene_recovered (f->result);
  g_assert_cmpuint (f->lab.moves_during_exposure, ==, 0);
  g_assert_cmpuint (folded_wrong (&f->lab), ==, 0);
}

/* A frame that never comes: nothing begins, the illuminator stays, the grab times out and the
 * phase is taken again. */
static void
test_lost_frame_keeps_the_phase (Fixture *f, gconstpointer d)
{
  (void) d;
  DsCaptureSettings s;
  settings (&s, 8, 1);
  f->lab.lose_in = 5; /* phase 4's frame */
  capture (f, &s);
  g_assert_no_error (f->failure);
  scripted_assert_scene_recovered (f->result);
  DsSequencerStatus st;
  status (f, &st);
  g_assert_cmpuint (st.frames.timeouts, ==, 1);
  g_assert_cmpuint (st.frames.folded, ==, 8);
  g_assert_cmpuint (f->lab.moves_during_exposure, ==, 0);
  /* Phase 5 only after phase 4's second frame: 7 moves during a transfer all the same. */
  g_assert_cmpuint (f->lab.moves_during_transfer, ==, 7);
  g_assert_cmpuint (folded_wrong (&f->lab), ==, 0);
}

/* Runs continuous mode until `sets` results came, each whole, and stops it. */
static void
run_continuous (Fixture *f, const DsCaptureSettings *s, guint sets)
{
  ds_sequencer_start (f->seq, s);
  while (f->results < sets) {
    g_main_loop_run (f->loop);
    g_assert_no_error (f->failure);
    scripted_assert_scene_recovered (f->result);
  }
  ds_sequencer_stop (f->seq);
  for (;;) {
    DsSequencerStatus st;
    ds_sequencer_get_status (f->seq, &st);
    if (!st.continuous)
      break;
    g_main_context_iteration (NULL, FALSE);
    g_usleep (1000);
  }
  while (g_main_context_iteration (NULL, FALSE))
    ;
  g_assert_no_error (f->failure);
}

/* Continuous mode: phase 0 of the next set is lit during the transfer of the set's last frame
 * and triggered once that frame arrived (carry.c), and phase 1 is lit during that
 * frame's transfer, which the next set grabs without triggering it. Every result whole, every
 * folded frame lit with its phase, and phase 0 lit between frames only for the first set:
 * fails if a set boundary still applies phase 0 after the last frame arrived. */
static void
test_continuous (Fixture *f, gconstpointer d)
{
  (void) d;
  DsCaptureSettings s;
  settings (&s, 8, 1);
  guint sets = 4;
  run_continuous (f, &s, sets);
  DsSequencerStatus st;
  status (f, &st);
  g_assert_cmpuint (st.frames.by_reason[DS_DROP_WRONG_PHASE], ==, 0);
  g_assert_cmpuint (f->lab.moves_during_exposure, ==, 0);
  /* Phases 1..7 and the next set's phase 0 during a transfer, phase 1 of a set started ahead
   * too. */
  g_assert_cmpuint (f->lab.moves_during_transfer, >=, 8 * (sets - 1) + 7);
  g_assert_cmpuint (f->lab.moves_between_frames, ==, 0);
  g_assert_cmpuint (f->lab.zero_between_frames, ==, 1);
  g_assert_cmpuint (folded_wrong (&f->lab), ==, 0);
}

/* Continuous mode, one frame near the set boundary reported begun while it still exposes, so
 * that the move during its "transfer" lands in its exposure (data: that frame's trigger;
 * triggers 1-8 are the first set, 9 the second set's phase 0 taken ahead, 10-16 its phases
 * 1-7). Trigger 16, the set's last frame: the next set's phase 0 lands in it and it shows
 * phase 0; it is refused (wrong phase) after the next set's first frame was triggered ahead,
 * which is grabbed and kept before phase 7 is lit again, and the next set starts from it.
 * Trigger 15, phase 6's frame (it shows phase 7): refused only after the last frame arrived,
 * phase 0 was lit during its transfer and the frame ahead triggered; the last frame is kept
 * back, the frame ahead grabbed and kept before phase 6 is lit again, and both are folded
 * where they belong. Either way one wrong-phase drop, every result whole, and not one frame
 * folded into a phase it was not lit with. */
static void
test_continuous_boundary_sends_while_exposing (Fixture *f, gconstpointer d)
{
  DsCaptureSettings s;
  settings (&s, 8, 1);
  f->lab.report_early_in = GPOINTER_TO_UINT (d);
  run_continuous (f, &s, 4);
  DsSequencerStatus st;
  status (f, &st);
  g_assert_cmpuint (f->lab.moves_during_exposure, ==, 1);
  g_assert_cmpuint (st.frames.by_reason[DS_DROP_WRONG_PHASE], ==, 1);
  g_assert_cmpuint (st.frames.by_reason[DS_DROP_ABORTED], <=, 1); /* a frame ahead at the stop */
  g_assert_cmpuint (st.frames.folded, >=, 4 * 8);
  g_assert_cmpuint (folded_wrong (&f->lab), ==, 0);
}

/* Continuous mode, lighting the next set's phase 0 during the last frame's transfer fails
 * (BUSY): the set it was lit for is not charged a retry and this set is whole; the frame ahead
 * is triggered after phase 0 is applied again once the last frame arrived. */
static void
test_continuous_phase0_fails_during_transfer (Fixture *f, gconstpointer d)
{
  (void) d;
  DsCaptureSettings s;
  settings (&s, 8, 1);
  f->lab.busy_in = 9; /* set_phase calls: 0-7 of the first set, then the next set's 0 */
  run_continuous (f, &s, 3);
  DsSequencerStatus st;
  status (f, &st);
  g_assert_cmpuint (st.frames.device_errors, ==, 1);
  g_assert_cmpuint (st.frames.retries, ==, 0);
  g_assert_cmpuint (st.sets_failed, ==, 0);
  g_assert_cmpuint (st.frames.dropped - st.frames.by_reason[DS_DROP_ABORTED], ==, 0);
  /* Phase 0 between frames: for the first set, and again after the failure. */
  g_assert_cmpuint (f->lab.zero_between_frames, ==, 2);
  g_assert_cmpuint (f->lab.moves_during_exposure, ==, 0);
  g_assert_cmpuint (folded_wrong (&f->lab), ==, 0);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
#define ADD(name, fn, data, set_up) \
  g_test_add ("/sequencer-transfer/" name, Fixture, data, set_up, fn, teardown)
  ADD ("moves-during-transfer", test_moves_during_transfer, GUINT_TO_POINTER (1), setup_trusted);
  ADD ("moves-during-transfer-averages", test_moves_during_transfer, GUINT_TO_POINTER (2), setup_trusted);
  ADD ("camera-sends-while-exposing", test_camera_sends_while_exposing, NULL, setup_trusted);
  ADD ("camera-always-sends-while-exposing", test_camera_always_sends_while_exposing, NULL, setup_trusted);
  ADD ("untrusted-camera", test_untrusted_camera, NULL, setup_untrusted);
  ADD ("set-phase-fails-during-transfer", test_set_phase_fails_during_transfer, NULL, setup_trusted);
  ADD ("illuminator-lost-during-transfer", test_illuminator_lost_during_transfer, NULL, setup_trusted);
  ADD ("lost-frame-keeps-the-phase", test_lost_frame_keeps_the_phase, NULL, setup_trusted);
  ADD ("continuous", test_continuous, NULL, setup_trusted);
  ADD ("continuous-last-frame-sends-while-exposing", test_continuous_boundary_sends_while_exposing,
       GUINT_TO_POINTER (16), setup_trusted);
  ADD ("continuous-drop-before-last", test_continuous_boundary_sends_while_exposing, GUINT_TO_POINTER (15),
       setup_trusted);
  ADD ("continuous-phase0-fails-during-transfer", test_continuous_phase0_fails_during_transfer, NULL,
       setup_trusted);
  return g_test_run ();
}
