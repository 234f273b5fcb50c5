/* Benchmark (not a test): how fast descatter-labsim serves frames at 1 MP (issue 13's goal:
 * >= 50 frames/s), against the ceiling of the same transport measured in the same run: an
 * ArvGvFakeCamera in this process whose fill is a memcpy of a prebuilt frame, polled at the
 * same 1 kHz, with the same 8 KiB GVSP packets. Both are driven the same way: software trigger,
 * wait for the frame, next; in alternating rounds (labsim's camera on 127.0.0.2, the ceiling's
 * on 127.0.0.1), the figure being the median of the rounds' ratios.
 * It checks what it measures: every labsim frame is complete and shows the phase lit over
 * Modbus (stripe phase measured in the frame), so the figure cannot come from empty frames.
 * Usage: bench-labsim-rate LABSIM SCENE [--quick]. Binds UDP 3956 on 127.0.0.1 and 127.0.0.2
 * (tests/drivers/netns_run.sh gives loopback both); exits 77 (skipped) without 127.0.0.2. */
#include <arv.h>
#include <glib/gstdio.h>
#include <ifaddrs.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "drivers/modbus/modbus_illuminator.h"
#include "drivers/sim/scene.h"
#include "proc/pixfmt.h"
#include "proc/stripe_phase.h"

#define SIDE 1024

typedef struct {
  double fps;
  guint frames, wrong, incomplete;
} Rate;

/* Software trigger, wait, next, for `seconds` on the camera at `address`; each frame handed to
 * `check` (may be NULL). */
static Rate
run_loop (const char *address, double seconds, gboolean (*check) (const void *data, gsize size, gpointer user),
          gpointer user)
{
  g_autoptr (GError) error = NULL;
  ArvCamera *cam = arv_camera_new (address, &error);
  g_assert_no_error (error);
  arv_camera_set_pixel_format_from_string (cam, "Mono16", &error);
  g_assert_no_error (error);
  arv_camera_set_trigger (cam, "Software", &error);
  g_assert_no_error (error);
  ArvStream *stream = arv_camera_create_stream (cam, NULL, NULL, &error);
  g_assert_no_error (error);
  g_object_set (stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_AUTO, NULL);
  guint payload = arv_camera_get_payload (cam, &error);
  for (guint i = 0; i < 4; i++)
    arv_stream_push_buffer (stream, arv_buffer_new (payload, NULL));
  arv_camera_start_acquisition (cam, &error);
  g_assert_no_error (error);
  Rate r = { 0 };
  gint64 t0 = 0;
  for (guint i = 0;; i++) {
    if (i == 2)
      t0 = g_get_monotonic_time (); /* after a warm-up frame or two */
    if (t0 && g_get_monotonic_time () - t0 > seconds * 1e6)
      break;
    arv_camera_software_trigger (cam, &error);
    g_assert_no_error (error);
    ArvBuffer *buf = arv_stream_timeout_pop_buffer (stream, 5000000);
    g_assert_nonnull (buf);
    gboolean whole = arv_buffer_get_status (buf) == ARV_BUFFER_STATUS_SUCCESS;
    gboolean right = TRUE;
    if (whole && check) {
      size_t size = 0;
      const void *data = arv_buffer_get_data (buf, &size);
      right = check (data, size, user);
    }
    if (t0) {
      r.frames++;
      r.incomplete += !whole;
      r.wrong += whole && !right;
    }
    arv_stream_push_buffer (stream, buf);
  }
  r.fps = r.frames / ((g_get_monotonic_time () - t0) / 1e6);
  arv_camera_stop_acquisition (cam, NULL);
  g_object_unref (stream);
  g_object_unref (cam);
  return r;
}

static void
memcpy_fill (ArvBuffer *buffer, void *data, guint32 exposure, guint32 gain, ArvPixelFormat pf)
{
  (void) exposure;
  (void) gain;
  (void) pf;
  memcpy ((void *) arv_buffer_get_data (buffer, NULL), data, (gsize) SIDE * SIDE * 2);
}

typedef struct {
  double period, expect;
  guint checked;
} PhaseCheck;

