/* The renderer: builds the stage list from the scene, runs it per frame. Stages live in
 * stage_<name>.c; the scattering kernels come from the transport (transport.h) unless given. */
#include "drivers/sim/renderer.h"

#include <math.h>
#include <string.h>

#include "drivers/sim/render_cost.h"
#include "drivers/sim/sim_error.h"
#include "drivers/sim/stage.h"
#include "drivers/sim/transport.h"

struct DsRenderer {
  DsScene *scene;          /* own copy */
  const DsSceneSpec *spec;
  DsStage *stages[DS_RENDER_N_STAGES];
  guint n_stages;
  DsStage *by_kind[DS_RENDER_N_STAGES];
  gint *runs;              /* atomic counters per stage kind */
  DsSensorModel sensor;
  guint margin;            /* scene rendered around the frame for the scattering kernels */
};

void
ds_stage_free (DsStage *st)
{
  if (!st)
    return;
  if (st->free_data)
    st->free_data (st->data);
  g_free (st->reason);
  g_free (st);
}

const char *
ds_render_stage_name (DsRenderStage s)
{
  static const char *const names[DS_RENDER_N_STAGES] = { "stripe-pattern", "boundary-fresnel",
                                                         "ballistic-attenuation", "motion", "object-transmittance",
                                                         "scattering", "ambient", "sensor" };
  return (guint) s < DS_RENDER_N_STAGES ? names[s] : "unknown";
}

static void
add_stage (DsRenderer *r, DsStage *st)
{
  r->stages[r->n_stages++] = st;
  r->by_kind[st->kind] = st;
}

/* The share of the scattered light the kernels must hold: the rest lands beyond their radius
 * and is lost (docs/scene-format.md, "Stages"). */
#define DS_RENDER_KERNEL_ENERGY 0.995

static DsSlabKernels *
transport_kernels (const DsSceneSpec *s, double pitch_mm, const DsSlabPlanes *planes, const char *cache_dir,
                   GError **error)
{
  DsSlab slab = { .mua = s->mua, .mus = s->mus, .g = s->g, .thickness_mm = s->thickness_mm,
                  .n_medium = s->n_medium, .n_above = 1.0, .n_below = 1.0 };
  DsSlabKernelSpec spec = { .model = s->diffusion ? DS_TRANSPORT_DIFFUSION : DS_TRANSPORT_MONTE_CARLO,
                            .pixel_pitch_mm = pitch_mm, .acceptance_half_angle_deg = s->acceptance_half_angle_deg,
                            .energy_fraction = DS_RENDER_KERNEL_ENERGY, .photons = s->photons, .seed = s->mc_seed,
                            .planes = *planes };
  return ds_slab_kernels_cached (&slab, &spec, cache_dir, NULL, error);
}

static gboolean
same_planes (const DsSlabPlanes *a, const DsSlabPlanes *b)
{
  if (a->n_planes != b->n_planes)
    return FALSE;
  for (guint j = 0; j < a->n_planes; j++)
    if (fabs (a->depth_mm[j] - b->depth_mm[j]) > DS_SCENE_DEPTH_TOLERANCE_MM)
      return FALSE;
  return TRUE;
}

