/* Two-scale convolutions (two_scale.h). Geometry: frame column x sits at fine column
 * x + fine_margin(L) of a level-L field; frame block b (columns b f .. b f + f - 1) at coarse
 * column b + block_margin(L). Block values are sums over the block's f x f pixels, so a field
 * of ones has f^2 in every block, and a kernel's coarse weights are
 *   Kc(D) = sum over offsets d of K(d) tri(dx - f Dx) tri(dy - f Dy),  tri(u) = max(0, 1 - |u|/f),
 * which turns block sums into block sums and keeps every total. */
#include "drivers/sim/two_scale.h"

#include <math.h>
#include <string.h>

#include "drivers/sim/sim_error.h"
#include "proc/cv_bridge.h"

void
ds_scale_init (DsScale *sc, guint r, guint width, guint height)
{
  sc->width = width;
  sc->height = height;
  if (r <= 2 * DS_SCALE_CORE) {
    sc->f = 1;
    sc->rc = r;
    sc->rb = 0;
  } else {
    sc->f = DS_SCALE_BLOCK;
    sc->rc = DS_SCALE_CORE;
    sc->rb = (r + sc->f - 1) / sc->f + 1;
  }
}

guint
ds_scale_fine_margin (const DsScale *sc, guint level)
{
  return level * sc->rc;
}

guint
ds_scale_block_margin (const DsScale *sc, guint level)
{
  return sc->f > 1 ? 1 + level * sc->rb : 0;
}

guint
ds_scale_block_margin_2d (const DsScale *sc, guint level)
{
  return ds_scale_block_margin (sc, MIN (level, 1u));
}

static guint
blocks (guint n, guint f)
{
  return (n + f - 1) / f;
}

guint
ds_scale_row_margin (const DsScale *sc, guint level, guint radius)
{
  guint m = sc->f > 1 ? ds_scale_block_margin (sc, level) * sc->f + (blocks (sc->width, sc->f) * sc->f - sc->width)
                      : ds_scale_fine_margin (sc, level);
  return m + radius;
}

/* ---- kernels ---------------------------------------------------------------------------- */

