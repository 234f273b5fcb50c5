/* On-disk cache of slab PSFs. A Monte Carlo PSF costs seconds to minutes and is a pure
 * function of its parameters, so it is computed once per parameter set.
 *
 * File: "DSPSF001" | key (64 hex chars) | side (u32 LE) | side^2 float32 | SHA-256 (32 bytes)
 * of everything before it. The key repeats inside the file so that a hash collision of the
 * file name, a truncated write or a flipped bit all read as "not cached". */
#include <errno.h>
#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "drivers/sim/sim_error.h"
#include "drivers/sim/transport.h"

/* Bump whenever the physics or the file layout changes: old files then miss. */
#define DS_TRANSPORT_CODE_VERSION "ds-transport-4"
#define DS_PSF_MAGIC "DSPSF001"
#define DS_PSF_MAGIC_LEN 8
#define DS_PSF_KEY_LEN 64
#define DS_PSF_SUM_LEN 32

static char *
psf_key (DsTransportModel model, const DsSlab *s, const DsPsfGrid *g, guint64 photons, guint64 seed)
{
  g_autoptr (GString) k = g_string_new (DS_TRANSPORT_CODE_VERSION);
  g_string_append_printf (k, " model=%d mua=%.17g mus=%.17g g=%.17g d=%.17g n=%.17g/%.17g/%.17g"
                          " pitch=%.17g r=%u accept=%.17g", (int) model, s->mua, s->mus, s->g,
                          s->thickness_mm, s->n_medium, s->n_above, s->n_below, g->pixel_pitch_mm,
                          g->radius_px, g->acceptance_half_angle_deg);
  if (model == DS_TRANSPORT_MONTE_CARLO)
    g_string_append_printf (k, " photons=%" G_GUINT64_FORMAT " seed=%" G_GUINT64_FORMAT, photons, seed);
  return g_compute_checksum_for_string (G_CHECKSUM_SHA256, k->str, -1);
}

static char *
cache_folder (const char *cache_dir)
{
  if (cache_dir)
    return g_strdup (cache_dir);
  const char *xdg = g_getenv ("XDG_CACHE_HOME");
  if (xdg && g_path_is_absolute (xdg))
    return g_build_filename (xdg, "descatter", "psf", NULL);
  return g_build_filename (g_get_user_cache_dir (), "descatter", "psf", NULL);
}

static void
sha256 (const guint8 *data, gsize len, guint8 out[DS_PSF_SUM_LEN])
{
  g_autoptr (GChecksum) c = g_checksum_new (G_CHECKSUM_SHA256);
  g_checksum_update (c, data, len);
  gsize n = DS_PSF_SUM_LEN;
  g_checksum_get_digest (c, out, &n);
}

/* The cached PSF, or NULL when the file is absent, damaged or not this key's. */
static DsImage *
cache_read (const char *path, const char *key, guint side)
{
  gsize pixels = (gsize) side * side;
  gsize body = DS_PSF_MAGIC_LEN + DS_PSF_KEY_LEN + 4 + pixels * sizeof (float);
  /* Size first: a stray huge file under our name is not read into memory. */
  GStatBuf st;
  if (g_stat (path, &st) != 0 || (guint64) st.st_size != body + DS_PSF_SUM_LEN)
    return NULL;
  g_autofree guint8 *buf = NULL;
  gsize len = 0;
  if (!g_file_get_contents (path, (char **) &buf, &len, NULL))
    return NULL;
  if (len != body + DS_PSF_SUM_LEN || memcmp (buf, DS_PSF_MAGIC, DS_PSF_MAGIC_LEN) != 0 ||
      memcmp (buf + DS_PSF_MAGIC_LEN, key, DS_PSF_KEY_LEN) != 0)
    return NULL;
  guint8 sum[DS_PSF_SUM_LEN];
  sha256 (buf, body, sum);
  if (memcmp (sum, buf + body, DS_PSF_SUM_LEN) != 0)
    return NULL;
  const guint8 *p = buf + DS_PSF_MAGIC_LEN + DS_PSF_KEY_LEN;
  guint32 stored_side = (guint32) p[0] | (guint32) p[1] << 8 | (guint32) p[2] << 16 | (guint32) p[3] << 24;
  if (stored_side != side)
    return NULL;
  p += 4;
  DsImage *psf = ds_image_new (DS_SAMPLE_F32, side, side, NULL);
  if (!psf)
    return NULL;
  for (guint y = 0; y < side; y++) {
    float *row = ds_image_row (psf, y);
    memcpy (row, p + (gsize) y * side * sizeof (float), side * sizeof (float));
    for (guint x = 0; x < side; x++)
      if (!isfinite (row[x]) || row[x] < 0) {
        ds_image_free (psf);
        return NULL;
      }
  }
  return psf;
}