static DsRenderer *
build (const DsScene *scene, const char *cache_dir, const DsSlabKernels *given, GError **error)
{
  g_autoptr (DsRenderer) r = g_new0 (DsRenderer, 1);
  r->runs = g_new0 (gint, DS_RENDER_N_STAGES);
  /* The renderer keeps its own copy: it may outlive the caller's scene. */
  r->scene = ds_scene_copy (scene);
  r->spec = ds_scene_spec (r->scene);
  const DsSceneSpec *s = r->spec;
  double pitch_mm = ds_scene_object_pitch_mm (r->scene);
  add_stage (r, ds_stage_pattern_new (s, pitch_mm));
  if (s->has_medium && s->n_medium != 1.0)
    add_stage (r, ds_stage_boundary_new (1.0, s->n_medium));
  double sigma_t = s->has_medium ? s->mua + s->mus : 0.0;
  if (sigma_t > 0)
    add_stage (r, ds_stage_ballistic_new (sigma_t, s->thickness_mm));
  /* Kernels first: their radius sets the margin of scene around the frame that is rendered. */
  gboolean scatters = s->has_medium && s->mus > 0;
  DsSlabPlanes planes;
  ds_stage_objects_interior_depths (s, &planes);
  g_autoptr (DsSlabKernels) computed = NULL;
  const DsSlabKernels *k = given;
  const char *how = "given";
  if (scatters && !given) {
    computed = transport_kernels (s, pitch_mm, &planes, cache_dir, error);
    if (!computed)
      return NULL;
    k = computed;
    how = s->diffusion ? (planes.n_planes ? "diffusion (multipole; planes by Monte Carlo)" : "diffusion (multipole)")
                       : "Monte Carlo";
  }
  if (scatters && (!k || !k->full || !same_planes (&k->planes, &planes))) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID,
                 "renderer: the scattering kernels must have the scene's %u object plane(s) inside the medium",
                 planes.n_planes);
    return NULL;
  }
  guint map_margin = 0;
  r->margin = 0;
  if (scatters)
    ds_stage_scattering_margins (s, k, &r->margin, &map_margin);
  DsStage *objects = NULL;
  if (s->n_objects) {
    objects = ds_stage_objects_new (s, map_margin, error);
    if (!objects)
      return NULL;
    /* Motion runs first: it places the moving objects for the objects stage to shade with. */
    if (ds_scene_has_motion (r->scene)) {
      DsStage *motion = ds_stage_motion_new (s, objects, error);
      if (!motion) {
        ds_stage_free (objects);
        return NULL;
      }
      add_stage (r, motion);
    }
    add_stage (r, objects);
  }
  if (scatters) {
    DsStage *st = ds_stage_scattering_new (s, objects, k, how, error);
    if (!st)
      return NULL;
    add_stage (r, st);
  }
  if (s->has_ambient) {
    double pitch_um = pitch_mm * 1000.0;
    add_stage (r, ds_stage_ambient_new (s->ambient_level * pitch_um * pitch_um));
  }
  r->sensor = (DsSensorModel) { .bit_depth = s->bit_depth, .quantum_efficiency = s->quantum_efficiency,
                                .system_gain = s->system_gain, .read_noise_e = s->read_noise_e,
                                .dark_current_e_s = s->dark_current_e_s, .full_well_e = s->full_well_e };
  add_stage (r, ds_stage_sensor_new (&r->sensor));
  return g_steal_pointer (&r);
}

DsRenderer *
ds_renderer_new (const DsScene *scene, const char *psf_cache_dir, GError **error)
{
  /* Refused before the kernels start: their cost is what runs away. */
  if (!ds_render_cost_check (scene, error))
    return NULL;
  return build (scene, psf_cache_dir, NULL, error);
}

DsRenderer *
ds_renderer_new_with_slab_kernels (const DsScene *scene, const DsSlabKernels *kernels, GError **error)
{
  if (!kernels) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "renderer: no kernels given");
    return NULL;
  }
  return build (scene, NULL, kernels, error);
}

DsRenderer *
ds_renderer_new_with_kernels (const DsScene *scene, const DsImage *psf_full, const DsImage *psf_before,
                              const DsImage *psf_after, GError **error)
{
  if (psf_before || psf_after || !psf_full || psf_full->type != DS_SAMPLE_F32 || psf_full->width != psf_full->height ||
      psf_full->width % 2 == 0) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID,
                 "renderer: one whole-slab kernel (f32, square, odd) is needed; objects inside the medium need "
                 "ds_renderer_new_with_slab_kernels");
    return NULL;
  }
  g_autoptr (DsSlabKernels) k = g_new0 (DsSlabKernels, 1);
  k->radius_px = psf_full->width / 2;
  k->full = ds_image_copy (psf_full, error);
  if (!k->full)
    return NULL;
  double sum = 0;
  for (guint y = 0; y < psf_full->height; y++)
    for (guint x = 0; x < psf_full->width; x++)
      sum += ((const float *) ds_image_row (psf_full, y))[x];
  k->scattered_in_cone = sum;
  k->held = 1.0;
  k->energy_fraction = 1.0;
  return build (scene, NULL, k, error);
}

gboolean
ds_renderer_scattering (const DsRenderer *r, DsRendererScattering *out)
{
  memset (out, 0, sizeof *out);
  const DsStage *st = r->by_kind[DS_RENDER_STAGE_SCATTERING];
  if (!st)
    return FALSE;
  ds_stage_scattering_info (st, &out->kernel_radius_px, &out->margin_px, &out->held, &out->scattered_in_cone,
                            &out->se_scattered_in_cone, &out->modulated, &out->modulated_noise);
  const DsSceneSpec *s = r->spec;
  out->kernel_radius_mm = out->kernel_radius_px * ds_scene_object_pitch_mm (r->scene);
  double rf = ds_stage_boundary_normal_reflectance (1.0, s->n_medium);
  out->ballistic = (1 - rf) * (1 - rf) * exp (-(s->mua + s->mus) * s->thickness_mm);
  DsSlabPlanes planes;
  ds_stage_objects_interior_depths (s, &planes);
  out->n_planes = planes.n_planes;
  memcpy (out->depth_mm, planes.depth_mm, sizeof out->depth_mm);
  return TRUE;
}

