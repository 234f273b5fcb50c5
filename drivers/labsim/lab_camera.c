#include "drivers/labsim/lab_camera.h"

#include <arv.h>
#include <gio/gio.h>
#include <glib/gstdio.h>
#include <string.h>
#include <unistd.h>

#include "drivers/labsim/lab_camera_fill.h"
#include "labsim_camera_xml.h"

/* labsim's own registers (labsim-camera.xml): the trigger is routed here. */
#define REG_TRIGGER_SOURCE 0x8000
#define REG_TRIGGER_ACTIVATION 0x8004
#define REG_TRIGGER_SOFTWARE 0x8008
#define REG_SENSOR_PIXEL_WIDTH_NM 0x800c
#define SOURCE_SOFTWARE 16

/* --camera-vanish-after: asked once by the camera thread, carried out by the main loop. */
enum { VANISH_NONE, VANISH_ASKED, VANISH_DONE };

typedef struct {
  guint line;
  gboolean rising;
} LineEdge;

struct DsLabCamera {
  DsLabCameraConfig cfg;
  char *address, *serial;
  DsLabFill *fill;
  guint sensor_width, sensor_height;
  double pixel_pitch_um;   /* the scene's sensor pitch, served as SensorPixelWidth */
  double default_exposure_us;

  GMutex gv_lock;          /* gv: swapped on the main thread, used by the trigger router */
  ArvGvFakeCamera *gv;     /* NULL while vanished */
  gint vanish_requested;   /* atomic: VANISH_NONE, then VANISH_ASKED (camera thread), VANISH_DONE */
  guint vanish_source, appear_source;

  /* The trigger router: software commands and line edges become frames. */
  GMutex trig_lock;
  GCond trig_cond;
  GArray *edges;           /* LineEdge, under trig_lock */
  gboolean quit;           /* under trig_lock */
  GThread *router;
  DsLabTriggerStats trig;  /* under trig_lock */
  guint prepared_states;   /* rendered before the camera appeared ... */
  double prepared_s;       /* ... in this long */
};

/* Called on Aravis's camera thread for every triggered frame. */
static void
fill_pattern (ArvBuffer *buffer, void *data, guint32 exposure_time_us, guint32 gain_centi_db,
              ArvPixelFormat pixel_format)
{
  DsLabCamera *c = data;
  guint64 n = ds_lab_fill_buffer (c->fill, buffer, exposure_time_us > 0 ? exposure_time_us : c->default_exposure_us,
                                  gain_centi_db / 100.0, (guint32) pixel_format);
  if (c->cfg.vanish_after_frames && n + 1 == c->cfg.vanish_after_frames)
    g_atomic_int_set (&c->vanish_requested, VANISH_ASKED);
}

/* ---- trigger router ------------------------------------------------------------------------ */

/* One frame more for the camera thread: its software-trigger register is a flag, so frames
 * are handed over one at a time, each once the previous one was taken, and each once the light
 * its trigger saw is rendered (lab_camera_fill.h). Returns the triggers still waiting. */
static guint
hand_over (ArvFakeCamera *fake, DsLabFill *fill)
{
  guint32 busy = 0;
  guint waiting = 0;
  arv_fake_camera_read_register (fake, ARV_FAKE_CAMERA_REGISTER_TRIGGER_SOFTWARE, &busy);
  if (ds_lab_fill_take_ready (fill, !busy, &waiting))
    arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_TRIGGER_SOFTWARE, 1);
  return waiting;
}

