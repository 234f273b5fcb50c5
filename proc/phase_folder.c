#include "proc/phase_folder.h"

#include "proc/proc_error.h"

#include <math.h>
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
ds_phase_folder_open (const char *dir, DsSidecarReader read_sidecar, GError **error)
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
  f->black_files = g_ptr_array_new_with_free_func (g_free);
  f->frames = g_array_new (FALSE, TRUE, sizeof (DsPhaseFolderFrame));
  f->skipped = g_ptr_array_new_with_free_func (g_free);
  f->sidecar.saturation_dn = f->sidecar.period_px = f->sidecar.duty = f->sidecar.black_level = f->sidecar.edge_blur_px = f->sidecar.harmonic_gain = NAN;
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
  g_autofree char *sidecar = g_build_filename (dir, "frames.json", NULL);
  if (g_file_test (sidecar, G_FILE_TEST_EXISTS)) {
    /* the sidecar's lists replace the names' guesses */
    g_ptr_array_set_size (f->phase_files, 0);
    g_clear_pointer (&f->black_file, g_free);
    if (!ds_phase_folder_read_sidecar (f, sidecar, read_sidecar, error))
      return NULL;
    for (guint i = 0; i < f->frames->len; i++)
      g_ptr_array_add (f->phase_files, g_strdup (g_array_index (f->frames, DsPhaseFolderFrame, i).file));
    if (f->black_files->len)
      f->black_file = g_strdup (f->black_files->pdata[0]);
    return g_steal_pointer (&f);
  }
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
  for (guint k = 0; k < f->phase_files->len; k++) {
    DsPhaseFolderFrame fr = { .file = g_strdup (f->phase_files->pdata[k]), .phase = k };
    g_array_append_val (f->frames, fr);
  }
  f->n_phases = f->phase_files->len;
  if (f->black_file)
    g_ptr_array_add (f->black_files, g_strdup (f->black_file));
  return g_steal_pointer (&f);
}

void
ds_phase_folder_free (DsPhaseFolder *folder)
{
  if (!folder)
    return;
  g_free (folder->dir);
  if (folder->frames) {
    for (guint i = 0; i < folder->frames->len; i++)
      g_free (g_array_index (folder->frames, DsPhaseFolderFrame, i).file);
    g_array_unref (folder->frames);
  }
  if (folder->black_files)
    g_ptr_array_unref (folder->black_files);
  g_free (folder->sidecar.producer);
  g_free (folder->sidecar.pixel_format);
  g_free (folder->sidecar.estimator);
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
  return folder->n_phases;
}

guint
ds_phase_folder_n_frames (const DsPhaseFolder *folder)
{
  return folder->frames->len;
}

const DsPhaseFolderFrame *
ds_phase_folder_frame (const DsPhaseFolder *folder, guint i)
{
  return i < folder->frames->len ? &g_array_index (folder->frames, DsPhaseFolderFrame, i) : NULL;
}

gboolean
ds_phase_folder_set_bit_depth (DsPhaseFolder *folder, guint bits, GError **error)
{
  if (bits < 1 || bits > 16) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "bit depth %u is outside 1..16", bits);
    return FALSE;
  }
  folder->bit_depth = bits;
  return TRUE;
}

/* Gives an integer image the folder's bit depth after checking its samples fit. */
static gboolean
apply_bit_depth (DsPhaseFolder *f, DsImage *img, const char *name, GError **error)
{
  guint d = f->bit_depth;
  if (d == 0 || d == 32)
    return TRUE;
  if (img->type == DS_SAMPLE_F32 || d > img->bit_depth) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT,
                 "%s: %s is %s with %u bits, which cannot hold %u-bit samples%s", f->dir, name,
                 ds_sample_type_name (img->type), img->bit_depth, d,
                 f->sidecar.present ? " (frames.json bit_depth)" : "");
    return FALSE;
  }
  guint top = (1u << d) - 1u;
  for (guint y = 0; y < img->height; y++)
    for (guint x = 0; x < img->width; x++) {
      guint v = img->type == DS_SAMPLE_U8 ? ((const guint8 *) ds_image_row (img, y))[x]
                                          : ((const guint16 *) ds_image_row (img, y))[x];
      if (v > top) {
        g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT,
                     "%s: %s pixel (%u, %u) is %u, above %u, the largest %u-bit value%s", f->dir, name,
                     x, y, v, top, d, f->sidecar.present ? " (frames.json bit_depth)" : "");
        return FALSE;
      }
    }
  img->bit_depth = d;
  return TRUE;
}

