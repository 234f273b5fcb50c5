/* On-disk cache of DsSlabKernels (the renderer's kernels with their chain through the object
 * planes): a Monte Carlo run costs seconds to minutes and is a pure function of its parameters.
 *
 * File: "DSKRN001" | key (64 hex chars) | body | SHA-256 (32 bytes) of everything before it.
 * body: radius u32, n_planes u32, depths f64[n], scattered_in_cone, se, held, energy_fraction
 * f64, photons, records u64, effective_records f64, per segment j = 0..n (when n > 0):
 * stays_ballistic f64, per plane: once_ballistic, once_scattered, recross_times[3] f64; then the
 * kernels, (2r+1)^2 float32
 * each: full, per segment from_ballistic and (j > 0) from_scattered, per plane
 * recross_ballistic and recross_scattered. All little-endian. A file
 * that does not parse to the end exactly, or holds a negative or non-finite value, is recomputed
 * and replaced, never trusted. */
#include <errno.h>
#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "drivers/sim/sim_error.h"
#include "drivers/sim/transport.h"

/* Bump whenever the physics or the layout changes: old files then miss. */
#define DS_KERNELS_CODE_VERSION "ds-kernels-5"
#define DS_KERNELS_MAGIC "DSKRN001"
#define MAGIC_LEN 8
#define KEY_LEN 64
#define SUM_LEN 32

static gboolean
uses_monte_carlo (const DsSlabKernelSpec *spec)
{
  return spec->model == DS_TRANSPORT_MONTE_CARLO || spec->planes.n_planes > 0;
}

