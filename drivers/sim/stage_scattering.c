/* Scattering stage (built when the medium has sigma_s > 0): the light that scatters in the
 * slab and still leaves the far face inside the lens' acceptance cone, as the incident light
 * convolved (DFT, OpenCV bridge) with the slab's point-spread function.
 *
 * Objects on a plane at depth z split the slab (docs/scene-format.md, "Objects inside the
 * medium"):
 *   s1   = incident (*) PSF_before          scattered light reaching the plane, any direction
 *   at_z = (incident T_in exp(-sigma_t z) + s1) O      both pass the object
 *   out  = at_z (*) PSF_after + s1 O exp(-sigma_t (d - z)) T_out kappa
 * The approximation: PSF_after is for a normally incident beam, but s1 arrives diffuse; the
 * last term lets diffuse light that crosses the rest unscattered in, weighted by the share
 * kappa = (sin(theta_accept) / n)^2 of a Lambertian flux inside the acceptance cone. Light the
 * second part sends back into the first is lost. Objects at z = 0 shade the incident light,
 * at z = d the leaving light. */
#include <math.h>
#include <string.h>

#include "drivers/sim/sim_error.h"
#include "drivers/sim/stage.h"
#include "proc/cv_bridge.h"

typedef enum { PLANE_NONE, PLANE_ENTRY, PLANE_EXIT, PLANE_INSIDE } Plane;

typedef struct {
  DsImage *psf_full, *psf_before, *psf_after;
  double *marginal_full, *marginal_before; /* column sums of the kernels (see convolve_rows) */
  const DsImage *objects; /* borrowed from the objects stage, NULL without objects */
  Plane plane;
  double t_in, t_out, b1, b2, kappa;
} ScatterData;

static gboolean
convolve (const DsImage *src, const DsImage *psf, DsImage *dst, GError **error)
{
  DsCvView vs = { (int) src->width, (int) src->height, DS_CV_F32, src->stride, src->data };
  DsCvView vk = { (int) psf->width, (int) psf->height, DS_CV_F32, psf->stride, psf->data };
  DsCvView vd = { (int) dst->width, (int) dst->height, DS_CV_F32, dst->stride, dst->data };
  char err[256];
  if (ds_cv_convolve_f32 (&vs, &vk, DS_CV_BORDER_REFLECT, &vd, err, sizeof err) != 0) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_NUMERIC, "scattering convolution: %s", err);
    return FALSE;
  }
  return TRUE;
}

/* The incident light varies along x only (stripes; objects come later), so its 2-D convolution
 * is the 1-D convolution of one row with the kernel's column sums, the same on every row: a
 * few thousand operations per row instead of a DFT. Rows are taken from row 0 of src, which
 * the caller guarantees is like every other row. Reflecting border, as the DFT path. */
static void
convolve_rows (const DsImage *src, const double *marginal, guint kw, DsImage *dst)
{
  int w = (int) src->width, r = (int) kw / 2;
  const float *in = ds_image_row (src, 0);
  float *out0 = ds_image_row (dst, 0);
  for (int x = 0; x < w; x++) {
    double acc = 0;
    for (int d = -r; d <= r; d++) {
      int i = x - d;
      if (i < 0)
        i = -i - 1;
      else if (i >= w)
        i = 2 * w - i - 1;
      acc += in[CLAMP (i, 0, w - 1)] * marginal[d + r];
    }
    out0[x] = (float) acc;
  }
  for (guint y = 1; y < dst->height; y++)
    memcpy (ds_image_row (dst, y), out0, dst->width * sizeof (float));
}

static double *
column_sums (const DsImage *k)
{
  double *m = g_new0 (double, k->width);
  for (guint y = 0; y < k->height; y++) {
    const float *row = ds_image_row (k, y);
    for (guint x = 0; x < k->width; x++)
      m[x] += row[x];
  }
  return m;
}

/* dst = a * o * k1 + c * k2 per pixel (o, c may be NULL: 1 and 0). */
static void
combine (DsImage *dst, const DsImage *a, double k1, const DsImage *o, const DsImage *c, double k2)
{
  for (guint y = 0; y < dst->height; y++) {
    float *d = ds_image_row (dst, y);
    const float *ar = ds_image_row (a, y), *orow = o ? ds_image_row (o, y) : NULL;
    const float *cr = c ? ds_image_row (c, y) : NULL;
    for (guint x = 0; x < dst->width; x++)
      d[x] = (float) (ar[x] * k1 * (orow ? orow[x] : 1.0f) + (cr ? cr[x] * k2 : 0.0));
  }
}