/* Every 10th frame: the stripes sit where phase 0 puts them (the first frame sets the origin). */
static gboolean
check_phase (const void *data, gsize size, gpointer user)
{
  PhaseCheck *pc = user;
  if (pc->checked++ % 10)
    return TRUE;
  g_autoptr (GError) error = NULL;
  g_autoptr (DsImage) img = ds_pixfmt_unpack (DS_PIXFMT_MONO16, data, size, SIDE, SIDE, 0, &error);
  if (!img)
    return FALSE;
  DsRegion region = { 0, 0, SIDE, 64 };
  DsStripePhase sp;
  if (!ds_stripe_phase_measure (img, pc->period, &region, &sp, &error) || !sp.reliable)
    return FALSE;
  if (isnan (pc->expect))
    pc->expect = sp.phase;
  return fabs (ds_stripe_phase_diff (sp.phase, pc->expect)) < 0.05;
}

/* Whether an interface has this IPv4 address (a GigE Vision camera serves on one). */
static gboolean
have_address (const char *address)
{
  struct ifaddrs *list = NULL;
  if (getifaddrs (&list) < 0)
    return FALSE;
  gboolean found = FALSE;
  for (struct ifaddrs *i = list; i && !found; i = i->ifa_next)
    if (i->ifa_addr && i->ifa_addr->sa_family == AF_INET) {
      char text[INET_ADDRSTRLEN];
      const struct sockaddr_in *in = (const struct sockaddr_in *) i->ifa_addr;
      found = inet_ntop (AF_INET, &in->sin_addr, text, sizeof text) && strcmp (text, address) == 0;
    }
  freeifaddrs (list);
  return found;
}

static int
cmp_double (const void *a, const void *b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return (x > y) - (x < y);
}

static double
median (const double *v, guint n)
{
  double s[8];
  memcpy (s, v, n * sizeof *s);
  qsort (s, n, sizeof *s, cmp_double);
  return n % 2 ? s[n / 2] : (s[n / 2 - 1] + s[n / 2]) / 2;
}

