#include "daemon/ctl/study_figures.h"

#include <string.h>

#include "daemon/operating/data_dir.h"

gboolean
ds_study_draw_figures (const char *csv_path, const char *dir, GError **error)
{
  const char *python = g_getenv ("DESCATTER_PYTHON");
  g_autofree char *script = ds_data_path ("plot_study.py");
  const char *argv[] = { python && *python ? python : "/usr/bin/python3", script, csv_path, dir, NULL };
  g_autofree char *err_text = NULL;
  int wait_status = 0;
  if (!g_spawn_sync (NULL, (char **) argv, NULL, G_SPAWN_STDOUT_TO_DEV_NULL, NULL, NULL, NULL, &err_text,
                     &wait_status, error)) {
    g_prefix_error (error, "figures: %s: ", argv[0]);
    return FALSE;
  }
  g_autoptr (GError) exit_error = NULL;
  if (!g_spawn_check_wait_status (wait_status, &exit_error)) {
    /* The helper's own words end its stderr (a traceback's last line, or its usage). */
    g_strchomp (err_text);
    const char *last = strrchr (err_text, '\n');
    g_set_error (error, exit_error->domain, exit_error->code,
                 "figures: %s %s failed (%s): %s (the figures need python3-matplotlib; --no-figures skips them)",
                 argv[0], script, exit_error->message, last ? last + 1 : err_text);
    return FALSE;
  }
  return TRUE;
}
