/* Object transmittance stage (built when objects are declared): one transmittance map per
 * depth at which objects sit, from the shapes or mask images, area-sampled 4x4 per pixel so
 * edges are partial as a lens sees them. The ballistic light passes every plane once (their
 * product); how scattered light meets them is the scattering stage's business (it reads the
 * same maps). */
#include <math.h>
#include <string.h>

#include "drivers/sim/sim_error.h"
#include "drivers/sim/stage.h"

/* u modulo p in [0, p). */
static inline double
wrap (double u, double p)
{
  return u - p * floor (u / p);
}

/* What a shape needs of the sample's row, computed once per row: the lateral shift of wavy
 * lines, or whether a grid's horizontal bars cover the row. */
static double
row_aux (const DsSceneObject *o, double y)
{
  /* A moving object's shape is sampled where it stood at time 0: subtracting 0 for a still one
   * leaves every sample's bits as they were. */
  y -= o->dy;
  switch (o->shape) {
  case DS_SHAPE_GRID:
    return wrap (y, o->pitch) < o->line_width;
  case DS_SHAPE_LINES:
    /* Vein-like: lines along y, laterally wavy. */
    return o->amplitude * sin (2 * G_PI * y / (4 * o->pitch));
  default:
    return 0;
  }
}

static inline gboolean
inside (const DsSceneObject *o, double x, double y, double aux)
{
  x -= o->dx;
  y -= o->dy;
  switch (o->shape) {
  case DS_SHAPE_RECT:
    return x >= o->x && x < o->x + o->width && y >= o->y && y < o->y + o->height;
  case DS_SHAPE_DISC:
    return (x - o->x) * (x - o->x) + (y - o->y) * (y - o->y) < o->radius * o->radius;
  case DS_SHAPE_GRID:
    return aux != 0 || wrap (x, o->pitch) < o->line_width;
  case DS_SHAPE_LINES:
    return wrap (x - aux, o->pitch) < o->line_width;
  case DS_SHAPE_MASK:
    return FALSE;
  }
  return FALSE;
}

/* A mask image: white (the type's maximum) is the object, black is clear, grey in between. */
static gboolean
apply_mask (const DsSceneObject *o, DsImage *map, guint margin, GError **error)
{
  g_autoptr (GError) local = NULL;
  g_autoptr (DsImage) m = ds_image_read (o->mask_path, &local);
  if (!m) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_IO, "[object.%s] mask: %s", o->name, local->message);
    return FALSE;
  }
  if (m->width + 2 * margin != map->width || m->height + 2 * margin != map->height) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "[object.%s] mask %s is %ux%u, the sensor %ux%u",
                 o->name, o->mask_path, m->width, m->height, map->width - 2 * margin, map->height - 2 * margin);
    return FALSE;
  }
  double full = m->type == DS_SAMPLE_U8 ? 255.0 : m->type == DS_SAMPLE_U16 ? 65535.0 : 1.0;
  for (guint y = 0; y < m->height; y++) {
    float *row = (float *) ds_image_row (map, y + margin) + margin;
    for (guint x = 0; x < m->width; x++) {
      double v = m->type == DS_SAMPLE_U8    ? ((const guint8 *) ds_image_row (m, y))[x]
                 : m->type == DS_SAMPLE_U16 ? ((const guint16 *) ds_image_row (m, y))[x]
                                            : ((const float *) ds_image_row (m, y))[x];
      v = CLAMP (v / full, 0.0, 1.0);
      row[x] = (float) (row[x] * (1.0 - v * (1.0 - o->transmittance)));
    }
  }
  return TRUE;
}

/* The scene's depth limit is the transport's plane limit. */
G_STATIC_ASSERT (DS_SCENE_MAX_DEPTHS == DS_SLAB_MAX_PLANES);

