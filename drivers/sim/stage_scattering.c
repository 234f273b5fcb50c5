/* Scattering stage (built when the medium has sigma_s > 0): the light that scatters in the
 * slab and still leaves the far face inside the lens' acceptance cone.
 *
 * Without objects inside the medium it is the incident light convolved with the slab's kernel.
 * The incident light varies along x only (stripes), so that is one row convolved with the
 * kernel's column sums, exactly. Objects at the entry face shade the incident light first (a 2-D
 * convolution), objects at the exit face shade what leaves.
 *
 * Objects at depths inside the medium (docs/scene-format.md, "Objects inside the medium";
 * docs/transport.md, "Object planes"): the light is followed from plane to plane with the kernels
 * of one Monte Carlo run. At plane j the light first crossing it is B (still unscattered) and D
 * (scattered); the plane's map O acts there; the share crossing once goes on, the rest crosses
 * again and meets O^2 (O^4, O^6 for 5, 7+ crossings) where it last crosses:
 *   Xb = O B, Xd = O D,  Z = R^b (*) Xb + R^d (*) Xd
 *   B' = once_b Xb,      D' = once_d Xd + (t3 O^2 + t5 O^4 + t7 O^6) Z
 *   B  = beta B',        D  = K^b (*) B' + K^d (*) D'      (at the next plane, or the exit)
 * The chain is exact except for how the segments' displacements correlate and where the middle
 * crossings lie, so the stage renders
 *   out = K_full (*) inc + chain(O) - chain(1)
 * with chain(1) the same arithmetic on the stripes' single row: with every object clear it is
 * the object-free light to float rounding, and far from objects too. Negative values (the
 * factorization's error near an opaque object) are clipped to 0. Convolutions run at two scales
 * (two_scale.h). */
#include <math.h>
#include <string.h>

#include "drivers/sim/sim_error.h"
#include "drivers/sim/stage.h"
#include "drivers/sim/two_scale.h"

typedef struct {
  DsScale sc;
  guint n;                  /* interior planes */
  guint R;                  /* kernel radius */
  guint in_margin;          /* of the incident row */
  guint top;                /* level of the light entering the chain */
  double *marg_full;        /* column sums of the whole slab's kernel, 2R + 1 */
  double *marg_seg0;        /* of segment 0's kernel (entry -> plane 1) */
  DsScaleKernel *k_entry;   /* the whole kernel (n = 0) or segment 0's (n > 0), objects at the entry */
  DsScaleStep *step_entry;
  DsScaleKernel *k_seg_b[DS_SLAB_MAX_PLANES + 1], *k_seg_d[DS_SLAB_MAX_PLANES + 1];
  DsScaleKernel *k_rc_b[DS_SLAB_MAX_PLANES + 1], *k_rc_d[DS_SLAB_MAX_PLANES + 1];
  const DsScaleKernel *pair_seg[DS_SLAB_MAX_PLANES + 1][2], *pair_rc[DS_SLAB_MAX_PLANES + 1][2];
  DsScaleStep *step_seg[DS_SLAB_MAX_PLANES + 1], *step_rc[DS_SLAB_MAX_PLANES + 1];
  double beta[DS_SLAB_MAX_PLANES + 1], once_b[DS_SLAB_MAX_PLANES + 1], once_d[DS_SLAB_MAX_PLANES + 1];
  double again[DS_SLAB_MAX_PLANES + 1][7]; /* t3 O^2 + t5 O^4 + t7 O^6 as coefficients of O^0..O^6 */
  DsScaleMap entry, plane[DS_SLAB_MAX_PLANES + 1]; /* planes 1..n */
  gboolean has_entry;
  const DsImage *exit;      /* frame + map margin, or NULL */
  /* The objects stage's plane behind each map (entry, planes 1..n, exit), so that a frame's
   * moved maps (DsLight.moved) replace the ones made here. */
  guint entry_plane, plane_of[DS_SLAB_MAX_PLANES + 1], exit_plane;
  double depth_of[DS_SCENE_MAX_DEPTHS + 2]; /* of each objects-stage plane */
  guint map_margin;
  guint radius_px;
  double held, scattered_in_cone, se_scattered_in_cone, mtf, mtf_noise;
} ScatterData;

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

