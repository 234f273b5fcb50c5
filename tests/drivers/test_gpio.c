/* The GPIO illuminator and trigger backends through the simulated chip: the exact bulk values
 * of every phase against hand-written tables (derived on paper from the mapping in
 * docs/drivers.md), the pulse shape, and failures typed. */
#include <errno.h>
#include <string.h>

#include "drivers/gpio/gpio_backends.h"
#include "drivers/gpio/gpio_sim_chip.h"

static void
check_table (guint L, guint N, double duty, const int *table /* N rows of L */)
{
  for (guint k = 0; k < N; k++) {
    int v[DS_GPIO_MAX_LINES];
    g_autoptr (GError) error = NULL;
    g_assert_true (ds_gpio_stripe_values (L, N, duty, k, v, &error));
    g_assert_no_error (error);
    for (guint j = 0; j < L; j++)
      if (v[j] != table[k * L + j])
        g_error ("L=%u N=%u duty=%g phase %u line %u: %d, table says %d", L, N, duty, k, j, v[j],
                 table[k * L + j]);
  }
}

static void
test_mapping (void)
{
  /* Group j centred at j/L of the period, phase k centred at k/N: lit iff
   * -duty/2 <= wrap(j/L - k/N) < duty/2. */
  const int l8n4[] = {
    1, 1, 0, 0, 0, 0, 1, 1, /* k=0: groups at -2/8, -1/8, 0, 1/8 */
    1, 1, 1, 1, 0, 0, 0, 0, /* k=1: centre 2/8 */
    0, 0, 1, 1, 1, 1, 0, 0, /* k=2: centre 4/8 */
    0, 0, 0, 0, 1, 1, 1, 1, /* k=3: centre 6/8 */
  };
  check_table (8, 4, 0.5, l8n4);
  const int l6n3[] = {
    1, 0, 0, 0, 0, 1, /* duty 1/3: two of six lines, centre 0 */
    0, 1, 1, 0, 0, 0, /* centre 1/3 = line 2 */
    0, 0, 0, 1, 1, 0, /* centre 2/3 = line 4 */
  };
  check_table (6, 3, 1.0 / 3.0, l6n3);
  const int l4n4[] = {
    1, 0, 0, 0,
    0, 1, 0, 0,
    0, 0, 1, 0,
    0, 0, 0, 1,
  };
  check_table (4, 4, 0.25, l4n4);
  const int l8n2[] = {
    1, 1, 0, 0, 0, 0, 0, 1, /* duty 3/8: groups -1, 0, 1 */
    0, 0, 0, 1, 1, 1, 0, 0, /* groups 3, 4, 5 around 4/8 */
  };
  check_table (8, 2, 0.375, l8n2);

  int v[DS_GPIO_MAX_LINES];
  g_autoptr (GError) error = NULL;
  g_assert_false (ds_gpio_stripe_values (6, 4, 0.5, 0, v, &error)); /* 6 lines, 4 phases */
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID);
  g_assert_nonnull (strstr (error->message, "multiple"));
  g_clear_error (&error);
  g_assert_false (ds_gpio_stripe_values (4, 2, 1.0, 0, v, &error));
  g_assert_nonnull (strstr (error->message, "every"));
  g_clear_error (&error);
  g_assert_false (ds_gpio_stripe_values (4, 2, 0.5, 2, v, &error));
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID);
}

typedef struct {
  DsGpioSimChip *chip;
  DsIlluminator *ill;
} Fixture;

static const guint stripe_offsets[8] = { 10, 11, 12, 13, 14, 15, 16, 17 };
static const guint enable_offset = 20;

static void
setup (Fixture *f, gconstpointer data)
{
  (void) data;
  g_autoptr (GError) error = NULL;
  f->chip = ds_gpio_sim_chip_new ("gpiochip-sim", 32);
  DsGpioLines *stripes = ds_gpio_sim_chip_request (f->chip, stripe_offsets, 8, NULL, "test", &error);
  g_assert_no_error (error);
  DsGpioLines *enable = ds_gpio_sim_chip_request (f->chip, &enable_offset, 1, NULL, "test", &error);
  g_assert_no_error (error);
  f->ill = ds_gpio_illuminator_new (stripes, enable, &error);
  g_assert_no_error (error);
  ds_gpio_sim_chip_clear_writes (f->chip);
}

