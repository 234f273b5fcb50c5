/* descatterd's configuration parser: defaults, errors that point at the mistake, round trip,
 * and the shipped example (etc/descatterd.conf) documenting every key. */
#include "daemon/service/config.h"

#include <math.h>
#include <string.h>

static const char *example_path;

static void
test_defaults_are_the_simulated_lab (void)
{
  g_autoptr (DsConfig) c = ds_config_new_default ();
  g_assert_cmpstr (c->camera_backend, ==, "sim");
  g_assert_cmpstr (c->illuminator_backend, ==, "sim");
  g_assert_cmpuint (c->phases, ==, 8);
  g_assert_cmpfloat (c->duty, ==, 0.5);
  g_assert_cmpuint (c->socket_mode, ==, 0660);
  g_assert_null (c->tcp_listen);
  g_assert_true (isnan (c->phase_tolerance_deg));
}

static void
test_values_override_defaults (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) c = ds_config_load_data ("[acquisition]\nphases = 12\nestimator=sine\n"
                                                "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:1502\n"
                                                "duty=0.25\n[daemon]\nsocket-mode=0600\n",
                                                "t.conf", &error);
  g_assert_no_error (error);
  g_assert_cmpuint (c->phases, ==, 12);
  g_assert_cmpstr (c->estimator, ==, "sine");
  g_assert_cmpstr (c->modbus_uri, ==, "tcp://127.0.0.1:1502");
  g_assert_cmpfloat (c->duty, ==, 0.25);
  g_assert_cmpuint (c->socket_mode, ==, 0600);
  g_assert_cmpuint (c->averages, ==, 1); /* untouched default */
}

static void
expect_error (const char *text, int code, const char *const *must_contain)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) c = ds_config_load_data (text, "bad.conf", &error);
  g_assert_null (c);
  g_assert_error (error, DS_CONFIG_ERROR, code);
  g_assert_nonnull (strstr (error->message, "bad.conf"));
  for (guint i = 0; must_contain[i]; i++)
    if (!strstr (error->message, must_contain[i]))
      g_error ("error \"%s\" does not mention \"%s\"", error->message, must_contain[i]);
}

static void
test_errors_name_the_place (void)
{
  expect_error ("[camera]\nbackend=sim\n[cmaera]\nx=1\n", DS_CONFIG_ERROR_UNKNOWN_GROUP,
                (const char *const[]) { "[cmaera]", "line 3", NULL });
  expect_error ("# c\n[acquisition]\n\nphase = 8\n", DS_CONFIG_ERROR_UNKNOWN_KEY,
                (const char *const[]) { "[acquisition]", "\"phase\"", "line 4", NULL });
  expect_error ("[acquisition]\nphases=1\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "phases", "2..64", "line 2", NULL });
  expect_error ("[acquisition]\nphases=eight\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "phases", "integer", NULL });
  expect_error ("[illuminator]\nduty=1.5\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "duty", "0.01..0.99", NULL });
  expect_error ("[illuminator]\nduty=nan\n", DS_CONFIG_ERROR_BAD_VALUE, (const char *const[]) { "duty", NULL });
  expect_error ("[acquisition]\nestimator=median\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "estimator", "maxmin|sine|robust", NULL });
  expect_error ("[acquisition]\ndark-frame=yes\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "dark-frame", "true or false", NULL });
  expect_error ("[daemon]\nsocket-mode=0999\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "socket-mode", "octal", NULL });
  expect_error ("[camera]\nbackend=aravis\n", DS_CONFIG_ERROR_INCONSISTENT,
                (const char *const[]) { "address", NULL });
  expect_error ("[acquisition]\nestimator=sine\nphases=2\n", DS_CONFIG_ERROR_INCONSISTENT,
                (const char *const[]) { "sine", "phases >= 3", NULL });
  expect_error ("[daemon]\ntcp-listen=127.0.0.1\n", DS_CONFIG_ERROR_INCONSISTENT,
                (const char *const[]) { "tcp-listen", "host:port", NULL });
  expect_error ("[daemon\nsocket=x\n", DS_CONFIG_ERROR_SYNTAX, (const char *const[]) { NULL });
}

static void
test_round_trip (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) a = ds_config_load_data ("[camera]\nexposure-us=1234.5\nroi=0,0,64,32\n[sim]\nseed=99\n"
                                                "[acquisition]\nphase-tolerance-deg=10\n",
                                                "a.conf", &error);
  g_assert_no_error (error);
  g_autofree char *text = ds_config_to_data (a);
  g_autoptr (DsConfig) b = ds_config_load_data (text, "printed", &error);
  g_assert_no_error (error);
  g_autofree char *text2 = ds_config_to_data (b);
  g_assert_cmpstr (text, ==, text2);
  g_assert_cmpfloat (b->exposure_us, ==, 1234.5);
  g_assert_cmpstr (b->roi, ==, "0,0,64,32");
  g_assert_cmpuint (b->sim_seed, ==, 99);
  g_assert_cmpfloat (b->phase_tolerance_deg, ==, 10.0);
  g_autoptr (DsConfig) copy = ds_config_copy (b);
  g_autofree char *text3 = ds_config_to_data (copy);
  g_assert_cmpstr (text, ==, text3);
}

static void
test_example_documents_every_key (void)
{
  g_autofree char *data = NULL;
  g_assert_true (g_file_get_contents (example_path, &data, NULL, NULL));
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) c = ds_config_load_data (data, example_path, &error);
  g_assert_no_error (error);
  /* Every key of the table appears in the example, set or commented out. */
  g_autofree char *defaults = ds_config_to_data (c);
  g_auto (GStrv) lines = g_strsplit (defaults, "\n", -1);
  for (guint i = 0; lines[i]; i++) {
    char *eq = strchr (lines[i], '=');
    if (!eq || lines[i][0] == '[')
      continue;
    *eq = '\0';
    g_autofree char *set = g_strdup_printf ("\n%s=", lines[i]);
    g_autofree char *commented = g_strdup_printf ("\n#%s=", lines[i]);
    if (!strstr (data, set) && !strstr (data, commented))
      g_error ("%s does not document key \"%s\"", example_path, lines[i]);
  }
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  example_path = argc > 1 ? argv[1] : "etc/descatterd.conf";
  g_test_add_func ("/config/defaults", test_defaults_are_the_simulated_lab);
  g_test_add_func ("/config/override", test_values_override_defaults);
  g_test_add_func ("/config/errors", test_errors_name_the_place);
  g_test_add_func ("/config/round-trip", test_round_trip);
  g_test_add_func ("/config/example", test_example_documents_every_key);
  return g_test_run ();
}