/* out[i] = sum_d m[r + d] in[x - d] for x = x0 + i, i < count (x in frame columns; the incident
 * row's column 0 is frame column -margin). */
static void
row_convolve (const float *in, guint margin, int x0, guint count, const double *m, guint r, float *out)
{
  for (guint i = 0; i < count; i++) {
    double acc = 0;
    const float *p = in + (x0 + (int) i + (int) margin) + (int) r;
    for (guint k = 0; k <= 2 * r; k++)
      acc += m[k] * p[-(int) k];
    out[i] = (float) acc;
  }
}

static const double identity[2] = { 0.0, 1.0 };

/* The chain through the interior planes over the frame (level 0), with the objects (*with) and
 * without (*clear: every field stays one row). The two run in step: beyond the blocks a field
 * with objects keeps, the object-free one stands for it (two_scale.h). d1_row: segment 0's
 * light at plane 1 (no entry objects), d1_x0 its first frame column. */
static gboolean
chain (const ScatterData *d, const DsLight *l, const DsScaleMap *entry, const DsScaleMap *planes,
       const float *d1_row, int d1_x0, DsField **with, DsField **clear, GError **error)
{
  const DsScale *sc = &d->sc;
  const float *in = ds_image_row (l->incident, 0);
  int in_x0 = -(int) d->in_margin;
  guint L = 2 * d->n;
  g_autoptr (DsField) b = NULL;
  g_autoptr (DsField) s = NULL;
  g_autoptr (DsField) b1 = NULL;
  g_autoptr (DsField) s1 = NULL;
  if (d->has_entry) {
    g_autoptr (DsField) inc = ds_field_from_row (sc, L + 1, in, in_x0, 1.0, error);
    g_autoptr (DsField) lit = inc ? ds_field_weigh (sc, inc, entry, identity, 2, L + 1, error) : NULL;
    if (!lit)
      return FALSE;
    const DsField *src1[1] = { inc }, *src[1] = { lit };
    if (!(s1 = ds_scale_step_apply (d->step_entry, src1, NULL, error)) ||
        !(b1 = ds_field_crop (sc, inc, L, d->beta[0], error)) ||
        !(s = ds_scale_step_apply (d->step_entry, src, src1, error)) ||
        !(b = ds_field_crop (sc, lit, L, d->beta[0], error)))
      return FALSE;
  } else {
    s1 = ds_field_from_row (sc, L, d1_row, d1_x0, 1.0, error);
    b1 = s1 ? ds_field_from_row (sc, L, in, in_x0, d->beta[0], error) : NULL;
    s = b1 ? ds_field_crop (sc, s1, L, 1, error) : NULL;
    b = s ? ds_field_crop (sc, b1, L, 1, error) : NULL;
    if (!b)
      return FALSE;
  }
  for (guint j = 1; j <= d->n; j++, L -= 2) {
    const DsScaleMap *map = &planes[j];
    /* Without objects. */
    g_autoptr (DsField) xb1 = ds_field_crop (sc, b1, L, 1, error);
    g_autoptr (DsField) xd1 = xb1 ? ds_field_crop (sc, s1, L, 1, error) : NULL;
    const DsField *x1[2] = { xb1, xd1 };
    g_autoptr (DsField) z1 = xd1 ? ds_scale_step_apply (d->step_rc[j], x1, NULL, error) : NULL;
    g_autoptr (DsField) bp1 = z1 ? ds_field_crop (sc, xb1, L - 1, d->once_b[j], error) : NULL;
    g_autoptr (DsField) dp1 = bp1 ? ds_field_crop (sc, xd1, L - 1, d->once_d[j], error) : NULL;
    if (!dp1)
      return FALSE;
    ds_field_add (sc, dp1, z1, 1.0);
    /* With them. */
    g_autoptr (DsField) xb = ds_field_weigh (sc, b, map, identity, 2, L, error);
    g_autoptr (DsField) xd = xb ? ds_field_weigh (sc, s, map, identity, 2, L, error) : NULL;
    const DsField *x[2] = { xb, xd };
    g_autoptr (DsField) z = xd ? ds_scale_step_apply (d->step_rc[j], x, x1, error) : NULL;
    g_autoptr (DsField) bp = z ? ds_field_crop (sc, xb, L - 1, d->once_b[j], error) : NULL;
    g_autoptr (DsField) dp = bp ? ds_field_crop (sc, xd, L - 1, d->once_d[j], error) : NULL;
    g_autoptr (DsField) q = dp ? ds_field_weigh (sc, z, map, d->again[j], 7, L - 1, error) : NULL;
    if (!q)
      return FALSE;
    ds_field_add (sc, dp, q, 1.0);
    const DsField *y1[2] = { bp1, dp1 }, *y[2] = { bp, dp };
    g_clear_pointer (&s1, ds_field_free);
    g_clear_pointer (&s, ds_field_free);
    if (!(s1 = ds_scale_step_apply (d->step_seg[j], y1, NULL, error)) ||
        !(s = ds_scale_step_apply (d->step_seg[j], y, y1, error)))
      return FALSE;
    g_clear_pointer (&b1, ds_field_free);
    g_clear_pointer (&b, ds_field_free);
    if (j < d->n && (!(b1 = ds_field_crop (sc, bp1, L - 2, d->beta[j], error)) ||
                     !(b = ds_field_crop (sc, bp, L - 2, d->beta[j], error))))
      return FALSE;
  }
  *with = g_steal_pointer (&s);
  *clear = g_steal_pointer (&s1);
  return TRUE;
}

