/* The ceiling of the daemon's rate benchmarks: a trigger-and-grab loop over the very devices
 * descatterd opens from a configuration, configured by the daemon's own code, with no
 * sequencer (no verification, no fold, no pipeline). What it reaches is what the camera, the
 * transport and (with set_phase) the illuminator allow; the daemon's rate is divided by it.
 *
 * It runs in a process of its own, as the daemon does, so that both receive the same way and
 * neither shares its process with the fake camera's threads: the benchmark starts itself again
 * with rate_ceiling_main's arguments. */
#pragma once
#include <glib.h>

#include "thread_cpu.h"

G_BEGIN_DECLS

typedef struct {
  double fps;          /* complete frames per second */
  guint incomplete;    /* frames that came with missing packets (transport losses) */
  guint lost;          /* triggers with no frame within the grab timeout */
  guint reconnects;    /* control of the camera lost and taken again */
  guint64 rcvbuf_drops; /* UDP datagrams the kernel dropped meanwhile because a receive buffer
                         * was full (this network namespace: the rig's GVSP packets) */
  /* Where the CPU went over the measured interval (thread_cpu.h), and the frames it was
   * divided among: the frames the loop grabbed complete, or the daemon folded. */
  guint64 frames;
  ThreadCpuTotals cpu;     /* the loop's (or the daemon's) own threads */
  ThreadCpuTotals rig_cpu; /* the rig's: the benchmark process (fake camera, Modbus controller) */
  /* The measured interval (g_get_monotonic_time: CLOCK_MONOTONIC, the same in every process). */
  gint64 from_us, to_us;
} RateSample;

/* The network namespace's count of UDP datagrams dropped for a full receive buffer
 * (/proc/net/snmp, RcvbufErrors); 0 when it cannot be read. */
guint64 rate_udp_rcvbuf_errors (void);

/* Runs the loop for `seconds` in a child process (self_path --ceiling ...) over the devices of
 * conf_text (a descatterd.conf body). with_phase: before each trigger the illuminator applies
 * the next phase of the configured pattern and settles, as the sequencer must before exposing
 * a phase. FALSE, with a message on stderr, when the child failed. */
gboolean rate_ceiling_measure (const char *self_path, const char *conf_text, double seconds,
                               gboolean with_phase, RateSample *out);

/* The child's side: when argv asks for the ceiling, runs it, prints the sample on stdout and
 * returns the exit status (0 ok); returns -1 when argv is not a ceiling invocation. */
int rate_ceiling_main (int argc, char **argv);

G_END_DECLS
