#include "daemon/ctl/ctl_interrupt.h"

#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <unistd.h>

/* The process's one guarded request. The watcher thread lives until the process exits, so the
 * state it reads is static, never freed. */
static struct {
  char *address, *token, *cmd;
  sigset_t signals;
  gint interrupted; /* atomic: a signal came during the request */
  gint finished;    /* atomic: the request returned; a signal now ends the process */
  GThread *canceller;
} guard;

/* Sends `cancel` and waits for its reply, which comes after the guarded request's `cancelled`. */
static gpointer
send_cancel (gpointer data)
{
  (void) data;
  DsCtlTarget target = { .address = guard.address, .token = guard.token };
  g_autoptr (DsClient) c = ds_ctl_connect (&target, guard.cmd);
  if (!c)
    return NULL;
  g_autoptr (DsMessage) m = ds_ctl_call (c, "cancel", NULL, NULL, NULL);
  return NULL;
}

/* sigwait in a thread of its own: a handler could only set a flag, and the main thread is
 * blocked in a read that a flag does not end. */
static gpointer
watch_signals (gpointer data)
{
  (void) data;
  for (;;) {
    int sig = 0;
    if (sigwait (&guard.signals, &sig) != 0)
      continue;
    if (g_atomic_int_get (&guard.finished) || g_atomic_int_get (&guard.interrupted)) {
      /* The second signal, or one after the request: no waiting any more. */
      static const char msg[] = "\ndescatterctl: interrupted\n";
      ssize_t n = write (STDERR_FILENO, msg, sizeof msg - 1);
      (void) n;
      _exit (DS_CTL_EXIT_INTERRUPTED);
    }
    fprintf (stderr, "\ndescatterctl %s: cancelling (Ctrl-C again to quit without waiting)\n", guard.cmd);
    guard.canceller = g_thread_new ("cancel", send_cancel, NULL);
    g_atomic_int_set (&guard.interrupted, 1);
  }
  return NULL;
}

void
ds_ctl_interrupt_begin (const DsCtlTarget *target, const char *cmd)
{
  guard.address = g_strdup (target->address);
  guard.token = g_strdup (target->token);
  guard.cmd = g_strdup (cmd);
  sigemptyset (&guard.signals);
  sigaddset (&guard.signals, SIGINT);
  sigaddset (&guard.signals, SIGTERM);
  /* Blocked before the watcher starts, so that every thread (it inherits the mask) leaves them
   * to sigwait. */
  pthread_sigmask (SIG_BLOCK, &guard.signals, NULL);
  g_thread_unref (g_thread_new ("signals", watch_signals, NULL));
}

gboolean
ds_ctl_interrupt_end (void)
{
  g_atomic_int_set (&guard.finished, 1);
  if (!g_atomic_int_get (&guard.interrupted))
    return FALSE;
  /* interrupted is set after canceller: the thread is there to join. Its reply comes after the
   * request's `cancelled`, so the daemon has stopped when this returns. */
  g_thread_join (guard.canceller);
  return TRUE;
}
