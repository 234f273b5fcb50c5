#include "drivers/labsim/lab_camera_fill.h"

#include <math.h>
#include <string.h>

#include "drivers/labsim/lab_states.h"
#include "drivers/sim/rng.h"
#include "drivers/sim/sensor.h"

#define PFNC_MONO8 0x01080001u
#define PFNC_MONO10 0x01100003u
#define PFNC_MONO12 0x01100005u
#define PFNC_MONO16 0x01100007u
#define PFNC_MONO10P 0x010A0046u
#define PFNC_MONO12P 0x010C0047u
#define PFNC_MONO12PACKED 0x010C0006u

/* Normal deviates drawn once; a row takes BANK_SIZE - width of them from a random offset. */
#define BANK_BITS 21
#define BANK_SIZE (1u << BANK_BITS)
/* Beyond this, the cache of noise-free frames is emptied (a study sweeping settings). */
#define CACHE_MAX_BYTES ((gsize) 1 << 30)

/* A trigger waits at most this long for its lighting state (a frame late, never wrong): longer
 * than any state of a servable scene takes to render on a loaded machine (the heaviest take a few
 * seconds). A client whose grab times out first triggers again; the late frame then arrives as
 * a surplus one, of the same light, which the daemon drops as stale. */
#define ORDER_WAIT_US 10000000
/* A free-running frame (TriggerMode Off) waits on the camera thread itself: briefly. */
#define FREE_RUN_WAIT_US 200000

typedef struct {
  DsLabLight light;
  double exposure_us, gain_db;
} ExposedKey;

typedef struct {
  float *mean;             /* expected DN, before quantisation */
  float *sigma;            /* noise sigma, DN */
} Expected;

/* A trigger the router accepted: the light that was on at its edge. */
typedef struct {
  DsLabLight light;
  DsLabState *state;       /* NULL until rendered */
  gint64 at;               /* monotonic µs of the edge */
  gboolean handed;         /* handed to the camera thread, which fills it next */
} Order;

struct DsLabFill {
  const DsRenderer *renderer;
  DsLabStates *states;
  guint64 seed;
  gboolean noiseless;
  guint width, height, depth;
  DsSensorModel sensor;
  float *bank;
  GHashTable *cache;       /* ExposedKey* -> Expected* (camera thread only) */
  gsize cache_bytes;
  guint16 *frame;          /* the current frame's values, width x height */
  GMutex lock;             /* frames, orders, dropped */
  guint64 frames;
  GQueue orders;           /* Order*, oldest first */
  guint64 dropped;
  gboolean moves;          /* an object declares a velocity: each frame is rendered at its time */
  gint64 origin_us;        /* monotonic µs of the scene's time 0 (the fill's creation) */
};

static guint
key_hash (gconstpointer p)
{
  const ExposedKey *k = p;
  return (guint) (k->light.on * 7919u + k->light.all_on * 104729u + k->light.phase * 131u + k->light.n_phases * 31u) ^
         (guint) (k->exposure_us * 16) ^ (guint) (k->gain_db * 1000) << 7 ^ (guint) (k->light.period_px * 100) << 13;
}

static gboolean
key_equal (gconstpointer a, gconstpointer b)
{
  const ExposedKey *x = a, *y = b;
  return x->light.on == y->light.on && x->light.all_on == y->light.all_on && x->light.phase == y->light.phase &&
         x->light.n_phases == y->light.n_phases &&
         x->light.period_px == y->light.period_px && x->exposure_us == y->exposure_us && x->gain_db == y->gain_db;
}

static void
expected_free (gpointer p)
{
  Expected *e = p;
  g_free (e->mean);
  g_free (e->sigma);
  g_free (e);
}

static void
order_free (gpointer p)
{
  Order *o = p;
  ds_lab_state_unref (o->state);
  g_free (o);
}

