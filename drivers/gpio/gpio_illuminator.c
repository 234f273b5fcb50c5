#include "drivers/gpio/gpio_illuminator.h"

#include <math.h>
#include <string.h>

typedef struct {
  DsGpioLines *stripes;
  DsGpioLines *enable;     /* NULL: none */
  double duty;
  guint n_phases;
  double period_px;        /* of the first pattern: the optics' (lines cannot change it); 0: none yet */
  gboolean have_pattern;
  gboolean lit;
  int applied_phase;       /* -1: off */
  guint64 apply_count;
} GpioIlluminator;

gboolean
ds_gpio_stripe_values (guint n_lines, guint n_phases, double duty, guint phase, int *values,
                       GError **error)
{
  if (n_phases < 2 || n_lines < n_phases || n_lines % n_phases != 0) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "GPIO illuminator: %u lines cannot shift through %u phases (the line count must be "
                 "a multiple of the phase count, phases >= 2)", n_lines, n_phases);
    return FALSE;
  }
  if (phase >= n_phases) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "GPIO illuminator: phase %u outside 0..%u", phase, n_phases - 1);
    return FALSE;
  }
  /* Exact integer offsets in units of 1/(L N) of a period: u = j N - k L, wrapped to
   * [-L N / 2, L N / 2); lit when -duty L N / 2 <= u < duty L N / 2 (the epsilon keeps a
   * boundary that duty hits exactly, e.g. 1/3 of 6 lines, on the half-open side). */
  gint64 ln = (gint64) n_lines * n_phases;
  double half = duty * (double) ln;
  guint lit = 0;
  for (guint j = 0; j < n_lines; j++) {
    gint64 u = ((gint64) j * n_phases - (gint64) phase * n_lines) % ln;
    if (u < 0)
      u += ln;
    if (2 * u >= ln)
      u -= ln;
    values[j] = (2.0 * (double) u >= -half - 1e-6 && 2.0 * (double) u < half - 1e-6) ? 1 : 0;
    lit += (guint) values[j];
  }
  if (lit == 0 || lit == n_lines) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "GPIO illuminator: duty %g over %u lines lights %s line", duty, n_lines,
                 lit == 0 ? "no" : "every");
    return FALSE;
  }
  return TRUE;
}

static gboolean
write_lines (GpioIlluminator *g, DsGpioLines *lines, const int *values, GError **error)
{
  GError *io = NULL;
  if (!ds_gpio_lines_set (lines, values, &io)) {
    ds_gpio_propagate_error (error, io, DS_ILLUMINATOR_ERROR);
    g_prefix_error (error, "GPIO illuminator: ");
    return FALSE;
  }
  (void) g;
  return TRUE;
}

/* The lines as the chip reports them must be what was written. */
static gboolean
read_back (DsGpioLines *lines, const int *expect, const char *what, GError **error)
{
  int got[DS_GPIO_MAX_LINES];
  GError *io = NULL;
  if (!ds_gpio_lines_get (lines, got, &io)) {
    ds_gpio_propagate_error (error, io, DS_ILLUMINATOR_ERROR);
    g_prefix_error (error, "GPIO illuminator: ");
    return FALSE;
  }
  for (guint i = 0; i < lines->n_lines; i++)
    if (got[i] != expect[i]) {
      g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_FAULT,
                   "GPIO illuminator: %s: line %u of %s reads %d after writing %d", what,
                   lines->offsets[i], lines->chip, got[i], expect[i]);
      return FALSE;
    }
  return TRUE;
}

static gboolean
gpio_set_pattern (gpointer backend, const DsStripePattern *p, GError **error)
{
  GpioIlluminator *g = backend;
  if (p->kind != DS_STRIPES_SQUARE) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED,
                 "GPIO illuminator: on/off lines make square stripes only, not sine");
    return FALSE;
  }
  /* The lines choose which stripe groups are lit, not how wide a period the optics image. */
  if (g->period_px > 0 && fabs (p->period_px - g->period_px) > 1e-9) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED,
                 "GPIO illuminator: the stripe period is the projector's optics', %g px as first configured; "
                 "on/off lines cannot change it to %g px", g->period_px, p->period_px);
    return FALSE;
  }
  int values[DS_GPIO_MAX_LINES];
  if (!ds_gpio_stripe_values (g->stripes->n_lines, p->n_phases, p->duty, 0, values, error))
    return FALSE;
  if (g->period_px == 0)
    g->period_px = p->period_px;
  g->duty = p->duty;
  g->n_phases = p->n_phases;
  g->have_pattern = TRUE;
  return TRUE;
}

