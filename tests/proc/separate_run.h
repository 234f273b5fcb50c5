/* Driving `descatterctl separate` through its entry point and reading its outputs back, as the
 * ctl-separate tests do. Header-only, static. */
#pragma once
#include <glib.h>
#include <stdarg.h>

#include "daemon/ctl/ctl_separate.h"
#include "proc/image.h"

/* `descatterctl separate` with the arguments up to NULL; its exit status. */
static inline int
separate_run (const char *first, ...)
{
  g_autoptr (GPtrArray) args = g_ptr_array_new ();
  g_ptr_array_add (args, (gpointer) "separate");
  va_list ap;
  va_start (ap, first);
  for (const char *s = first; s; s = va_arg (ap, const char *))
    g_ptr_array_add (args, (gpointer) s);
  va_end (ap);
  g_ptr_array_add (args, NULL);
  /* GOption rearranges argv; give it a copy of the pointers. */
  g_autofree char **argv = g_memdup2 (args->pdata, args->len * sizeof (char *));
  return ds_ctl_separate ((int) args->len - 1, argv);
}

/* An output image, which must read back. */
static inline DsImage *
separate_read_out (const char *dir, const char *name)
{
  g_autofree char *path = g_build_filename (dir, name, NULL);
  g_autoptr (GError) error = NULL;
  DsImage *img = ds_image_read (path, &error);
  g_assert_no_error (error);
  return img;
}