DsLabFill *
ds_lab_fill_new (const DsRenderer *renderer, DsLabIlluminationFunc illumination, gpointer user_data, guint64 seed,
                 gboolean noiseless)
{
  DsLabFill *f = g_new0 (DsLabFill, 1);
  f->renderer = renderer;
  f->states = ds_lab_states_new (renderer, illumination, user_data);
  f->seed = seed;
  f->noiseless = noiseless;
  const DsScene *scene = ds_renderer_scene (renderer);
  const DsSceneSpec *s = ds_scene_spec (scene);
  f->width = ds_scene_width (scene);
  f->height = ds_scene_height (scene);
  f->depth = ds_scene_bit_depth (scene);
  f->sensor = (DsSensorModel) { .bit_depth = s->bit_depth, .quantum_efficiency = s->quantum_efficiency,
                                .system_gain = s->system_gain, .read_noise_e = s->read_noise_e,
                                .dark_current_e_s = s->dark_current_e_s, .full_well_e = s->full_well_e };
  f->moves = ds_scene_has_motion (scene);
  f->origin_us = g_get_monotonic_time ();
  g_mutex_init (&f->lock);
  g_queue_init (&f->orders);
  f->cache = g_hash_table_new_full (key_hash, key_equal, g_free, expected_free);
  f->frame = g_new0 (guint16, (gsize) f->width * f->height);
  f->bank = g_new (float, BANK_SIZE);
  DsRng rng;
  ds_rng_seed (&rng, seed ^ 0x6e6f697365ull /* "noise" */);
  for (guint i = 0; i < BANK_SIZE; i++)
    f->bank[i] = (float) ds_rng_normal (&rng);
  return f;
}

gboolean
ds_lab_fill_prepare (DsLabFill *f, guint *n_states, double *seconds, GError **error)
{
  return ds_lab_states_prepare (f->states, n_states, seconds, error);
}

/* ---- triggers: the light at the edge, the frame once its state is rendered --------------- */

void
ds_lab_fill_arm (DsLabFill *f)
{
  Order *o = g_new0 (Order, 1);
  o->at = g_get_monotonic_time ();
  ds_lab_states_sample (f->states, &o->light);
  o->state = ds_lab_states_get (f->states, &o->light, 0);
  g_mutex_lock (&f->lock);
  g_queue_push_tail (&f->orders, o);
  g_mutex_unlock (&f->lock);
}

gboolean
ds_lab_fill_take_ready (DsLabFill *f, gboolean take, guint *waiting)
{
  gboolean ready = FALSE;
  gint64 now = g_get_monotonic_time ();
  g_mutex_lock (&f->lock);
  GList *l = f->orders.head;
  while (l && ((Order *) l->data)->handed)
    l = l->next;
  while (l && !ready) {
    Order *o = l->data;
    if (!o->state)
      o->state = ds_lab_states_get (f->states, &o->light, 0);
    if (o->state) {
      o->handed = ready = take;
      break;
    }
    if (now - o->at < ORDER_WAIT_US)
      break;
    /* Never a frame of another light: the trigger is dropped, as a camera drops one it cannot
     * take, and the client's grab times out. */
    g_warning ("labsim camera: a trigger dropped: %s %u of %u (period %g px) not rendered %.1f s after it",
               !o->light.on ? "dark" : o->light.all_on ? "all on, phase" : "phase", o->light.phase, o->light.n_phases,
               o->light.period_px,
               (double) (now - o->at) / 1e6);
    f->dropped++;
    GList *next = l->next;
    g_queue_delete_link (&f->orders, l);
    order_free (o);
    l = next;
  }
  guint n = 0;
  for (GList *m = f->orders.head; m; m = m->next)
    n += !((Order *) m->data)->handed;
  g_mutex_unlock (&f->lock);
  if (waiting)
    *waiting = n;
  return ready;
}

void
ds_lab_fill_cancel (DsLabFill *f)
{
  g_mutex_lock (&f->lock);
  g_queue_clear_full (&f->orders, order_free);
  g_mutex_unlock (&f->lock);
}

guint64
ds_lab_fill_dropped (DsLabFill *f)
{
  g_mutex_lock (&f->lock);
  guint64 n = f->dropped;
  g_mutex_unlock (&f->lock);
  return n;
}

