#include "drivers/simdev/sim_lab.h"

#include <errno.h>
#include <math.h>
#include <string.h>

#include "drivers/sim/rng.h"

/* The simulated camera's ranges, as configure checks them and get_info reports them. */
#define SIM_EXPOSURE_MAX_US 1e7
#define SIM_GAIN_MAX_DB 48.0

struct DsSimLab {
  gint ref;
  DsRenderer *renderer;
  guint64 seed;
  GMutex lock;
  DsSimFaults faults;
  DsRng rng;               /* fault dice */
  /* illuminator state */
  gboolean on;
  gboolean all_on;         /* on, with every stripe lit (ill_all_on): no phase shown */
  guint phase, n_phases, shown_phase, previous_phase;
  double period_px;        /* the period it projects (0: the scene's) */
  gboolean period_fixed;   /* it projects the scene's period only */
  gboolean any_pattern;    /* it takes any kind and duty asked for and draws the scene's (as a
                              projector ignores what it cannot change) */
  guint64 apply_count;
  /* camera state */
  gboolean connected, started;
  double exposure_us, gain_db;
  DsCameraSettings settings;
  guint64 next_id, frames_triggered, renders;
  guint64 begun;           /* frames sent (whole or not): rendered at their trigger */
  DsFrameIdTracker ids;
  GQueue pending;          /* rendered frames waiting for grab (DsFrame*, or NULL = incomplete) */
  DsCameraStats stats;
  gint64 opened_us;        /* monotonic clock at creation: the scene's time origin, where moving
                              objects stand at their declared position */
};

gboolean
ds_sim_faults_parse (const char *text, DsSimFaults *out, GError **error)
{
  memset (out, 0, sizeof *out);
  if (!text || !*text)
    return TRUE;
  g_auto (GStrv) items = g_strsplit (text, ",", -1);
  for (guint i = 0; items[i]; i++) {
    char *item = g_strstrip (items[i]);
    if (!*item)
      continue;
    char *eq = strchr (item, '=');
    if (!eq) {
      g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_INVALID_VALUE,
                   "faults: \"%s\" is not name=value", item);
      return FALSE;
    }
    *eq = 0;
    const char *name = item, *value = eq + 1;
    char *end = NULL;
    errno = 0;
    double v = g_ascii_strtod (value, &end);
    if (errno || !end || *end || end == value || !isfinite (v) || v < 0) {
      g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_INVALID_VALUE,
                   "faults: %s=\"%s\" is not a non-negative number", name, value);
      return FALSE;
    }
    struct {
      const char *name;
      double *field;
    } probs[] = { { "stale", &out->stale }, { "incomplete", &out->incomplete }, { "timeout", &out->timeout },
                  { "drop", &out->drop }, { "wrong-phase", &out->wrong_phase }, { "not-ready", &out->not_ready } };
    gboolean known = FALSE;
    for (guint k = 0; k < G_N_ELEMENTS (probs); k++)
      if (strcmp (name, probs[k].name) == 0) {
        if (v > 1) {
          g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_INVALID_VALUE,
                       "faults: %s=%g is a probability, allowed 0..1", name, v);
          return FALSE;
        }
        *probs[k].field = v;
        known = TRUE;
      }
    struct {
      const char *name;
      guint *field;
    } counts[] = { { "disconnect-after", &out->disconnect_after }, { "faults-after", &out->faults_after },
                   { "drop-every", &out->drop_every },
                   { "stale-next", &out->stale_next },
                   { "incomplete-next", &out->incomplete_next }, { "timeout-next", &out->timeout_next },
                   { "drop-next", &out->drop_next }, { "wrong-phase-next", &out->wrong_phase_next },
                   { "not-ready-next", &out->not_ready_next }, { "open-delay-ms", &out->open_delay_ms } };
    for (guint k = 0; k < G_N_ELEMENTS (counts); k++)
      if (strcmp (name, counts[k].name) == 0) {
        if (v != floor (v) || v > 1e9) {
          g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_INVALID_VALUE,
                       "faults: %s=%g must be a whole number (0..1e9)", name, v);
          return FALSE;
        }
        *counts[k].field = (guint) v;
        known = TRUE;
      }
    if (!known) {
      g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_INVALID_VALUE,
                   "faults: unknown fault \"%s\" (stale, incomplete, timeout, drop, wrong-phase, "
                   "not-ready, disconnect-after, faults-after, drop-every, open-delay-ms, and <name>-next counts)", name);
      return FALSE;
    }
  }
  return TRUE;
}

