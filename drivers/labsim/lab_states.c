#include "drivers/labsim/lab_states.h"

#include <string.h>

/* The worker looks at the light this often for a new phase count or period. */
#define WATCH_US 20000
/* Beyond this, states of sets other than the current one are dropped (a study sweeping periods). */
#define STATES_MAX_BYTES ((gsize) 512 << 20)

struct DsLabStates {
  const DsRenderer *renderer;
  guint width, height;
  double reference_exposure_us;

  GMutex illum_lock;       /* one caller of the illumination function at a time */
  DsLabIlluminationFunc illumination;
  gpointer user_data;

  GMutex lock;
  GCond work_cond;         /* the worker: something to render, or quit */
  GCond done_cond;         /* waiters: a state was rendered */
  GHashTable *states;      /* DsLabLight* -> DsLabState* (a reference) */
  GQueue wanted;           /* DsLabLight*, to render, most urgent first */
  gboolean have_set;
  guint set_phases;        /* the set the light belongs to now */
  double set_period_px;
  gsize bytes;
  guint64 rendered;
  double render_s;
  gboolean quit;
  GThread *worker;
};

static DsLabLight
normalised (const DsLabLight *l)
{
  if (!l->on)
    return (DsLabLight) { 0 };
  DsLabLight n = *l;
  if (n.all_on)
    n.phase = 0;
  return n;
}

static guint
light_hash (gconstpointer p)
{
  const DsLabLight *l = p;
  return (guint) l->on * 7919u ^ (guint) l->all_on * 104729u ^ l->phase * 131u ^ l->n_phases * 31u ^
         (guint) (l->period_px * 100) << 11;
}

static gboolean
light_equal (gconstpointer a, gconstpointer b)
{
  const DsLabLight *x = a, *y = b;
  return x->on == y->on && x->all_on == y->all_on && x->phase == y->phase && x->n_phases == y->n_phases &&
         x->period_px == y->period_px;
}

static void
state_free (DsLabState *s)
{
  g_free (s->photons);
}

DsLabState *
ds_lab_state_ref (DsLabState *s)
{
  return g_atomic_rc_box_acquire (s);
}

void
ds_lab_state_unref (DsLabState *s)
{
  if (s)
    g_atomic_rc_box_release_full (s, (GDestroyNotify) state_free);
}

DsLabStates *
ds_lab_states_new (const DsRenderer *renderer, DsLabIlluminationFunc illumination, gpointer user_data)
{
  DsLabStates *s = g_new0 (DsLabStates, 1);
  s->renderer = renderer;
  const DsScene *scene = ds_renderer_scene (renderer);
  s->width = ds_scene_width (scene);
  s->height = ds_scene_height (scene);
  s->reference_exposure_us = ds_scene_default_exposure_us (scene);
  s->illumination = illumination;
  s->user_data = user_data;
  g_mutex_init (&s->illum_lock);
  g_mutex_init (&s->lock);
  g_cond_init (&s->work_cond);
  g_cond_init (&s->done_cond);
  s->states = g_hash_table_new_full (light_hash, light_equal, g_free, (GDestroyNotify) ds_lab_state_unref);
  g_queue_init (&s->wanted);
  return s;
}

void
ds_lab_states_sample (DsLabStates *s, DsLabLight *light)
{
  DsRenderRequest req = { .phase = 0, .n_phases = 4, .illuminator_on = FALSE };
  g_mutex_lock (&s->illum_lock);
  s->illumination (s->user_data, &req);
  g_mutex_unlock (&s->illum_lock);
  /* The set is known even while dark: the phase count and period the controller holds. */
  *light = (DsLabLight) { .on = req.illuminator_on, .all_on = req.illuminator_on && req.all_on, .phase = req.phase,
                          .n_phases = MAX (req.n_phases, 1u),
                          .period_px = req.period_px };
}

static DsLabState *
render (DsLabStates *s, const DsLabLight *light, GError **error)
{
  DsRenderRequest req = { .phase = light->phase, .n_phases = light->on ? light->n_phases : 1,
                          .illuminator_on = light->on, .all_on = light->all_on,
                          .exposure_us = s->reference_exposure_us, .gain_db = 0,
                          .period_px = light->period_px };
  gint64 t0 = g_get_monotonic_time ();
  g_autoptr (DsImage) img = ds_renderer_render_photons (s->renderer, &req, error);
  if (!img)
    return NULL;
  DsLabState *st = g_atomic_rc_box_new0 (DsLabState);
  st->light = *light;
  st->reference_exposure_us = s->reference_exposure_us;
  st->photons = g_new (float, (gsize) s->width * s->height);
  for (guint y = 0; y < s->height; y++)
    memcpy (st->photons + (gsize) y * s->width, ds_image_row (img, y), s->width * sizeof (float));
  st->render_s = (double) (g_get_monotonic_time () - t0) / 1e6;
  return st;
}

/* Called with the lock held. */
static gboolean
is_wanted (DsLabStates *s, const DsLabLight *light)
{
  for (GList *l = s->wanted.head; l; l = l->next)
    if (light_equal (l->data, light))
      return TRUE;
  return FALSE;
}

/* Called with the lock held: drops the states of other sets when over budget. */
static void
insert_locked (DsLabStates *s, DsLabState *st)
{
  gsize bytes = (gsize) s->width * s->height * sizeof (float);
  if (s->bytes + bytes > STATES_MAX_BYTES) {
    GHashTableIter it;
    gpointer key, value;
    g_hash_table_iter_init (&it, s->states);
    while (g_hash_table_iter_next (&it, &key, &value)) {
      const DsLabLight *l = key;
      if (l->on && (l->n_phases != s->set_phases || l->period_px != s->set_period_px)) {
        g_hash_table_iter_remove (&it);
        s->bytes -= bytes;
      }
    }
  }
  if (g_hash_table_replace (s->states, g_memdup2 (&st->light, sizeof st->light), st))
    s->bytes += bytes;
  s->rendered++;
  s->render_s += st->render_s;
  g_cond_broadcast (&s->done_cond);
}