static gboolean
scattering_apply (const DsStage *st, DsLight *l, const DsStageArgs *a, GError **error)
{
  (void) a;
  const ScatterData *d = st->data;
  guint w = l->incident->width, h = l->incident->height, m = l->margin;
  g_autoptr (DsImage) out = ds_image_new (DS_SAMPLE_F32, w, h, error);
  if (!out)
    return FALSE;
  switch (d->plane) {
  case PLANE_NONE:
    convolve_rows (l->incident, d->marginal_full, d->psf_full->width, out);
    break;
  case PLANE_ENTRY: {
    g_autoptr (DsImage) shaded = ds_image_new (DS_SAMPLE_F32, w, h, error);
    if (!shaded)
      return FALSE;
    combine (shaded, l->incident, 1.0, d->objects, NULL, 0);
    if (!convolve (shaded, d->psf_full, out, error))
      return FALSE;
    break;
  }
  case PLANE_EXIT:
    convolve_rows (l->incident, d->marginal_full, d->psf_full->width, out);
    combine (out, out, 1.0, d->objects, NULL, 0);
    break;
  case PLANE_INSIDE: {
    g_autoptr (DsImage) s1 = ds_image_new (DS_SAMPLE_F32, w, h, error);
    g_autoptr (DsImage) at_z = s1 ? ds_image_new (DS_SAMPLE_F32, w, h, error) : NULL;
    if (!at_z)
      return FALSE;
    convolve_rows (l->incident, d->marginal_before, d->psf_before->width, s1);
    combine (s1, s1, 1.0, d->objects, NULL, 0); /* s1 O from here on */
    combine (at_z, l->incident, d->t_in * d->b1, d->objects, s1, 1.0);
    if (!convolve (at_z, d->psf_after, out, error))
      return FALSE;
    combine (out, out, 1.0, NULL, s1, d->b2 * d->t_out * d->kappa);
    break;
  }
  }
  for (guint y = 0; y < l->scattered->height; y++)
    memcpy (ds_image_row (l->scattered, y), (const float *) ds_image_row (out, y + m) + m,
            l->scattered->width * sizeof (float));
  return TRUE;
}

guint
ds_stage_scattering_margin (const DsImage *psf_full, const DsImage *psf_before, const DsImage *psf_after)
{
  guint r = 0;
  const DsImage *k[] = { psf_full, psf_before, psf_after };
  for (guint i = 0; i < 3; i++)
    if (k[i])
      r = MAX (r, MAX (k[i]->width, k[i]->height) / 2);
  return r;
}

static void
scatter_free (gpointer p)
{
  ScatterData *d = p;
  ds_image_free (d->psf_full);
  ds_image_free (d->psf_before);
  ds_image_free (d->psf_after);
  g_free (d->marginal_full);
  g_free (d->marginal_before);
  g_free (d);
}

static gboolean
check_kernel (const DsImage *k, const char *what, const DsSceneSpec *s, GError **error)
{
  if (!k || k->type != DS_SAMPLE_F32 || k->width != k->height || k->width % 2 == 0 || k->width > s->width ||
      k->height > s->height) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID,
                 "scattering: %s kernel must be f32, square, odd and no larger than the %ux%u frame", what,
                 s->width, s->height);
    return FALSE;
  }
  return TRUE;
}

DsStage *
ds_stage_scattering_new (const DsSceneSpec *s, const DsStage *objects, const DsImage *psf_full,
                         const DsImage *psf_before, const DsImage *psf_after, const char *how, GError **error)
{
  ScatterData *d = g_new0 (ScatterData, 1);
  d->objects = objects ? ds_stage_objects_map (objects) : NULL;
  double z = objects ? s->objects[0].depth_mm : 0.0, sigma_t = s->mua + s->mus;
  d->plane = !objects ? PLANE_NONE : z <= 0 ? PLANE_ENTRY : z >= s->thickness_mm ? PLANE_EXIT : PLANE_INSIDE;
  double r = (s->n_medium - 1.0) / (s->n_medium + 1.0);
  d->t_in = d->t_out = 1.0 - r * r;
  d->b1 = exp (-sigma_t * z);
  d->b2 = exp (-sigma_t * (s->thickness_mm - z));
  double sa = sin (s->acceptance_half_angle_deg * G_PI / 180.0) / s->n_medium;
  d->kappa = sa * sa;
  gboolean ok;
  if (d->plane == PLANE_INSIDE)
    ok = check_kernel (psf_before, "before-object", s, error) && check_kernel (psf_after, "after-object", s, error);
  else
    ok = check_kernel (psf_full, "whole-slab", s, error);
  if (!ok) {
    g_free (d);
    return NULL;
  }
  if (d->plane == PLANE_INSIDE) {
    d->psf_before = ds_image_copy (psf_before, NULL);
    d->psf_after = ds_image_copy (psf_after, NULL);
    d->marginal_before = column_sums (psf_before);
  } else {
    d->psf_full = ds_image_copy (psf_full, NULL);
    d->marginal_full = column_sums (psf_full);
  }
  DsStage *st = g_new0 (DsStage, 1);
  st->kind = DS_RENDER_STAGE_SCATTERING;
  static const char *const planes[] = { "whole slab", "objects at the entry face", "objects at the exit face",
                                        "slab split at the object plane" };
  st->reason = g_strdup_printf ("medium sigma_s = %g /mm, g = %g, %g mm: %s PSF%s (%s)", s->mus, s->g,
                                s->thickness_mm, how, d->plane == PLANE_INSIDE ? "s" : "", planes[d->plane]);
  st->apply = scattering_apply;
  st->data = d;
  st->free_data = scatter_free;
  return st;
}
