/* The service's state, shared by the files that make up DsService and by no one else:
 * service.c (lifecycle, watchdog, reload), service_events.c (what the sequencer reports),
 * service_requests.c (clients' commands), request_set.c (the `set` command and the camera's
 * settings) and service_status.c (status and metrics documents).
 * Main thread only: the acquisition thread reaches the service through sequencer events. */
#pragma once
#include <glib.h>

#include "daemon/acquire/capture_settings.h"
#include "daemon/acquire/result.h"
#include "daemon/acquire/sequencer.h"
#include "daemon/output/result_files.h"
#include "daemon/operating/operating_point.h"
#include "daemon/service/calibrate_set.h"
#include "daemon/service/http_server.h"
#include "daemon/service/live_view.h"
#include "daemon/service/metrics.h"
#include "daemon/service/server.h"
#include "daemon/service/service.h"
#include "daemon/service/spool.h"

G_BEGIN_DECLS

/* A request the acquisition thread answers later (capture, dark, calibrate, release, acquire),
 * by its tag. */
typedef struct {
  guint64 tag;
  DsConnection *conn; /* ref + hold */
  JsonNode *id;
  DsOutputFormat format;
  gboolean extrema;
  guint outputs;      /* bit i: payload i of the result's payload set */
  gboolean progress;
  gboolean save_phases; /* the raw frames go back with the reply */
  gboolean calibrate;   /* a calibrate request: the reply is the set's calibration */
  DsCalibrateRequest calibration;
  DsCaptureSettings calibrate_settings; /* the first set's, for a second period */
  gboolean calibrate_second;            /* this is the set at the second period (calibrate_set.h) */
  DsCalibration calibrate_first;        /* ... and the first set's calibration */
  guint64 calibrate_first_set;
  gboolean cancellable;   /* capture, dark, calibrate: work a `cancel` answers `cancelled` */
  guint64 cancels_before; /* DsService.cancels when it was asked: a calibrate's second set is
                           * not queued after a cancel */
  gboolean cancel;        /* a `cancel` request: answered once the thread took the cancel ... */
  guint cancelled;        /* ... with how many requests it answered `cancelled` ... */
  gboolean stream_stopped;/* ... and whether continuous acquisition was running */
  gboolean camera_set;    /* a `set` request: answered with the camera's settings */
  gboolean preview;       /* a `preview` request: answered with the preview's state */
} PendingCapture;

typedef struct {
  DsConfig *config;
} OpenData;

struct DsService {
  OpenData open_data;
  DsConfig *config;
  char *config_path;
  DsServiceOptions options;
  char *scene_override;
  GMainLoop *loop;
  DsServer *server;
  DsSequencer *sequencer;
  DsSpool *spool;
  char *socket_path;
  GHashTable *pending;   /* tag -> PendingCapture */
  guint64 next_tag;
  gboolean ready;
  gboolean devices_failed;
  guint watchdog_source;
  guint64 watchdog_usec;
  gint64 started_us;
  gint64 started_unix_us;       /* g_get_real_time () at start: process_start_time_seconds */
  gint64 last_result_unix_us;   /* g_get_real_time () at the last result published; 0: none */
  guint64 results_published;
  char config_sha256[65];    /* of the effective configuration: in every result */
  DsMetrics *metrics;
  DsLiveView *live;          /* with http: NULL when [http] listen is off */
  DsHttpServer *http;
  char *http_token_path;   /* the token file we wrote (loopback, no token-file): removed at exit */
  gboolean in_run;           /* continuous acquisition started and not stopped */
  guint64 cancels;           /* `cancel` requests taken */
  gint preview_frame_in_flight; /* atomic: a preview frame copied and not yet published */
  DsOperatingModel *model;  /* NULL when no model file could be read (automatic captures fail) */
  char *model_error;
  char *model_path;         /* the file the model was (or failed to be) read from */
};

/* The result's payloads a capture may ask for, in the order of PendingCapture.outputs' bits. */
#define DS_SERVICE_N_OUTPUTS 6
/* Descriptors kept for the daemon's own use (logs, devices, GigE streams, the spool, the
 * listeners) when sizing [http] max-connections against the descriptor limit. */
#define DS_FD_RESERVE 64
extern const char *const ds_service_output_names[DS_SERVICE_N_OUTPUTS];

/* service_requests.c: every command the server does not answer itself. */
void ds_service_on_request (DsServer *server, DsConnection *conn, DsRequest *req, gpointer user_data);
/* The success reply to a request (id copied), with body and no payloads. */
void ds_service_reply_ok (DsService *svc, DsConnection *conn, JsonNode *id, JsonNode *body);
/* The reply to a `cancel` request. */
void ds_service_reply_cancel (DsService *svc, DsConnection *conn, JsonNode *id, guint cancelled,
                              gboolean stream_stopped);
/* A request answered later by the acquisition thread's event with `tag`: the connection is held
 * until then. */
PendingCapture *ds_service_pending_add (DsService *svc, DsConnection *conn, DsRequest *req, guint64 tag);
/* A PendingCapture's destructor (the pending table's value). */
void ds_service_pending_free (gpointer pending);

/* request_set.c: the `set` command, its reply, the camera's settings in status, and the
 * exposure and gain of captures that give none (what `set` left, else the configuration's). */
void ds_service_handle_set (DsService *svc, DsConnection *conn, DsRequest *req);
void ds_service_reply_camera_set (DsService *svc, DsConnection *conn, JsonNode *id);
void ds_service_status_add_camera_live (JsonBuilder *b, const DsSequencerStatus *st);
void ds_service_camera_defaults (DsService *svc, DsCaptureSettings *s);

/* service_preview.c: the `preview` command, its reply and status, and preview frames as
 * `frame` events (the sequencer's preview hook, on the acquisition thread). */
void ds_service_handle_preview (DsService *svc, DsConnection *conn, DsRequest *req);
void ds_service_reply_preview (DsService *svc, DsConnection *conn, JsonNode *id, const char *message);
JsonNode *ds_service_preview_status_json (const DsSequencerStatus *st);
void ds_service_on_preview_frame (const DsFrame *frame, DsPreviewLight light, guint phase, guint n_phases,
                                  gpointer user_data);

/* service_events.c: events of the acquisition thread, delivered on the main loop. */
void ds_service_on_sequencer_event (const DsSequencerEvent *ev, gpointer user_data);

/* service_status.c: the `status` document (also the live view's) and the /metrics text. */
JsonNode *ds_service_status_to_json (DsService *svc);
/* status `not_ready_reason`: NULL when ready, else why (free it). */
char *ds_service_not_ready_reason (DsService *svc);
char *ds_service_metrics_text (DsService *svc);

/* service.c: the configuration in effect, as `config` prints it and every result hashes it. */
char *ds_service_effective_config_text (DsService *svc);

G_END_DECLS
