#include "fake_rig.h"

#include <arv.h>
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

struct FakeRig {
  ArvGvFakeCamera *gv;
  DsModbusServer *modbus;
  DsModbusServerConfig modbus_config;
  guint width, height, n_phases;
  guint16 **lit;           /* one frame per phase */
  guint16 *dark;           /* illuminator off */
  gint frames;             /* atomic */
  ArvFakeCamera *fake;     /* owned by gv */
  guint64 trigger_period_us;
  gboolean spin;           /* DS_BENCH_CAMERA_POLL=spin: Aravis's own wait (for comparison) */
  gint camera_tid;         /* atomic: the camera thread's id, once it filled a frame */
  /* When each fill began (fake_rig_cycles), written by the camera's thread only: an entry is
   * written before n_fills counts it. Full: the later fills are not recorded. */
  gint64 *fill_us;
  guint8 *fill_phase;      /* the phase lit at that fill; G_MAXUINT8 when off */
  gint n_fills;            /* atomic */
};

/* 2^20 fills: 45 minutes at 400 frames/s, longer than any run of the benchmark. */
#define FILL_LOG_CAPACITY (1 << 20)

/* The camera polls its software trigger at FAKE_RIG_TRIGGER_HZ, as issue 13 defines the
 * measurement: a trigger waits 0.5 ms on average for the poll, the same for the ceiling and
 * the daemon. DS_BENCH_TRIGGER_HZ changes it (for comparisons with earlier runs: 2000). */
#define FAKE_RIG_TRIGGER_HZ 1000.0

/* ---- the camera's thread sleeps between its trigger polls instead of spinning ----
 *
 * Aravis's ArvGvFakeCamera thread (arvgvfakecamera.c) checks the software trigger at the
 * multiples of the trigger period in real time; until the next one it polls its control
 * sockets with g_poll, the timeout the time left truncated to whole milliseconds. With the
 * trigger polled every millisecond that timeout is always 0, so the thread spins on a core for
 * as long as it streams: it took half of the machine's CPU from the daemon, the ceiling and
 * the stream threads, and ran into the kernel's real-time throttling (which then stalled
 * every real-time thread of that core for up to 50 ms: the drift of the ceilings in runs D-F).
 * Aravis offers no hook to signal a trigger, and its loop is not ours to copy. So this program
 * provides g_poll (the executable's definition comes first in symbol lookup for the libraries
 * it links, libaravis among them): on the camera's thread a zero timeout becomes a wait, with
 * microsecond resolution, until the camera's next trigger poll
 * (arv_fake_camera_get_sleep_time_for_next_frame, Aravis's own schedule) or until a control
 * packet arrives, whichever comes first. The camera then checks its trigger at the same
 * instants as before; it only stops burning the CPU between them. Everywhere else (other
 * threads, other timeouts) g_poll is what GLib's is on Linux: poll(2). */

/* Set by the camera's own thread in its first fill: the rig whose camera runs on it. Until
 * then (before the first trigger) the thread polls as Aravis wrote it. */
static __thread FakeRig *camera_thread_rig;

/* Crossing the poll instant between Aravis's check of the time and this call: the next
 * instant is then almost a whole period away, and sleeping to it would delay a trigger by a
 * period. Such a call returns at once (Aravis's loop then leaves its wait). */
#define CROSSED_US 30

gint
g_poll (GPollFD *fds, guint nfds, gint timeout)
{
  FakeRig *rig = camera_thread_rig;
  G_STATIC_ASSERT (sizeof (GPollFD) == sizeof (struct pollfd));
  if (timeout != 0 || !rig)
    return poll ((struct pollfd *) fds, nfds, timeout);
  guint64 sleep_us = arv_fake_camera_get_sleep_time_for_next_frame (rig->fake, NULL);
  if (sleep_us + CROSSED_US >= rig->trigger_period_us)
    return poll ((struct pollfd *) fds, nfds, 0);
  struct timespec ts = { .tv_sec = (time_t) (sleep_us / 1000000), .tv_nsec = (long) (sleep_us % 1000000) * 1000 };
  return ppoll ((struct pollfd *) fds, nfds, &ts, NULL);
}

