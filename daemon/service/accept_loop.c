#include "daemon/service/accept_loop.h"

/* How long accepting pauses after an error (out of descriptors, say). */
#define PAUSE_MS 250
#define PAUSE_LOG_US (10 * G_USEC_PER_SEC)

/* An accept in flight may complete after the loop is freed: it holds this, which the loop
 * clears when it goes. */
typedef struct {
  gint ref;
  DsAcceptLoop *loop;
} Hold;

struct DsAcceptLoop {
  GSocketListener *listener;
  DsAcceptFunc on_accept;
  gpointer user_data;
  Hold *hold;
  GCancellable *cancel;
  GSource *resume;
  gboolean running, in_flight;
  gint64 last_log_us;
  guint64 paused;
};

static void
hold_unref (Hold *h)
{
  if (--h->ref == 0)
    g_free (h);
}

static void accept_next (DsAcceptLoop *loop);

static gboolean
resume (gpointer data)
{
  DsAcceptLoop *loop = data;
  g_clear_pointer (&loop->resume, g_source_unref);
  accept_next (loop);
  return G_SOURCE_REMOVE;
}

static void
pause_after (DsAcceptLoop *loop, const GError *error)
{
  loop->paused++;
  gint64 now = g_get_monotonic_time ();
  if (now - loop->last_log_us > PAUSE_LOG_US) {
    loop->last_log_us = now;
    g_warning ("socket: accepting paused for %d ms: %s", PAUSE_MS, error->message);
  }
  loop->resume = g_timeout_source_new (PAUSE_MS);
  g_source_set_callback (loop->resume, resume, loop, NULL);
  g_source_attach (loop->resume, g_main_context_get_thread_default ());
}

static void
on_accepted (GObject *src, GAsyncResult *res, gpointer data)
{
  Hold *h = data;
  DsAcceptLoop *loop = h->loop;
  hold_unref (h);
  g_autoptr (GError) error = NULL;
  g_autoptr (GSocketConnection) conn = g_socket_listener_accept_finish (G_SOCKET_LISTENER (src), res, NULL, &error);
  if (!loop)
    return;
  loop->in_flight = FALSE;
  if (!loop->running)
    return;
  if (g_error_matches (error, G_IO_ERROR, G_IO_ERROR_CANCELLED)) {
    accept_next (loop); /* stopped and started again meanwhile */
    return;
  }
  if (!conn) {
    pause_after (loop, error);
    return;
  }
  loop->on_accept (conn, loop->user_data);
  accept_next (loop);
}

static void
accept_next (DsAcceptLoop *loop)
{
  if (!loop->running || loop->in_flight || loop->resume)
    return;
  loop->in_flight = TRUE;
  loop->hold->ref++;
  g_socket_listener_accept_async (loop->listener, loop->cancel, on_accepted, loop->hold);
}

DsAcceptLoop *
ds_accept_loop_new (GSocketListener *listener, DsAcceptFunc on_accept, gpointer user_data)
{
  DsAcceptLoop *loop = g_new0 (DsAcceptLoop, 1);
  loop->listener = g_object_ref (listener);
  loop->on_accept = on_accept;
  loop->user_data = user_data;
  loop->hold = g_new0 (Hold, 1);
  loop->hold->ref = 1;
  loop->hold->loop = loop;
  loop->cancel = g_cancellable_new ();
  return loop;
}

void
ds_accept_loop_start (DsAcceptLoop *loop)
{
  if (loop->running)
    return;
  loop->running = TRUE;
  if (g_cancellable_is_cancelled (loop->cancel)) {
    g_object_unref (loop->cancel);
    loop->cancel = g_cancellable_new ();
  }
  accept_next (loop);
}

void
ds_accept_loop_stop (DsAcceptLoop *loop)
{
  loop->running = FALSE;
  g_cancellable_cancel (loop->cancel);
  if (loop->resume) {
    g_source_destroy (loop->resume);
    g_clear_pointer (&loop->resume, g_source_unref);
  }
}

void
ds_accept_loop_free (DsAcceptLoop *loop)
{
  if (!loop)
    return;
  ds_accept_loop_stop (loop);
  loop->hold->loop = NULL;
  hold_unref (loop->hold);
  g_object_unref (loop->cancel);
  g_object_unref (loop->listener);
  g_free (loop);
}

guint64
ds_accept_loop_paused (const DsAcceptLoop *loop)
{
  return loop->paused;
}