/* The core window along one axis: 1 to rc/2, a cosine down to 0 at rc. */
static double
window (guint u, guint rc)
{
  double ramp = rc / 2.0, start = rc - ramp;
  if (u <= start)
    return 1.0;
  if (u >= rc)
    return 0.0;
  return 0.5 * (1.0 + cos (G_PI * (u - start) / ramp));
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

void
ds_scale_kernel_free (DsScaleKernel *k)
{
  if (!k)
    return;
  ds_image_free (k->core);
  ds_image_free (k->tail);
  ds_image_free (k->whole);
  g_free (k->core_x);
  g_free (k->tail_x);
  g_free (k->whole_x);
  g_free (k);
}

/* Adds w to the coarse kernel at offset (dx, dy), spread by tri() over the blocks it touches. */
static void
coarse_add (DsImage *c, guint rb, guint f, int dx, int dy, double w)
{
  int bx0 = (int) floor ((double) dx / f), by0 = (int) floor ((double) dy / f);
  for (int by = by0; by <= by0 + 1; by++) {
    double ty = 1.0 - fabs ((double) dy - (double) f * by) / f;
    if (ty <= 0 || abs (by) > (int) rb)
      continue;
    for (int bx = bx0; bx <= bx0 + 1; bx++) {
      double tx = 1.0 - fabs ((double) dx - (double) f * bx) / f;
      if (tx <= 0 || abs (bx) > (int) rb)
        continue;
      ((float *) ds_image_row (c, (guint) (by + (int) rb)))[bx + (int) rb] += (float) (w * tx * ty);
    }
  }
}

DsScaleKernel *
ds_scale_kernel_new (const DsScale *sc, const DsImage *k, GError **error)
{
  guint r = k->width / 2;
  if (k->type != DS_SAMPLE_F32 || k->width != k->height || k->width % 2 == 0 || r > sc->rb * sc->f + sc->rc) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "scale kernel: %ux%u is not an f32 square of odd side "
                 "within the scale's reach", k->width, k->height);
    return NULL;
  }
  g_autoptr (GError) local = NULL;
  DsScaleKernel *sk = g_new0 (DsScaleKernel, 1);
  guint side = 2 * sc->rc + 1;
  sk->core = ds_image_new (DS_SAMPLE_F32, side, side, &local);
  if (sc->f > 1 && sk->core) {
    sk->tail = ds_image_new (DS_SAMPLE_F32, 2 * sc->rb + 1, 2 * sc->rb + 1, &local);
    sk->whole = sk->tail ? ds_image_new (DS_SAMPLE_F32, 2 * sc->rb + 1, 2 * sc->rb + 1, &local) : NULL;
  }
  if (local) {
    ds_scale_kernel_free (sk);
    g_propagate_error (error, g_steal_pointer (&local));
    return NULL;
  }
  for (guint y = 0; y < k->height; y++) {
    const float *row = ds_image_row (k, y);
    int dy = (int) y - (int) r;
    for (guint x = 0; x < k->width; x++) {
      int dx = (int) x - (int) r;
      double v = row[x];
      if (v == 0)
        continue;
      double w = sc->f > 1 ? window ((guint) abs (dx), sc->rc) * window ((guint) abs (dy), sc->rc) : 1.0;
      if (w > 0 && (guint) abs (dx) <= sc->rc && (guint) abs (dy) <= sc->rc)
        ((float *) ds_image_row (sk->core, (guint) (dy + (int) sc->rc)))[dx + (int) sc->rc] += (float) (v * w);
      if (sc->f > 1) {
        coarse_add (sk->whole, sc->rb, sc->f, dx, dy, v);
        if (w < 1)
          coarse_add (sk->tail, sc->rb, sc->f, dx, dy, v * (1 - w));
      }
    }
  }
  sk->core_x = column_sums (sk->core);
  if (sc->f > 1) {
    sk->tail_x = column_sums (sk->tail);
    sk->whole_x = column_sums (sk->whole);
  }
  return sk;
}

/* ---- fields ----------------------------------------------------------------------------- */

void
ds_field_free (DsField *f)
{
  if (!f)
    return;
  ds_image_free (f->fine);
  ds_image_free (f->coarse);
  g_free (f);
}

DsField *
ds_field_new (const DsScale *sc, guint level, gboolean x_only, GError **error)
{
  guint m = ds_scale_fine_margin (sc, level);
  guint b = x_only ? ds_scale_block_margin (sc, level) : ds_scale_block_margin_2d (sc, level);
  g_autoptr (DsField) f = g_new0 (DsField, 1);
  f->level = level;
  f->x_only = x_only;
  f->block_margin = b;
  f->fine = ds_image_new (DS_SAMPLE_F32, sc->width + 2 * m, x_only ? 1 : sc->height + 2 * m, error);
  if (!f->fine)
    return NULL;
  if (sc->f > 1) {
    f->coarse = ds_image_new (DS_SAMPLE_F32, blocks (sc->width, sc->f) + 2 * b,
                              x_only ? 1 : blocks (sc->height, sc->f) + 2 * b, error);
    if (!f->coarse)
      return NULL;
  }
  return g_steal_pointer (&f);
}