typedef struct {
  guint n_planes;
  double depth_mm[DS_SCENE_MAX_DEPTHS + 2];
  DsImage *map[DS_SCENE_MAX_DEPTHS + 2]; /* frame + margin */
  DsImage *direct;                       /* frame: the product of every plane's map */
} ObjectPlanes;

static gboolean
objects_apply (const DsStage *st, DsLight *l, const DsStageArgs *a, GError **error)
{
  (void) a;
  (void) error;
  const ObjectPlanes *op = st->data;
  /* The motion stage, when built, has rendered this frame's time: its product replaces the one
   * made at time 0. */
  const DsImage *direct = l->moved ? l->moved->direct : op->direct;
  for (guint y = 0; y < l->direct->height; y++) {
    float *dr = ds_image_row (l->direct, y);
    const float *o = ds_image_row (direct, y);
    for (guint x = 0; x < l->direct->width; x++)
      dr[x] *= o[x];
  }
  return TRUE;
}

static void
planes_free (gpointer p)
{
  ObjectPlanes *op = p;
  for (guint i = 0; i < op->n_planes; i++)
    ds_image_free (op->map[i]);
  ds_image_free (op->direct);
  g_free (op);
}

guint
ds_stage_objects_n_planes (const DsStage *st)
{
  return ((const ObjectPlanes *) st->data)->n_planes;
}

double
ds_stage_objects_plane_depth (const DsStage *st, guint i)
{
  return ((const ObjectPlanes *) st->data)->depth_mm[i];
}

const DsImage *
ds_stage_objects_plane_map (const DsStage *st, guint i)
{
  return ((const ObjectPlanes *) st->data)->map[i];
}

/* Whether object i sits on the plane at `depth` (everything is on one plane without a medium). */
static gboolean
object_depth (const DsSceneSpec *s, guint i, double depth)
{
  double z = s->has_medium ? CLAMP (s->objects[i].depth_mm, 0.0, s->thickness_mm) : 0.0;
  return fabs (z - depth) <= DS_SCENE_DEPTH_TOLERANCE_MM;
}

void
ds_stage_objects_interior_depths (const DsSceneSpec *s, DsSlabPlanes *planes)
{
  memset (planes, 0, sizeof *planes);
  for (guint i = 0; s->has_medium && i < s->n_objects; i++) {
    double z = s->objects[i].depth_mm;
    if (z <= 0 || z >= s->thickness_mm)
      continue;
    gboolean seen = FALSE;
    for (guint j = 0; j < planes->n_planes && !seen; j++)
      seen = fabs (planes->depth_mm[j] - z) <= DS_SCENE_DEPTH_TOLERANCE_MM;
    if (!seen && planes->n_planes < DS_SLAB_MAX_PLANES)
      planes->depth_mm[planes->n_planes++] = z;
  }
  for (guint i = 1; i < planes->n_planes; i++)
    for (guint j = i; j > 0 && planes->depth_mm[j] < planes->depth_mm[j - 1]; j--) {
      double t = planes->depth_mm[j];
      planes->depth_mm[j] = planes->depth_mm[j - 1];
      planes->depth_mm[j - 1] = t;
    }
}

/* Whether object o is one `select` asks for. */
static gboolean
selected (const DsSceneObject *o, DsObjectSelect select)
{
  return select == DS_OBJECTS_ALL || (select == DS_OBJECTS_MOVING) == ds_scene_object_moves (o);
}