int
main (int argc, char **argv)
{
  if (argc < 3) {
    fprintf (stderr, "usage: bench-labsim-rate LABSIM SCENE [--quick]\n");
    return 2;
  }
  gboolean quick = argc > 3 && strcmp (argv[3], "--quick") == 0;
  if (!have_address ("127.0.0.2")) {
    fprintf (stderr, "bench-labsim-rate: skipped: no interface has 127.0.0.2 for labsim's camera (run it through "
                     "tests/drivers/netns_run.sh as root, or: ip addr add 127.0.0.2/8 dev lo)\n");
    return 77;
  }
  double seconds = quick ? 0.75 : 1.5;
  g_autoptr (GError) error = NULL;
  /* The scene at 1024 x 1024. */
  g_autofree char *text = NULL;
  if (!g_file_get_contents (argv[2], &text, NULL, &error)) {
    fprintf (stderr, "%s\n", error->message);
    return 1;
  }
  g_auto (GStrv) lines = g_strsplit (text, "\n", -1);
  for (guint i = 0; lines[i]; i++) {
    if (g_str_has_prefix (lines[i], "width="))
      g_free (lines[i]), lines[i] = g_strdup_printf ("width=%d", SIDE);
    else if (g_str_has_prefix (lines[i], "height="))
      g_free (lines[i]), lines[i] = g_strdup_printf ("height=%d", SIDE);
  }
  g_autofree char *big = g_strjoinv ("\n", lines);
  g_autofree char *dir = g_dir_make_tmp ("ds-bench-XXXXXX", &error);
  g_autofree char *scene_path = g_build_filename (dir, "1mp.scene", NULL);
  g_assert_true (g_file_set_contents (scene_path, big, -1, &error));
  g_autoptr (DsScene) scene = ds_scene_load (scene_path, &error);
  if (!scene) {
    fprintf (stderr, "%s\n", error->message);
    return 1;
  }

  /* Ceiling: the transport alone, on 127.0.0.1; labsim's camera on 127.0.0.2. Both stay up and
   * are measured in alternating rounds, so that a change of the machine's load falls on both
   * (this machine is shared): the figure is the median of the rounds' ratios. */
  /* labsim, phase 0 lit. */
  const char *lab_args[] = { "--camera-address", "127.0.0.2", NULL };
  TestLabsim *l = test_labsim_start (argv[1], scene_path, lab_args);
  g_autofree char *uri = g_strdup_printf ("tcp://127.0.0.1:%u", l->modbus_port);
  DsIlluminator *ill = ds_modbus_illuminator_open (uri, 1, 300, &error);
  g_assert_no_error (error);
  DsStripePattern pattern = { .kind = ds_scene_pattern_is_sine (scene) ? DS_STRIPES_SINE : DS_STRIPES_SQUARE,
                              .period_px = ds_scene_period_px (scene), .duty = ds_scene_duty (scene),
                              .black_level = ds_scene_black_level (scene), .intensity = 1, .n_phases = 8 };
  g_assert_true (ill->ops->set_pattern (ill->backend, &pattern, &error));
  g_assert_true (ill->ops->set_phase (ill->backend, 0, 1000, &error));
  PhaseCheck pc = { .period = ds_scene_period_px (scene), .expect = NAN };

  /* Then the ceiling's camera: bound after labsim's, since it also listens for discovery on
   * every address. */
  g_autofree guint16 *frame = g_new0 (guint16, (gsize) SIDE * SIDE);
  ArvGvFakeCamera *gv = arv_gv_fake_camera_new ("127.0.0.1", "DSBENCH1");
  g_assert_true (arv_gv_fake_camera_is_running (gv));
  ArvFakeCamera *fake = arv_gv_fake_camera_get_fake_camera (gv);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_WIDTH, SIDE);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_HEIGHT, SIDE);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, SIDE);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, SIDE);
  arv_fake_camera_write_register (fake, 0xd04 /* stream packet size, as labsim serves */, 8192);
  arv_fake_camera_set_trigger_frequency (fake, 1000.0);
  arv_fake_camera_set_fill_pattern (fake, memcpy_fill, frame);

  guint rounds = quick ? 2 : 5;
  double ratios[5], lab_fps[5], ceiling_fps[5];
  Rate lab = { 0 }, ceiling = { 0 };
  for (guint r = 0; r < rounds; r++) {
    Rate c = run_loop ("127.0.0.1", seconds, NULL, NULL);
    Rate x = run_loop ("127.0.0.2", seconds, check_phase, &pc);
    ceiling_fps[r] = c.fps;
    lab_fps[r] = x.fps;
    ratios[r] = x.fps / c.fps;
    printf ("round %u: labsim %.1f frames/s, ceiling %.1f frames/s, ratio %.2f\n", r + 1, x.fps, c.fps, ratios[r]);
    ceiling.frames += c.frames;
    ceiling.wrong += c.wrong;
    ceiling.incomplete += c.incomplete;
    lab.frames += x.frames;
    lab.wrong += x.wrong;
    lab.incomplete += x.incomplete;
  }
  ds_illuminator_close (ill);
  test_labsim_stop (l);
  g_object_unref (gv);
  g_unlink (scene_path);
  g_rmdir (dir);

  printf ("labsim at %dx%d Mono16: median %.1f frames/s (goal >= 50); transport ceiling (memcpy fill, same "
          "trigger polling) median %.1f frames/s; labsim/ceiling median of %u rounds %.2f; %u frames, %u wrong, %u "
          "incomplete (ceiling: %u incomplete)\n",
          SIDE, SIDE, median (lab_fps, rounds), median (ceiling_fps, rounds), rounds, median (ratios, rounds),
          lab.frames, lab.wrong, lab.incomplete, ceiling.incomplete);
  /* Results, not speed, decide the exit status: a whole frame of the wrong content fails it. A
   * frame whose packets a starved machine dropped (incomplete: the UDP receive buffer overflowed)
   * is the transport's, on either side, and is only reported, unless so many were lost that the
   * rates say nothing (a quarter). */
  gboolean transport_ok = lab.incomplete * 4 <= lab.frames && ceiling.incomplete * 4 <= ceiling.frames;
  return lab.wrong == 0 && ceiling.wrong == 0 && lab.frames > 0 && transport_ok ? 0 : 1;
}
