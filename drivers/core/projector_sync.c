#include "drivers/core/projector_sync.h"

typedef enum { NOTHING, PHASE, OFF, ALL_ON } Pending;

typedef struct {
  DsIlluminator *inner;
  Pending what;
  guint phase;
  guint timeout_ms;
} Sync;

static gboolean
sync_set_pattern (gpointer b, const DsStripePattern *pattern, GError **error)
{
  Sync *s = b;
  s->what = NOTHING;
  return s->inner->ops->set_pattern (s->inner->backend, pattern, error);
}

static gboolean
sync_set_phase (gpointer b, guint phase, guint timeout_ms, GError **error)
{
  (void) error;
  Sync *s = b;
  s->what = PHASE;
  s->phase = phase;
  s->timeout_ms = timeout_ms;
  return TRUE;
}

static gboolean
sync_off (gpointer b, guint timeout_ms, GError **error)
{
  (void) error;
  Sync *s = b;
  s->what = OFF;
  s->timeout_ms = timeout_ms;
  return TRUE;
}

/* Deferred like the others to the fire; a device without all_on refuses at once. */
static gboolean
sync_all_on (gpointer b, guint timeout_ms, GError **error)
{
  Sync *s = b;
  if (!s->inner->ops->all_on)
    return ds_illuminator_all_on (s->inner, timeout_ms, error); /* fails now, not at the fire */
  s->what = ALL_ON;
  s->timeout_ms = timeout_ms;
  return TRUE;
}

static gboolean
sync_get_status (gpointer b, DsIlluminatorStatus *status, GError **error)
{
  Sync *s = b;
  return s->inner->ops->get_status (s->inner->backend, status, error);
}

static gboolean
sync_reconnect (gpointer b, GError **error)
{
  Sync *s = b;
  return s->inner->ops->reconnect (s->inner->backend, error);
}

static void
sync_close (gpointer b)
{
  Sync *s = b;
  ds_illuminator_close (s->inner);
  g_free (s);
}

static const DsIlluminatorOps sync_illuminator_ops = {
  .name = "projector-sync",
  .set_pattern = sync_set_pattern,
  .set_phase = sync_set_phase,
  .off = sync_off,
  .get_status = sync_get_status,
  .reconnect = sync_reconnect,
  .close = sync_close,
  .all_on = sync_all_on,
};

/* The apply whose sync pulse exposes the frame. */
static gboolean
sync_fire (gpointer b, GError **error)
{
  Sync *s = b;
  gboolean ok;
  switch (s->what) {
  case PHASE:
    ok = s->inner->ops->set_phase (s->inner->backend, s->phase, s->timeout_ms, error);
    break;
  case OFF:
    ok = s->inner->ops->off (s->inner->backend, s->timeout_ms, error);
    break;
  case ALL_ON:
    ok = ds_illuminator_all_on (s->inner, s->timeout_ms, error);
    break;
  default:
    g_set_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_INVALID,
                 "projector sync: nothing to apply (set a phase or switch off first)");
    return FALSE;
  }
  if (!ok)
    g_prefix_error (error, "projector sync: ");
  return ok;
}

static void
sync_trigger_close (gpointer b)
{
  (void) b; /* borrowed: the illuminator wrapper owns it */
}

static const DsTriggerOps sync_trigger_ops = {
  .name = "projector-sync",
  .fire = sync_fire,
  .close = sync_trigger_close,
};

DsIlluminator *
ds_projector_sync_wrap (DsIlluminator *illuminator, DsTrigger **trigger)
{
  Sync *s = g_new0 (Sync, 1);
  s->inner = illuminator;
  DsIlluminator *ill = g_new0 (DsIlluminator, 1);
  ill->ops = &sync_illuminator_ops;
  ill->backend = s;
  DsTrigger *t = g_new0 (DsTrigger, 1);
  t->ops = &sync_trigger_ops;
  t->backend = s;
  *trigger = t;
  return ill;
}