DsImage *
ds_stage_objects_map_at_depth (const DsSceneSpec *s, double depth, guint margin, DsObjectSelect select,
                               GError **error)
{
  g_autoptr (DsImage) map = ds_image_new (DS_SAMPLE_F32, s->width + 2 * margin, s->height + 2 * margin, error);
  if (!map)
    return NULL;
  g_autofree const DsSceneObject **here = g_new0 (const DsSceneObject *, s->n_objects + 1);
  guint n = 0;
  gboolean masks = FALSE;
  for (guint i = 0; i < s->n_objects; i++)
    if (object_depth (s, i, depth) && selected (&s->objects[i], select)) {
      masks |= s->objects[i].shape == DS_SHAPE_MASK;
      if (s->objects[i].shape != DS_SHAPE_MASK)
        here[n++] = &s->objects[i];
    }
  /* Map pixel (x, y) is the sensor pixel (x - margin, y - margin), sampled 4 x 4. */
  g_autofree double *aux = g_new0 (double, 4 * (gsize) MAX (n, 1u));
  for (guint y = 0; y < map->height; y++) {
    float *row = ds_image_row (map, y);
    double y0 = (double) y - margin;
    for (int sy = 0; sy < 4; sy++)
      for (guint i = 0; i < n; i++)
        aux[sy * n + i] = row_aux (here[i], y0 + (sy + 0.5) / 4.0 - 0.5);
    for (guint x = 0; x < map->width; x++) {
      double acc = 0, x0 = (double) x - margin;
      for (int sy = 0; sy < 4; sy++)
        for (int sx = 0; sx < 4; sx++) {
          double px = x0 + (sx + 0.5) / 4.0 - 0.5, py = y0 + (sy + 0.5) / 4.0 - 0.5, t = 1.0;
          for (guint i = 0; i < n; i++)
            if (inside (here[i], px, py, aux[sy * n + i]))
              t *= here[i]->transmittance;
          acc += t;
        }
      row[x] = (float) (acc / 16.0);
    }
  }
  for (guint i = 0; masks && i < s->n_objects; i++)
    if (s->objects[i].shape == DS_SHAPE_MASK && object_depth (s, i, depth) && selected (&s->objects[i], select) &&
        !apply_mask (&s->objects[i], map, margin, error))
      return NULL;
  return g_steal_pointer (&map);
}

DsImage *
ds_stage_objects_coarse_map (const DsSceneSpec *s, const DsStage *st, guint plane, guint f, guint block_margin,
                             GError **error)
{
  const ObjectPlanes *op = st->data;
  return ds_stage_objects_coarse_map_of (s, op->map[plane], op->depth_mm[plane], f, block_margin, error);
}

DsImage *
ds_stage_objects_coarse_map_of (const DsSceneSpec *s, const DsImage *fine, double depth, guint f,
                                guint block_margin, GError **error)
{
  guint fm = (fine->width - s->width) / 2;
  guint bw = (s->width + f - 1) / f + 2 * block_margin, bh = (s->height + f - 1) / f + 2 * block_margin;
  g_autoptr (DsImage) c = ds_image_new (DS_SAMPLE_F32, bw, bh, error);
  if (!c)
    return NULL;
  g_autofree const DsSceneObject **here = g_new0 (const DsSceneObject *, s->n_objects + 1);
  guint n = 0;
  for (guint i = 0; i < s->n_objects; i++)
    if (object_depth (s, i, depth) && s->objects[i].shape != DS_SHAPE_MASK)
      here[n++] = &s->objects[i];
  g_autofree double *aux = g_new0 (double, (gsize) f * MAX (n, 1u));
  for (guint by = 0; by < bh; by++) {
    int y0 = ((int) by - (int) block_margin) * (int) f; /* frame row of the block's first pixel */
    gboolean rows_in = y0 + (int) fm >= 0 && y0 + (int) f <= (int) (s->height + fm);
    for (guint yy = 0; yy < f; yy++)
      for (guint i = 0; i < n; i++)
        aux[yy * n + i] = row_aux (here[i], y0 + (int) yy);
    float *row = ds_image_row (c, by);
    for (guint bx = 0; bx < bw; bx++) {
      int x0 = ((int) bx - (int) block_margin) * (int) f;
      double acc = 0;
      if (rows_in && x0 + (int) fm >= 0 && x0 + (int) f <= (int) (s->width + fm)) {
        /* Inside the fine map: its (4 x 4 sampled) pixels. */
        for (guint yy = 0; yy < f; yy++) {
          const float *m = (const float *) ds_image_row (fine, (guint) (y0 + (int) fm) + yy) + x0 + (int) fm;
          for (guint xx = 0; xx < f; xx++)
            acc += m[xx];
        }
      } else {
        /* Beyond it: the shapes at the pixel centres (masks are clear there). */
        for (guint yy = 0; yy < f; yy++)
          for (guint xx = 0; xx < f; xx++) {
            double t = 1.0;
            for (guint i = 0; i < n; i++)
              if (inside (here[i], x0 + (int) xx, y0 + (int) yy, aux[yy * n + i]))
                t *= here[i]->transmittance;
            acc += t;
          }
      }
      row[bx] = (float) (acc / ((double) f * f));
    }
  }
  return g_steal_pointer (&c);
}

