/* Everything descatterd checks before it binds a socket or opens a device, in one function
 * that `descatterd --check` and start-up both run, so that --check passes exactly what start
 * accepts: the configuration's own rules (config.c), the command-line overrides, the device
 * addresses as their drivers parse them (Modbus URI, GPIO line lists, simulated faults), and
 * the files the configuration names (scene and its masks, operating model, TCP token), and
 * what start creates and binds: the spool folder is test-created (and removed again), the
 * TCP and HTTP addresses must differ and are test-bound (and closed again). Opening the
 * devices is the next step (devices.c; `--check --probe`).
 * Main thread; reads files, touches no device, leaves nothing behind. */
#pragma once
#include <glib.h>

#include "daemon/operating/operating_point.h"
#include "daemon/config/config.h"

G_BEGIN_DECLS

/* Command-line options that override the file. Relative paths are taken from the current
 * directory (they come from a shell), unlike the file's, which must be absolute. */
typedef struct {
  const char *config_name; /* the file's name, to prefix errors with (NULL: none) */
  const char *socket_path; /* --socket */
  const char *tcp_listen;  /* --tcp */
  const char *scene_path;  /* --scene */
  const char *http_listen; /* --http */
  /* The daemon is running (a reload): its own listeners hold their addresses, so they are not
   * test-bound. */
  gboolean running;
} DsPreflightOverrides;

typedef struct {
  DsConfig *config;          /* the effective configuration (overrides applied) */
  char *token;               /* read from tcp-token-file, or NULL */
  char *tcp_host;            /* NULL: no TCP */
  guint16 tcp_port;
  char *http_token;          /* read from [http] token-file, or NULL */
  char *http_host;           /* NULL: no live view and /metrics */
  guint16 http_port;
  DsOperatingModel *model;   /* NULL: automatic captures are off, model_note says why */
  char *model_path;
  char *model_note;
} DsPreflight;

/* config is not consumed. Fails with DS_CONFIG_ERROR naming the key (or option) and why. */
DsPreflight *ds_preflight_run (const DsConfig *config, const DsPreflightOverrides *overrides,
                               GError **error);
void ds_preflight_free (DsPreflight *preflight);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsPreflight, ds_preflight_free)

G_END_DECLS
