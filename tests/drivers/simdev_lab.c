/* The in-process simulated camera and illuminator: each frame shows the phase the illuminator
 * applied at trigger time (measured in the frame with proc/stripe_phase, against k/N), the
 * signal scales with exposure, and every fault knob gives its typed error or wrong frame.
 * The test of drivers/simdev (the devices of `descatterd --sim`), not a rig of the tests. */
#include <math.h>
#include <string.h>

#include "drivers/simdev/sim_lab.h"
#include "drivers/sim/scene.h"
#include "period_check.h"
#include "proc/stripe_phase.h"

#define N_PHASES 4

typedef struct {
  DsSimLab *lab;
  DsCamera *cam;
  DsIlluminator *ill;
  double period_px;
} Lab;

static void
lab_setup (Lab *l, gconstpointer data)
{
  (void) data;
  g_autoptr (GError) error = NULL;
  /* Clear water, no scattering: cheap to render and the stripes are crisp. */
  g_autoptr (DsScene) scene = ds_scene_load (DS_SCENE_DIR "/clear-grid.scene", &error);
  g_assert_no_error (error);
  DsRenderer *r = ds_renderer_new (scene, NULL, &error);
  g_assert_no_error (error);
  l->lab = ds_sim_lab_new (r, 42);
  l->cam = ds_sim_camera_new (l->lab);
  l->ill = ds_sim_illuminator_new (l->lab);
  l->period_px = ds_scene_period_px (scene);
  DsStripePattern p = { .kind = DS_STRIPES_SQUARE, .period_px = l->period_px, .duty = ds_scene_duty (scene),
                        .black_level = ds_scene_black_level (scene), .intensity = 1, .n_phases = N_PHASES };
  g_assert_true (l->ill->ops->set_pattern (l->ill->backend, &p, &error));
  g_assert_no_error (error);
  DsCameraSettings s = { .exposure_us = ds_scene_default_exposure_us (scene), .pixel_format = "Mono16" };
  g_assert_true (l->cam->ops->configure (l->cam->backend, &s, &error));
  g_assert_no_error (error);
  g_assert_true (l->cam->ops->start (l->cam->backend, &error));
  g_assert_no_error (error);
}

static void
lab_teardown (Lab *l, gconstpointer data)
{
  (void) data;
  ds_camera_close (l->cam);
  ds_illuminator_close (l->ill);
  ds_sim_lab_unref (l->lab);
}

static void
set_faults (Lab *l, const char *text)
{
  DsSimFaults f;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_sim_faults_parse (text, &f, &error));
  g_assert_no_error (error);
  ds_sim_lab_set_faults (l->lab, &f);
}

static DsFrame *
shoot (Lab *l, GError **error)
{
  if (!l->cam->ops->trigger (l->cam->backend, error))
    return NULL;
  return l->cam->ops->grab (l->cam->backend, 100, error);
}

static void
set_phase (Lab *l, guint k)
{
  g_autoptr (GError) error = NULL;
  g_assert_true (l->ill->ops->set_phase (l->ill->backend, k, 1000, &error));
  g_assert_no_error (error);
}

/* The phase (in units of 1/N) measured in the frame. */
static guint
measured_phase (Lab *l, const DsFrame *f)
{
  DsStripePhase m;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_stripe_phase_measure (f->image, l->period_px, NULL, &m, &error));
  g_assert_no_error (error);
  g_assert_true (m.reliable);
  double k = m.phase * N_PHASES;
  guint ki = (guint) lround (k) % N_PHASES;
  /* Within a tenth of a phase step of a whole step: a clean frame. */
  g_assert_cmpfloat (fabs (ds_stripe_phase_diff (m.phase, (double) ki / N_PHASES)), <, 0.1 / N_PHASES);
  return ki;
}

static double
mean_of (const DsImage *im)
{
  double s = 0;
  for (guint y = 0; y < im->height; y++) {
    const guint16 *row = ds_image_row (im, y);
    for (guint x = 0; x < im->width; x++)
      s += row[x];
  }
  return s / ((double) im->width * im->height);
}

static void
test_frame_shows_applied_phase (Lab *l, gconstpointer data)
{
  (void) data;
  for (guint k = 0; k < N_PHASES; k++) {
    set_phase (l, k);
    g_autoptr (GError) error = NULL;
    g_autoptr (DsFrame) f = shoot (l, &error);
    g_assert_no_error (error);
    g_assert_cmpuint (measured_phase (l, f), ==, k);
  }
  DsIlluminatorStatus st;
  g_autoptr (GError) error = NULL;
  g_assert_true (l->ill->ops->get_status (l->ill->backend, &st, &error));
  g_assert_cmpint (st.applied_phase, ==, N_PHASES - 1);
  g_assert_cmpuint (st.apply_count, ==, N_PHASES);
}