static void
teardown (Fixture *f, gconstpointer data)
{
  (void) data;
  ds_illuminator_close (f->ill);
  /* Every line is released by close. */
  for (guint i = 0; i < 32; i++)
    g_assert_null (ds_gpio_sim_chip_consumer (f->chip, i));
  ds_gpio_sim_chip_unref (f->chip);
}

static void
assert_write (const DsGpioSimChip *chip, guint i, guint n, const guint *offsets, const int *values)
{
  const DsGpioSimWrite *w = ds_gpio_sim_chip_get_write (chip, i);
  g_assert_nonnull (w);
  g_assert_cmpuint (w->n_lines, ==, n);
  for (guint j = 0; j < n; j++) {
    g_assert_cmpuint (w->offsets[j], ==, offsets[j]);
    g_assert_cmpint (w->values[j], ==, values[j]);
  }
}

static const DsStripePattern square4 = {
  .kind = DS_STRIPES_SQUARE, .period_px = 8, .duty = 0.5, .black_level = 0.02, .intensity = 1, .n_phases = 4,
};

/* One bulk write per phase with exactly the table's values; enable once, after the stripes. */
static void
test_illuminator_phases (Fixture *f, gconstpointer data)
{
  (void) data;
  const int table[4][8] = {
    { 1, 1, 0, 0, 0, 0, 1, 1 }, { 1, 1, 1, 1, 0, 0, 0, 0 },
    { 0, 0, 1, 1, 1, 1, 0, 0 }, { 0, 0, 0, 0, 1, 1, 1, 1 },
  };
  const int one = 1, zero = 0;
  const int zeros[8] = { 0 };
  g_autoptr (GError) error = NULL;
  g_assert_true (f->ill->ops->set_pattern (f->ill->backend, &square4, &error));
  g_assert_cmpuint (ds_gpio_sim_chip_n_writes (f->chip), ==, 0); /* loaded, not lit */
  for (guint k = 0; k < 4; k++) {
    guint before = ds_gpio_sim_chip_n_writes (f->chip);
    g_assert_true (f->ill->ops->set_phase (f->ill->backend, k, 0, &error));
    g_assert_no_error (error);
    guint after = ds_gpio_sim_chip_n_writes (f->chip);
    g_assert_cmpuint (after - before, ==, k == 0 ? 2 : 1);
    assert_write (f->chip, before, 8, stripe_offsets, table[k]);
    if (k == 0)
      assert_write (f->chip, before + 1, 1, &enable_offset, &one);
    for (guint j = 0; j < 8; j++)
      g_assert_cmpint (ds_gpio_sim_chip_value (f->chip, stripe_offsets[j]), ==, table[k][j]);
    DsIlluminatorStatus st;
    g_assert_true (f->ill->ops->get_status (f->ill->backend, &st, &error));
    g_assert_cmpint (st.applied_phase, ==, (int) k);
    g_assert_true (st.enabled && st.ready);
  }
  guint before = ds_gpio_sim_chip_n_writes (f->chip);
  g_assert_true (f->ill->ops->off (f->ill->backend, 0, &error));
  g_assert_cmpuint (ds_gpio_sim_chip_n_writes (f->chip) - before, ==, 2);
  assert_write (f->chip, before, 1, &enable_offset, &zero); /* enable drops first */
  assert_write (f->chip, before + 1, 8, stripe_offsets, zeros);
  DsIlluminatorStatus st;
  g_assert_true (f->ill->ops->get_status (f->ill->backend, &st, &error));
  g_assert_cmpint (st.applied_phase, ==, -1);
  g_assert_false (st.enabled);
}