static gpointer
router_thread (gpointer data)
{
  DsLabCamera *c = data;
  guint pending = 0, arms = 0;
  g_autoptr (GArray) edges = g_array_new (FALSE, FALSE, sizeof (LineEdge));
  for (;;) {
    g_mutex_lock (&c->trig_lock);
    /* The software command is a register the client writes: polled at 1 kHz, like the fake
     * camera's own trigger; line edges wake the router at once. */
    gint64 until = g_get_monotonic_time () + (pending ? 200 : 1000);
    while (!c->quit && c->edges->len == 0 && g_cond_wait_until (&c->trig_cond, &c->trig_lock, until))
      ;
    if (c->quit) {
      g_mutex_unlock (&c->trig_lock);
      break;
    }
    g_array_append_vals (edges, c->edges->data, c->edges->len);
    g_array_set_size (c->edges, 0);
    g_mutex_unlock (&c->trig_lock);

    g_mutex_lock (&c->gv_lock);
    /* A camera asked to vanish takes no trigger more: the main loop takes it away when it next
     * runs, which on a loaded machine can be after the client's next trigger; the frame count
     * it vanishes after must not depend on that. */
    gboolean vanishing = g_atomic_int_get (&c->vanish_requested) == VANISH_ASKED;
    ArvFakeCamera *fake = c->gv && !vanishing ? arv_gv_fake_camera_get_fake_camera (c->gv) : NULL;
    guint32 source = SOURCE_SOFTWARE, activation = 0, sw = 0;
    if (fake) {
      arv_fake_camera_read_register (fake, REG_TRIGGER_SOURCE, &source);
      arv_fake_camera_read_register (fake, REG_TRIGGER_ACTIVATION, &activation);
      arv_fake_camera_read_register (fake, REG_TRIGGER_SOFTWARE, &sw);
      if (sw)
        arv_fake_camera_write_register (fake, REG_TRIGGER_SOFTWARE, 0);
    }
    g_mutex_lock (&c->trig_lock);
    if (sw && source == SOURCE_SOFTWARE) {
      arms++;
      c->trig.software++;
    } else if (sw)
      c->trig.software_ignored++; /* a real camera ignores TriggerSoftware with a line source */
    for (guint i = 0; i < edges->len; i++) {
      LineEdge *e = &g_array_index (edges, LineEdge, i);
      if (!fake || source != e->line || e->rising != (activation == 0))
        continue;
      guint64 k = ++c->trig.line;
      if (c->cfg.line_miss_every && k % c->cfg.line_miss_every == 0) {
        c->trig.line_missed++;
        continue;
      }
      arms++;
      if (c->cfg.line_double_every && k % c->cfg.line_double_every == 0) {
        arms++;
        c->trig.line_doubled++;
      }
    }
    g_array_set_size (edges, 0);
    g_mutex_unlock (&c->trig_lock);
    /* Each frame shows the light that was on at its trigger. */
    for (; arms > 0; arms--)
      if (fake)
        ds_lab_fill_arm (c->fill);
    if (!fake)
      ds_lab_fill_cancel (c->fill);
    pending = fake ? hand_over (fake, c->fill) : 0;
    g_mutex_unlock (&c->gv_lock);
  }
  return NULL;
}

void
ds_lab_camera_line_edge (DsLabCamera *c, guint line, gboolean rising)
{
  LineEdge e = { line, rising };
  g_mutex_lock (&c->trig_lock);
  g_array_append_val (c->edges, e);
  g_cond_signal (&c->trig_cond);
  g_mutex_unlock (&c->trig_lock);
}

void
ds_lab_camera_trigger_stats (DsLabCamera *c, DsLabTriggerStats *stats)
{
  g_mutex_lock (&c->trig_lock);
  *stats = c->trig;
  g_mutex_unlock (&c->trig_lock);
  stats->not_rendered = ds_lab_fill_dropped (c->fill);
}

void
ds_lab_camera_prepared (DsLabCamera *c, guint *n_states, double *seconds)
{
  *n_states = c->prepared_states;
  *seconds = c->prepared_s;
}

/* ---- the device ---------------------------------------------------------------------------- */

/* labsim-camera.xml as this camera describes itself: only the PixelFormat entries it offers,
 * its gain range (a camera that lacks a format, or has less gain, as a lab meets one). */