/* The frame's maps: the ones made at construction, with those of planes a moving object is on
 * made again from the motion stage's maps (coarse blocks from the displaced shapes). */
struct FrameMaps {
  DsScaleMap entry, plane[DS_SLAB_MAX_PLANES + 1];
  const DsImage *exit;
  DsImage *owned[DS_SLAB_MAX_PLANES + 2];
};
typedef struct FrameMaps FrameMaps;

static gboolean
scatter_frame (const ScatterData *d, DsLight *l, const FrameMaps *fm, GError **error)
{
  guint W = l->direct->width, H = l->direct->height, M = d->in_margin;
  const float *in = ds_image_row (l->incident, 0);
  g_autofree float *full = g_new (float, W);
  row_convolve (in, M, 0, W, d->marg_full, d->R, full);
  if (d->n == 0 && !d->has_entry) {
    for (guint y = 0; y < H; y++)
      memcpy (ds_image_row (l->scattered, y), full, W * sizeof (float));
  } else if (d->n == 0) {
    g_autoptr (DsField) inc = ds_field_from_row (&d->sc, 1, in, -(int) M, 1.0, error);
    g_autoptr (DsField) lit = inc ? ds_field_weigh (&d->sc, inc, &fm->entry, identity, 2, 1, error) : NULL;
    const DsField *src[1] = { lit };
    g_autoptr (DsField) out = lit ? ds_scale_step_apply (d->step_entry, src, NULL, error) : NULL;
    if (!out)
      return FALSE;
    for (guint y = 0; y < H; y++)
      memcpy (ds_image_row (l->scattered, y), ds_image_row (out->fine, y), W * sizeof (float));
  } else {
    /* Segment 0's light at plane 1, exact along the row, as far as the top field reaches. */
    g_autofree float *d1 = NULL;
    int d1_x0 = 0;
    if (!d->has_entry) {
      guint reach = ds_scale_row_margin (&d->sc, d->top, 0);
      d1_x0 = -(int) reach;
      d1 = g_new (float, W + 2 * reach);
      row_convolve (in, M, d1_x0, W + 2 * reach, d->marg_seg0, d->R, d1);
    }
    g_autoptr (DsField) with = NULL;
    g_autoptr (DsField) clear = NULL;
    if (!chain (d, l, &fm->entry, fm->plane, d1, d1_x0, &with, &clear, error))
      return FALSE;
    const float *c1 = ds_image_row (clear->fine, 0);
    for (guint y = 0; y < H; y++) {
      const float *c = ds_image_row (with->fine, y);
      float *o = ds_image_row (l->scattered, y);
      for (guint x = 0; x < W; x++) {
        double v = (double) full[x] + ((double) c[x] - (double) c1[x]);
        o[x] = (float) MAX (v, 0.0);
      }
    }
  }
  if (fm->exit)
    for (guint y = 0; y < H; y++) {
      float *o = ds_image_row (l->scattered, y);
      const float *e = (const float *) ds_image_row (fm->exit, y + d->map_margin) + d->map_margin;
      for (guint x = 0; x < W; x++)
        o[x] *= e[x];
    }
  return TRUE;
}