/* e's mean and sigma from photons at scale x their exposure. */
static void
fill_expected (const DsLabFill *f, const float *photons, double scale, double exposure_us, double gain_db, Expected *e)
{
  gsize n = (gsize) f->width * f->height;
  e->mean = g_new (float, n);
  e->sigma = g_new (float, n);
  /* Variance in DN^2 = K^2 (mean electrons + read^2) with mean electrons = mean DN / K. */
  double k = ds_sensor_gain_dn_per_e (&f->sensor, gain_db);
  double read2 = k * k * f->sensor.read_noise_e * f->sensor.read_noise_e;
  for (gsize i = 0; i < n; i++) {
    double p = photons[i];
    double m = (float) ds_sensor_mean_dn (&f->sensor, scale == 1.0 ? p : p * scale, exposure_us, gain_db);
    e->mean[i] = (float) m;
    e->sigma[i] = (float) sqrt (k * MAX (m, 0.0) + read2);
  }
}

/* The noise-free frame of a scene with moving objects: the light of `light` rendered at the
 * frame's own time, on the camera thread (a moving scene costs one render per frame: describe
 * prints it), never cached. NULL when the render fails. */
static Expected *
expected_moving (DsLabFill *f, const DsLabLight *light, double exposure_us, double gain_db, gint64 trigger_us)
{
  /* The exposure starts at the trigger: its midpoint is where the objects are. */
  double t = (double) (trigger_us - f->origin_us) / 1e6 + exposure_us / 2e6;
  DsRenderRequest req = { .phase = light->phase, .n_phases = light->on ? light->n_phases : 1,
                          .illuminator_on = light->on, .all_on = light->all_on, .exposure_us = exposure_us,
                          .period_px = light->period_px, .time_s = t };
  g_autoptr (GError) error = NULL;
  g_autoptr (DsImage) photons = ds_renderer_render_photons (f->renderer, &req, &error);
  if (!photons) {
    g_warning ("labsim camera: a moving scene's frame at %.3f s: %s", t, error->message);
    return NULL;
  }
  g_autofree float *flat = g_new (float, (gsize) f->width * f->height);
  for (guint y = 0; y < f->height; y++)
    memcpy (flat + (gsize) y * f->width, ds_image_row (photons, y), f->width * sizeof (float));
  Expected *e = g_new0 (Expected, 1);
  fill_expected (f, flat, 1.0, exposure_us, gain_db, e);
  return e;
}

/* The noise-free frame of a lighting state at an exposure and gain, derived on first use from
 * the state's photons (linear in both; at the reference exposure and 0 dB the very numbers of
 * ds_renderer_render_expected). */
static const Expected *
expected_for (DsLabFill *f, const DsLabState *st, double exposure_us, double gain_db)
{
  ExposedKey key = { .light = st->light, .exposure_us = exposure_us, .gain_db = gain_db };
  Expected *e = g_hash_table_lookup (f->cache, &key);
  if (e)
    return e;
  gsize n = (gsize) f->width * f->height;
  if (f->cache_bytes + 2 * n * sizeof (float) > CACHE_MAX_BYTES) {
    g_hash_table_remove_all (f->cache);
    f->cache_bytes = 0;
  }
  e = g_new0 (Expected, 1);
  fill_expected (f, st->photons, exposure_us / st->reference_exposure_us, exposure_us, gain_db, e);
  g_hash_table_insert (f->cache, g_memdup2 (&key, sizeof key), e);
  f->cache_bytes += 2 * n * sizeof (float);
  return e;
}

/* One row: mean + sigma z (z NULL: noiseless), clipped at 0 and `top`, rounded. Written for the
 * auto-vectoriser (drivers/labsim/CMakeLists.txt builds this file with it, as proc/ does). */