DsField *
ds_field_from_row (const DsScale *sc, guint level, const float *row, int row_x0, double scale, GError **error)
{
  DsField *f = ds_field_new (sc, level, TRUE, error);
  if (!f)
    return NULL;
  int m = (int) ds_scale_fine_margin (sc, level);
  float *fine = ds_image_row (f->fine, 0);
  for (guint i = 0; i < f->fine->width; i++)
    fine[i] = (float) (scale * row[(int) i - m - row_x0]);
  if (f->coarse) {
    int b = (int) f->block_margin, bf = (int) sc->f;
    float *c = ds_image_row (f->coarse, 0);
    for (guint i = 0; i < f->coarse->width; i++) {
      double s = 0;
      int x0 = ((int) i - b) * bf;
      for (int x = x0; x < x0 + bf; x++)
        s += row[x - row_x0];
      /* A block sum counts f rows of this row. */
      c[i] = (float) (scale * s * bf);
    }
  }
  return f;
}

/* dst (w x h) = scale * the window of src at (ox, oy) (src rows repeat when src has one). */
static void
copy_window (DsImage *dst, const DsImage *src, guint ox, guint oy, double scale, gboolean add)
{
  for (guint y = 0; y < dst->height; y++) {
    const float *s = (const float *) ds_image_row (src, src->height == 1 ? 0 : y + oy) + ox;
    float *d = ds_image_row (dst, y);
    for (guint x = 0; x < dst->width; x++)
      d[x] = (float) ((add ? d[x] : 0.0f) + scale * s[x]);
  }
}

DsField *
ds_field_crop (const DsScale *sc, const DsField *src, guint level, double scale, GError **error)
{
  g_assert (level <= src->level);
  DsField *f = ds_field_new (sc, level, src->x_only, error);
  if (!f)
    return NULL;
  guint dm = ds_scale_fine_margin (sc, src->level) - ds_scale_fine_margin (sc, level);
  copy_window (f->fine, src->fine, dm, src->x_only ? 0 : dm, scale, FALSE);
  if (f->coarse) {
    guint db = src->block_margin - f->block_margin;
    copy_window (f->coarse, src->coarse, db, src->x_only ? 0 : db, scale, FALSE);
  }
  return f;
}

void
ds_field_add (const DsScale *sc, DsField *dst, const DsField *src, double scale)
{
  g_assert (dst->level <= src->level && (!dst->x_only || src->x_only));
  guint dm = ds_scale_fine_margin (sc, src->level) - ds_scale_fine_margin (sc, dst->level);
  copy_window (dst->fine, src->fine, dm, src->x_only ? 0 : dm, scale, TRUE);
  if (dst->coarse) {
    g_assert (src->block_margin >= dst->block_margin);
    guint db = src->block_margin - dst->block_margin;
    copy_window (dst->coarse, src->coarse, db, src->x_only ? 0 : db, scale, TRUE);
  }
}

static inline double
poly_at (const double *p, guint n, double t)
{
  double v = 0;
  for (guint k = n; k-- > 0;)
    v = v * t + p[k];
  return v;
}

DsField *
ds_field_weigh (const DsScale *sc, const DsField *src, const DsScaleMap *map, const double *poly, guint n_poly,
                guint level, GError **error)
{
  g_assert (level <= src->level);
  DsField *f = ds_field_new (sc, level, FALSE, error);
  if (!f)
    return NULL;
  guint m = ds_scale_fine_margin (sc, level), sm = ds_scale_fine_margin (sc, src->level);
  guint W = f->fine->width, H = f->fine->height;
  for (guint y = 0; y < H; y++) {
    const float *s = (const float *) ds_image_row (src->fine, src->x_only ? 0 : y + sm - m) + (sm - m);
    const float *o = (const float *) ds_image_row (map->fine, y + map->fine_margin - m) + (map->fine_margin - m);
    float *d = ds_image_row (f->fine, y);
    for (guint x = 0; x < W; x++)
      d[x] = (float) (poly_at (poly, n_poly, o[x]) * s[x]);
  }
  if (!f->coarse)
    return f;
  guint b = f->block_margin, sb = src->block_margin, bf = sc->f;
  g_assert (sb >= b && map->block_margin >= b);
  for (guint by = 0; by < f->coarse->height; by++) {
    const float *s = (const float *) ds_image_row (src->coarse, src->x_only ? 0 : by + sb - b) + (sb - b);
    const float *o = (const float *) ds_image_row (map->coarse, by + map->block_margin - b) + (map->block_margin - b);
    float *d = ds_image_row (f->coarse, by);
    for (guint bx = 0; bx < f->coarse->width; bx++) {
      /* Frame coordinates of the block's first pixel, and where that is in the fine result. */
      int fx = ((int) bx - (int) b) * (int) bf + (int) m, fy = ((int) by - (int) b) * (int) bf + (int) m;
      if (fx >= 0 && fy >= 0 && fx + (int) bf <= (int) W && fy + (int) bf <= (int) H) {
        double sum = 0;
        for (guint yy = 0; yy < bf; yy++) {
          const float *row = (const float *) ds_image_row (f->fine, (guint) fy + yy) + fx;
          for (guint xx = 0; xx < bf; xx++)
            sum += row[xx];
        }
        d[bx] = (float) sum;
      } else
        d[bx] = (float) (poly_at (poly, n_poly, o[bx]) * s[bx]);
    }
  }
  return f;
}