static void
test_exposure_doubles_signal (Lab *l, gconstpointer data)
{
  (void) data;
  set_phase (l, 0);
  double means[2];
  for (guint i = 0; i < 2; i++) {
    DsCameraSettings s = { .exposure_us = 1000.0 * (i + 1), .pixel_format = "Mono16" };
    g_autoptr (GError) error = NULL;
    l->cam->ops->stop (l->cam->backend);
    g_assert_true (l->cam->ops->configure (l->cam->backend, &s, &error));
    g_assert_true (l->cam->ops->start (l->cam->backend, &error));
    g_autoptr (DsFrame) f = shoot (l, &error);
    g_assert_no_error (error);
    g_assert_cmpfloat (f->exposure_us, ==, s.exposure_us);
    means[i] = mean_of (f->image);
  }
  g_test_message ("mean signal at 1 ms %.1f DN, at 2 ms %.1f DN", means[0], means[1]);
  g_assert_cmpfloat (means[0], >, 20); /* well above quantization */
  /* Photon signal is linear in exposure; dark current (20 e/s) adds < 0.1 e here. */
  g_assert_cmpfloat (fabs (means[1] / means[0] - 2.0), <, 0.05);
}

static void
test_fault_drop (Lab *l, gconstpointer data)
{
  (void) data;
  set_phase (l, 0);
  set_faults (l, "drop=1");
  g_autoptr (GError) error = NULL;
  g_assert_null (shoot (l, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_TIMEOUT);
  g_clear_error (&error);
  g_autoptr (DsFrame) first = NULL;
  set_faults (l, "");
  first = shoot (l, &error);
  g_assert_no_error (error);
  /* The dropped frame's id is missing between the two delivered ones. */
  set_faults (l, "drop=1");
  g_assert_null (shoot (l, &error));
  g_clear_error (&error);
  set_faults (l, "");
  g_autoptr (DsFrame) second = shoot (l, &error);
  g_assert_no_error (error);
  /* Its id is missing (the extended ids show it), but its grab timed out: the loss was counted
   * once, as a timeout, and is no gap for the next frame (before, ids_skipped was 1 here, and
   * the sequencer dropped this good frame as frame_gap: one loss cost two retries). */
  g_assert_cmpuint (second->frame_id, ==, first->frame_id + 2);
  g_assert_cmpuint (second->ids_skipped, ==, 0);
  DsCameraStats st;
  l->cam->ops->get_stats (l->cam->backend, &st);
  g_assert_cmpuint (st.timeouts, ==, 2);
  g_assert_cmpuint (st.ids_skipped, ==, 0);
}

/* A frame that goes missing without a grab noticing (its trigger's grab was never made, so
 * nobody counted the loss) is still a gap, also right after a counted loss: a lost trigger
 * (no id) noted as a timeout excuses nothing later. Ids by hand: a, lost trigger (no id), b = a
 * + 1, a frame dropped without its grab (id b + 1), c = b + 2 with one id missing. */
static void
test_fault_drop_unaccounted (Lab *l, gconstpointer data)
{
  (void) data;
  set_phase (l, 0);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsFrame) a = shoot (l, &error);
  g_assert_no_error (error);
  set_faults (l, "timeout=1");
  g_assert_null (shoot (l, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_TIMEOUT);
  g_clear_error (&error);
  set_faults (l, "");
  g_autoptr (DsFrame) b = shoot (l, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (b->frame_id, ==, a->frame_id + 1);
  g_assert_cmpuint (b->ids_skipped, ==, 0);
  set_faults (l, "drop=1");
  g_assert_true (l->cam->ops->trigger (l->cam->backend, &error)); /* lost in transit, not grabbed */
  set_faults (l, "");
  g_autoptr (DsFrame) c = shoot (l, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (c->frame_id, ==, b->frame_id + 2);
  g_assert_cmpuint (c->ids_skipped, ==, 1);
}

/* drop-every=3 after faults-after=1: triggers 4, 7 and 10 are lost in transit (grab TIMEOUT,
 * their ids skipped), every other one delivers. */
static void
test_drop_every (Lab *l, gconstpointer data)
{
  (void) data;
  set_phase (l, 0);
  set_faults (l, "faults-after=1,drop-every=3");
  guint64 last_id = 0;
  for (guint t = 1; t <= 10; t++) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsFrame) f = shoot (l, &error);
    if (t == 4 || t == 7 || t == 10) {
      g_assert_null (f);
      g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_TIMEOUT);
      continue;
    }
    g_assert_no_error (error);
    if (last_id)
      g_assert_cmpuint (f->frame_id, ==, last_id + (t == 5 || t == 8 ? 2 : 1));
    last_id = f->frame_id;
  }
}