static inline __attribute__ ((always_inline)) void
expose_row (const float *restrict m, const float *restrict s, const float *restrict z, guint16 *restrict o,
            guint n, float top)
{
  if (!z) {
    for (guint x = 0; x < n; x++) {
      float v = m[x] < 0.0f ? 0.0f : m[x] > top ? top : m[x];
      o[x] = (guint16) (v + 0.5f);
    }
    return;
  }
  for (guint x = 0; x < n; x++) {
    float v = m[x] + s[x] * z[x];
    v = v < 0.0f ? 0.0f : v > top ? top : v;
    o[x] = (guint16) (v + 0.5f);
  }
}

/* mean + sigma z, clipped at full well, rounded, clipped to the ADC range. */
static void
expose (DsLabFill *f, const Expected *e, double gain_db, guint64 frame_seed)
{
  /* A full pixel reads exactly this (ds_renderer_saturation_dn: full well or ADC top). */
  float top = (float) ds_renderer_saturation_dn (f->renderer, gain_db);
  DsRng rng;
  /* ds_rng_seed mixes its seed through splitmix64: neighbouring frames get unrelated offsets. */
  ds_rng_seed (&rng, f->seed * 0x9E3779B97F4A7C15ull + frame_seed);
  for (guint y = 0; y < f->height; y++) {
    const float *z = f->bank + (ds_rng_next (&rng) % (BANK_SIZE - f->width));
    expose_row (e->mean + (gsize) y * f->width, e->sigma + (gsize) y * f->width, f->noiseless ? NULL : z,
                f->frame + (gsize) y * f->width, f->width, top);
  }
}

guint
ds_lab_pixel_bits (guint32 pf)
{
  switch (pf) {
  case PFNC_MONO8: return 8;
  case PFNC_MONO10:
  case PFNC_MONO12:
  case PFNC_MONO16: return 16;
  case PFNC_MONO10P: return 10;
  case PFNC_MONO12P:
  case PFNC_MONO12PACKED: return 12;
  default: return 0;
  }
}

/* Significant bits of the format's values. */
static guint
value_bits (guint32 pf)
{
  switch (pf) {
  case PFNC_MONO8: return 8;
  case PFNC_MONO10:
  case PFNC_MONO10P: return 10;
  case PFNC_MONO12:
  case PFNC_MONO12P:
  case PFNC_MONO12PACKED: return 12;
  default: return 16;
  }
}

gboolean
ds_lab_pack (guint32 pf, const guint16 *values, gsize stride, guint depth, guint w, guint h, guint8 *out,
             gsize out_size)
{
  guint bits = ds_lab_pixel_bits (pf);
  if (!bits || (guint64) w * h * bits / 8 > out_size)
    return FALSE;
  guint vb = value_bits (pf);
  guint shift = depth > vb ? depth - vb : 0;
  /* 16-bit little-endian containers holding the values as they are: the rows as they are. */
  if (bits == 16 && shift == 0 && G_BYTE_ORDER == G_LITTLE_ENDIAN) {
    for (guint y = 0; y < h; y++)
      memcpy (out + (gsize) y * w * 2, values + (gsize) y * stride, (gsize) w * 2);
    return TRUE;
  }
  gsize o = 0;
  guint64 acc = 0;
  guint nacc = 0;
  gboolean half = FALSE;   /* Mono12Packed: a first pixel of a pair is waiting */
  guint pending = 0;
  for (guint y = 0; y < h; y++) {
    const guint16 *row = values + (gsize) y * stride;
    for (guint x = 0; x < w; x++) {
      guint v = row[x] >> shift;
      switch (pf) {
      case PFNC_MONO8:
        out[o++] = (guint8) v;
        break;
      case PFNC_MONO10:
      case PFNC_MONO12:
      case PFNC_MONO16:
        out[o++] = (guint8) (v & 0xff);
        out[o++] = (guint8) (v >> 8);
        break;
      case PFNC_MONO12PACKED:
        if (!half) {
          pending = v;
          half = TRUE;
        } else {
          out[o++] = (guint8) (pending >> 4);
          out[o++] = (guint8) ((v & 0xf) << 4 | (pending & 0xf));
          out[o++] = (guint8) (v >> 4);
          half = FALSE;
        }
        break;
      default: /* Mono10p, Mono12p: least significant bit first */
        acc |= (guint64) v << nacc;
        nacc += bits;
        while (nacc >= 8) {
          out[o++] = (guint8) (acc & 0xff);
          acc >>= 8;
          nacc -= 8;
        }
        break;
      }
    }
  }
  if (half && o + 2 <= out_size) {
    out[o++] = (guint8) (pending >> 4);
    out[o++] = (guint8) (pending & 0xf);
  }
  if (nacc > 0 && o < out_size)
    out[o] = (guint8) (acc & 0xff);
  return TRUE;
}