DsSimLab *
ds_sim_lab_new (DsRenderer *renderer, guint64 seed)
{
  DsSimLab *lab = g_new0 (DsSimLab, 1);
  lab->ref = 1;
  lab->renderer = renderer;
  lab->seed = seed;
  g_mutex_init (&lab->lock);
  ds_rng_seed (&lab->rng, seed ^ 0xfa17u);
  lab->n_phases = 1;
  lab->connected = TRUE;
  /* GigE Vision-like ids: start near the 16-bit wrap, as real cameras (and Aravis's fake
   * camera) do, so the wrap is exercised early. */
  lab->next_id = 65400;
  ds_frame_id_tracker_init (&lab->ids, 16);
  const DsSceneSpec *s = ds_scene_spec (ds_renderer_scene (renderer));
  lab->exposure_us = s->exposure_us;
  g_queue_init (&lab->pending);
  lab->opened_us = g_get_monotonic_time ();
  return lab;
}

DsSimLab *
ds_sim_lab_ref (DsSimLab *lab)
{
  g_atomic_int_inc (&lab->ref);
  return lab;
}

static void
clear_pending (DsSimLab *lab)
{
  DsFrame *f;
  while (!g_queue_is_empty (&lab->pending))
    if ((f = g_queue_pop_head (&lab->pending)))
      ds_frame_free (f);
}

void
ds_sim_lab_unref (DsSimLab *lab)
{
  if (!lab || !g_atomic_int_dec_and_test (&lab->ref))
    return;
  clear_pending (lab);
  ds_renderer_free (lab->renderer);
  g_mutex_clear (&lab->lock);
  g_free (lab);
}

void
ds_sim_lab_set_faults (DsSimLab *lab, const DsSimFaults *faults)
{
  g_mutex_lock (&lab->lock);
  lab->faults = *faults;
  g_mutex_unlock (&lab->lock);
}

void
ds_sim_lab_set_period_fixed (DsSimLab *lab, gboolean fixed)
{
  lab->period_fixed = fixed;
}

void
ds_sim_lab_set_any_pattern (DsSimLab *lab, gboolean any)
{
  lab->any_pattern = any;
}

const DsRenderer *
ds_sim_lab_renderer (const DsSimLab *lab)
{
  return lab->renderer;
}

/* Under the lab's lock: a counted fault first, else the probability. */
static gboolean
dice (DsSimLab *lab, double p, guint *next)
{
  if (*next > 0) {
    (*next)--;
    return TRUE;
  }
  return p > 0 && ds_rng_uniform (&lab->rng) < p;
}

/* ---- camera ---- */

static gboolean
cam_check (DsSimLab *lab, GError **error)
{
  if (!lab->connected) {
    g_set_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_DISCONNECTED, "simulated camera: disconnected");
    return FALSE;
  }
  return TRUE;
}

static gboolean
cam_configure (gpointer b, const DsCameraSettings *s, GError **error)
{
  DsSimLab *lab = b;
  if (!cam_check (lab, error))
    return FALSE;
  const DsSceneSpec *spec = ds_scene_spec (ds_renderer_scene (lab->renderer));
  if (s->roi_width && (s->roi_x + s->roi_width > spec->width || s->roi_y + s->roi_height > spec->height)) {
    g_set_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INVALID,
                 "simulated camera: ROI %u,%u %ux%u outside the %ux%u sensor", s->roi_x, s->roi_y,
                 s->roi_width, s->roi_height, spec->width, spec->height);
    return FALSE;
  }
  if (!(s->exposure_us > 0 && s->exposure_us <= SIM_EXPOSURE_MAX_US) || s->gain_db < 0 ||
      s->gain_db > SIM_GAIN_MAX_DB) {
    g_set_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INVALID,
                 "simulated camera: exposure %g µs (0, 1e7], gain %g dB [0, 48]", s->exposure_us, s->gain_db);
    return FALSE;
  }
  lab->settings = *s;
  lab->exposure_us = s->exposure_us;
  lab->gain_db = s->gain_db;
  return TRUE;
}

static gboolean
cam_start (gpointer b, GError **error)
{
  DsSimLab *lab = b;
  if (!cam_check (lab, error))
    return FALSE;
  lab->started = TRUE;
  return TRUE;
}