/* ---- steps ------------------------------------------------------------------------------ */

struct DsScaleStep {
  const DsScale *sc;
  guint level, n;
  const DsScaleKernel *const *k; /* borrowed: the caller keeps the kernels */
  DsCvConvPlan *fine;            /* cores */
  DsCvConvPlan *coarse;          /* tails (0 .. n-1), then wholes (n .. 2n-1) */
  guint in_block_margin;         /* of the plan's 2-D inputs: the output's plus rb */
};

void
ds_scale_step_free (DsScaleStep *st)
{
  if (!st)
    return;
  ds_cv_conv_plan_free (st->fine);
  ds_cv_conv_plan_free (st->coarse);
  g_free (st);
}

static DsCvView
view (const DsImage *im)
{
  return (DsCvView) { (int) im->width, (int) im->height, DS_CV_F32, im->stride, im->data };
}

DsScaleStep *
ds_scale_step_new (const DsScale *sc, guint level, const DsScaleKernel *const *k, guint n, GError **error)
{
  g_assert (level >= 1 && n >= 1 && n <= 4);
  DsScaleStep *st = g_new0 (DsScaleStep, 1);
  st->sc = sc;
  st->level = level;
  st->n = n;
  st->k = k;
  guint m = ds_scale_fine_margin (sc, level);
  DsCvView ks[8];
  char err[256];
  for (guint i = 0; i < n; i++)
    ks[i] = view (k[i]->core);
  st->fine = ds_cv_conv_plan_new ((int) (sc->width + 2 * m), (int) (sc->height + 2 * m), ks, (int) n, err, sizeof err);
  if (st->fine && sc->f > 1) {
    guint b = st->in_block_margin = ds_scale_block_margin_2d (sc, level - 1) + sc->rb;
    for (guint i = 0; i < n; i++) {
      ks[i] = view (k[i]->tail);
      ks[n + i] = view (k[i]->whole);
    }
    st->coarse = ds_cv_conv_plan_new ((int) (blocks (sc->width, sc->f) + 2 * b), (int) (blocks (sc->height, sc->f) + 2 * b),
                                      ks, (int) (2 * n), err, sizeof err);
  }
  if (!st->fine || (sc->f > 1 && !st->coarse)) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_NUMERIC, "scattering step: %s", err);
    ds_scale_step_free (st);
    return NULL;
  }
  return st;
}

/* dst row (width w) += the valid 1-D convolution of src with m (radius r): sum_d m[r+d] src[x + r - d]. */
static void
row_convolve_add (float *dst, guint w, const float *src, const double *m, guint r)
{
  for (guint x = 0; x < w; x++) {
    double acc = 0;
    const float *p = src + x + 2 * r;
    for (guint i = 0; i <= 2 * r; i++)
      acc += m[i] * p[-(int) i];
    dst[x] = (float) (dst[x] + acc);
  }
}

