/* Drives the real GPIO backends (libgpiod) for tests/hw/gpio_sim.sh:
 *   gpio_sim_drive CHIP LINES N SYSFS_DIR
 * lights each phase of a duty-1/N pattern on LINES (comma-separated, N lines)
 * and prints, per phase, the level of every line as the kernel's gpio-sim reports it in
 * SYSFS_DIR/sim_gpio<offset>/value: "phase k: 0100". Then pulses the trigger on the line after
 * the last and prints its level after the pulse. Exit 1 on any error (printed). */
#include <stdio.h>
#include <stdlib.h>

#include "drivers/gpio/gpio_backends.h"

static int
sim_level (const char *dir, guint offset)
{
  g_autofree char *path = g_strdup_printf ("%s/sim_gpio%u/value", dir, offset);
  g_autofree char *text = NULL;
  if (!g_file_get_contents (path, &text, NULL, NULL))
    return -1;
  return atoi (text);
}

int
main (int argc, char **argv)
{
  if (argc != 5) {
    fprintf (stderr, "usage: gpio_sim_drive CHIP LINES N SYSFS_DIR\n");
    return 2;
  }
  const char *chip = argv[1], *lines = argv[2], *dir = argv[4];
  guint n = (guint) atoi (argv[3]);
  g_autoptr (GError) error = NULL;
  guint offsets[DS_GPIO_MAX_LINES], n_lines;
  if (!ds_gpio_parse_offsets (lines, offsets, &n_lines, &error)) {
    fprintf (stderr, "%s\n", error->message);
    return 1;
  }
  DsIlluminator *ill = ds_gpio_illuminator_open_from_config (chip, lines, -1, &error);
  if (!ill) {
    fprintf (stderr, "open: %s\n", error->message);
    return 1;
  }
  DsStripePattern p = { .kind = DS_STRIPES_SQUARE, .period_px = 8, .duty = 1.0 / n, .intensity = 1, .n_phases = n };
  if (!ill->ops->set_pattern (ill->backend, &p, &error)) {
    fprintf (stderr, "set_pattern: %s\n", error->message);
    return 1;
  }
  for (guint k = 0; k < n; k++) {
    if (!ill->ops->set_phase (ill->backend, k, 100, &error)) {
      fprintf (stderr, "set_phase %u: %s\n", k, error->message);
      return 1;
    }
    printf ("phase %u: ", k);
    for (guint j = 0; j < n_lines; j++)
      printf ("%d", sim_level (dir, offsets[j]));
    printf ("\n");
  }
  ds_illuminator_close (ill);
  DsTrigger *t = ds_gpio_trigger_open_from_config (chip, (int) offsets[n_lines - 1] + 1, 1000, TRUE, &error);
  if (!t || !t->ops->fire (t->backend, &error)) {
    fprintf (stderr, "trigger: %s\n", error->message);
    return 1;
  }
  printf ("trigger idle: %d\n", sim_level (dir, offsets[n_lines - 1] + 1));
  ds_trigger_close (t);
  fflush (stdout);
  return 0;
}
