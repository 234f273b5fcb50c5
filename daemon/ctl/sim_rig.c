#include "daemon/ctl/sim_rig.h"

#include <math.h>
#include <string.h>

struct DsSimRig {
  char *text, *name;
  DsScene *scene;
  DsRenderer *renderer;
};

DsSimRig *
ds_sim_rig_new_from_data (const char *text, const char *name, GError **error)
{
  g_autoptr (DsScene) scene = ds_scene_load_data (text, strlen (text), name, error);
  if (!scene)
    return NULL;
  DsRenderer *r = ds_renderer_new (scene, NULL, error);
  if (!r)
    return NULL;
  DsSimRig *rig = g_new0 (DsSimRig, 1);
  rig->text = g_strdup (text);
  rig->name = g_strdup (name);
  rig->scene = g_steal_pointer (&scene);
  rig->renderer = r;
  return rig;
}

DsSimRig *
ds_sim_rig_new (const char *path, GError **error)
{
  g_autofree char *text = NULL;
  if (!g_file_get_contents (path, &text, NULL, error))
    return NULL;
  return ds_sim_rig_new_from_data (text, path, error);
}

void
ds_sim_rig_free (DsSimRig *rig)
{
  if (!rig)
    return;
  ds_renderer_free (rig->renderer);
  ds_scene_free (rig->scene);
  g_free (rig->text);
  g_free (rig->name);
  g_free (rig);
}

static GKeyFile *
key_file_of (const DsSimRig *rig, GError **error)
{
  GKeyFile *kf = g_key_file_new ();
  if (!g_key_file_load_from_data (kf, rig->text, (gsize) -1, G_KEY_FILE_KEEP_COMMENTS, error)) {
    g_key_file_free (kf);
    return NULL;
  }
  return kf;
}

static DsSimRig *
variant (const DsSimRig *rig, double period_px, gboolean reference, GError **error)
{
  g_autoptr (GKeyFile) kf = key_file_of (rig, error);
  if (!kf)
    return NULL;
  if (period_px > 0)
    g_key_file_set_double (kf, "illuminator", "period-px", period_px);
  if (reference) {
    g_auto (GStrv) groups = g_key_file_get_groups (kf, NULL);
    for (guint i = 0; groups[i]; i++)
      if (g_str_has_prefix (groups[i], "object.") || strcmp (groups[i], "medium") == 0 ||
          strcmp (groups[i], "ambient") == 0)
        g_key_file_remove_group (kf, groups[i], NULL);
  }
  g_autofree char *text = g_key_file_to_data (kf, NULL, NULL);
  return ds_sim_rig_new_from_data (text, rig->name, error);
}

DsSimRig *
ds_sim_rig_with_period (const DsSimRig *rig, double period_px, GError **error)
{
  return variant (rig, period_px, FALSE, error);
}

DsSimRig *
ds_sim_rig_with_speed (const DsSimRig *rig, double speed_px_s, const char *object, GError **error)
{
  g_autoptr (GKeyFile) kf = key_file_of (rig, error);
  if (!kf)
    return NULL;
  g_autofree char *velocity = g_strdup_printf ("%.17g, 0", speed_px_s);
  g_auto (GStrv) groups = g_key_file_get_groups (kf, NULL);
  gboolean found = FALSE;
  for (guint i = 0; groups[i]; i++) {
    if (!g_str_has_prefix (groups[i], "object."))
      continue;
    const char *name = groups[i] + strlen ("object.");
    g_autofree char *shape = g_key_file_get_value (kf, groups[i], "shape", NULL);
    gboolean mask = shape && strcmp (g_strstrip (shape), "mask") == 0;
    if (object ? strcmp (name, object) != 0 : mask)
      continue;
    g_key_file_set_value (kf, groups[i], "velocity", velocity);
    found = TRUE;
  }
  if (object && !found) {
    g_set_error (error, G_KEY_FILE_ERROR, G_KEY_FILE_ERROR_GROUP_NOT_FOUND, "%s: no [object.%s] to move",
                 rig->name, object);
    return NULL;
  }
  g_autofree char *text = g_key_file_to_data (kf, NULL, NULL);
  return ds_sim_rig_new_from_data (text, rig->name, error);
}

DsSimRig *
ds_sim_rig_reference (const DsSimRig *rig, GError **error)
{
  return variant (rig, 0, TRUE, error);
}

const DsScene *
ds_sim_rig_scene (const DsSimRig *rig)
{
  return rig->scene;
}

const DsRenderer *
ds_sim_rig_renderer (const DsSimRig *rig)
{
  return rig->renderer;
}

const char *
ds_sim_rig_name (const DsSimRig *rig)
{
  return rig->name;
}

const char *
ds_sim_rig_text (const DsSimRig *rig)
{
  return rig->text;
}

double
ds_sim_rig_clip_dn (const DsSimRig *rig)
{
  return ds_renderer_saturation_dn (rig->renderer, 0.0);
}

DsImage *
ds_sim_rig_frame_at (const DsSimRig *rig, guint phase, guint n, gboolean on, double exposure_us,
                     guint64 seed, double time_s, GError **error)
{
  DsRenderRequest req = { .phase = phase, .n_phases = n, .illuminator_on = on,
                          .exposure_us = exposure_us, .gain_db = 0, .seed = seed, .time_s = time_s };
  return ds_renderer_render (rig->renderer, &req, error);
}