static DsImage *
read_checked (DsPhaseFolder *f, const char *name, GError **error)
{
  g_autofree char *path = g_build_filename (f->dir, name, NULL);
  g_autoptr (DsImage) img = ds_image_read (path, error); /* the error names the path */
  if (!img)
    return NULL;
  const DsPhaseFolderSidecar *sc = &f->sidecar;
  if (sc->present && (img->width != sc->width || img->height != sc->height)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "%s: %s is %ux%u, frames.json says width %u, height %u", f->dir, name, img->width,
                 img->height, sc->width, sc->height);
    return NULL;
  }
  if (sc->present && sc->bit_depth == 32 && img->type != DS_SAMPLE_F32) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT,
                 "%s: %s has %s samples, frames.json bit_depth 32 says float", f->dir, name,
                 ds_sample_type_name (img->type));
    return NULL;
  }
  if (!apply_bit_depth (f, img, name, error))
    return NULL;
  if (!f->have_reference) {
    f->have_reference = TRUE;
    f->width = img->width;
    f->height = img->height;
    f->type = img->type;
    f->ref_bit_depth = img->bit_depth;
    f->reference_file = g_strdup (name);
    return g_steal_pointer (&img);
  }
  if (img->width != f->width || img->height != f->height || img->type != f->type ||
      img->bit_depth != f->ref_bit_depth) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "%s: %s is %ux%u %s (%u bits) but %s is %ux%u %s (%u bits); all images of a set "
                 "must match",
                 f->dir, name, img->width, img->height, ds_sample_type_name (img->type), img->bit_depth,
                 f->reference_file, f->width, f->height, ds_sample_type_name (f->type), f->ref_bit_depth);
    return NULL;
  }
  return g_steal_pointer (&img);
}

DsImage *
ds_phase_folder_read (DsPhaseFolder *folder, guint i, GError **error)
{
  if (i >= folder->frames->len) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "%s: no frame %u (there are %u)",
                 folder->dir, i, folder->frames->len);
    return NULL;
  }
  return read_checked (folder, g_array_index (folder->frames, DsPhaseFolderFrame, i).file, error);
}

DsImage *
ds_phase_folder_read_black (DsPhaseFolder *folder, GError **error)
{
  if (!folder->black_file) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "%s: no black frame", folder->dir);
    return NULL;
  }
  guint n = folder->black_files->len;
  g_autoptr (DsImage) first = read_checked (folder, folder->black_files->pdata[0], error);
  if (!first || n == 1)
    return g_steal_pointer (&first);
  /* Averaged as descatterd averages its dark frames: a double sum, integers rounded. */
  gsize w = first->width;
  g_autofree double *sum = g_new0 (double, w * first->height);
  for (guint i = 0; i < n; i++) {
    g_autoptr (DsImage) img = i == 0 ? g_steal_pointer (&first) : read_checked (folder, folder->black_files->pdata[i], error);
    if (!img)
      return NULL;
    for (guint y = 0; y < img->height; y++) {
      const void *row = ds_image_row (img, y);
      for (guint x = 0; x < img->width; x++)
        sum[y * w + x] += img->type == DS_SAMPLE_U8    ? ((const guint8 *) row)[x]
                          : img->type == DS_SAMPLE_U16 ? ((const guint16 *) row)[x]
                                                       : ((const float *) row)[x];
    }
    if (i + 1 == n) {
      g_autoptr (DsImage) dark = ds_image_new (img->type, img->width, img->height, error);
      if (!dark)
        return NULL;
      dark->bit_depth = img->bit_depth;
      for (guint y = 0; y < img->height; y++)
        for (guint x = 0; x < img->width; x++) {
          double v = sum[y * w + x] / n;
          void *row = ds_image_row (dark, y);
          if (img->type == DS_SAMPLE_F32)
            ((float *) row)[x] = (float) v;
          else if (img->type == DS_SAMPLE_U16)
            ((guint16 *) row)[x] = (guint16) CLAMP (v + 0.5, 0, 65535);
          else
            ((guint8 *) row)[x] = (guint8) CLAMP (v + 0.5, 0, 255);
        }
      return g_steal_pointer (&dark);
    }
  }
  return NULL;
}