static char *
camera_xml (const DsLabCameraConfig *cfg, GError **error)
{
  g_auto (GStrv) keep = cfg->pixel_formats ? g_strsplit (cfg->pixel_formats, ",", -1) : NULL;
  GString *out = g_string_new (NULL);
  guint kept = 0;
  g_auto (GStrv) lines = g_strsplit (ds_labsim_camera_xml, "\n", -1);
  for (guint i = 0; lines[i]; i++) {
    const char *entry = strstr (lines[i], "<EnumEntry Name=\"");
    if (keep && entry && strstr (lines[i], "<Value>0x01")) { /* PixelFormat's entries */
      const char *name = entry + strlen ("<EnumEntry Name=\"");
      gsize n = strcspn (name, "\"");
      gboolean wanted = FALSE;
      for (guint k = 0; keep[k]; k++)
        wanted |= strlen (g_strstrip (keep[k])) == n && strncmp (keep[k], name, n) == 0;
      if (!wanted)
        continue;
      kept++;
    }
    if (cfg->gain_max_db > 0 && strstr (lines[i], "<pValue>GainConverter</pValue>")) {
      g_autofree char *max = g_strdup_printf ("<Max>%.1f</Max>", cfg->gain_max_db);
      g_autoptr (GString) l = g_string_new (lines[i]);
      g_string_replace (l, "<Max>24.0</Max>", max, 1);
      g_string_append_printf (out, "%s\n", l->str);
      continue;
    }
    g_string_append_printf (out, "%s%s", lines[i], lines[i + 1] ? "\n" : "");
  }
  if (keep && kept != g_strv_length (keep)) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT,
                 "--pixel-formats \"%s\": only Mono8, Mono10, Mono12, Mono16, Mono10p, Mono12p, Mono12Packed",
                 cfg->pixel_formats);
    g_string_free (out, TRUE);
    return NULL;
  }
  return g_string_free (out, FALSE);
}

static gboolean
appear (DsLabCamera *c, GError **error)
{
  /* The fake camera reads its GenICam description from a file, once, when it is made. */
  g_autofree char *xml_path = NULL;
  int fd = g_file_open_tmp ("labsim-camera-XXXXXX.xml", &xml_path, error);
  if (fd < 0)
    return FALSE;
  close (fd);
  g_autofree char *xml = camera_xml (&c->cfg, error);
  if (!xml || !g_file_set_contents (xml_path, xml, -1, error)) {
    g_unlink (xml_path);
    return FALSE;
  }
  ArvGvFakeCamera *gv = g_object_new (ARV_TYPE_GV_FAKE_CAMERA, "interface-name", c->address,
                                      "serial-number", c->serial, "genicam-filename", xml_path,
                                      "gvsp-lost-ratio", c->cfg.gvsp_lost_ratio, NULL);
  g_unlink (xml_path);
  if (!gv || !arv_gv_fake_camera_is_running (gv)) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_FAILED,
                 "GigE Vision fake camera on %s: cannot serve (UDP port 3956 in use, or no such "
                 "address?)", c->address);
    g_clear_object (&gv);
    return FALSE;
  }
  ArvFakeCamera *fake = arv_gv_fake_camera_get_fake_camera (gv);
  static const char vendor[32] = "descatter-labsim", model[32] = "labsim-camera";
  arv_fake_camera_write_memory (fake, 0x48 /* GigE Vision bootstrap: manufacturer name */, sizeof vendor, vendor);
  arv_fake_camera_write_memory (fake, 0x68 /* model name */, sizeof model, model);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_WIDTH, c->sensor_width);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_HEIGHT, c->sensor_height);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, c->sensor_width);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, c->sensor_height);
  arv_fake_camera_write_register (fake, REG_SENSOR_PIXEL_WIDTH_NM, (guint32) (c->pixel_pitch_um * 1000 + 0.5));
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT, ARV_PIXEL_FORMAT_MONO_16);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US,
                                  (guint32) c->default_exposure_us);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_GAIN_RAW, 0);
  /* The fake camera takes every frame from its software-trigger register (source 1): the
   * router decides what may set it. */
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_TRIGGER_SOURCE, 1);
  arv_fake_camera_write_register (fake, REG_TRIGGER_SOURCE, SOURCE_SOFTWARE);
  arv_fake_camera_write_register (fake, REG_TRIGGER_ACTIVATION, 0);
  arv_fake_camera_write_register (fake, REG_TRIGGER_SOFTWARE, 0);
  /* GVSP packets of 8 KiB (the fake camera's default is 1400 bytes): a frame in 6x fewer
   * datagrams, as a NIC with jumbo frames would carry it; loopback carries 64 KiB. */
  arv_fake_camera_write_register (fake, 0xd04 /* GigE Vision SCPS0: stream packet size */, 8192);
  /* Triggers are polled at this rate: 25 Hz by default would add up to 40 ms per frame. */
  arv_fake_camera_set_trigger_frequency (fake, 1000.0);
  arv_fake_camera_set_fill_pattern (fake, fill_pattern, c);
  g_mutex_lock (&c->gv_lock);
  c->gv = gv;
  g_mutex_unlock (&c->gv_lock);
  return TRUE;
}

