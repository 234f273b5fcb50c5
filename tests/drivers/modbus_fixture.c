#include "modbus_fixture.h"

#include <glib/gstdio.h>

const DsStripePattern modbus_fixture_four_phases = {
  .kind = DS_STRIPES_SQUARE, .period_px = 6.0, .duty = 0.5, .black_level = 0.0, .intensity = 1.0, .n_phases = 4,
};

void
modbus_fixture_open (Fixture *f, gboolean rtu)
{
  g_autoptr (GError) error = NULL;
  f->server = ds_modbus_server_new (rtu ? NULL : "127.0.0.1", 0, &f->cfg, &error);
  g_assert_no_error (error);
  if (rtu) {
    f->dir = g_dir_make_tmp ("ds-rtu-XXXXXX", &error);
    g_assert_no_error (error);
    g_autofree char *link = g_build_filename (f->dir, "ttyLAB", NULL);
    DsModbusRtuConfig rc = { .device = "pty", .link = link, .unit_id = 1 };
    g_assert_true (ds_modbus_server_add_rtu (f->server, &rc, &error));
    g_assert_no_error (error);
    g_assert_cmpstr (ds_modbus_server_rtu_path (f->server), ==, link);
    f->uri = g_strdup_printf ("rtu:%s?baud=115200&parity=N&data=8&stop=1", link);
  } else
    f->uri = g_strdup_printf ("tcp://127.0.0.1:%u", ds_modbus_server_port (f->server));
  f->ill = ds_modbus_illuminator_open (f->uri, 1, ANSWER_MS, &error);
  g_assert_no_error (error);
  g_assert_nonnull (f->ill);
}

void
modbus_fixture_close (Fixture *f)
{
  ds_illuminator_close (f->ill);
  ds_modbus_server_free (f->server);
  g_free (f->uri);
  if (f->dir) {
    g_rmdir (f->dir);
    g_free (f->dir);
  }
}
