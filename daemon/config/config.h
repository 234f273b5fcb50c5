/* descatterd's configuration: a GKeyFile (etc/descatterd.conf documents every key), checked
 * against one table of keys with types, ranges and reload rules, so that the parser, `--check`,
 * a reload and the documentation cannot disagree. Loading is pure (no device is touched): main
 * thread. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

#define DS_CONFIG_ERROR (ds_config_error_quark ())
GQuark ds_config_error_quark (void);

typedef enum {
  DS_CONFIG_ERROR_IO = 1,
  DS_CONFIG_ERROR_SYNTAX = 2,
  DS_CONFIG_ERROR_UNKNOWN_GROUP = 3,
  DS_CONFIG_ERROR_UNKNOWN_KEY = 4,
  DS_CONFIG_ERROR_BAD_VALUE = 5,
  DS_CONFIG_ERROR_INCONSISTENT = 6,
} DsConfigError;

typedef struct {
  /* [daemon] */
  char *socket_path;
  guint socket_mode;
  char *tcp_listen;       /* "host:port" or NULL (off) */
  char *tcp_token_file;
  guint max_clients;
  guint max_tcp_clients;  /* 0: half of max_clients */
  guint idle_timeout_ms;  /* 0: never */
  guint auth_timeout_ms;
  guint64 max_queued_bytes;
  char *spool_dir;        /* NULL: no recording */
  guint64 spool_max_bytes;
  char *spool_formats;    /* comma-separated DsFileKinds names (daemon/output/result_files.h) */
  gboolean spool_save_phases;
  guint spool_max_pending;
  /* [http] */
  char *http_listen;      /* "host:port" or NULL (off) */
  char *http_token_file;
  double http_live_fps;
  char *http_server_names;     /* comma-separated, or NULL */
  guint http_max_connections;
  guint http_max_per_peer;
  guint http_max_header_bytes;
  guint http_max_body_bytes;
  guint http_header_timeout_ms;
  guint http_idle_timeout_ms;
  guint http_max_live_clients;
  guint http_live_send_budget;
  /* [camera] */
  char *camera_backend;   /* "sim" | "aravis" */
  char *camera_address;
  char *pixel_format;
  double exposure_us;
  double gain_db;
  double saturation_dn;   /* NAN: the pixel format's top */
  double gain_dn_per_e;   /* system gain K (DN/e-) for the noise model; NAN: none */
  double read_noise_dn;   /* read noise sigma (DN) for the noise model; NAN: 0 */
  double pixel_pitch_um;  /* NAN: the camera's, if it says */
  double acceptance_half_angle_deg; /* the lens's acceptance cone, object side; NAN: not known */
  char *roi;              /* "x,y,w,h" or NULL (full sensor) */
  char *camera_trigger;   /* "software" | "line0".."line3" */
  guint grab_timeout_ms;
  guint receive_buffer_frames; /* aravis, GigE Vision */
  guint frame_retention_ms;    /* aravis, GigE Vision */
  gboolean sends_after_exposure;
  /* [optics] */
  double magnification;   /* NAN: unknown */
  /* [illuminator] */
  char *illuminator_backend; /* "sim" | "modbus" | "gpio" */
  char *modbus_uri;
  guint modbus_unit_id;
  guint modbus_timeout_ms;
  char *gpio_chip;
  char *gpio_lines;
  int gpio_enable_line;   /* -1: none */
  char *pattern;          /* "square" | "sine" */
  double period_px;
  double duty;
  double black_level;
  double harmonic_gain;   /* NAN: not calibrated */
  double edge_blur_px;    /* NAN: not calibrated */
  double open_field_dn_per_ms; /* NAN: not calibrated (descatterctl calibrate's open field) */
  char *open_field_pixel_format; /* the camera's pixel format it was measured in; NULL: not said */
  double intensity;
  guint settle_timeout_ms;
  /* [trigger] */
  char *trigger_backend;  /* "software" | "gpio" */
  int trigger_gpio_line;
  guint trigger_pulse_us;
  gboolean trigger_active_low;
  /* [acquisition] */
  guint phases;
  guint averages;
  char *estimator;
  gboolean dark_frame;
  guint phase_retries;
  guint max_failed_sets;  /* continuous mode stops after this many failed sets in a row; 0 = never */
  char *results;          /* continuous mode: "per-set" or "per-frame" (sliding window) */
  gboolean verify_phase;
  gboolean detect_motion;  /* the mask's motion bit (N >= 4) */
  double speed_px_s;       /* declared speed for automatic captures (px/s along x); NAN: none */
  double phase_tolerance_deg;
  gboolean single_frame;   /* one frame per result, separated from one stripe period around each pixel */
  char *operating_model;  /* NULL: built-in */
  double timing_settle_ms;
  double timing_link_mbit;
  /* [sim] */
  char *sim_scene;
  guint64 sim_seed;
  char *sim_faults;       /* "name=value,..." or NULL */
  char *sim_geometry;     /* "scene" | "config": the stripe pattern descatterd assumes */
} DsConfig;

/* The table's defaults; the device backends are left unset (a file must choose them). */
DsConfig *ds_config_new_default (void);
/* The defaults with simulated camera and illuminator: `descatterd --sim`. */
DsConfig *ds_config_new_sim (void);
/* Defaults, then the file over them. Errors name the file, group, key (and line for syntax
 * errors) and the allowed values. */
DsConfig *ds_config_load_file (const char *path, GError **error);
DsConfig *ds_config_load_data (const char *data, const char *name_for_errors, GError **error);
DsConfig *ds_config_copy (const DsConfig *config);
void ds_config_free (DsConfig *config);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsConfig, ds_config_free)

/* "x,y,width,height" -> v (width, height > 0). BAD_VALUE naming the key otherwise. */
gboolean ds_config_parse_roi (const char *roi, guint v[4], GError **error);
/* "IP:PORT" (IPv6 in brackets allowed) -> host (newly allocated, may be NULL) and port. */
gboolean ds_config_parse_host_port (const char *text, char **host, guint16 *port);

/* The pixel format the camera delivers as results name it: "simulated" for the simulated camera
 * (the scene's sensor depth whatever [camera] pixel-format asks), else [camera] pixel-format. */
const char *ds_config_camera_pixel_format (const DsConfig *config);

/* A configuration file larger than this is refused (it is not one). */
#define DS_CONFIG_MAX_BYTES (1024 * 1024)
/* sockaddr_un's sun_path, terminator included. */
#define DS_CONFIG_MAX_SOCKET_PATH 108

/* The effective configuration as a key file text (what `descatterd --check` prints). */
char *ds_config_to_data (const DsConfig *config);
/* SIGHUP's rule, the key table's reload column: the keys that take effect only at start and
 * whose value differs between `running` and `fresh`, named as "[group] key, key; [group] key";
 * NULL when there are none (every change applies from the next set). */
char *ds_config_restart_keys_changed (const DsConfig *running, const DsConfig *fresh);
/* The keys a reload applies from the next set, named the same way. */
char *ds_config_live_keys (void);
/* Markdown table of every key with type, range, default, reload rule and meaning. */
char *ds_config_describe_keys (void);

G_END_DECLS