static void
cam_stop (gpointer b)
{
  DsSimLab *lab = b;
  lab->started = FALSE;
  clear_pending (lab);
}

static DsImage *
crop (const DsCameraSettings *s, DsImage *img)
{
  if (!s->roi_width)
    return img;
  DsImage *c = ds_image_new (img->type, s->roi_width, s->roi_height, NULL);
  c->bit_depth = img->bit_depth;
  for (guint y = 0; y < s->roi_height; y++)
    memcpy (ds_image_row (c, y), (guint8 *) ds_image_row (img, s->roi_y + y) + s->roi_x * ds_sample_size (img->type),
            s->roi_width * ds_sample_size (img->type));
  ds_image_free (img);
  return c;
}

/* Renders now, for the phase shown now: that is what "exposed while phase k was applied"
 * means for a simulated camera. */
static gboolean
cam_trigger (gpointer b, GError **error)
{
  DsSimLab *lab = b;
  g_mutex_lock (&lab->lock);
  DsSimFaults f = lab->faults;
  gboolean gone = f.disconnect_after && lab->frames_triggered >= f.disconnect_after && lab->connected;
  if (gone) {
    lab->connected = FALSE;
    lab->faults.disconnect_after = 0; /* once: it comes back on reconnect */
  }
  g_mutex_unlock (&lab->lock);
  if (!cam_check (lab, error))
    return FALSE;
  if (!lab->started) {
    g_set_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INVALID, "simulated camera: trigger before start");
    return FALSE;
  }
  if (lab->settings.trigger_source == DS_CAMERA_TRIGGER_LINE) {
    g_set_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INVALID,
                 "simulated camera: triggered by a line, not by software");
    return FALSE;
  }
  /* Faults are drawn only for a trigger that goes out, so a counted fault hits a real frame. */
  g_mutex_lock (&lab->lock);
  DsSimFaults *lf = &lab->faults;
  gboolean spared = lab->frames_triggered < lf->faults_after;
  gboolean timeout = !spared && dice (lab, lf->timeout, &lf->timeout_next),
           drop = !spared && (dice (lab, lf->drop, &lf->drop_next) ||
                              (lf->drop_every && (lab->frames_triggered - lf->faults_after + 1) % lf->drop_every == 0)),
           incomplete = !spared && dice (lab, lf->incomplete, &lf->incomplete_next),
           stale = !spared && dice (lab, lf->stale, &lf->stale_next);
  g_mutex_unlock (&lab->lock);
  lab->frames_triggered++;
  if (timeout)
    return TRUE; /* the trigger was lost: no frame, no id */
  guint64 id = lab->next_id++;
  if (lab->next_id > 65535)
    lab->next_id = 1;
  if (drop)
    return TRUE; /* the frame is lost in transit: its id never shows up */
  if (incomplete) {
    lab->begun++;
    g_queue_push_tail (&lab->pending, NULL);
    guint32 skipped;
    ds_frame_id_tracker_update (&lab->ids, id, &skipped);
    return TRUE;
  }
  guint shown = stale ? lab->previous_phase : lab->shown_phase;
  DsRenderRequest req = { .phase = shown, .n_phases = lab->n_phases, .illuminator_on = lab->on,
                          .all_on = lab->on && lab->all_on,
                          .exposure_us = lab->exposure_us, .gain_db = lab->gain_db,
                          .seed = lab->seed * 1000003u + lab->renders++, .period_px = lab->period_px,
                          /* The exposure starts at the trigger: its midpoint is where moving objects are. */
                          .time_s = (double) (g_get_monotonic_time () - lab->opened_us) / 1e6 +
                                    lab->exposure_us / 2e6 };
  DsImage *img = ds_renderer_render (lab->renderer, &req, error);
  if (!img) {
    g_prefix_error (error, "simulated camera: ");
    return FALSE;
  }
  DsFrame *fr = g_new0 (DsFrame, 1);
  fr->image = crop (&lab->settings, img);
  guint32 skipped;
  fr->frame_id = ds_frame_id_tracker_update (&lab->ids, id, &skipped);
  fr->ids_skipped = skipped;
  fr->host_time_us = (guint64) g_get_monotonic_time ();
  fr->timestamp_ns = fr->host_time_us * 1000;
  fr->exposure_us = lab->exposure_us;
  fr->gain_db = lab->gain_db;
  lab->stats.ids_skipped += skipped;
  lab->begun++;
  g_queue_push_tail (&lab->pending, fr);
  return TRUE;
}