DsImage *
ds_sim_rig_frame (const DsSimRig *rig, guint phase, guint n, gboolean on, double exposure_us,
                  guint64 seed, GError **error)
{
  return ds_sim_rig_frame_at (rig, phase, n, on, exposure_us, seed, 0.0, error);
}

static DsImage *
expected_frame (const DsSimRig *rig, guint phase, guint n, gboolean on, double exposure_us, double time_s,
                GError **error)
{
  DsRenderRequest req = { .phase = phase, .n_phases = n, .illuminator_on = on,
                          .exposure_us = exposure_us, .gain_db = 0, .seed = 0, .time_s = time_s };
  DsImage *f = ds_renderer_render_expected (rig->renderer, &req, error);
  if (!f)
    return NULL;
  double clip = ds_sim_rig_clip_dn (rig);
  for (guint y = 0; y < f->height; y++) {
    float *r = ds_image_row (f, y);
    for (guint x = 0; x < f->width; x++)
      r[x] = (float) MIN ((double) r[x], clip);
  }
  return f;
}

gboolean
ds_sim_rig_separate (const DsSimRig *rig, const DsSeparationParams *params, guint n_params,
                     guint m, double exposure_us, guint64 seed, gboolean noise_free,
                     DsSeparation **seps, double *compute_us, GError **error)
{
  return ds_sim_rig_separate_at (rig, params, n_params, m, exposure_us, seed, noise_free, NULL, seps, compute_us,
                                 error);
}

gboolean
ds_sim_rig_separate_at (const DsSimRig *rig, const DsSeparationParams *params, guint n_params,
                        guint m, double exposure_us, guint64 seed, gboolean noise_free,
                        const double *frame_time_s, DsSeparation **seps, double *compute_us, GError **error)
{
  guint w = ds_scene_width (rig->scene), h = ds_scene_height (rig->scene);
  guint n = params[0].n_phases;
  g_autoptr (GPtrArray) sets = g_ptr_array_new_with_free_func ((GDestroyNotify) ds_phase_set_free);
  for (guint i = 0; i < n_params; i++) {
    seps[i] = NULL;
    if (compute_us)
      compute_us[i] = 0;
    DsSeparationParams p = params[i];
    if (noise_free && !(p.saturation_level > 0))
      p.saturation_level = ds_sim_rig_clip_dn (rig);
    DsPhaseSet *set = ds_phase_set_new (&p, w, h, error);
    if (!set)
      return FALSE;
    g_ptr_array_add (sets, set);
  }
  /* Dark frame: M frames with the illuminator off, averaged in float; the set subtracts like
   * from like, so integer frames get the average as rounded u16. */
  g_autoptr (DsImage) dark = NULL;
  if (noise_free) {
    dark = expected_frame (rig, 0, n, FALSE, exposure_us, 0.0, error);
  } else {
    g_autoptr (DsImage) acc = ds_image_new (DS_SAMPLE_F32, w, h, error);
    if (!acc)
      return FALSE;
    guint64 frame_seed = seed;
    for (guint j = 0; j < m; j++) {
      g_autoptr (DsImage) f = ds_sim_rig_frame (rig, 0, n, FALSE, exposure_us, frame_seed++, error);
      if (!f)
        return FALSE;
      for (guint y = 0; y < h; y++) {
        const guint16 *src = ds_image_row (f, y);
        float *dst = ds_image_row (acc, y);
        for (guint x = 0; x < w; x++)
          dst[x] += (float) src[x] / (float) m;
      }
    }
    dark = ds_image_convert_f32_clamped (acc, DS_SAMPLE_U16, 65535.0, error);
    if (dark)
      dark->bit_depth = ds_scene_bit_depth (rig->scene);
  }
  if (!dark)
    return FALSE;
  for (guint i = 0; i < n_params; i++)
    if (!ds_phase_set_set_dark (g_ptr_array_index (sets, i), dark, error))
      return FALSE;
  guint64 frame_seed = seed + m;
  /* Without motion one expected frame per phase is all M of them; with it each is its own. */
  guint m_expected = frame_time_s ? m : 1;
  for (guint k = 0; k < n; k++)
    for (guint j = 0; j < (noise_free ? m_expected : m); j++) {
      double t = frame_time_s ? frame_time_s[k * m + j] : 0.0;
      g_autoptr (DsImage) f = noise_free ? expected_frame (rig, k, n, TRUE, exposure_us, t, error)
                                         : ds_sim_rig_frame_at (rig, k, n, TRUE, exposure_us, frame_seed++, t, error);
      if (!f)
        return FALSE;
      for (guint i = 0; i < n_params; i++) {
        gint64 t0 = g_get_monotonic_time ();
        if (!ds_phase_set_accumulate (g_ptr_array_index (sets, i), k, f, error))
          return FALSE;
        if (compute_us)
          compute_us[i] += (double) (g_get_monotonic_time () - t0);
      }
    }
  for (guint i = 0; i < n_params; i++) {
    gint64 t0 = g_get_monotonic_time ();
    seps[i] = ds_phase_set_finalize (g_ptr_array_index (sets, i), error);
    if (compute_us)
      compute_us[i] += (double) (g_get_monotonic_time () - t0);
    if (!seps[i]) {
      for (guint j = 0; j < i; j++)
        g_clear_pointer (&seps[j], ds_separation_free);
      return FALSE;
    }
  }
  return TRUE;
}
