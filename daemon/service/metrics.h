/* /metrics: descatterd's counters in the Prometheus text exposition format (version 0.0.4),
 * for a Prometheus server or anything that parses it (docs/operations.md, "Metrics"). The
 * result-latency histogram is kept here; everything else is read from the sources at each
 * scrape. Main thread. */
#pragma once
#include <glib.h>

#include "daemon/acquire/sequencer.h"
#include "daemon/service/server.h"
#include "daemon/service/spool.h"

G_BEGIN_DECLS

typedef struct DsMetrics DsMetrics;

DsMetrics *ds_metrics_new (void);
void ds_metrics_free (DsMetrics *metrics);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsMetrics, ds_metrics_free)

/* One published result, `latency_s` after its last frame arrived. */
void ds_metrics_observe_result (DsMetrics *metrics, double latency_s);

typedef struct {
  guint clients;             /* WebSocket clients of the live view */
  guint64 sent;              /* live updates sent */
  guint64 superseded;        /* live updates replaced by a newer one before a client took them */
  guint64 http_requests;
  guint64 http_unauthorized;
  guint http_connections;           /* HTTP connections open now, WebSockets included */
  guint64 http_refused;             /* over max-connections or max-connections-per-peer */
  guint64 http_timed_out;           /* closed for header-timeout-ms or idle-timeout-ms */
  guint64 http_accept_paused;       /* times accepting paused for want of descriptors */
} DsLiveStats;

typedef struct {
  const DsSequencerStatus *sequencer;
  const DsServerStats *server;
  const DsSpoolStats *spool;  /* NULL: no spool */
  const DsLiveStats *live;    /* NULL: no HTTP server */
  guint64 results_published;
  gboolean ready;             /* status.ready: devices open, settings taken, nothing reconnecting */
  double start_unix_s;        /* when descatterd started (Unix time, seconds) */
  double last_result_unix_s;  /* when the last result was published; 0: none yet */
} DsMetricsSources;

/* The shortest decimal text that reads back as exactly `value` (strtod), as Prometheus client
 * libraries print it: "0.0025", not "0.0025000000000000001". Integers up to 2^53 print
 * without exponent; NaN and infinities as the exposition format spells them. Writes into buf
 * (at least G_ASCII_DTOSTR_BUF_SIZE bytes) and returns it. */
const char *ds_metrics_format_value (char *buf, gsize size, double value);

/* The exposition text; the caller frees it. */
char *ds_metrics_render (DsMetrics *metrics, const DsMetricsSources *sources);

G_END_DECLS
