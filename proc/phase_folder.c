#include "proc/phase_folder.h"

#include "proc/proc_error.h"

#include <string.h>

static const char *const image_exts[] = { "png", "tif", "tiff", "bmp", "jpg", "jpeg", "pgm" };
/* Outputs of the authors' scripts and of descatterctl separate. */
static const char *const output_names[] = {
  "direct", "global", "max", "min", "mean", "transmissive", "scattered", "mask",
  "sigma_transmissive", "sigma_scattered",
};

int
ds_natural_compare (const char *a, const char *b)
{
  const char *pa = a, *pb = b;
  while (*pa && *pb) {
    if (g_ascii_isdigit (*pa) && g_ascii_isdigit (*pb)) {
      while (*pa == '0')
        pa++;
      while (*pb == '0')
        pb++;
      const char *ea = pa, *eb = pb;
      while (g_ascii_isdigit (*ea))
        ea++;
      while (g_ascii_isdigit (*eb))
        eb++;
      if (ea - pa != eb - pb)
        return ea - pa < eb - pb ? -1 : 1;
      int c = strncmp (pa, pb, (size_t) (ea - pa));
      if (c != 0)
        return c < 0 ? -1 : 1;
      pa = ea;
      pb = eb;
      continue;
    }
    int ca = g_ascii_tolower (*pa), cb = g_ascii_tolower (*pb);
    if (ca != cb)
      return ca < cb ? -1 : 1;
    pa++;
    pb++;
  }
  if (*pa || *pb)
    return *pa ? 1 : -1;
  int c = strcmp (a, b); /* "img01" vs "img1": still a total order */
  return c < 0 ? -1 : c > 0 ? 1 : 0;
}

static gint
compare_names (gconstpointer a, gconstpointer b)
{
  return ds_natural_compare (*(const char *const *) a, *(const char *const *) b);
}

/* The lower-cased stem when name is an image file, else NULL. */
static char *
image_stem (const char *name)
{
  const char *dot = strrchr (name, '.');
  if (!dot || dot == name)
    return NULL;
  for (gsize i = 0; i < G_N_ELEMENTS (image_exts); i++)
    if (g_ascii_strcasecmp (dot + 1, image_exts[i]) == 0)
      return g_ascii_strdown (name, dot - name);
  return NULL;
}

DsPhaseFolder *
ds_phase_folder_open (const char *dir, GError **error)
{
  GError *local = NULL;
  g_autoptr (GDir) d = g_dir_open (dir, 0, &local);
  if (!d) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_IO, "%s: cannot read folder: %s", dir, local->message);
    g_error_free (local);
    return NULL;
  }
  g_autoptr (DsPhaseFolder) f = g_new0 (DsPhaseFolder, 1);
  f->dir = g_strdup (dir);
  f->phase_files = g_ptr_array_new_with_free_func (g_free);
  f->skipped = g_ptr_array_new_with_free_func (g_free);
  guint others = 0;
  const char *name;
  while ((name = g_dir_read_name (d))) {
    if (name[0] == '.')
      continue;
    g_autofree char *stem = image_stem (name);
    if (!stem) {
      others++;
      continue;
    }
    g_autofree char *path = g_build_filename (dir, name, NULL);
    if (!g_file_test (path, G_FILE_TEST_IS_REGULAR)) {
      others++;
      continue;
    }
    if (strcmp (stem, "black") == 0) {
      if (f->black_file) {
        g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                     "%s: two black frames, %s and %s; keep one", dir, f->black_file, name);
        return NULL;
      }
      f->black_file = g_strdup (name);
      continue;
    }
    if (strcmp (stem, "white") == 0) {
      g_free (f->white_file);
      f->white_file = g_strdup (name);
      continue;
    }
    gboolean output = g_str_has_prefix (stem, "truth") || g_str_has_suffix (stem, "-preview");
    for (gsize i = 0; !output && i < G_N_ELEMENTS (output_names); i++)
      output = strcmp (stem, output_names[i]) == 0;
    if (output) {
      g_ptr_array_add (f->skipped, g_strdup (name));
      continue;
    }
    g_ptr_array_add (f->phase_files, g_strdup (name));
  }
  g_ptr_array_sort (f->phase_files, compare_names);
  g_ptr_array_sort (f->skipped, compare_names);
  if (f->phase_files->len == 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY,
                 "%s: no phase images (.png .tif .tiff .bmp .jpg .jpeg .pgm); skipped %u earlier "
                 "outputs, %s black, %s white, %u other files",
                 dir, f->skipped->len, f->black_file ? "a" : "no", f->white_file ? "a" : "no", others);
    return NULL;
  }
  if (f->phase_files->len == 1) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_NOT_ENOUGH_PHASES,
                 "%s: only one phase image (%s); a separation needs at least 2", dir,
                 (const char *) f->phase_files->pdata[0]);
    return NULL;
  }
  return g_steal_pointer (&f);
}

void
ds_phase_folder_free (DsPhaseFolder *folder)
{
  if (!folder)
    return;
  g_free (folder->dir);
  if (folder->phase_files)
    g_ptr_array_unref (folder->phase_files);
  if (folder->skipped)
    g_ptr_array_unref (folder->skipped);
  g_free (folder->black_file);
  g_free (folder->white_file);
  g_free (folder->reference_file);
  g_free (folder);
}

guint
ds_phase_folder_n_phases (const DsPhaseFolder *folder)
{
  return folder->phase_files->len;
}

static DsImage *
read_checked (DsPhaseFolder *f, const char *name, GError **error)
{
  g_autofree char *path = g_build_filename (f->dir, name, NULL);
  DsImage *img = ds_image_read (path, error); /* the error names the path */
  if (!img)
    return NULL;
  if (!f->have_reference) {
    f->have_reference = TRUE;
    f->width = img->width;
    f->height = img->height;
    f->type = img->type;
    f->bit_depth = img->bit_depth;
    f->reference_file = g_strdup (name);
    return img;
  }
  if (img->width != f->width || img->height != f->height || img->type != f->type ||
      img->bit_depth != f->bit_depth) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "%s: %s is %ux%u %s (%u bits) but %s is %ux%u %s (%u bits); all images of a set "
                 "must match",
                 f->dir, name, img->width, img->height, ds_sample_type_name (img->type), img->bit_depth,
                 f->reference_file, f->width, f->height, ds_sample_type_name (f->type), f->bit_depth);
    ds_image_free (img);
    return NULL;
  }
  return img;
}

DsImage *
ds_phase_folder_read (DsPhaseFolder *folder, guint k, GError **error)
{
  if (k >= folder->phase_files->len) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "%s: no phase %u (there are %u)",
                 folder->dir, k, folder->phase_files->len);
    return NULL;
  }
  return read_checked (folder, folder->phase_files->pdata[k], error);
}

DsImage *
ds_phase_folder_read_black (DsPhaseFolder *folder, GError **error)
{
  if (!folder->black_file) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "%s: no black frame", folder->dir);
    return NULL;
  }
  return read_checked (folder, folder->black_file, error);
}