static char *
kernels_key (const DsSlab *s, const DsSlabKernelSpec *spec)
{
  g_autoptr (GString) k = g_string_new (DS_KERNELS_CODE_VERSION);
  g_string_append_printf (k, " model=%d mua=%.17g mus=%.17g g=%.17g d=%.17g n=%.17g/%.17g/%.17g pitch=%.17g"
                          " accept=%.17g energy=%.17g planes=%u", (int) spec->model, s->mua, s->mus, s->g,
                          s->thickness_mm, s->n_medium, s->n_above, s->n_below, spec->pixel_pitch_mm,
                          spec->acceptance_half_angle_deg, spec->energy_fraction, spec->planes.n_planes);
  for (guint j = 0; j < spec->planes.n_planes; j++)
    g_string_append_printf (k, " z%u=%.17g", j, spec->planes.depth_mm[j]);
  if (uses_monte_carlo (spec))
    g_string_append_printf (k, " photons=%" G_GUINT64_FORMAT " seed=%" G_GUINT64_FORMAT, spec->photons, spec->seed);
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
sha256 (const guint8 *data, gsize len, guint8 out[SUM_LEN])
{
  g_autoptr (GChecksum) c = g_checksum_new (G_CHECKSUM_SHA256);
  g_checksum_update (c, data, len);
  gsize n = SUM_LEN;
  g_checksum_get_digest (c, out, &n);
}

static void
put_u64 (GByteArray *b, guint64 v)
{
  guint8 x[8];
  for (int i = 0; i < 8; i++)
    x[i] = (guint8) (v >> (8 * i));
  g_byte_array_append (b, x, 8);
}

static void
put_f64 (GByteArray *b, double v)
{
  guint64 u;
  memcpy (&u, &v, 8);
  put_u64 (b, u);
}

static void
put_u32 (GByteArray *b, guint32 v)
{
  guint8 x[4];
  for (int i = 0; i < 4; i++)
    x[i] = (guint8) (v >> (8 * i));
  g_byte_array_append (b, x, 4);
}

static void
put_kernel (GByteArray *b, const DsImage *k)
{
  for (guint y = 0; y < k->height; y++) {
    const float *row = ds_image_row (k, y);
    for (guint x = 0; x < k->width; x++) {
      guint32 u;
      memcpy (&u, &row[x], 4);
      put_u32 (b, u);
    }
  }
}

typedef struct {
  const guint8 *p;
  gsize left;
  gboolean ok;
} Cursor;

static guint64
get_u64 (Cursor *c)
{
  if (c->left < 8) {
    c->ok = FALSE;
    return 0;
  }
  guint64 v = 0;
  for (int i = 0; i < 8; i++)
    v |= (guint64) c->p[i] << (8 * i);
  c->p += 8;
  c->left -= 8;
  return v;
}

static double
get_f64 (Cursor *c)
{
  guint64 u = get_u64 (c);
  double v;
  memcpy (&v, &u, 8);
  if (!isfinite (v))
    c->ok = FALSE;
  return v;
}

static guint32
get_u32 (Cursor *c)
{
  if (c->left < 4) {
    c->ok = FALSE;
    return 0;
  }
  guint32 v = (guint32) c->p[0] | (guint32) c->p[1] << 8 | (guint32) c->p[2] << 16 | (guint32) c->p[3] << 24;
  c->p += 4;
  c->left -= 4;
  return v;
}

static DsImage *
get_kernel (Cursor *c, guint side)
{
  if (!c->ok || c->left < (gsize) side * side * 4) {
    c->ok = FALSE;
    return NULL;
  }
  DsImage *k = ds_image_new (DS_SAMPLE_F32, side, side, NULL);
  if (!k) {
    c->ok = FALSE;
    return NULL;
  }
  for (guint y = 0; y < side; y++) {
    float *row = ds_image_row (k, y);
    memcpy (row, c->p, side * sizeof (float));
    c->p += side * sizeof (float);
    c->left -= side * sizeof (float);
    for (guint x = 0; x < side; x++)
      if (!isfinite (row[x]) || row[x] < 0)
        c->ok = FALSE;
  }
  return k;
}

static GByteArray *
serialize (const DsSlabKernels *k, const char *key)
{
  GByteArray *b = g_byte_array_new ();
  g_byte_array_append (b, (const guint8 *) DS_KERNELS_MAGIC, MAGIC_LEN);
  g_byte_array_append (b, (const guint8 *) key, KEY_LEN);
  guint n = k->planes.n_planes;
  put_u32 (b, k->radius_px);
  put_u32 (b, n);
  for (guint j = 0; j < n; j++)
    put_f64 (b, k->planes.depth_mm[j]);
  put_f64 (b, k->scattered_in_cone);
  put_f64 (b, k->se_scattered_in_cone);
  put_f64 (b, k->held);
  put_f64 (b, k->energy_fraction);
  put_u64 (b, k->photons);
  put_u64 (b, k->records);
  put_f64 (b, k->effective_records);
  for (guint j = 0; n && j <= n; j++)
    put_f64 (b, k->segments[j].stays_ballistic);
  for (guint j = 0; j < n; j++) {
    const DsSlabPlaneCrossing *c = &k->crossings[j];
    put_f64 (b, c->once_ballistic);
    put_f64 (b, c->once_scattered);
    for (guint t = 0; t < DS_SLAB_RECROSS_CLASSES; t++)
      put_f64 (b, c->recross_times[t]);
  }
  put_kernel (b, k->full);
  for (guint j = 0; n && j <= n; j++) {
    put_kernel (b, k->segments[j].from_ballistic);
    if (j > 0)
      put_kernel (b, k->segments[j].from_scattered);
  }
  for (guint j = 0; j < n; j++) {
    put_kernel (b, k->crossings[j].recross_ballistic);
    put_kernel (b, k->crossings[j].recross_scattered);
  }
  guint8 sum[SUM_LEN];
  sha256 (b->data, b->len, sum);
  g_byte_array_append (b, sum, SUM_LEN);
  return b;
}

/* The cached kernels, or NULL when the file is absent, damaged or not this key's. */
static DsSlabKernels *
cache_read (const char *path, const char *key, const DsSlabKernelSpec *spec)
{
  /* A stray huge file under our name is not read into memory: (2 x 2048 + 1)^2 floats x 19 kernels
   * is the largest a valid file can be. */
  GStatBuf st;
  if (g_stat (path, &st) != 0 || st.st_size < MAGIC_LEN + KEY_LEN + SUM_LEN || st.st_size > ((gint64) 1 << 31))
    return NULL;
  g_autofree guint8 *buf = NULL;
  gsize len = 0;
  if (!g_file_get_contents (path, (char **) &buf, &len, NULL) || len < MAGIC_LEN + KEY_LEN + SUM_LEN)
    return NULL;
  gsize body = len - SUM_LEN;
  guint8 sum[SUM_LEN];
  sha256 (buf, body, sum);
  if (memcmp (buf, DS_KERNELS_MAGIC, MAGIC_LEN) != 0 || memcmp (buf + MAGIC_LEN, key, KEY_LEN) != 0 ||
      memcmp (sum, buf + body, SUM_LEN) != 0)
    return NULL;
  Cursor c = { buf + MAGIC_LEN + KEY_LEN, body - MAGIC_LEN - KEY_LEN, TRUE };
  g_autoptr (DsSlabKernels) k = g_new0 (DsSlabKernels, 1);
  k->model = spec->model;
  k->pixel_pitch_mm = spec->pixel_pitch_mm;
  k->acceptance_half_angle_deg = spec->acceptance_half_angle_deg;
  k->radius_px = get_u32 (&c);
  guint n = get_u32 (&c);
  if (!c.ok || k->radius_px > 2048 || n != spec->planes.n_planes)
    return NULL;
  k->planes.n_planes = n;
  for (guint j = 0; j < n; j++)
    k->planes.depth_mm[j] = get_f64 (&c);
  k->scattered_in_cone = get_f64 (&c);
  k->se_scattered_in_cone = get_f64 (&c);
  k->held = get_f64 (&c);
  k->energy_fraction = get_f64 (&c);
  k->photons = get_u64 (&c);
  k->records = get_u64 (&c);
  k->effective_records = get_f64 (&c);
  for (guint j = 0; n && j <= n; j++)
    k->segments[j].stays_ballistic = get_f64 (&c);
  for (guint j = 0; j < n; j++) {
    DsSlabPlaneCrossing *x = &k->crossings[j];
    x->once_ballistic = get_f64 (&c);
    x->once_scattered = get_f64 (&c);
    for (guint t = 0; t < DS_SLAB_RECROSS_CLASSES; t++)
      x->recross_times[t] = get_f64 (&c);
  }
  guint side = 2 * k->radius_px + 1;
  k->full = get_kernel (&c, side);
  for (guint j = 0; n && j <= n; j++) {
    k->segments[j].from_ballistic = get_kernel (&c, side);
    if (j > 0)
      k->segments[j].from_scattered = get_kernel (&c, side);
  }
  for (guint j = 0; j < n; j++) {
    k->crossings[j].recross_ballistic = get_kernel (&c, side);
    k->crossings[j].recross_scattered = get_kernel (&c, side);
  }
  if (!c.ok || c.left != 0)
    return NULL;
  return g_steal_pointer (&k);
}

DsSlabKernels *
ds_slab_kernels_cached (const DsSlab *slab, const DsSlabKernelSpec *spec, const char *cache_dir,
                        gboolean *from_cache, GError **error)
{
  if (from_cache)
    *from_cache = FALSE;
  if (!ds_slab_validate (slab, error) || !ds_slab_planes_validate (slab, &spec->planes, error))
    return NULL;
  g_autofree char *key = kernels_key (slab, spec);
  g_autofree char *dir = cache_folder (cache_dir);
  g_autofree char *name = g_strconcat (key, ".kernels", NULL);
  g_autofree char *path = g_build_filename (dir, name, NULL);
  DsSlabKernels *k = cache_read (path, key, spec);
  if (k) {
    if (from_cache)
      *from_cache = TRUE;
    return k;
  }
  k = ds_slab_kernels_compute (slab, spec, 0, error);
  if (!k)
    return NULL;
  g_autoptr (GError) werr = NULL;
  g_autoptr (GByteArray) bytes = serialize (k, key);
  if (g_mkdir_with_parents (dir, 0755) != 0)
    g_message ("kernel cache: cannot create %s: %s (kernels not cached)", dir, g_strerror (errno));
  else if (!g_file_set_contents_full (path, (const char *) bytes->data, (gssize) bytes->len,
                                      G_FILE_SET_CONTENTS_CONSISTENT, 0644, &werr))
    g_message ("kernel cache: %s (kernels not cached)", werr->message);
  return k;
}
