/* descatterd as an object: configuration, socket server, acquisition thread, spool and
 * systemd notification, wired together. Main thread only; descatterd.c only parses options
 * and runs the loop, so tests can run a whole daemon in-process too. */
#pragma once
#include <glib.h>

#include "daemon/config/config.h"

G_BEGIN_DECLS

typedef struct {
  const char *config_path;     /* NULL: the built-in simulated lab (or the file already loaded) */
  const char *socket_path;     /* overrides [daemon] socket */
  const char *tcp_listen;      /* overrides [daemon] tcp-listen */
  const char *http_listen;     /* overrides [http] listen */
  const char *scene_path;      /* overrides [sim] scene */
  gboolean no_systemd_sockets; /* ignore LISTEN_FDS (tests) */
} DsServiceOptions;

typedef struct DsService DsService;

/* Takes ownership of config. Binds the listeners and starts the acquisition thread (which opens
 * the devices); READY is notified once they are open. `on_fatal` quits the loop. */
DsService *ds_service_new (DsConfig *config, const DsServiceOptions *options, GMainLoop *loop,
                           GError **error);
/* SIGHUP: reloads the configuration file; a bad file is refused and the running one kept. */
gboolean ds_service_reload (DsService *service, GError **error);
/* Stops acquisition (abandoning a set between frames), answers pending captures with
 * `cancelled`, closes every connection and the devices. */
void ds_service_free (DsService *service);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsService, ds_service_free)

/* Where a client connects (the UNIX socket path, or NULL with systemd sockets only). */
const char *ds_service_socket_path (const DsService *service);
guint16 ds_service_tcp_port (const DsService *service);
/* The live view's address ("http://127.0.0.1:8420/"), or NULL when HTTP is off. */
const char *ds_service_http_url (const DsService *service);
/* TRUE when the devices could not be opened (the loop was quit; exit with failure). */
gboolean ds_service_devices_failed (const DsService *service);

G_END_DECLS
