#include "drivers/labsim/lab_camera.h"

#include <arv.h>
#include <gio/gio.h>
#include <string.h>

struct DsLabCamera {
  DsLabCameraConfig cfg;
  char *address, *serial;
  const DsRenderer *renderer;
  DsLabIlluminationFunc illumination;
  gpointer user_data;
  guint sensor_width, sensor_height, bit_depth;
  double default_exposure_us;

  ArvGvFakeCamera *gv;     /* NULL while vanished */
  GMutex lock;             /* frames: counted on the camera thread */
  guint64 frames;
  gint vanish_requested;   /* atomic: set once by the camera thread */
  guint vanish_source, appear_source;
};

/* Renders what is lit now and writes it into the buffer's image region. */
static void
fill_pattern (ArvBuffer *buffer, void *data, guint32 exposure_time_us, guint32 gain,
              ArvPixelFormat pixel_format)
{
  DsLabCamera *c = data;
  (void) gain;
  /* The data size reads 0 here (the received size is set after the fill); the fake camera has
   * checked that the buffer holds width * height pixels of this format before calling us. */
  guint8 *out = (guint8 *) arv_buffer_get_data (buffer, NULL);
  gint x0 = 0, y0 = 0, w = 0, h = 0;
  arv_buffer_get_image_region (buffer, &x0, &y0, &w, &h);
  guint bpp = ARV_PIXEL_FORMAT_BIT_PER_PIXEL (pixel_format) / 8;
  if (!out || w <= 0 || h <= 0 || bpp == 0)
    return;
  memset (out, 0, (gsize) w * (gsize) h * bpp);

  g_mutex_lock (&c->lock);
  guint64 n = c->frames++;
  g_mutex_unlock (&c->lock);
  DsRenderRequest req = {
    .phase = 0, .n_phases = 4, .illuminator_on = FALSE,
    .exposure_us = exposure_time_us > 0 ? exposure_time_us : c->default_exposure_us,
    .gain_db = 0, .seed = c->cfg.seed + n,
  };
  c->illumination (c->user_data, &req);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsImage) img = ds_renderer_render (c->renderer, &req, &error);
  if (!img) {
    g_warning ("labsim camera: frame %" G_GUINT64_FORMAT ": %s", n, error->message);
    return;
  }
  guint shift = img->bit_depth > 8 ? img->bit_depth - 8 : 0;
  for (gint y = 0; y < h; y++) {
    guint sy = (guint) (y0 + y);
    if (sy >= img->height)
      break;
    const guint16 *src = ds_image_row (img, sy);
    guint8 *dst = out + (gsize) y * (gsize) w * bpp;
    for (gint x = 0; x < w; x++) {
      guint sx = (guint) (x0 + x);
      if (sx >= img->width)
        break;
      guint16 v = src[sx];
      if (pixel_format == ARV_PIXEL_FORMAT_MONO_16) {
        dst[2 * x] = (guint8) (v & 0xff);
        dst[2 * x + 1] = (guint8) (v >> 8);
      } else {
        guint8 v8 = (guint8) MIN (v >> shift, 255u);
        for (guint b = 0; b < bpp; b++)
          dst[bpp * (guint) x + b] = v8;
      }
    }
  }

  if (c->cfg.vanish_after_frames && n + 1 == c->cfg.vanish_after_frames)
    g_atomic_int_set (&c->vanish_requested, 1);
}

static gboolean
appear (DsLabCamera *c, GError **error)
{
  ArvGvFakeCamera *gv = g_object_new (ARV_TYPE_GV_FAKE_CAMERA, "interface-name", c->address,
                                      "serial-number", c->serial, "gvsp-lost-ratio",
                                      c->cfg.gvsp_lost_ratio, NULL);
  if (!gv || !arv_gv_fake_camera_is_running (gv)) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_FAILED,
                 "GigE Vision fake camera on %s: cannot serve (UDP port 3956 in use, or no such "
                 "address?)", c->address);
    g_clear_object (&gv);
    return FALSE;
  }
  ArvFakeCamera *fake = arv_gv_fake_camera_get_fake_camera (gv);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_WIDTH, c->sensor_width);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_HEIGHT, c->sensor_height);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, c->sensor_width);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, c->sensor_height);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT, ARV_PIXEL_FORMAT_MONO_16);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US,
                                  (guint32) c->default_exposure_us);
  /* The software trigger is polled at this rate: 25 Hz by default would add up to 40 ms per
   * frame; 1 kHz keeps the trigger-to-fill latency at about a millisecond. */
  arv_fake_camera_set_trigger_frequency (fake, 1000.0);
  arv_fake_camera_set_fill_pattern (fake, fill_pattern, c);
  c->gv = gv;
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

/* Watches for the camera thread's request to vanish: the fake camera cannot be destroyed from
 * its own thread. */
static gboolean
vanish_watch (gpointer data)
{
  DsLabCamera *c = data;
  if (!g_atomic_int_get (&c->vanish_requested) || !c->gv)
    return G_SOURCE_CONTINUE;
  g_message ("labsim camera: vanishing for %.1f s after %u frames", c->cfg.vanish_for_s,
             c->cfg.vanish_after_frames);
  g_clear_object (&c->gv);
  c->appear_source = g_timeout_add ((guint) (c->cfg.vanish_for_s * 1000), appear_cb, c);
  c->vanish_source = 0;
  return G_SOURCE_REMOVE;
}

DsLabCamera *
ds_lab_camera_new (const DsLabCameraConfig *config, const DsRenderer *renderer,
                   DsLabIlluminationFunc illumination, gpointer user_data, GError **error)
{
  DsLabCamera *c = g_new0 (DsLabCamera, 1);
  g_mutex_init (&c->lock);
  c->cfg = *config;
  c->address = g_strdup (config->address ? config->address : "127.0.0.1");
  c->serial = g_strdup (config->serial ? config->serial : "DSLAB01");
  c->renderer = renderer;
  c->illumination = illumination;
  c->user_data = user_data;
  const DsScene *scene = ds_renderer_scene (renderer);
  c->sensor_width = ds_scene_width (scene);
  c->sensor_height = ds_scene_height (scene);
  c->bit_depth = ds_scene_bit_depth (scene);
  c->default_exposure_us = ds_scene_default_exposure_us (scene);
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
  g_mutex_lock (&c->lock);
  guint64 n = c->frames;
  g_mutex_unlock (&c->lock);
  return n;
}

gboolean
ds_lab_camera_present (DsLabCamera *c)
{
  return c->gv != NULL;
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
  g_clear_object (&c->gv); /* joins the camera thread: no fill runs after this */
  g_free (c->address);
  g_free (c->serial);
  g_mutex_clear (&c->lock);
  g_free (c);
}