/* Called with the lock held: the light's whole set (every phase, and dark) is wanted next,
 * behind anything a trigger is waiting for. */
static void
want_set_locked (DsLabStates *s, const DsLabLight *light)
{
  if (s->have_set && s->set_phases == light->n_phases && s->set_period_px == light->period_px)
    return;
  s->have_set = TRUE;
  s->set_phases = light->n_phases;
  s->set_period_px = light->period_px;
  DsLabLight dark = { 0 };
  /* Every phase, dark, then every stripe lit (preview's light, last: a set needs the others). */
  for (guint k = 0; k <= light->n_phases + 1; k++) {
    DsLabLight l = k < light->n_phases ? (DsLabLight) { .on = TRUE, .phase = k, .n_phases = light->n_phases,
                                                        .period_px = light->period_px }
                   : k == light->n_phases ? dark
                                          : (DsLabLight) { .on = TRUE, .all_on = TRUE, .n_phases = light->n_phases,
                                                           .period_px = light->period_px };
    if (!g_hash_table_contains (s->states, &l) && !is_wanted (s, &l))
      g_queue_push_tail (&s->wanted, g_memdup2 (&l, sizeof l));
  }
  g_cond_signal (&s->work_cond);
}

static gpointer
worker (gpointer data)
{
  DsLabStates *s = data;
  g_mutex_lock (&s->lock);
  while (!s->quit) {
    g_mutex_unlock (&s->lock);
    DsLabLight now;
    ds_lab_states_sample (s, &now);
    g_mutex_lock (&s->lock);
    want_set_locked (s, &now);
    DsLabLight *next = g_queue_pop_head (&s->wanted);
    if (!next) {
      g_cond_wait_until (&s->work_cond, &s->lock, g_get_monotonic_time () + WATCH_US);
      continue;
    }
    if (g_hash_table_contains (s->states, next)) {
      g_free (next);
      continue;
    }
    g_mutex_unlock (&s->lock);
    g_autoptr (GError) error = NULL;
    DsLabState *st = render (s, next, &error);
    if (!st)
      g_warning ("labsim camera: cannot render %s %u of %u at period %g px: %s", next->on ? "phase" : "dark",
                 next->phase, next->n_phases, next->period_px, error->message);
    g_free (next);
    g_mutex_lock (&s->lock);
    if (st)
      insert_locked (s, st);
  }
  g_mutex_unlock (&s->lock);
  return NULL;
}

gboolean
ds_lab_states_prepare (DsLabStates *s, guint *n_rendered, double *seconds, GError **error)
{
  g_return_val_if_fail (!s->worker, FALSE);
  gint64 t0 = g_get_monotonic_time ();
  DsLabLight now;
  ds_lab_states_sample (s, &now);
  g_mutex_lock (&s->lock);
  want_set_locked (s, &now);
  g_mutex_unlock (&s->lock);
  guint n = 0;
  DsLabLight *next;
  /* The worker does not run yet: the queue is ours. */
  while ((next = g_queue_pop_head (&s->wanted))) {
    DsLabState *st = render (s, next, error);
    g_free (next);
    if (!st)
      return FALSE;
    g_mutex_lock (&s->lock);
    insert_locked (s, st);
    g_mutex_unlock (&s->lock);
    n++;
  }
  *n_rendered = n;
  *seconds = (double) (g_get_monotonic_time () - t0) / 1e6;
  s->worker = g_thread_new ("labsim-render", worker, s);
  return TRUE;
}

DsLabState *
ds_lab_states_get (DsLabStates *s, const DsLabLight *light, gint64 deadline)
{
  DsLabLight key = normalised (light);
  g_mutex_lock (&s->lock);
  DsLabState *st = g_hash_table_lookup (s->states, &key);
  if (!st) {
    /* First in line: a trigger waits for it. */
    GList *l = s->wanted.head;
    while (l && !light_equal (l->data, &key))
      l = l->next;
    if (l)
      g_queue_unlink (&s->wanted, l);
    g_queue_push_head (&s->wanted, l ? l->data : g_memdup2 (&key, sizeof key));
    if (l)
      g_list_free_1 (l);
    g_cond_signal (&s->work_cond);
    gboolean waiting = deadline > 0;
    while (!(st = g_hash_table_lookup (s->states, &key)) && waiting && !s->quit)
      waiting = g_cond_wait_until (&s->done_cond, &s->lock, deadline);
  }
  if (st)
    ds_lab_state_ref (st);
  g_mutex_unlock (&s->lock);
  return st;
}

void
ds_lab_states_rendered (DsLabStates *s, guint64 *n, double *seconds)
{
  g_mutex_lock (&s->lock);
  *n = s->rendered;
  *seconds = s->render_s;
  g_mutex_unlock (&s->lock);
}

void
ds_lab_states_free (DsLabStates *s)
{
  if (!s)
    return;
  g_mutex_lock (&s->lock);
  s->quit = TRUE;
  g_cond_broadcast (&s->work_cond);
  g_cond_broadcast (&s->done_cond);
  g_mutex_unlock (&s->lock);
  if (s->worker)
    g_thread_join (s->worker); /* after the render in progress */
  g_queue_clear_full (&s->wanted, g_free);
  g_hash_table_unref (s->states);
  g_cond_clear (&s->work_cond);
  g_cond_clear (&s->done_cond);
  g_mutex_clear (&s->lock);
  g_mutex_clear (&s->illum_lock);
  g_free (s);
}
