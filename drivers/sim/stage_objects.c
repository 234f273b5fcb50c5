/* Object transmittance stage (built when objects are declared): a transmittance map from the
 * shapes or mask images, area-sampled 4x4 per pixel so edges are partial as a lens sees them.
 * Every object sits on one plane at depth-mm; the ballistic light passes it once. How
 * scattered light meets it is the scattering stage's business (it reads the same map). */
#include <math.h>

#include "drivers/sim/sim_error.h"
#include "drivers/sim/stage.h"

static gboolean
inside (const DsSceneObject *o, double x, double y)
{
  switch (o->shape) {
  case DS_SHAPE_RECT:
    return x >= o->x && x < o->x + o->width && y >= o->y && y < o->y + o->height;
  case DS_SHAPE_DISC:
    return (x - o->x) * (x - o->x) + (y - o->y) * (y - o->y) < o->radius * o->radius;
  case DS_SHAPE_GRID: {
    double u = fmod (x + 1e6 * o->pitch, o->pitch), v = fmod (y + 1e6 * o->pitch, o->pitch);
    return u < o->line_width || v < o->line_width;
  }
  case DS_SHAPE_LINES: {
    /* Vein-like: lines along y, laterally wavy. */
    double xs = x - o->amplitude * sin (2 * G_PI * y / (4 * o->pitch));
    return fmod (xs + 1e6 * o->pitch, o->pitch) < o->line_width;
  }
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

static gboolean
objects_apply (const DsStage *st, DsLight *l, const DsStageArgs *a, GError **error)
{
  (void) a;
  (void) error;
  const DsImage *map = st->data;
  guint m = (map->width - l->direct->width) / 2;
  for (guint y = 0; y < l->direct->height; y++) {
    float *dr = ds_image_row (l->direct, y);
    const float *o = (const float *) ds_image_row (map, y + m) + m;
    for (guint x = 0; x < l->direct->width; x++)
      dr[x] *= o[x];
  }
  return TRUE;
}

const DsImage *
ds_stage_objects_map (const DsStage *st)
{
  return st->data;
}

DsStage *
ds_stage_objects_new (const DsSceneSpec *s, guint margin, GError **error)
{
  g_autoptr (DsImage) map = ds_image_new (DS_SAMPLE_F32, s->width + 2 * margin, s->height + 2 * margin, error);
  if (!map)
    return NULL;
  for (guint y = 0; y < map->height; y++) {
    float *row = ds_image_row (map, y);
    for (guint x = 0; x < map->width; x++) {
      double acc = 0, x0 = (double) x - margin, y0 = (double) y - margin;
      for (int sy = 0; sy < 4; sy++)
        for (int sx = 0; sx < 4; sx++) {
          double px = x0 + (sx + 0.5) / 4.0 - 0.5, py = y0 + (sy + 0.5) / 4.0 - 0.5, t = 1.0;
          for (guint i = 0; i < s->n_objects; i++)
            if (inside (&s->objects[i], px, py))
              t *= s->objects[i].transmittance;
          acc += t;
        }
      row[x] = (float) (acc / 16.0);
    }
  }
  for (guint i = 0; i < s->n_objects; i++)
    if (s->objects[i].shape == DS_SHAPE_MASK && !apply_mask (&s->objects[i], map, margin, error))
      return NULL;
  GString *names = g_string_new (NULL);
  for (guint i = 0; i < s->n_objects; i++)
    g_string_append_printf (names, "%s%s", i ? ", " : "", s->objects[i].name);
  DsStage *st = g_new0 (DsStage, 1);
  st->kind = DS_RENDER_STAGE_OBJECTS;
  st->reason = g_strdup_printf ("%u object(s) declared (%s) at %g mm depth", s->n_objects, names->str,
                                s->objects[0].depth_mm);
  g_string_free (names, TRUE);
  st->apply = objects_apply;
  st->data = g_steal_pointer (&map);
  st->free_data = (GDestroyNotify) ds_image_free;
  return st;
}