/* faults-after=N spares the first N triggers: the counted fault hits trigger N + 1. */
static void
test_faults_after (Lab *l, gconstpointer data)
{
  (void) data;
  set_phase (l, 0);
  set_faults (l, "faults-after=2,drop-next=1");
  g_autoptr (GError) error = NULL;
  for (guint i = 0; i < 2; i++) {
    g_autoptr (DsFrame) f = shoot (l, &error);
    g_assert_no_error (error);
  }
  g_assert_null (shoot (l, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_TIMEOUT);
  g_clear_error (&error);
  g_autoptr (DsFrame) f = shoot (l, &error);
  g_assert_no_error (error);
}

static void
test_fault_timeout (Lab *l, gconstpointer data)
{
  (void) data;
  set_phase (l, 0);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsFrame) a = shoot (l, &error);
  g_assert_no_error (error);
  set_faults (l, "timeout=1");
  g_assert_null (shoot (l, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_TIMEOUT);
  g_clear_error (&error);
  set_faults (l, "");
  g_autoptr (DsFrame) b = shoot (l, &error);
  g_assert_no_error (error);
  /* A lost trigger consumes no id. */
  g_assert_cmpuint (b->frame_id, ==, a->frame_id + 1);
  g_assert_cmpuint (b->ids_skipped, ==, 0);
}

static void
test_fault_incomplete (Lab *l, gconstpointer data)
{
  (void) data;
  set_phase (l, 0);
  set_faults (l, "incomplete=1");
  g_autoptr (GError) error = NULL;
  g_assert_null (shoot (l, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INCOMPLETE);
  DsCameraStats st;
  l->cam->ops->get_stats (l->cam->backend, &st);
  g_assert_cmpuint (st.failures, ==, 1);
}

static void
test_fault_stale (Lab *l, gconstpointer data)
{
  (void) data;
  set_phase (l, 1);
  set_phase (l, 2);
  set_faults (l, "stale=1");
  g_autoptr (GError) error = NULL;
  g_autoptr (DsFrame) f = shoot (l, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (measured_phase (l, f), ==, 1); /* the previous phase */
}

static void
test_fault_wrong_phase (Lab *l, gconstpointer data)
{
  (void) data;
  set_faults (l, "wrong-phase=1");
  set_phase (l, 1); /* reports success... */
  DsIlluminatorStatus st;
  g_autoptr (GError) error = NULL;
  g_assert_true (l->ill->ops->get_status (l->ill->backend, &st, &error));
  g_assert_cmpint (st.applied_phase, ==, 1); /* ...and reads back 1... */
  g_autoptr (DsFrame) f = shoot (l, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (measured_phase (l, f), ==, 2); /* ...but shows 2 */
}

static void
test_fault_not_ready (Lab *l, gconstpointer data)
{
  (void) data;
  set_faults (l, "not-ready=1");
  g_autoptr (GError) error = NULL;
  g_assert_false (l->ill->ops->set_phase (l->ill->backend, 1, 100, &error));
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_BUSY);
}

static void
test_fault_disconnect (Lab *l, gconstpointer data)
{
  (void) data;
  set_phase (l, 0);
  set_faults (l, "disconnect-after=2");
  g_autoptr (GError) error = NULL;
  for (guint i = 0; i < 2; i++) {
    g_autoptr (DsFrame) f = shoot (l, &error);
    g_assert_no_error (error);
  }
  g_assert_null (shoot (l, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
  g_clear_error (&error);
  g_assert_null (l->cam->ops->grab (l->cam->backend, 10, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
  g_clear_error (&error);
  DsCameraInfo info;
  l->cam->ops->get_info (l->cam->backend, &info);
  g_assert_false (info.connected);
  g_assert_true (l->cam->ops->reconnect (l->cam->backend, &error));
  g_assert_true (l->cam->ops->start (l->cam->backend, &error));
  g_assert_no_error (error);
  g_autoptr (DsFrame) f = shoot (l, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (measured_phase (l, f), ==, 0);
}

/* Counted faults hit exactly the next N events, then stop. */
static void
test_fault_counted (Lab *l, gconstpointer data)
{
  (void) data;
  set_faults (l, "incomplete-next=2, wrong-phase-next=1");
  set_phase (l, 1);
  g_autoptr (GError) error = NULL;
  for (guint i = 0; i < 2; i++) {
    g_assert_null (shoot (l, &error));
    g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INCOMPLETE);
    g_clear_error (&error);
  }
  g_autoptr (DsFrame) wrong = shoot (l, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (measured_phase (l, wrong), ==, 2); /* the one wrong set_phase */
  set_phase (l, 1);
  g_autoptr (DsFrame) right = shoot (l, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (measured_phase (l, right), ==, 1);
}

/* A projector that can change its period (issue 12): the status says so, and frames show the
 * period asked for, measured in the frames themselves, whatever the scene declares. */
static void
test_period (Lab *l, gconstpointer data)
{
  (void) data;
  DsIlluminatorStatus st;
  g_autoptr (GError) error = NULL;
  g_assert_true (l->ill->ops->get_status (l->ill->backend, &st, &error));
  g_assert_true (st.period_adjustable);
  g_assert_cmpfloat (st.period_min_px, <=, 2.0);
  g_assert_cmpfloat (st.period_max_px, >=, 100.0);
  const DsSceneSpec *spec = ds_scene_spec (ds_renderer_scene (ds_sim_lab_renderer (l->lab)));
  const double periods[] = { l->period_px, 0.625 * l->period_px, 1.6875 * l->period_px };
  for (guint i = 0; i < G_N_ELEMENTS (periods); i++) {
    DsStripePattern p = { .kind = DS_STRIPES_SQUARE, .period_px = periods[i], .duty = spec->duty,
                          .black_level = spec->black_level, .intensity = 1, .n_phases = N_PHASES };
    period_check_frames (l->ill, l->cam, &p, NULL, 0.005);
  }
}

/* A projector whose period is fixed: the status says which, another period is refused
 * (UNSUPPORTED, naming both), the scene's is taken. */
static void
test_fixed_period (Lab *l, gconstpointer data)
{
  (void) data;
  ds_sim_lab_set_period_fixed (l->lab, TRUE);
  DsIlluminatorStatus st;
  g_autoptr (GError) error = NULL;
  g_assert_true (l->ill->ops->get_status (l->ill->backend, &st, &error));
  g_assert_false (st.period_adjustable);
  g_assert_cmpfloat (st.period_min_px, ==, l->period_px);
  g_assert_cmpfloat (st.period_max_px, ==, l->period_px);
  const DsSceneSpec *spec = ds_scene_spec (ds_renderer_scene (ds_sim_lab_renderer (l->lab)));
  DsStripePattern p = { .kind = DS_STRIPES_SQUARE, .period_px = 2 * l->period_px, .duty = spec->duty,
                        .black_level = spec->black_level, .intensity = 1, .n_phases = N_PHASES };
  g_assert_false (l->ill->ops->set_pattern (l->ill->backend, &p, &error));
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED);
  g_autofree char *asked = g_strdup_printf ("asked for %g px", 2 * l->period_px);
  g_autofree char *fixed = g_strdup_printf ("fixed at the scene's %g px", l->period_px);
  g_assert_nonnull (strstr (error->message, asked));
  g_assert_nonnull (strstr (error->message, fixed));
  p.period_px = l->period_px;
  period_check_frames (l->ill, l->cam, &p, NULL, 0.005);
}

static void
test_faults_parse_errors (void)
{
  DsSimFaults f;
  const char *bad[] = { "drop", "drop=2", "stale=-1", "nonsense=1", "disconnect-after=1.5", "timeout=abc",
                        "stale-next=0.5" };
  for (guint i = 0; i < G_N_ELEMENTS (bad); i++) {
    g_autoptr (GError) error = NULL;
    g_assert_false (ds_sim_faults_parse (bad[i], &f, &error));
    g_assert_nonnull (error);
  }
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_sim_faults_parse ("drop=0.5, disconnect-after=3", &f, &error));
  g_assert_cmpfloat (f.drop, ==, 0.5);
  g_assert_cmpuint (f.disconnect_after, ==, 3);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/simdev/faults-parse", test_faults_parse_errors);
#define ADD(path, fn) g_test_add (path, Lab, NULL, lab_setup, fn, lab_teardown)
  ADD ("/simdev/frame-shows-applied-phase", test_frame_shows_applied_phase);
  ADD ("/simdev/exposure-doubles-signal", test_exposure_doubles_signal);
  ADD ("/simdev/fault/drop", test_fault_drop);
  ADD ("/simdev/fault/drop-unaccounted", test_fault_drop_unaccounted);
  ADD ("/simdev/fault/drop-every", test_drop_every);
  ADD ("/simdev/fault/faults-after", test_faults_after);
  ADD ("/simdev/fault/timeout", test_fault_timeout);
  ADD ("/simdev/fault/incomplete", test_fault_incomplete);
  ADD ("/simdev/fault/stale", test_fault_stale);
  ADD ("/simdev/fault/wrong-phase", test_fault_wrong_phase);
  ADD ("/simdev/fault/not-ready", test_fault_not_ready);
  ADD ("/simdev/fault/disconnect", test_fault_disconnect);
  ADD ("/simdev/fault/counted", test_fault_counted);
  ADD ("/simdev/period", test_period);
  ADD ("/simdev/fixed-period", test_fixed_period);
  return g_test_run ();
}