static void
frame_maps_clear (FrameMaps *fm)
{
  for (guint i = 0; i < G_N_ELEMENTS (fm->owned); i++)
    ds_image_free (fm->owned[i]);
}

static gboolean
moved_map (const ScatterData *d, const DsMovedObjects *m, guint plane, DsScaleMap *map, DsImage **owned,
           GError **error)
{
  if (!m || !m->map[plane])
    return TRUE;
  map->fine = m->map[plane];
  if (d->sc.f > 1) {
    double depth = d->depth_of[plane];
    *owned = ds_stage_objects_coarse_map_of (&m->spec, map->fine, depth, d->sc.f, map->block_margin, error);
    map->coarse = *owned;
    return *owned != NULL;
  }
  return TRUE;
}

static gboolean
frame_maps (const ScatterData *d, const DsMovedObjects *m, FrameMaps *fm, GError **error)
{
  fm->entry = d->entry;
  memcpy (fm->plane, d->plane, sizeof fm->plane);
  fm->exit = d->exit;
  if (!m)
    return TRUE;
  if (d->has_entry && !moved_map (d, m, d->entry_plane, &fm->entry, &fm->owned[0], error))
    return FALSE;
  for (guint j = 1; j <= d->n; j++)
    if (!moved_map (d, m, d->plane_of[j], &fm->plane[j], &fm->owned[j], error))
      return FALSE;
  if (d->exit && m->map[d->exit_plane])
    fm->exit = m->map[d->exit_plane];
  return TRUE;
}

static gboolean
scattering_apply (const DsStage *st, DsLight *l, const DsStageArgs *a, GError **error)
{
  (void) a;
  const ScatterData *d = st->data;
  FrameMaps fm = { 0 };
  gboolean ok = frame_maps (d, l->moved, &fm, error) && scatter_frame (d, l, &fm, error);
  frame_maps_clear (&fm);
  return ok;
}

static gboolean
has_entry_objects (const DsSceneSpec *s)
{
  for (guint i = 0; i < s->n_objects; i++)
    if (s->objects[i].depth_mm <= 0)
      return TRUE;
  return FALSE;
}

/* Level of the light entering the chain: two steps per interior plane, one more for entry objects. */
static guint
top_level (guint n, gboolean entry)
{
  return 2 * n + (entry ? 1 : 0);
}

void
ds_stage_scattering_margins (const DsSceneSpec *s, const DsSlabKernels *k, guint *incident_margin, guint *map_margin)
{
  DsScale sc;
  ds_scale_init (&sc, k->radius_px, s->width, s->height);
  guint top = top_level (k->planes.n_planes, has_entry_objects (s));
  /* The row feeds fields up to the top level, segment 0's exact row (radius R) and K_full. */
  *incident_margin = MAX (ds_scale_row_margin (&sc, top, k->radius_px), k->radius_px);
  *map_margin = ds_scale_fine_margin (&sc, MAX (top, 1u));
}

static void
scatter_free (gpointer p)
{
  ScatterData *d = p;
  g_free (d->marg_full);
  g_free (d->marg_seg0);
  ds_scale_step_free (d->step_entry);
  ds_scale_kernel_free (d->k_entry);
  for (guint j = 0; j <= DS_SLAB_MAX_PLANES; j++) {
    ds_scale_step_free (d->step_seg[j]);
    ds_scale_step_free (d->step_rc[j]);
    ds_scale_kernel_free (d->k_seg_b[j]);
    ds_scale_kernel_free (d->k_seg_d[j]);
    ds_scale_kernel_free (d->k_rc_b[j]);
    ds_scale_kernel_free (d->k_rc_d[j]);
    ds_image_free (d->plane[j].coarse);
  }
  ds_image_free (d->entry.coarse);
  g_free (d);
}