static gboolean
cache_write (const char *path, const char *key, const DsImage *psf, GError **error)
{
  guint side = psf->width;
  gsize pixels = (gsize) side * side;
  gsize body = DS_PSF_MAGIC_LEN + DS_PSF_KEY_LEN + 4 + pixels * sizeof (float);
  g_autofree guint8 *buf = g_malloc (body + DS_PSF_SUM_LEN);
  memcpy (buf, DS_PSF_MAGIC, DS_PSF_MAGIC_LEN);
  memcpy (buf + DS_PSF_MAGIC_LEN, key, DS_PSF_KEY_LEN);
  guint8 *p = buf + DS_PSF_MAGIC_LEN + DS_PSF_KEY_LEN;
  for (int i = 0; i < 4; i++)
    p[i] = (guint8) (side >> (8 * i));
  p += 4;
  for (guint y = 0; y < side; y++)
    memcpy (p + (gsize) y * side * sizeof (float), ds_image_row (psf, y), side * sizeof (float));
  sha256 (buf, body, buf + body);
  /* Temporary file in the same folder, fsynced, renamed over the final name. */
  return g_file_set_contents_full (path, (const char *) buf, (gssize) (body + DS_PSF_SUM_LEN),
                                   G_FILE_SET_CONTENTS_CONSISTENT, 0644, error);
}

DsImage *
ds_slab_psf_cached (DsTransportModel model, const DsSlab *slab, const DsPsfGrid *grid,
                    guint64 photons, guint64 seed, const char *cache_dir, gboolean *from_cache,
                    GError **error)
{
  if (from_cache)
    *from_cache = FALSE;
  if (model != DS_TRANSPORT_MONTE_CARLO && model != DS_TRANSPORT_DIFFUSION) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "psf: unknown transport model %d",
                 (int) model);
    return NULL;
  }
  if (!ds_slab_validate (slab, error) || !ds_psf_grid_validate (grid, error))
    return NULL;
  g_autofree char *key = psf_key (model, slab, grid, photons, seed);
  g_autofree char *dir = cache_folder (cache_dir);
  g_autofree char *name = g_strconcat (key, ".psf", NULL);
  g_autofree char *path = g_build_filename (dir, name, NULL);
  guint side = 2 * grid->radius_px + 1;
  DsImage *psf = cache_read (path, key, side);
  if (psf) {
    if (from_cache)
      *from_cache = TRUE;
    return psf;
  }
  psf = model == DS_TRANSPORT_MONTE_CARLO ? ds_slab_psf_monte_carlo (slab, grid, photons, seed, error)
                                          : ds_slab_psf_diffusion (slab, grid, error);
  if (!psf)
    return NULL;
  g_autoptr (GError) werr = NULL;
  if (g_mkdir_with_parents (dir, 0755) != 0)
    g_message ("psf cache: cannot create %s: %s (PSF not cached)", dir, g_strerror (errno));
  else if (!cache_write (path, key, psf, &werr))
    g_message ("psf cache: %s (PSF not cached)", werr->message);
  return psf;
}