/* What one scale of a step convolves: 2-D sources through the plan (source i with kernel
 * plan_offset + i), x-only rows through column sums added to every row. */
typedef struct {
  const DsImage *grid[4];  /* 2-D, the plan's input size, or NULL */
  const DsImage *row[8];   /* x-only, or NULL ... */
  guint row_kernel[8];     /* ... with the kernel index (0 .. n-1) whose column sums apply ... */
  guint row_skip[8];       /* ... and its first column that lines up with the output's column -r */
  guint n_rows;
} Sources;

static gboolean
convolve (const DsCvConvPlan *plan, guint plan_offset, const Sources *src, guint n, const double *const *marg,
          guint r, DsImage *out, GError **error)
{
  DsCvView views[8] = { { 0 } };
  gboolean any_2d = FALSE;
  for (guint i = 0; i < n; i++)
    if (src->grid[i]) {
      views[plan_offset + i] = view (src->grid[i]);
      any_2d = TRUE;
    }
  if (any_2d) {
    DsCvView d = view (out);
    char err[256];
    if (ds_cv_conv_plan_apply (plan, views, &d, err, sizeof err) != 0) {
      g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_NUMERIC, "scattering convolution: %s", err);
      return FALSE;
    }
  }
  g_autofree float *row = NULL;
  for (guint i = 0; i < src->n_rows; i++) {
    if (!row)
      row = g_new0 (float, out->width);
    const float *in = (const float *) ds_image_row (src->row[i], 0) + src->row_skip[i];
    row_convolve_add (row, out->width, in, marg[src->row_kernel[i]], r);
  }
  for (guint y = 0; row && y < out->height; y++) {
    float *d = ds_image_row (out, y);
    for (guint x = 0; x < out->width; x++)
      d[x] += row[x];
  }
  return TRUE;
}

/* fine += the tail's block sums (coarse, block margin b) interpolated between block centres,
 * per pixel. */
static void
add_tail (const DsScale *sc, guint level, guint b, DsImage *fine, const DsImage *tail)
{
  guint m = ds_scale_fine_margin (sc, level), f = sc->f;
  double per_px = 1.0 / ((double) f * f);
  g_autofree int *ix = g_new (int, fine->width);
  g_autofree double *tx = g_new (double, fine->width);
  for (guint x = 0; x < fine->width; x++) {
    double u = ((double) x - m + 0.5) / f - 0.5 + b;
    ix[x] = CLAMP ((int) floor (u), 0, (int) tail->width - 2);
    tx[x] = u - ix[x];
  }
  for (guint y = 0; y < fine->height; y++) {
    float *d = ds_image_row (fine, y);
    const float *t0, *t1;
    double ty = 0;
    if (tail->height == 1)
      t0 = t1 = ds_image_row (tail, 0);
    else {
      double v = ((double) y - m + 0.5) / f - 0.5 + b;
      int iy = CLAMP ((int) floor (v), 0, (int) tail->height - 2);
      ty = v - iy;
      t0 = ds_image_row (tail, (guint) iy);
      t1 = ds_image_row (tail, (guint) iy + 1);
    }
    for (guint x = 0; x < fine->width; x++) {
      int i = ix[x];
      double a = t0[i] + tx[x] * (t0[i + 1] - t0[i]), c = t1[i] + tx[x] * (t1[i + 1] - t1[i]);
      d[x] = (float) (d[x] + per_px * (a + ty * (c - a)));
    }
  }
}

/* A 2-D field's blocks minus its object-free counterpart's, padded with zeros to the plan's
 * input margin pb (beyond its blocks the field is the object-free light). */