static gboolean
check_kernel (const DsImage *k, guint side, const char *what, GError **error)
{
  if (!k || k->type != DS_SAMPLE_F32 || k->width != side || k->height != side) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "scattering: %s kernel must be f32 %ux%u", what, side,
                 side);
    return FALSE;
  }
  return TRUE;
}

static gboolean
make_map (ScatterData *d, const DsSceneSpec *s, const DsStage *objects, guint plane, guint top, DsScaleMap *map,
          GError **error)
{
  map->fine = ds_stage_objects_plane_map (objects, plane);
  map->fine_margin = d->map_margin;
  if (d->sc.f > 1) {
    map->block_margin = ds_scale_block_margin_2d (&d->sc, top);
    map->coarse = ds_stage_objects_coarse_map (s, objects, plane, d->sc.f, map->block_margin, error);
    return map->coarse != NULL;
  }
  return TRUE;
}

static gboolean
build_chain (ScatterData *d, const DsSlabKernels *k, GError **error)
{
  guint n = d->n, side = 2 * d->R + 1;
  for (guint j = 0; j <= n; j++) {
    const DsSlabSegment *g = &k->segments[j];
    g_autofree char *what = g_strdup_printf ("segment %u", j);
    if (!check_kernel (g->from_ballistic, side, what, error) ||
        (j > 0 && !check_kernel (g->from_scattered, side, what, error)))
      return FALSE;
    d->beta[j] = g->stays_ballistic;
    if (j == 0)
      continue;
    const DsSlabPlaneCrossing *c = &k->crossings[j - 1];
    g_autofree char *plane = g_strdup_printf ("plane %u re-crossing", j);
    if (!check_kernel (c->recross_ballistic, side, plane, error) || !check_kernel (c->recross_scattered, side, plane, error))
      return FALSE;
    d->once_b[j] = c->once_ballistic;
    d->once_d[j] = c->once_scattered;
    for (guint t = 0; t < DS_SLAB_RECROSS_CLASSES; t++)
      d->again[j][2 * (t + 1)] = c->recross_times[t];
    /* Level of plane j's light: 2 (n - j + 1); the re-crossing step leaves it one lower, the
     * segment to the next plane one lower again. */
    guint L = 2 * (n - j + 1);
    if (!(d->k_rc_b[j] = ds_scale_kernel_new (&d->sc, c->recross_ballistic, error)) ||
        !(d->k_rc_d[j] = ds_scale_kernel_new (&d->sc, c->recross_scattered, error)) ||
        !(d->k_seg_b[j] = ds_scale_kernel_new (&d->sc, g->from_ballistic, error)) ||
        !(d->k_seg_d[j] = ds_scale_kernel_new (&d->sc, g->from_scattered, error)))
      return FALSE;
    d->pair_rc[j][0] = d->k_rc_b[j];
    d->pair_rc[j][1] = d->k_rc_d[j];
    d->pair_seg[j][0] = d->k_seg_b[j];
    d->pair_seg[j][1] = d->k_seg_d[j];
    if (!(d->step_rc[j] = ds_scale_step_new (&d->sc, L, d->pair_rc[j], 2, error)) ||
        !(d->step_seg[j] = ds_scale_step_new (&d->sc, L - 1, d->pair_seg[j], 2, error)))
      return FALSE;
  }
  d->marg_seg0 = column_sums (k->segments[0].from_ballistic);
  return TRUE;
}