static DsFrame *
cam_grab (gpointer b, guint timeout_ms, GError **error)
{
  (void) timeout_ms; /* frames are rendered at trigger time: there is nothing to wait for */
  DsSimLab *lab = b;
  if (!cam_check (lab, error))
    return NULL;
  if (g_queue_is_empty (&lab->pending)) {
    lab->stats.timeouts++;
    /* Counted as a timeout: a frame lost in transit ("drop") leaves its id missing. */
    ds_frame_id_tracker_note_lost (&lab->ids);
    g_set_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_TIMEOUT, "simulated camera: no frame within %u ms",
                 timeout_ms);
    return NULL;
  }
  DsFrame *f = g_queue_pop_head (&lab->pending);
  if (!f) {
    lab->stats.failures++;
    lab->stats.missing_packets++;
    g_set_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INCOMPLETE, "simulated camera: frame incomplete");
    return NULL;
  }
  lab->stats.completed++;
  return f;
}

/* A simulated frame is exposed and rendered at its trigger: once trigger returned, it is sent. */
static guint64
cam_frames_begun (gpointer b, guint64 after, guint timeout_ms)
{
  (void) after;
  (void) timeout_ms;
  return ((DsSimLab *) b)->begun;
}

static guint
cam_flush (gpointer b)
{
  DsSimLab *lab = b;
  guint n = g_queue_get_length (&lab->pending);
  clear_pending (lab);
  return n;
}

static gboolean
cam_reconnect (gpointer b, GError **error)
{
  (void) error;
  DsSimLab *lab = b;
  clear_pending (lab);
  lab->connected = TRUE;
  lab->started = FALSE;
  lab->stats.reconnects++;
  ds_frame_id_tracker_init (&lab->ids, 16);
  return TRUE;
}

static void
cam_get_stats (gpointer b, DsCameraStats *s)
{
  *s = ((DsSimLab *) b)->stats;
}

static void
cam_get_info (gpointer b, DsCameraInfo *i)
{
  DsSimLab *lab = b;
  const DsSceneSpec *s = ds_scene_spec (ds_renderer_scene (lab->renderer));
  memset (i, 0, sizeof *i);
  g_strlcpy (i->vendor, "descatter", sizeof i->vendor);
  g_strlcpy (i->model, "simulated camera", sizeof i->model);
  g_strlcpy (i->serial, s->name ? s->name : "sim", sizeof i->serial);
  g_strlcpy (i->address, "in-process", sizeof i->address);
  i->sensor_width = s->width;
  i->sensor_height = s->height;
  i->pixel_pitch_um = s->pixel_pitch_um;
  i->connected = lab->connected;
  /* Any pixel format: frames are rendered as floats. */
  i->has_gain = TRUE;
  i->gain_max_db = SIM_GAIN_MAX_DB;
  i->exposure_max_us = SIM_EXPOSURE_MAX_US;
}

static void
cam_close (gpointer b)
{
  ds_sim_lab_unref (b);
}

static const DsCameraOps sim_camera_ops = {
  .name = "sim", .configure = cam_configure, .start = cam_start, .trigger = cam_trigger,
  .grab = cam_grab, .flush = cam_flush, .stop = cam_stop, .reconnect = cam_reconnect,
  .get_stats = cam_get_stats, .get_info = cam_get_info, .close = cam_close,
  .frames_begun = cam_frames_begun,
};

DsCamera *
ds_sim_camera_new (DsSimLab *lab)
{
  DsCamera *c = g_new0 (DsCamera, 1);
  c->ops = &sim_camera_ops;
  c->backend = ds_sim_lab_ref (lab);
  return c;
}

/* ---- illuminator ---- */