static void
test_illuminator_invalid (Fixture *f, gconstpointer data)
{
  (void) data;
  g_autoptr (GError) error = NULL;
  g_assert_false (f->ill->ops->set_phase (f->ill->backend, 0, 0, &error)); /* no pattern yet */
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID);
  g_clear_error (&error);
  DsStripePattern p = square4;
  p.kind = DS_STRIPES_SINE;
  g_assert_false (f->ill->ops->set_pattern (f->ill->backend, &p, &error));
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED);
  g_clear_error (&error);
  p = square4;
  p.n_phases = 3; /* 8 lines */
  g_assert_false (f->ill->ops->set_pattern (f->ill->backend, &p, &error));
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID);
  g_assert_cmpuint (ds_gpio_sim_chip_n_writes (f->chip), ==, 0);
  /* The period is the optics': lines cannot change it. The first pattern's is kept, another is
   * refused, and the status says the period is not adjustable. */
  g_clear_error (&error);
  g_assert_true (f->ill->ops->set_pattern (f->ill->backend, &square4, &error));
  p = square4;
  p.period_px = 12;
  g_assert_false (f->ill->ops->set_pattern (f->ill->backend, &p, &error));
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED);
  g_assert_nonnull (strstr (error->message, "8 px"));
  g_assert_nonnull (strstr (error->message, "12 px"));
  g_clear_error (&error);
  p = square4;
  p.n_phases = 2;
  g_assert_true (f->ill->ops->set_pattern (f->ill->backend, &p, &error));
  DsIlluminatorStatus st;
  g_assert_true (f->ill->ops->get_status (f->ill->backend, &st, &error));
  g_assert_false (st.period_adjustable);
  g_assert_cmpuint (ds_gpio_sim_chip_n_writes (f->chip), ==, 0);
}

/* Failed writes become typed errors; reconnect recovers. A stuck line is caught by the
 * read-back and named. */
static void
test_illuminator_failures (Fixture *f, gconstpointer data)
{
  (void) data;
  g_autoptr (GError) error = NULL;
  g_assert_true (f->ill->ops->set_pattern (f->ill->backend, &square4, &error));
  const struct { int err; DsDeviceError code; } cases[] = {
    { EIO, DS_DEVICE_ERROR_FAULT },
    { EBUSY, DS_DEVICE_ERROR_BUSY },
    { ENODEV, DS_DEVICE_ERROR_DISCONNECTED },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    ds_gpio_sim_chip_fail_after (f->chip, 0, cases[i].err, FALSE);
    g_clear_error (&error);
    g_assert_false (f->ill->ops->set_phase (f->ill->backend, 1, 0, &error));
    g_assert_error (error, DS_ILLUMINATOR_ERROR, cases[i].code);
    g_assert_nonnull (strstr (error->message, g_strerror (cases[i].err)));
    g_clear_error (&error);
    g_assert_true (f->ill->ops->reconnect (f->ill->backend, &error));
    g_assert_true (f->ill->ops->set_phase (f->ill->backend, 1, 0, &error));
    g_assert_no_error (error);
  }
  ds_gpio_sim_chip_stick_line (f->chip, 16, 1); /* group 6 is dark in phase 2 */
  g_assert_false (f->ill->ops->set_phase (f->ill->backend, 2, 0, &error));
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_FAULT);
  g_assert_nonnull (strstr (error->message, "line 16"));
}

static void
test_trigger_pulse (void)
{
  g_autoptr (DsGpioSimChip) chip = ds_gpio_sim_chip_new ("gpiochip-sim", 8);
  for (int active_low = 0; active_low <= 1; active_low++) {
    g_autoptr (GError) error = NULL;
    const guint off = 5;
    DsGpioLines *line = ds_gpio_sim_chip_request (chip, &off, 1, NULL, "trigger", &error);
    g_assert_no_error (error);
    DsTrigger *t = ds_gpio_trigger_new (line, 3000, active_low, &error);
    g_assert_no_error (error);
    int idle = active_low ? 1 : 0, active = 1 - idle;
    g_assert_cmpint (ds_gpio_sim_chip_value (chip, off), ==, idle);
    ds_gpio_sim_chip_clear_writes (chip);
    for (guint i = 0; i < 3; i++)
      g_assert_true (t->ops->fire (t->backend, &error));
    /* Three pulses: active then idle, each at least the pulse width long. */
    g_assert_cmpuint (ds_gpio_sim_chip_n_writes (chip), ==, 6);
    for (guint i = 0; i < 3; i++) {
      const DsGpioSimWrite *a = ds_gpio_sim_chip_get_write (chip, 2 * i);
      const DsGpioSimWrite *b = ds_gpio_sim_chip_get_write (chip, 2 * i + 1);
      g_assert_cmpuint (a->n_lines, ==, 1);
      g_assert_cmpuint (a->offsets[0], ==, off);
      g_assert_cmpint (a->values[0], ==, active);
      g_assert_cmpint (b->values[0], ==, idle);
      g_assert_cmpint (b->time_us - a->time_us, >=, 3000); /* g_usleep sleeps at least that long */
    }
    g_assert_cmpint (ds_gpio_sim_chip_value (chip, off), ==, idle);
    /* The pulse's end fails: FAULT, and the message says it was the end. */
    ds_gpio_sim_chip_fail_after (chip, 1, EIO, FALSE);
    g_assert_false (t->ops->fire (t->backend, &error));
    g_assert_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_FAULT);
    g_assert_nonnull (strstr (error->message, "pulse end"));
    ds_trigger_close (t);
    g_assert_null (ds_gpio_sim_chip_consumer (chip, off));
  }
  g_autoptr (GError) error = NULL;
  const guint two[2] = { 1, 2 };
  DsGpioLines *lines = ds_gpio_sim_chip_request (chip, two, 2, NULL, "trigger", &error);
  g_assert_null (ds_gpio_trigger_new (lines, 100, FALSE, &error));
  g_assert_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_INVALID);
}