DsStage *
ds_stage_scattering_new (const DsSceneSpec *s, const DsStage *objects, const DsSlabKernels *k, const char *how,
                         GError **error)
{
  ScatterData *d = g_new0 (ScatterData, 1);
  d->n = k->planes.n_planes;
  d->R = k->radius_px;
  ds_scale_init (&d->sc, d->R, s->width, s->height);
  ds_stage_scattering_margins (s, k, &d->in_margin, &d->map_margin);
  d->has_entry = objects && has_entry_objects (s);
  d->top = top_level (d->n, d->has_entry);
  d->radius_px = k->radius_px;
  d->held = k->held;
  d->scattered_in_cone = k->scattered_in_cone;
  d->se_scattered_in_cone = k->se_scattered_in_cone;
  gboolean ok = check_kernel (k->full, 2 * d->R + 1, "whole-slab", error);
  if (ok) {
    d->mtf = ds_kernel_mtf_x (k->full, s->period_px);
    d->mtf_noise = k->effective_records > 0 ? 1.0 / sqrt (k->effective_records) : 0.0;
    d->marg_full = column_sums (k->full);
  }
  /* Which of the objects' planes is which: the faces, and the kernels' interior planes in order. */
  guint found = 0;
  for (guint i = 0; ok && objects && i < ds_stage_objects_n_planes (objects); i++) {
    double z = ds_stage_objects_plane_depth (objects, i);
    d->depth_of[i] = z;
    if (ds_stage_objects_plane_map (objects, i)->width != s->width + 2 * d->map_margin) {
      g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "scattering: object maps need a margin of %u px",
                   d->map_margin);
      ok = FALSE;
    } else if (z <= 0) {
      d->entry_plane = i;
      ok = make_map (d, s, objects, i, MAX (d->top, 1u), &d->entry, error);
    } else if (z >= s->thickness_mm) {
      d->exit_plane = i;
      d->exit = ds_stage_objects_plane_map (objects, i);
    } else if (found < d->n && fabs (z - k->planes.depth_mm[found]) <= DS_SCENE_DEPTH_TOLERANCE_MM) {
      d->plane_of[found + 1] = i;
      ok = make_map (d, s, objects, i, d->top, &d->plane[++found], error);
    }
  }
  if (ok && found != d->n) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID,
                 "scattering: the kernels' %u planes are not the objects' depths inside the medium", d->n);
    ok = FALSE;
  }
  if (ok && d->n > 0)
    ok = build_chain (d, k, error);
  if (ok && d->has_entry) {
    const DsImage *ke = d->n ? k->segments[0].from_ballistic : k->full;
    ok = (d->k_entry = ds_scale_kernel_new (&d->sc, ke, error)) &&
         (d->step_entry = ds_scale_step_new (&d->sc, d->top ? d->top : 1, (const DsScaleKernel *const *) &d->k_entry, 1,
                                             error));
  }
  if (!ok) {
    scatter_free (d);
    return NULL;
  }
  GString *where = g_string_new (NULL);
  if (d->has_entry)
    g_string_append (where, ", objects at the entry face");
  if (d->n) {
    g_string_append_printf (where, ", followed through %u plane%s at", d->n, d->n > 1 ? "s" : "");
    for (guint j = 0; j < d->n; j++)
      g_string_append_printf (where, " %g", k->planes.depth_mm[j]);
    g_string_append (where, " mm");
  }
  if (d->exit)
    g_string_append (where, ", objects at the exit face");
  DsStage *st = g_new0 (DsStage, 1);
  st->kind = DS_RENDER_STAGE_SCATTERING;
  st->reason = g_strdup_printf ("medium sigma_s = %g /mm, g = %g, %g mm: %s kernel of radius %u px holding %.1f %% "
                                "of the scattered light in the cone%s", s->mus, s->g, s->thickness_mm, how, d->R,
                                100 * d->held, where->str);
  g_string_free (where, TRUE);
  st->apply = scattering_apply;
  st->data = d;
  st->free_data = scatter_free;
  return st;
}

void
ds_stage_scattering_info (const DsStage *st, guint *radius_px, guint *margin_px, double *held,
                          double *scattered_in_cone, double *se, double *mtf, double *mtf_noise)
{
  const ScatterData *d = st->data;
  *radius_px = d->radius_px;
  *margin_px = d->in_margin;
  *held = d->held;
  *scattered_in_cone = d->scattered_in_cone;
  *se = d->se_scattered_in_cone;
  *mtf = d->mtf;
  *mtf_noise = d->mtf_noise;
}
