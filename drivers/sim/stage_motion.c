/* Motion stage (built when an object declares a velocity): the object planes at the frame's
 * time t. A moving object stands at its declared position plus v t; its shape is sampled there
 * (4 x 4 per pixel, as at time 0), so an edge moves by sub-pixel steps as the lens would see it.
 * The light does not move: stripes, medium and kernels are the scene's, only the transmittance
 * maps change.
 *
 * Only what moves is rendered per frame: a plane without a moving object keeps the objects
 * stage's map, and on a plane with one the still objects' map is made here once and multiplied
 * by the moving objects' map at t. Overlapping objects multiply (docs/scene-format.md), so the
 * product is the plane's map up to how a pixel straddling both a still and a moving edge is
 * sampled. One exposure is one instant: the object does not blur within it (the motion between
 * frames is what the separation meets). */
#include <math.h>
#include <string.h>

#include "drivers/sim/sim_error.h"
#include "drivers/sim/stage.h"

typedef struct {
  const DsSceneSpec *spec;      /* the renderer's, outlives the stage */
  const DsStage *objects;       /* borrowed */
  guint margin;                 /* of the objects stage's maps */
  guint n_planes;
  gboolean moves[DS_SCENE_MAX_DEPTHS + 2];
  DsImage *still[DS_SCENE_MAX_DEPTHS + 2]; /* the still objects on a plane that also holds a moving one */
} MotionData;

void
ds_moved_objects_free (DsMovedObjects *m)
{
  if (!m)
    return;
  for (guint j = 0; j < G_N_ELEMENTS (m->map); j++)
    ds_image_free (m->map[j]);
  ds_image_free (m->direct);
  g_free (m->objects);
  g_free (m);
}

static void
motion_free (gpointer p)
{
  MotionData *d = p;
  for (guint j = 0; j < d->n_planes; j++)
    ds_image_free (d->still[j]);
  g_free (d);
}

static gboolean
motion_apply (const DsStage *st, DsLight *l, const DsStageArgs *a, GError **error)
{
  const MotionData *d = st->data;
  const DsSceneSpec *s = d->spec;
  DsMovedObjects *m = g_new0 (DsMovedObjects, 1);
  /* Owned by the light from here: freed with it whatever happens below. */
  ds_moved_objects_free (l->moved);
  l->moved = m;
  m->time_s = a->time_s;
  m->objects = g_new0 (DsSceneObject, MAX (1u, s->n_objects));
  for (guint i = 0; i < s->n_objects; i++) {
    m->objects[i] = s->objects[i];
    m->objects[i].dx = s->objects[i].vx * a->time_s;
    m->objects[i].dy = s->objects[i].vy * a->time_s;
  }
  m->spec = *s;
  m->spec.objects = m->objects;
  for (guint j = 0; j < d->n_planes; j++) {
    if (!d->moves[j])
      continue;
    double depth = ds_stage_objects_plane_depth (d->objects, j);
    m->map[j] = ds_stage_objects_map_at_depth (&m->spec, depth, d->margin, DS_OBJECTS_MOVING, error);
    if (!m->map[j])
      return FALSE;
    DsImage *map = m->map[j];
    for (guint y = 0; y < map->height; y++) {
      float *row = ds_image_row (map, y);
      const float *still = ds_image_row (d->still[j], y);
      for (guint x = 0; x < map->width; x++)
        row[x] *= still[x];
    }
  }
  m->direct = ds_image_new (DS_SAMPLE_F32, s->width, s->height, error);
  if (!m->direct)
    return FALSE;
  for (guint y = 0; y < s->height; y++) {
    float *dr = ds_image_row (m->direct, y);
    for (guint x = 0; x < s->width; x++) {
      double t = 1.0;
      for (guint j = 0; j < d->n_planes; j++) {
        const DsImage *map = m->map[j] ? m->map[j] : ds_stage_objects_plane_map (d->objects, j);
        t *= ((const float *) ds_image_row (map, y + d->margin))[x + d->margin];
      }
      dr[x] = (float) t;
    }
  }
  return TRUE;
}

DsStage *
ds_stage_motion_new (const DsSceneSpec *s, const DsStage *objects, GError **error)
{
  MotionData *d = g_new0 (MotionData, 1);
  d->spec = s;
  d->objects = objects;
  d->n_planes = ds_stage_objects_n_planes (objects);
  d->margin = (ds_stage_objects_plane_map (objects, 0)->width - s->width) / 2;
  GString *names = g_string_new (NULL);
  for (guint i = 0; i < s->n_objects; i++) {
    const DsSceneObject *o = &s->objects[i];
    if (!ds_scene_object_moves (o))
      continue;
    g_string_append_printf (names, "%s%s at (%g, %g) px/s", names->len ? ", " : "", o->name, o->vx, o->vy);
    double z = s->has_medium ? CLAMP (o->depth_mm, 0.0, s->thickness_mm) : 0.0;
    for (guint j = 0; j < d->n_planes; j++)
      if (fabs (ds_stage_objects_plane_depth (objects, j) - z) <= DS_SCENE_DEPTH_TOLERANCE_MM)
        d->moves[j] = TRUE;
  }
  for (guint j = 0; j < d->n_planes; j++) {
    if (!d->moves[j])
      continue;
    d->still[j] = ds_stage_objects_map_at_depth (s, ds_stage_objects_plane_depth (objects, j), d->margin,
                                                 DS_OBJECTS_STILL, error);
    if (!d->still[j]) {
      g_string_free (names, TRUE);
      motion_free (d);
      return NULL;
    }
  }
  DsStage *st = g_new0 (DsStage, 1);
  st->kind = DS_RENDER_STAGE_MOTION;
  st->reason = g_strdup_printf ("moving object(s): %s; each frame rendered at its exposure's midpoint",
                                names->str);
  g_string_free (names, TRUE);
  st->apply = motion_apply;
  st->data = d;
  st->free_data = motion_free;
  return st;
}
