/* descatter-labsim's command line: every option in one struct, parsed and range-checked in one
 * place (labsim_options.c). Adding a fault knob: a field here, an entry in the option table
 * and, for a number, a row in the range table there. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

typedef struct {
  gboolean version;        /* --version: print it and exit; nothing else is checked */
  char *scene_path;
  char *psf_cache_dir;
  gint64 seed;

  /* camera */
  char *camera_address;
  char *camera_serial;
  double gvsp_lost_ratio;
  int vanish_after;        /* frames */
  double vanish_for;       /* s */
  gboolean noiseless;
  int sync_line;           /* the projector's sync output drives this camera line; -1: none */
  int line_miss_every, line_double_every;
  char *pixel_formats;     /* NULL: every format of labsim-camera.xml; else a comma list of them */
  double gain_max_db;      /* 0: labsim-camera.xml's 24 dB */

  /* illuminator controller */
  char *modbus_address;    /* HOST:PORT */
  char *modbus_host;       /* split from modbus_address */
  guint modbus_port;
  char *modbus_rtu;        /* NULL: no serial side; "pty" or a device */
  char *modbus_rtu_link;
  int modbus_unit_id;
  double settle_ms;
  int delay_ms, delay_every;
  double exception_rate;
  int exception_code;
  int drop_every, short_every, silent_every, bad_crc_every;
  int rtu_vanish_after;    /* requests */
  double rtu_vanish_for;   /* s */
  gboolean stuck, wrong_phase, fault, over_temp;
  gboolean fixed_period;   /* the projector cannot change its period (the scene's) */
  int map_revision;        /* 1: no CAPABILITIES, PERIOD_CENTIPX stored but not drawn; default 2 */
  char *light_from;        /* NULL: the camera sees labsim's own controller */

  /* simulated GPIO chip (gpio_chip_server.h) */
  char *gpio_chip;         /* NULL: none; else the UNIX socket it is served on */
  int gpio_camera_line;    /* the camera line input the chip's line 0 drives */
  int gpio_stripe_lines;   /* 0: none; else chip lines 1..N drive the stripe groups the camera sees */
  int gpio_enable_line;    /* -1: none; else the chip line that must be high for any light */
} DsLabsimOptions;

/* Parses argv (removing what it took). FALSE with a message naming the option on bad input. */
gboolean ds_labsim_options_parse (DsLabsimOptions *options, int *argc, char ***argv, GError **error);
void ds_labsim_options_clear (DsLabsimOptions *options);

G_END_DECLS