/* The fake camera's thread: copy the frame of the phase lit now. */
static void
fill (ArvBuffer *buffer, void *data, guint32 exposure_time_us, guint32 gain, ArvPixelFormat format)
{
  (void) exposure_time_us;
  (void) gain;
  FakeRig *rig = data;
  if (G_UNLIKELY (!g_atomic_int_get (&rig->camera_tid))) {
    g_atomic_int_set (&rig->camera_tid, (gint) syscall (SYS_gettid));
    if (!rig->spin) {
      /* The wait above to the microsecond: no timer slack (the normal class has 50 us). */
      prctl (PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
      camera_thread_rig = rig;
    }
  }
  gint64 filled_at = g_get_monotonic_time ();
  guint8 *out = (guint8 *) arv_buffer_get_data (buffer, NULL);
  gint x0 = 0, y0 = 0, w = 0, h = 0;
  arv_buffer_get_image_region (buffer, &x0, &y0, &w, &h);
  if (!out || format != ARV_PIXEL_FORMAT_MONO_16 || (guint) w != rig->width || (guint) h != rig->height)
    return;
  DsModbusServerState st;
  ds_modbus_server_get_state (rig->modbus, &st);
  const guint16 *src = st.enabled ? rig->lit[st.phase % rig->n_phases] : rig->dark;
  gint logged = g_atomic_int_get (&rig->n_fills);
  if (logged < FILL_LOG_CAPACITY) {
    rig->fill_us[logged] = filled_at;
    rig->fill_phase[logged] = st.enabled ? (guint8) (st.phase % rig->n_phases) : G_MAXUINT8;
    g_atomic_int_set (&rig->n_fills, logged + 1);
  }
  memcpy (out, src, (gsize) rig->width * rig->height * 2);
  g_atomic_int_inc (&rig->frames);
}

/* run_rate_bench.sh gives the benchmark real-time priority 2, which the camera's thread
 * inherits. A real camera fills and sends on hardware of its own: the daemon's CPU use never
 * slows it, and the daemon never waits for it. Two cores shared with a fake camera cannot give
 * both; the rig offers two orders (docs/benchmarks.md, "Daemon rate").
 * - same (the default since run V): the camera keeps the benchmark's priority. Under SCHED_RR
 *   neither side preempts the other: the camera, once it fills and sends a frame, finishes it
 *   whatever the daemon does, as a real camera would, and a daemon thread that wakes meanwhile
 *   waits for a core in turn, which a real camera would not make it do (in the normal class:
 *   the same nice). Until the stream asked for a receive buffer of several frames, that wait
 *   overflowed the one-frame buffer Aravis asks for and cost frames (run U).
 * - below: the camera is made on a thread one real-time priority lower (the normal class when
 *   there is none lower), which its thread inherits: it takes what the daemon's and the
 *   ceiling's threads leave. Then every wake-up of a daemon thread on the camera's core preempts
 *   the camera in the middle of a frame (the daemon put the camera on a CPU 11 times per frame
 *   at 1 MP, the ceiling loop 3 times), and the daemon's CPU slows the camera it is measured
 *   against, which a real camera never suffers.
 * The rest of the rig (the Modbus controller) keeps the caller's priority. */
typedef enum { CAMERA_PRIORITY_BELOW, CAMERA_PRIORITY_SAME } CameraPriority;

static CameraPriority
camera_priority_from_env (void)
{
  const char *v = g_getenv ("DS_BENCH_CAMERA_PRIORITY");
  if (!v || strcmp (v, "same") == 0)
    return CAMERA_PRIORITY_SAME;
  if (strcmp (v, "below") == 0)
    return CAMERA_PRIORITY_BELOW;
  fprintf (stderr, "fake rig: DS_BENCH_CAMERA_PRIORITY is same or below, not \"%s\"; using same\n", v);
  return CAMERA_PRIORITY_SAME;
}

static gpointer
new_camera_thread (gpointer data)
{
  int policy;
  struct sched_param sp;
  if (GPOINTER_TO_INT (data) == CAMERA_PRIORITY_SAME) {
    /* the caller's priority, inherited as is */
  } else if (pthread_getschedparam (pthread_self (), &policy, &sp) == 0 && policy != SCHED_OTHER) {
    /* lowering needs no privilege */
    if (sp.sched_priority > sched_get_priority_min (policy)) {
      sp.sched_priority--;
      pthread_setschedparam (pthread_self (), policy, &sp);
    } else {
      struct sched_param normal = { .sched_priority = 0 };
      pthread_setschedparam (pthread_self (), SCHED_OTHER, &normal);
    }
  } else {
    /* In the normal class (ctest's reduced run, DS_BENCH_SCHED=other) the same order by
     * weight: a camera thread waking from its trigger wait would otherwise preempt the stream
     * thread receiving its packets, and on a loaded machine the receive buffer overflows.
     * Raising one's own nice needs no privilege; the camera's thread inherits it. */
    pid_t tid = (pid_t) syscall (SYS_gettid);
    errno = 0;
    int nice_now = getpriority (PRIO_PROCESS, (id_t) tid);
    if (errno == 0)
      setpriority (PRIO_PROCESS, (id_t) tid, MIN (nice_now + 5, 19));
  }
  return g_object_new (ARV_TYPE_GV_FAKE_CAMERA, "interface-name", "127.0.0.1", "serial-number",
                       "FR0001", NULL);
}

FakeRig *
fake_rig_new (guint width, guint height, guint n_phases, guint settle_us)
{
  FakeRig *rig = g_new0 (FakeRig, 1);
  rig->width = width;
  rig->height = height;
  rig->n_phases = n_phases;
  gsize npix = (gsize) width * height;
  rig->lit = g_new0 (guint16 *, n_phases);
  for (guint k = 0; k < n_phases; k++) {
    rig->lit[k] = g_new (guint16, npix);
    for (guint x = 0; x < width; x++)
      rig->lit[k][x] = stripe_scene_value (x, (int) k, n_phases, FAKE_RIG_PERIOD_PX);
    for (guint y = 1; y < height; y++)
      memcpy (rig->lit[k] + (gsize) y * width, rig->lit[k], width * 2);
  }
  rig->fill_us = g_new (gint64, FILL_LOG_CAPACITY);
  rig->fill_phase = g_new (guint8, FILL_LOG_CAPACITY);
  rig->dark = g_new (guint16, npix);
  for (gsize i = 0; i < npix; i++)
    rig->dark[i] = (guint16) FAKE_RIG_DARK_DN;

  g_autoptr (GError) error = NULL;
  ds_modbus_server_config_init (&rig->modbus_config);
  rig->modbus_config.settle_us = settle_us;
  rig->modbus = ds_modbus_server_new ("127.0.0.1", 0, &rig->modbus_config, &error);
  if (!rig->modbus) {
    fprintf (stderr, "fake rig: Modbus server: %s\n", error->message);
    fake_rig_free (rig);
    return NULL;
  }
  CameraPriority priority = camera_priority_from_env ();
  printf ("fake rig: camera thread priority %s\n",
          priority == CAMERA_PRIORITY_SAME ? "the same as the benchmark's (DS_BENCH_CAMERA_PRIORITY=same, the default)"
                                           : "one below the benchmark's (DS_BENCH_CAMERA_PRIORITY=below)");
  rig->gv = g_thread_join (g_thread_new ("fake-rig-camera", new_camera_thread, GINT_TO_POINTER (priority)));
  if (!rig->gv || !arv_gv_fake_camera_is_running (rig->gv)) {
    fprintf (stderr, "fake rig: the GigE Vision fake camera cannot serve on 127.0.0.1:3956 "
                     "(port taken? run in a private network namespace)\n");
    fake_rig_free (rig);
    return NULL;
  }
  ArvFakeCamera *fake = arv_gv_fake_camera_get_fake_camera (rig->gv);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_WIDTH, width);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_HEIGHT, height);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, width);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, height);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT, ARV_PIXEL_FORMAT_MONO_16);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US, 1000);
  /* 8 KiB GVSP packets, as a GigE Vision link with jumbo frames carries them (and as labsim
   * serves): the fake camera has no test packet, so Aravis's packet size negotiation keeps it. */
  arv_fake_camera_write_register (fake, 0xd04 /* GigE Vision SCPS0: stream packet size */, 8192);
  /* The software trigger is polled, not signalled (g_poll above). */
  rig->fake = fake;
  const char *hz_env = g_getenv ("DS_BENCH_TRIGGER_HZ");
  double hz = hz_env ? g_ascii_strtod (hz_env, NULL) : FAKE_RIG_TRIGGER_HZ;
  if (!(hz >= 1.0 && hz <= 100000.0))
    hz = FAKE_RIG_TRIGGER_HZ;
  rig->trigger_period_us = (guint64) (1e6 / hz);
  rig->spin = g_strcmp0 (g_getenv ("DS_BENCH_CAMERA_POLL"), "spin") == 0;
  printf ("fake camera: software trigger polled at %g Hz, its thread %s between the polls%s\n", hz,
          rig->spin ? "spinning" : "sleeping", rig->spin ? " (DS_BENCH_CAMERA_POLL=spin)" : "");
  arv_fake_camera_set_trigger_frequency (fake, hz);
  arv_fake_camera_set_fill_pattern (fake, fill, rig);
  return rig;
}