static gboolean
gpio_set_phase (gpointer backend, guint phase, guint timeout_ms, GError **error)
{
  GpioIlluminator *g = backend;
  (void) timeout_ms;
  if (!g->have_pattern) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "GPIO illuminator: set_phase before set_pattern");
    return FALSE;
  }
  int values[DS_GPIO_MAX_LINES];
  if (!ds_gpio_stripe_values (g->stripes->n_lines, g->n_phases, g->duty, phase, values, error) ||
      !write_lines (g, g->stripes, values, error) ||
      !read_back (g->stripes, values, "stripe lines", error))
    return FALSE;
  if (g->enable && !g->lit) {
    const int on = 1;
    if (!write_lines (g, g->enable, &on, error) || !read_back (g->enable, &on, "enable line", error))
      return FALSE;
  }
  g->lit = TRUE;
  g->applied_phase = (int) phase;
  g->apply_count++;
  return TRUE;
}

static gboolean
gpio_off (gpointer backend, guint timeout_ms, GError **error)
{
  GpioIlluminator *g = backend;
  (void) timeout_ms;
  int zeros[DS_GPIO_MAX_LINES] = { 0 };
  /* Enable first, so no partial pattern is ever lit on the way down. */
  if (g->enable && (!write_lines (g, g->enable, zeros, error) || !read_back (g->enable, zeros, "enable line", error)))
    return FALSE;
  if (!write_lines (g, g->stripes, zeros, error) || !read_back (g->stripes, zeros, "stripe lines", error))
    return FALSE;
  g->lit = FALSE;
  g->applied_phase = -1;
  g->apply_count++;
  return TRUE;
}

/* Every stripe line high: every stripe group lit at once. Acquisition thread; blocks for the
 * line writes and their read-back; fails as set_phase (FAULT when a line reads back wrong). */
static gboolean
gpio_all_on (gpointer backend, guint timeout_ms, GError **error)
{
  GpioIlluminator *g = backend;
  (void) timeout_ms;
  int ones[DS_GPIO_MAX_LINES];
  for (guint i = 0; i < G_N_ELEMENTS (ones); i++)
    ones[i] = 1;
  if (!write_lines (g, g->stripes, ones, error) || !read_back (g->stripes, ones, "stripe lines", error))
    return FALSE;
  if (g->enable && !g->lit) {
    const int on = 1;
    if (!write_lines (g, g->enable, &on, error) || !read_back (g->enable, &on, "enable line", error))
      return FALSE;
  }
  g->lit = TRUE;
  g->applied_phase = -1; /* no one phase */
  g->apply_count++;
  return TRUE;
}

static gboolean
gpio_get_status (gpointer backend, DsIlluminatorStatus *st, GError **error)
{
  GpioIlluminator *g = backend;
  (void) error;
  memset (st, 0, sizeof *st);
  st->ready = TRUE;
  st->enabled = g->lit;
  st->applied_phase = g->applied_phase;
  st->apply_count = g->apply_count;
  st->temperature_c = NAN;
  return TRUE;
}

static gboolean
gpio_reconnect (gpointer backend, GError **error)
{
  GpioIlluminator *g = backend;
  GError *io = NULL;
  if (!ds_gpio_lines_reopen (g->stripes, &io) || (g->enable && !ds_gpio_lines_reopen (g->enable, &io))) {
    ds_gpio_propagate_error (error, io, DS_ILLUMINATOR_ERROR);
    g_prefix_error (error, "GPIO illuminator: ");
    return FALSE;
  }
  return TRUE;
}

static void
gpio_close (gpointer backend)
{
  GpioIlluminator *g = backend;
  gpio_off (g, 0, NULL); /* best effort */
  ds_gpio_lines_free (g->stripes);
  ds_gpio_lines_free (g->enable);
  g_free (g);
}

static const DsIlluminatorOps gpio_ops = {
  .name = "gpio",
  .set_pattern = gpio_set_pattern,
  .set_phase = gpio_set_phase,
  .off = gpio_off,
  .all_on = gpio_all_on,
  .get_status = gpio_get_status,
  .reconnect = gpio_reconnect,
  .close = gpio_close,
};

DsIlluminator *
ds_gpio_illuminator_new (DsGpioLines *stripes, DsGpioLines *enable, GError **error)
{
  if (enable && enable->n_lines != 1) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "GPIO illuminator: the enable set has %u lines, expected 1", enable->n_lines);
    ds_gpio_lines_free (stripes);
    ds_gpio_lines_free (enable);
    return NULL;
  }
  GpioIlluminator *g = g_new0 (GpioIlluminator, 1);
  g->stripes = stripes;
  g->enable = enable;
  g->applied_phase = -1;
  if (!gpio_off (g, 0, error)) {
    ds_gpio_lines_free (g->stripes);
    ds_gpio_lines_free (g->enable);
    g_free (g);
    return NULL;
  }
  g->apply_count = 0;
  DsIlluminator *ill = g_new0 (DsIlluminator, 1);
  ill->ops = &gpio_ops;
  ill->backend = g;
  return ill;
}