static gboolean
appear_cb (gpointer data)
{
  DsLabCamera *c = data;
  c->appear_source = 0;
  g_autoptr (GError) error = NULL;
  if (!appear (c, &error))
    g_warning ("labsim camera: cannot come back: %s", error->message);
  else
    g_message ("labsim camera: back on %s", c->address);
  return G_SOURCE_REMOVE;
}

static void
disappear (DsLabCamera *c)
{
  g_mutex_lock (&c->gv_lock);
  ArvGvFakeCamera *gv = g_steal_pointer (&c->gv);
  g_mutex_unlock (&c->gv_lock);
  g_clear_object (&gv); /* joins the camera thread: no fill runs after this */
}

/* Watches for the camera thread's request to vanish: the fake camera cannot be destroyed from
 * its own thread. */
static gboolean
vanish_watch (gpointer data)
{
  DsLabCamera *c = data;
  if (g_atomic_int_get (&c->vanish_requested) != VANISH_ASKED || !c->gv)
    return G_SOURCE_CONTINUE;
  g_message ("labsim camera: vanishing for %.1f s after %u frames", c->cfg.vanish_for_s,
             c->cfg.vanish_after_frames);
  disappear (c);
  g_atomic_int_set (&c->vanish_requested, VANISH_DONE);
  c->appear_source = g_timeout_add ((guint) (c->cfg.vanish_for_s * 1000), appear_cb, c);
  c->vanish_source = 0;
  return G_SOURCE_REMOVE;
}

DsLabCamera *
ds_lab_camera_new (const DsLabCameraConfig *config, const DsRenderer *renderer,
                   DsLabIlluminationFunc illumination, gpointer user_data, GError **error)
{
  DsLabCamera *c = g_new0 (DsLabCamera, 1);
  g_mutex_init (&c->gv_lock);
  g_mutex_init (&c->trig_lock);
  g_cond_init (&c->trig_cond);
  c->edges = g_array_new (FALSE, FALSE, sizeof (LineEdge));
  c->cfg = *config;
  c->address = g_strdup (config->address ? config->address : "127.0.0.1");
  c->serial = g_strdup (config->serial ? config->serial : "DSLAB01");
  const DsScene *scene = ds_renderer_scene (renderer);
  c->sensor_width = ds_scene_width (scene);
  c->sensor_height = ds_scene_height (scene);
  c->pixel_pitch_um = ds_scene_spec (scene)->pixel_pitch_um;
  c->default_exposure_us = ds_scene_default_exposure_us (scene);
  c->fill = ds_lab_fill_new (renderer, illumination, user_data, config->seed, config->noiseless);
  /* Before the camera appears: a client that sees it can take frames at once. */
  if (!ds_lab_fill_prepare (c->fill, &c->prepared_states, &c->prepared_s, error)) {
    ds_lab_camera_free (c);
    return NULL;
  }
  c->router = g_thread_new ("labsim-trigger", router_thread, c);
  if (!appear (c, error)) {
    ds_lab_camera_free (c);
    return NULL;
  }
  if (c->cfg.vanish_after_frames)
    c->vanish_source = g_timeout_add (20, vanish_watch, c);
  return c;
}

guint64
ds_lab_camera_frames (DsLabCamera *c)
{
  return ds_lab_fill_frames (c->fill);
}

gboolean
ds_lab_camera_present (DsLabCamera *c)
{
  g_mutex_lock (&c->gv_lock);
  gboolean present = c->gv != NULL;
  g_mutex_unlock (&c->gv_lock);
  return present;
}

void
ds_lab_camera_free (DsLabCamera *c)
{
  if (!c)
    return;
  if (c->vanish_source)
    g_source_remove (c->vanish_source);
  if (c->appear_source)
    g_source_remove (c->appear_source);
  if (c->router) {
    g_mutex_lock (&c->trig_lock);
    c->quit = TRUE;
    g_cond_signal (&c->trig_cond);
    g_mutex_unlock (&c->trig_lock);
    g_thread_join (c->router);
  }
  disappear (c);
  ds_lab_fill_free (c->fill);
  g_array_unref (c->edges);
  g_free (c->address);
  g_free (c->serial);
  g_cond_clear (&c->trig_cond);
  g_mutex_clear (&c->trig_lock);
  g_mutex_clear (&c->gv_lock);
  g_free (c);
}