void
fake_rig_free (FakeRig *rig)
{
  if (!rig)
    return;
  g_clear_object (&rig->gv);
  g_clear_pointer (&rig->modbus, ds_modbus_server_free);
  for (guint k = 0; rig->lit && k < rig->n_phases; k++)
    g_free (rig->lit[k]);
  g_free (rig->lit);
  g_free (rig->dark);
  g_free (rig->fill_us);
  g_free (rig->fill_phase);
  g_free (rig);
}

guint
fake_rig_modbus_port (const FakeRig *rig)
{
  return ds_modbus_server_port (rig->modbus);
}

void
fake_rig_set_settle_us (FakeRig *rig, guint settle_us)
{
  rig->modbus_config.settle_us = settle_us;
  ds_modbus_server_set_config (rig->modbus, &rig->modbus_config);
}

guint64
fake_rig_frames (FakeRig *rig)
{
  return (guint64) g_atomic_int_get (&rig->frames);
}

double
fake_rig_camera_cpu_s (FakeRig *rig)
{
  gint tid = g_atomic_int_get (&rig->camera_tid);
  if (!tid)
    return NAN;
  g_autofree char *path = g_strdup_printf ("/proc/self/task/%d/stat", tid);
  g_autofree char *text = NULL;
  if (!g_file_get_contents (path, &text, NULL, NULL))
    return NAN;
  /* Fields after the command name (which may hold spaces): state is the 3rd field, utime and
   * stime the 14th and 15th (proc(5)), in clock ticks. */
  const char *p = strrchr (text, ')');
  if (!p)
    return NAN;
  g_auto (GStrv) f = g_strsplit (p + 2, " ", -1);
  if (g_strv_length (f) < 13)
    return NAN;
  double ticks = g_ascii_strtod (f[11], NULL) + g_ascii_strtod (f[12], NULL);
  return ticks / (double) sysconf (_SC_CLK_TCK);
}

guint64
fake_rig_trigger_period_us (const FakeRig *rig)
{
  return rig->trigger_period_us;
}

guint64
fake_rig_cycles (FakeRig *rig, gint64 from_us, gint64 to_us, guint64 *counts, guint n_bins,
                 double *by_phase_us, guint64 *by_phase_n)
{
  gint n = g_atomic_int_get (&rig->n_fills);
  double period = (double) rig->trigger_period_us;
  guint64 fills = 0;
  for (gint i = 0; i < n; i++) {
    gint64 t = rig->fill_us[i];
    if (t < from_us || t > to_us)
      continue;
    fills++;
    if (i == 0 || rig->fill_us[i - 1] < from_us)
      continue; /* the interval began before this one */
    double dt = (double) (t - rig->fill_us[i - 1]);
    double periods = round (dt / period);
    if (periods > FAKE_RIG_CYCLE_MAX_PERIODS)
      continue;
    counts[MIN ((guint) periods, n_bins - 1)]++;
    guint k = rig->fill_phase[i - 1];
    if (k < rig->n_phases) {
      by_phase_us[k] += dt;
      by_phase_n[k]++;
    }
  }
  return fills;
}