DsStage *
ds_stage_objects_new (const DsSceneSpec *s, guint margin, GError **error)
{
  ObjectPlanes *op = g_new0 (ObjectPlanes, 1);
  /* Without a medium depth means nothing: every object is on one plane. With one, the scene
   * allows at most DS_SCENE_MAX_DEPTHS depths inside plus the two faces. */
  for (guint i = 0; i < s->n_objects; i++) {
    double z = s->has_medium ? CLAMP (s->objects[i].depth_mm, 0.0, s->thickness_mm) : 0.0;
    gboolean seen = FALSE;
    for (guint j = 0; j < op->n_planes && !seen; j++)
      seen = fabs (op->depth_mm[j] - z) <= DS_SCENE_DEPTH_TOLERANCE_MM;
    if (!seen) {
      g_assert (op->n_planes < G_N_ELEMENTS (op->depth_mm));
      op->depth_mm[op->n_planes++] = z;
    }
  }
  /* Shallowest first: the order light meets them. */
  for (guint i = 1; i < op->n_planes; i++)
    for (guint j = i; j > 0 && op->depth_mm[j] < op->depth_mm[j - 1]; j--) {
      double t = op->depth_mm[j];
      op->depth_mm[j] = op->depth_mm[j - 1];
      op->depth_mm[j - 1] = t;
    }
  GError *local = NULL;
  op->direct = ds_image_new (DS_SAMPLE_F32, s->width, s->height, &local);
  for (guint j = 0; !local && j < op->n_planes; j++) {
    op->map[j] = ds_stage_objects_map_at_depth (s, op->depth_mm[j], margin, DS_OBJECTS_ALL, &local);
    if (!op->map[j])
      break;
  }
  if (local) {
    planes_free (op);
    g_propagate_error (error, local);
    return NULL;
  }
  for (guint y = 0; y < s->height; y++) {
    float *d = ds_image_row (op->direct, y);
    for (guint x = 0; x < s->width; x++) {
      double t = 1.0;
      for (guint j = 0; j < op->n_planes; j++)
        t *= ((const float *) ds_image_row (op->map[j], y + margin))[x + margin];
      d[x] = (float) t;
    }
  }
  GString *names = g_string_new (NULL);
  for (guint i = 0; i < s->n_objects; i++)
    g_string_append_printf (names, "%s%s", i ? ", " : "", s->objects[i].name);
  GString *depths = g_string_new (NULL);
  for (guint j = 0; j < op->n_planes; j++)
    g_string_append_printf (depths, "%s%g", j ? ", " : "", op->depth_mm[j]);
  DsStage *st = g_new0 (DsStage, 1);
  st->kind = DS_RENDER_STAGE_OBJECTS;
  st->reason = g_strdup_printf ("%u object(s) declared (%s) at %s mm depth", s->n_objects, names->str, depths->str);
  g_string_free (names, TRUE);
  g_string_free (depths, TRUE);
  st->apply = objects_apply;
  st->data = op;
  st->free_data = planes_free;
  return st;
}