void
ds_renderer_free (DsRenderer *r)
{
  if (!r)
    return;
  for (guint i = 0; i < r->n_stages; i++)
    ds_stage_free (r->stages[i]);
  g_free (r->runs);
  ds_scene_free (r->scene);
  g_free (r);
}

guint ds_renderer_n_stages (const DsRenderer *r) { return r->n_stages; }
DsRenderStage ds_renderer_stage (const DsRenderer *r, guint i) { return i < r->n_stages ? r->stages[i]->kind : DS_RENDER_N_STAGES; }
const char *ds_renderer_stage_name (const DsRenderer *r, guint i) { return i < r->n_stages ? ds_render_stage_name (r->stages[i]->kind) : NULL; }
const char *ds_renderer_stage_reason (const DsRenderer *r, guint i) { return i < r->n_stages ? r->stages[i]->reason : NULL; }
gboolean ds_renderer_has_stage (const DsRenderer *r, DsRenderStage s) { return (guint) s < DS_RENDER_N_STAGES && r->by_kind[s]; }
guint64 ds_renderer_stage_runs (const DsRenderer *r, DsRenderStage s) { return (guint) s < DS_RENDER_N_STAGES ? (guint64) g_atomic_int_get (&r->runs[s]) : 0; }
const DsScene *ds_renderer_scene (const DsRenderer *r) { return r->scene; }

static void
light_clear (DsLight *l)
{
  ds_image_free (l->incident);
  ds_image_free (l->direct);
  ds_image_free (l->scattered);
  ds_image_free (l->frame);
  ds_moved_objects_free (l->moved);
  memset (l, 0, sizeof *l);
}

/* Runs the stages in order; ambient and sensor only when asked (the truth has neither). */
static gboolean
run_stages (const DsRenderer *r, DsLight *l, const DsStageArgs *a, gboolean with_ambient, gboolean with_sensor,
            double *secs, GError **error)
{
  const DsSceneSpec *s = r->spec;
  l->margin = r->margin;
  /* The incident light varies along x only: one row covers it. */
  l->incident = ds_image_new (DS_SAMPLE_F32, s->width + 2 * r->margin, 1, error);
  l->direct = l->incident ? ds_image_new (DS_SAMPLE_F32, s->width, s->height, error) : NULL;
  l->scattered = l->direct ? ds_image_new (DS_SAMPLE_F32, s->width, s->height, error) : NULL;
  if (!l->scattered)
    return FALSE;
  for (guint i = 0; i < r->n_stages; i++) {
    const DsStage *st = r->stages[i];
    if ((st->kind == DS_RENDER_STAGE_AMBIENT && !with_ambient) || (st->kind == DS_RENDER_STAGE_SENSOR && !with_sensor))
      continue;
    gint64 t0 = g_get_monotonic_time ();
    if (!st->apply (st, l, a, error))
      return FALSE;
    g_atomic_int_inc (&r->runs[st->kind]);
    if (secs)
      secs[st->kind] += (double) (g_get_monotonic_time () - t0) / 1e6;
  }
  return TRUE;
}

static gboolean
check_exposure (double exposure_us, double gain_db, GError **error)
{
  if (!(exposure_us > 0) || !(exposure_us <= 1e7) || !(gain_db >= 0) || !(gain_db <= 48)) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID,
                 "render: exposure %g us must be in (0, 1e7] and gain %g dB in [0, 48]", exposure_us, gain_db);
    return FALSE;
  }
  return TRUE;
}

/* A frame's time: finite and within a year of the origin; anything else is a clock mistaken
 * for seconds (microseconds, an epoch), never an experiment. */
static gboolean
check_time (double time_s, GError **error)
{
  if (!(fabs (time_s) <= 3.2e7)) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "render: time %g s must be finite and within 3.2e7 s",
                 time_s);
    return FALSE;
  }
  return TRUE;
}

static gboolean
check_request (const DsRenderRequest *req, GError **error)
{
  if (req->illuminator_on && (req->n_phases < 1 || req->phase >= req->n_phases)) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "render: phase %u of %u (phase < phases, phases >= 1)",
                 req->phase, req->n_phases);
    return FALSE;
  }
  if (!(req->period_px == 0 || (req->period_px >= 2 && req->period_px <= 1e5))) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "render: period %g px (0 = the scene's, else [2, 1e5])",
                 req->period_px);
    return FALSE;
  }
  if (!check_time (req->time_s, error))
    return FALSE;
  return check_exposure (req->exposure_us, req->gain_db, error);
}