static DsImage *
padded_difference (const DsScale *sc, const DsField *in, const DsField *clear, guint pb, GError **error)
{
  g_autoptr (DsImage) p = ds_image_new (DS_SAMPLE_F32, blocks (sc->width, sc->f) + 2 * pb,
                                        blocks (sc->height, sc->f) + 2 * pb, error);
  if (!p)
    return NULL;
  guint off = pb - in->block_margin, cskip = clear->block_margin - in->block_margin;
  const float *c = (const float *) ds_image_row (clear->coarse, 0) + cskip;
  for (guint y = 0; y < in->coarse->height; y++) {
    const float *s = ds_image_row (in->coarse, y);
    float *d = (float *) ds_image_row (p, y + off) + off;
    for (guint x = 0; x < in->coarse->width; x++)
      d[x] = s[x] - c[x];
  }
  return g_steal_pointer (&p);
}

DsField *
ds_scale_step_apply (const DsScaleStep *st, const DsField *const *in, const DsField *const *clear, GError **error)
{
  const DsScale *sc = st->sc;
  gboolean x_only = TRUE;
  for (guint i = 0; i < st->n; i++) {
    g_assert (!in[i] || in[i]->level == st->level);
    if (in[i] && !in[i]->x_only)
      x_only = FALSE;
  }
  g_autoptr (DsField) out = ds_field_new (sc, st->level - 1, x_only, error);
  if (!out)
    return NULL;
  const double *core_m[4], *tail_m[4], *whole_m[4];
  for (guint i = 0; i < st->n; i++) {
    core_m[i] = st->k[i]->core_x;
    tail_m[i] = st->k[i]->tail_x;
    whole_m[i] = st->k[i]->whole_x;
  }
  /* Fine: every margin is the full one. */
  Sources fine = { 0 };
  for (guint i = 0; i < st->n; i++) {
    if (in[i] && !in[i]->x_only)
      fine.grid[i] = in[i]->fine;
    else if (in[i]) {
      fine.row[fine.n_rows] = in[i]->fine;
      fine.row_kernel[fine.n_rows++] = i;
    }
  }
  if (!convolve (st->fine, 0, &fine, st->n, core_m, sc->rc, out->fine, error))
    return NULL;
  if (sc->f == 1)
    return g_steal_pointer (&out);
  /* Coarse: 2-D inputs short of the plan's margin go in as their difference from the
   * object-free light, which goes in as a row. */
  Sources coarse = { 0 };
  DsImage *pads[4] = { NULL };
  gboolean ok = TRUE;
  for (guint i = 0; ok && i < st->n; i++) {
    const DsField *row = NULL;
    if (!in[i])
      continue;
    if (in[i]->x_only)
      row = in[i];
    else if (in[i]->block_margin >= st->in_block_margin) {
      g_assert (in[i]->block_margin == st->in_block_margin);
      coarse.grid[i] = in[i]->coarse;
    } else {
      g_assert (clear && clear[i] && clear[i]->x_only && clear[i]->level == st->level);
      ok = (pads[i] = padded_difference (sc, in[i], clear[i], st->in_block_margin, error)) != NULL;
      coarse.grid[i] = pads[i];
      row = clear[i];
    }
    if (row) {
      coarse.row[coarse.n_rows] = row->coarse;
      coarse.row_kernel[coarse.n_rows] = i;
      coarse.row_skip[coarse.n_rows++] = row->block_margin - out->block_margin - sc->rb;
    }
  }
  g_autoptr (DsImage) tail = ok ? ds_image_new (DS_SAMPLE_F32, out->coarse->width, out->coarse->height, error) : NULL;
  ok = tail && convolve (st->coarse, 0, &coarse, st->n, tail_m, sc->rb, tail, error) &&
       convolve (st->coarse, st->n, &coarse, st->n, whole_m, sc->rb, out->coarse, error);
  for (guint i = 0; i < st->n; i++)
    ds_image_free (pads[i]);
  if (!ok)
    return NULL;
  add_tail (sc, st->level - 1, out->block_margin, out->fine, tail);
  return g_steal_pointer (&out);
}