static gboolean
ill_set_pattern (gpointer b, const DsStripePattern *p, GError **error)
{
  DsSimLab *lab = b;
  const DsSceneSpec *s = ds_scene_spec (ds_renderer_scene (lab->renderer));
  if (p->n_phases < 2 || (!lab->any_pattern && fabs (p->duty - s->duty) > 1e-9)) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "simulated illuminator: it projects the scene's pattern (duty %g) with N >= 2; asked for "
                 "duty %g, N %u", s->duty, p->duty, p->n_phases);
    return FALSE;
  }
  /* Like a projector with a PERIOD register: any period the renderer draws, unless it is fixed. */
  if (lab->period_fixed ? fabs (p->period_px - s->period_px) > 1e-9 : !(p->period_px >= 2 && p->period_px <= 1e5)) {
    if (lab->period_fixed)
      g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED,
                   "simulated illuminator: its period is fixed at the scene's %g px; asked for %g px",
                   s->period_px, p->period_px);
    else
      g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED,
                   "simulated illuminator: it projects periods of 2 .. 1e5 px; asked for %g px", p->period_px);
    return FALSE;
  }
  lab->n_phases = p->n_phases;
  lab->period_px = fabs (p->period_px - s->period_px) > 1e-9 ? p->period_px : 0;
  lab->phase = lab->shown_phase = lab->previous_phase = 0;
  return TRUE;
}

static gboolean
ill_set_phase (gpointer b, guint phase, guint timeout_ms, GError **error)
{
  DsSimLab *lab = b;
  if (phase >= lab->n_phases) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "simulated illuminator: phase %u of %u", phase, lab->n_phases);
    return FALSE;
  }
  g_mutex_lock (&lab->lock);
  gboolean busy = dice (lab, lab->faults.not_ready, &lab->faults.not_ready_next),
           wrong = dice (lab, lab->faults.wrong_phase, &lab->faults.wrong_phase_next);
  g_mutex_unlock (&lab->lock);
  if (busy) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_BUSY,
                 "simulated illuminator: not ready within %u ms", timeout_ms);
    return FALSE;
  }
  lab->previous_phase = lab->on ? lab->shown_phase : phase;
  lab->phase = phase;
  /* The wrong-phase fault lies: it reports phase k applied but shows k + 1, which only the
   * frame itself can reveal. */
  lab->shown_phase = wrong ? (phase + 1) % lab->n_phases : phase;
  lab->on = TRUE;
  lab->all_on = FALSE;
  lab->apply_count++;
  return TRUE;
}

static gboolean
ill_off (gpointer b, guint timeout_ms, GError **error)
{
  (void) timeout_ms;
  (void) error;
  DsSimLab *lab = b;
  lab->on = FALSE;
  lab->all_on = FALSE;
  lab->apply_count++;
  return TRUE;
}

/* Every stripe lit: the renderer's pattern at its lit level everywhere. Never blocks, never
 * fails (the simulated device has no faults for it). */
static gboolean
ill_all_on (gpointer b, guint timeout_ms, GError **error)
{
  (void) timeout_ms;
  (void) error;
  DsSimLab *lab = b;
  lab->on = TRUE;
  lab->all_on = TRUE;
  lab->apply_count++;
  return TRUE;
}

static gboolean
ill_get_status (gpointer b, DsIlluminatorStatus *st, GError **error)
{
  (void) error;
  DsSimLab *lab = b;
  memset (st, 0, sizeof *st);
  st->ready = TRUE;
  st->enabled = lab->on;
  st->applied_phase = lab->on && !lab->all_on ? (int) lab->phase : -1;
  st->apply_count = lab->apply_count;
  st->temperature_c = 35.0;
  st->firmware_version = 1;
  double scene_period = ds_scene_period_px (ds_renderer_scene (lab->renderer));
  st->period_adjustable = !lab->period_fixed;
  st->period_min_px = lab->period_fixed ? scene_period : 2;
  st->period_max_px = lab->period_fixed ? scene_period : 1e5;
  return TRUE;
}

static gboolean
ill_reconnect (gpointer b, GError **error)
{
  (void) b;
  (void) error;
  return TRUE;
}

static void
ill_close (gpointer b)
{
  ds_sim_lab_unref (b);
}

static const DsIlluminatorOps sim_illuminator_ops = {
  .name = "sim", .set_pattern = ill_set_pattern, .set_phase = ill_set_phase, .off = ill_off,
  .get_status = ill_get_status, .reconnect = ill_reconnect, .close = ill_close, .all_on = ill_all_on,
};

DsIlluminator *
ds_sim_illuminator_new (DsSimLab *lab)
{
  DsIlluminator *i = g_new0 (DsIlluminator, 1);
  i->ops = &sim_illuminator_ops;
  i->backend = ds_sim_lab_ref (lab);
  return i;
}