guint64
ds_lab_fill_buffer (DsLabFill *f, ArvBuffer *buffer, double exposure_us, double gain_db, guint32 pf)
{
  g_mutex_lock (&f->lock);
  guint64 n = f->frames++;
  g_mutex_unlock (&f->lock);
  /* The data size reads 0 here (the received size is set after the fill); the fake camera has
   * checked that the buffer holds the payload of this format before calling us. */
  guint8 *out = (guint8 *) arv_buffer_get_data (buffer, NULL);
  gint x0 = 0, y0 = 0, w = 0, h = 0;
  arv_buffer_get_image_region (buffer, &x0, &y0, &w, &h);
  guint bits = ds_lab_pixel_bits (pf);
  if (!out || w <= 0 || h <= 0 || !bits || x0 < 0 || y0 < 0 || (guint) (x0 + w) > f->width ||
      (guint) (y0 + h) > f->height) {
    g_warning ("labsim camera: frame %" G_GUINT64_FORMAT ": region %d,%d %dx%d or format 0x%08x not served",
               n, x0, y0, w, h, pf);
    return n;
  }
  /* The light of the trigger this frame answers (the router handed it over once its state was
   * rendered); free-running, the light now. */
  g_mutex_lock (&f->lock);
  Order *o = f->orders.head && ((Order *) f->orders.head->data)->handed ? g_queue_pop_head (&f->orders) : NULL;
  g_mutex_unlock (&f->lock);
  gint64 trigger_us = o ? o->at : g_get_monotonic_time ();
  g_autoptr (DsLabState) st = o ? g_steal_pointer (&o->state) : NULL;
  g_clear_pointer (&o, order_free);
  if (!st) {
    DsLabLight now;
    ds_lab_states_sample (f->states, &now);
    st = ds_lab_states_get (f->states, &now, g_get_monotonic_time () + FREE_RUN_WAIT_US);
    if (!st) {
      /* No stripes and no light: the frame fails any check of its phase, never passes for one. */
      g_warning ("labsim camera: frame %" G_GUINT64_FORMAT ": free-running, its light is not rendered yet: "
                 "sent black", n);
      memset (out, 0, (gsize) w * h * bits / 8);
      return n;
    }
  }
  Expected *moving = f->moves ? expected_moving (f, &st->light, exposure_us, gain_db, trigger_us) : NULL;
  if (f->moves && !moving) {
    memset (out, 0, (gsize) w * h * bits / 8);
    return n;
  }
  const Expected *e = moving ? moving : expected_for (f, st, exposure_us, gain_db);
  expose (f, e, gain_db, n);
  if (moving)
    expected_free (moving);
  ds_lab_pack (pf, f->frame + (gsize) y0 * f->width + x0, f->width, f->depth, (guint) w, (guint) h, out,
               (gsize) w * h * bits / 8);
  return n;
}

guint64
ds_lab_fill_frames (DsLabFill *f)
{
  g_mutex_lock (&f->lock);
  guint64 n = f->frames;
  g_mutex_unlock (&f->lock);
  return n;
}

void
ds_lab_fill_free (DsLabFill *f)
{
  if (!f)
    return;
  /* Before the cache: the worker borrows the renderer, not the fill. */
  ds_lab_states_free (f->states);
  g_queue_clear_full (&f->orders, order_free);
  g_hash_table_unref (f->cache);
  g_free (f->frame);
  g_free (f->bank);
  g_mutex_clear (&f->lock);
  g_free (f);
}
