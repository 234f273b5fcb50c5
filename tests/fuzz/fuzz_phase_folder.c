/* Fuzz target: phase folders. The input is a list of files, each record
 *   [name length: 1 byte][name][content length: 2 bytes little-endian][content]
 * (names mapped onto [a-z0-9._], at most 8 files of at most 4 KiB), written into a scratch
 * folder; the folder is then listed, the images' headers checked against the offline
 * commands' limits (as separate and calibrate do before decoding) and every image read.
 * Whatever the names and contents, the result is a set of same-shaped images or an error with
 * a message. */
#include <glib/gstdio.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "daemon/ctl/ctl_folder.h"
#include "proc/phase_folder.h"

int LLVMFuzzerTestOneInput (const uint8_t *data, size_t size);

static void
clear_folder (const char *dir)
{
  GDir *d = g_dir_open (dir, 0, NULL);
  const char *name;
  while (d && (name = g_dir_read_name (d))) {
    char *p = g_build_filename (dir, name, NULL);
    g_remove (p);
    g_free (p);
  }
  if (d)
    g_dir_close (d);
}

static char *dir; /* one scratch folder per process, emptied for every input */

static void
remove_folder (void)
{
  clear_folder (dir);
  g_rmdir (dir);
  g_free (dir);
}

int
LLVMFuzzerTestOneInput (const uint8_t *data, size_t size)
{
  if (!dir) {
    dir = g_dir_make_tmp ("ds-fuzz-folder-XXXXXX", NULL);
    g_assert (dir);
    atexit (remove_folder);
  }
  clear_folder (dir);
  static const char alphabet[] = "abcdefghijklmnopqrstuvwxyz0123456789._";
  gsize pos = 0;
  for (int files = 0; files < 8 && pos < size; files++) {
    guint nlen = 1u + data[pos++] % 24u;
    if (pos + nlen + 2 > size)
      break;
    char name[32];
    for (guint i = 0; i < nlen; i++)
      name[i] = alphabet[data[pos + i] % (sizeof alphabet - 1)];
    name[nlen] = '\0';
    pos += nlen;
    gsize clen = (data[pos] | ((gsize) data[pos + 1] << 8)) % 4097u;
    pos += 2;
    if (clen > size - pos)
      clen = size - pos;
    if (strcmp (name, ".") != 0 && strcmp (name, "..") != 0) {
      char *path = g_build_filename (dir, name, NULL);
      g_assert (g_file_set_contents (path, (const char *) data + pos, (gssize) clen, NULL));
      g_free (path);
    }
    pos += clen;
  }
  GError *error = NULL;
  DsPhaseFolder *f = ds_phase_folder_open (dir, ds_folder_read_sidecar, &error);
  if (!f) {
    g_assert (error && error->message && *error->message);
    g_error_free (error);
    return 0;
  }
  g_assert (ds_phase_folder_n_phases (f) >= 2);
  /* 1 GiB at most, whatever the machine has: a header that passes the side and pixel caps may
   * still not be decoded here */
  DsFolderLimits limits;
  ds_folder_limits_init (&limits);
  limits.max_memory = 1u << 30;
  if (!ds_folder_check_images (f, &limits, 16.0, "a read", &error)) {
    g_assert (error && error->message && *error->message);
    g_error_free (error);
    ds_phase_folder_free (f);
    return 0;
  }
  for (guint k = 0; k <= ds_phase_folder_n_phases (f); k++) {
    DsImage *img = k < ds_phase_folder_n_phases (f) ? ds_phase_folder_read (f, k, &error)
                   : f->black_file                  ? ds_phase_folder_read_black (f, &error)
                                                    : NULL;
    if (img) {
      g_assert (img->width == f->width && img->height == f->height && img->type == f->type);
      ds_image_free (img);
    } else if (error) {
      g_assert (error->message && *error->message);
      g_clear_error (&error);
    }
  }
  ds_phase_folder_free (f);
  return 0;
}