static void
test_requests (void)
{
  g_autoptr (DsGpioSimChip) chip = ds_gpio_sim_chip_new ("gpiochip-sim", 8);
  g_autoptr (GError) error = NULL;
  const guint a[2] = { 1, 2 }, b[2] = { 2, 3 }, far[1] = { 8 }, dup[2] = { 4, 4 };
  g_autoptr (DsGpioLines) la = ds_gpio_sim_chip_request (chip, a, 2, NULL, "first", &error);
  g_assert_no_error (error);
  g_assert_null (ds_gpio_sim_chip_request (chip, b, 2, NULL, "second", &error));
  g_assert_error (error, G_IO_ERROR, G_IO_ERROR_BUSY);
  g_assert_nonnull (strstr (error->message, "line 2"));
  g_clear_error (&error);
  g_assert_null (ds_gpio_sim_chip_request (chip, far, 1, NULL, "x", &error));
  g_assert_error (error, G_IO_ERROR, G_IO_ERROR_NOT_FOUND);
  g_clear_error (&error);
  g_assert_null (ds_gpio_sim_chip_request (chip, dup, 2, NULL, "x", &error));
  g_assert_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT);
  g_clear_error (&error);

  guint offs[DS_GPIO_MAX_LINES], n;
  g_assert_true (ds_gpio_parse_offsets ("3, 4,5,6", offs, &n, &error));
  g_assert_cmpuint (n, ==, 4);
  g_assert_cmpuint (offs[0], ==, 3);
  g_assert_cmpuint (offs[3], ==, 6);
  g_assert_false (ds_gpio_parse_offsets ("3,x,5", offs, &n, &error));
  g_assert_nonnull (strstr (error->message, "element 2"));
  g_clear_error (&error);
  /* The real backend on a chip that does not exist here: typed, named. */
  g_assert_null (ds_gpio_illuminator_open_from_config ("descatter-no-such-chip", "1,2", -1, &error));
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
  g_assert_nonnull (strstr (error->message, "descatter-no-such-chip"));
  g_clear_error (&error);
  g_assert_null (ds_gpio_illuminator_open_from_config ("gpiochip0", "1,2", 2, &error));
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID);
  g_clear_error (&error);
  g_assert_null (ds_gpio_trigger_open_from_config ("descatter-no-such-chip", 3, 100, FALSE, &error));
  g_assert_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/gpio/mapping", test_mapping);
  g_test_add_func ("/gpio/requests", test_requests);
  g_test_add_func ("/gpio/trigger-pulse", test_trigger_pulse);
  g_test_add ("/gpio/illuminator-phases", Fixture, NULL, setup, test_illuminator_phases, teardown);
  g_test_add ("/gpio/illuminator-invalid", Fixture, NULL, setup, test_illuminator_invalid, teardown);
  g_test_add ("/gpio/illuminator-failures", Fixture, NULL, setup, test_illuminator_failures, teardown);
  return g_test_run ();
}