static DsImage *
render (const DsRenderer *r, const DsRenderRequest *req, gboolean expected, double *secs, GError **error)
{
  if (!check_request (req, error))
    return NULL;
  DsStageArgs a = { .phase = req->phase, .n_phases = req->n_phases, .illuminator_on = req->illuminator_on,
                    .full = req->all_on, .expected = expected, .exposure_us = req->exposure_us, .gain_db = req->gain_db,
                    .seed = req->seed, .period_px = req->period_px, .time_s = req->time_s };
  DsLight l = { 0 };
  DsImage *out = NULL;
  if (run_stages (r, &l, &a, TRUE, TRUE, secs, error))
    out = g_steal_pointer (&l.frame);
  light_clear (&l);
  return out;
}

DsImage *
ds_renderer_render_timed (const DsRenderer *r, const DsRenderRequest *req, double *secs, GError **error)
{
  return render (r, req, FALSE, secs, error);
}

DsImage *
ds_renderer_render (const DsRenderer *r, const DsRenderRequest *req, GError **error)
{
  return render (r, req, FALSE, NULL, error);
}

DsImage *
ds_renderer_render_expected (const DsRenderer *r, const DsRenderRequest *req, GError **error)
{
  return render (r, req, TRUE, NULL, error);
}

DsImage *
ds_renderer_render_photons (const DsRenderer *r, const DsRenderRequest *req, GError **error)
{
  if (!check_request (req, error))
    return NULL;
  DsStageArgs a = { .phase = req->phase, .n_phases = req->n_phases, .illuminator_on = req->illuminator_on,
                    .full = req->all_on, .exposure_us = req->exposure_us, .gain_db = req->gain_db, .seed = req->seed,
                    .period_px = req->period_px, .time_s = req->time_s };
  DsLight l = { 0 };
  DsImage *out = NULL;
  if (run_stages (r, &l, &a, TRUE, FALSE, NULL, error)) {
    ds_stage_sensor_photons (&l);
    out = g_steal_pointer (&l.direct);
  }
  light_clear (&l);
  return out;
}

DsImage *
ds_renderer_expose (const DsRenderer *r, const DsImage *photons, const DsRenderRequest *req, GError **error)
{
  if (!check_exposure (req->exposure_us, req->gain_db, error))
    return NULL;
  const DsSceneSpec *s = r->spec;
  if (!photons || photons->type != DS_SAMPLE_F32 || photons->width != s->width || photons->height != s->height) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "expose: photons must be an f32 image of %ux%u",
                 s->width, s->height);
    return NULL;
  }
  g_autoptr (DsImage) frame = ds_image_new (DS_SAMPLE_U16, s->width, s->height, error);
  if (!frame || !ds_sensor_expose (&r->sensor, photons, 0.0, req->exposure_us, req->gain_db, req->seed, frame, error))
    return NULL;
  g_atomic_int_inc (&r->runs[DS_RENDER_STAGE_SENSOR]);
  return g_steal_pointer (&frame);
}

double
ds_renderer_saturation_dn (const DsRenderer *r, double gain_db)
{
  return ds_sensor_saturation_dn (&r->sensor, gain_db);
}

gboolean
ds_renderer_truth (const DsRenderer *r, double exposure_us, double gain_db, DsImage **transmissive,
                   DsImage **scattered, GError **error)
{
  return ds_renderer_truth_at (r, exposure_us, gain_db, 0.0, transmissive, scattered, error);
}

gboolean
ds_renderer_truth_at (const DsRenderer *r, double exposure_us, double gain_db, double time_s,
                      DsImage **transmissive, DsImage **scattered, GError **error)
{
  DsRenderRequest req = { .phase = 0, .n_phases = 1, .illuminator_on = TRUE, .exposure_us = exposure_us,
                          .gain_db = gain_db, .time_s = time_s };
  if (!check_request (&req, error))
    return FALSE;
  DsStageArgs a = { .n_phases = 1, .illuminator_on = TRUE, .full = TRUE, .exposure_us = exposure_us,
                    .gain_db = gain_db, .time_s = time_s };
  DsLight l = { 0 };
  if (!run_stages (r, &l, &a, FALSE, FALSE, NULL, error)) {
    light_clear (&l);
    return FALSE;
  }
  double scale = r->sensor.quantum_efficiency * ds_sensor_gain_dn_per_e (&r->sensor, gain_db);
  DsImage *imgs[] = { l.direct, l.scattered };
  for (guint i = 0; i < 2; i++)
    for (guint y = 0; y < imgs[i]->height; y++) {
      float *row = ds_image_row (imgs[i], y);
      for (guint x = 0; x < imgs[i]->width; x++)
        row[x] = (float) (row[x] * scale);
    }
  *transmissive = g_steal_pointer (&l.direct);
  *scattered = g_steal_pointer (&l.scattered);
  light_clear (&l);
  return TRUE;
}
