/* The scene renderer: frames of the stripe-lit scene as the camera would record them, and the
 * noise-free truth. Built from what the scene declares: a stage the scene does not call for is
 * not in the list and costs nothing (docs/scene-format.md, "Stages").
 *
 * Threads: ds_renderer_new may take seconds (Monte Carlo kernels, cached on disk); after that
 * the renderer is immutable (only atomic run counters change) and every function here may be
 * called from any thread at once. All randomness of a frame comes from its request's seed. */
#pragma once
#include <glib.h>

#include "drivers/sim/scene.h"
#include "drivers/sim/transport.h"
#include "proc/image.h"

G_BEGIN_DECLS

typedef struct DsRenderer DsRenderer;

/* In the order they run. */
typedef enum {
  DS_RENDER_STAGE_PATTERN = 0, /* stripe pattern: always */
  DS_RENDER_STAGE_BOUNDARY,    /* Fresnel transmittance: medium index != outside index */
  DS_RENDER_STAGE_BALLISTIC,   /* Beer-Lambert attenuation: a medium with sigma_t > 0 */
  DS_RENDER_STAGE_MOTION,      /* moving objects at the frame's time: an object with a velocity */
  DS_RENDER_STAGE_OBJECTS,     /* object transmittance: objects declared */
  DS_RENDER_STAGE_SCATTERING,  /* PSF convolution: a medium with sigma_s > 0 */
  DS_RENDER_STAGE_AMBIENT,     /* pattern-independent light: [ambient] declared */
  DS_RENDER_STAGE_SENSOR,      /* EMVA 1288 model: always (the scene declares a sensor) */
  DS_RENDER_N_STAGES
} DsRenderStage;

/* psf_cache_dir: where Monte Carlo kernels are cached; NULL = the transport's default. Fails
 * DS_SIM_ERROR_TOO_COSTLY, before any work, when the estimated cost exceeds the scene's
 * [scene] max-render-s (render_cost.h). */
DsRenderer *ds_renderer_new (const DsScene *scene, const char *psf_cache_dir, GError **error);
/* As ds_renderer_new with the scattering kernels given instead of computed (tests): their
 * planes must be the scene's object depths inside the medium; copied from. */
DsRenderer *ds_renderer_new_with_slab_kernels (const DsScene *scene, const DsSlabKernels *kernels, GError **error);
/* The same with one whole-slab kernel psf_full (f32, odd square, centred; copied), for a scene
 * without objects inside the medium. psf_before and psf_after must be NULL: the split-slab
 * model they fed is gone (docs/scene-format.md, "Objects inside the medium"). */
DsRenderer *ds_renderer_new_with_kernels (const DsScene *scene, const DsImage *psf_full,
                                          const DsImage *psf_before, const DsImage *psf_after,
                                          GError **error);
void ds_renderer_free (DsRenderer *renderer);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsRenderer, ds_renderer_free)

typedef struct {
  guint phase, n_phases;
  gboolean illuminator_on;
  /* With illuminator_on: every stripe lit at once (the illuminator's "all on"), the pattern's
   * lit level everywhere; phase is then unused. */
  gboolean all_on;
  double exposure_us;
  double gain_db;
  guint64 seed;
  /* The stripe period on the sensor (px): 0 = the scene's. An illuminator that can change its
   * period (the PERIOD register) projects the scene's pattern at another period. */
  double period_px;
  /* The frame's time (s): the midpoint of its exposure, from the scene's time origin (0, where
   * moving objects stand at their declared position). Moves the objects that declare a velocity;
   * a scene without one renders the same bits at every time. */
  double time_s;
} DsRenderRequest;

/* u16 frame with the sensor's bit depth. */
DsImage *ds_renderer_render (const DsRenderer *r, const DsRenderRequest *req, GError **error);
/* As render, adding each stage's time (s) into stage_seconds[DS_RENDER_N_STAGES]. */
DsImage *ds_renderer_render_timed (const DsRenderer *r, const DsRenderRequest *req,
                                   double *stage_seconds, GError **error);
/* The frame's expectation: f32 DN, noise-free, before quantization and clipping (ambient and
 * dark signal included). The mean of many render() calls over seeds converges to it where
 * nothing saturates. */
DsImage *ds_renderer_render_expected (const DsRenderer *r, const DsRenderRequest *req, GError **error);
/* The light of a frame before the sensor: f32 photons per pixel reaching it in the exposure
 * (direct + scattered + ambient). With ds_renderer_expose it is render() in two steps, same
 * bits: a caller that shows the same light many times (labsim) renders it once and exposes it
 * per frame. */
DsImage *ds_renderer_render_photons (const DsRenderer *r, const DsRenderRequest *req, GError **error);
/* The sensor model (EMVA 1288, docs/scene-format.md) on photons from ds_renderer_render_photons:
 * a u16 frame with the sensor's bit depth, noise from req->seed, dark signal from
 * req->exposure_us, gain req->gain_db (phase fields unused). Fails INVALID on a request out of
 * range or photons of the wrong type or size. */
DsImage *ds_renderer_expose (const DsRenderer *r, const DsImage *photons, const DsRenderRequest *req,
                             GError **error);
/* The lowest DN that means "clipped" at this gain (full well or ADC top, whichever is lower):
 * frames.json's saturation_dn (docs/phase-folder.md). */
double ds_renderer_saturation_dn (const DsRenderer *r, double gain_db);
/* f32 DN, noise-free, no ambient or dark: Ld = direct and Lg = scattered light under full
 * uniform illumination (the pattern's "on" level everywhere). */
gboolean ds_renderer_truth (const DsRenderer *r, double exposure_us, double gain_db,
                            DsImage **transmissive, DsImage **scattered, GError **error);
/* The truth at time_s (s): moving objects where they are then (ds_renderer_truth is time 0). */
gboolean ds_renderer_truth_at (const DsRenderer *r, double exposure_us, double gain_db, double time_s,
                               DsImage **transmissive, DsImage **scattered, GError **error);

/* The stages built for this scene, in order, with the reason each is there. */
guint ds_renderer_n_stages (const DsRenderer *r);
DsRenderStage ds_renderer_stage (const DsRenderer *r, guint i);
const char *ds_renderer_stage_name (const DsRenderer *r, guint i);
const char *ds_renderer_stage_reason (const DsRenderer *r, guint i);
/* The name of a stage kind ("stripe-pattern", "scattering", ...). */
const char *ds_render_stage_name (DsRenderStage stage);
gboolean ds_renderer_has_stage (const DsRenderer *r, DsRenderStage stage);
/* How many times a stage ran (all threads): proof that an undeclared stage costs nothing. */
guint64 ds_renderer_stage_runs (const DsRenderer *r, DsRenderStage stage);

const DsScene *ds_renderer_scene (const DsRenderer *r);

/* What the scattering stage was built with (describe). FALSE without one. */
typedef struct {
  guint kernel_radius_px, margin_px;
  double kernel_radius_mm;
  double scattered_in_cone, se_scattered_in_cone; /* fraction of the incident light, all of it */
  double held;       /* the share of it inside the kernel */
  double modulated;  /* the kernel's MTF at 1/period along x: the share of the scattered light
                      * that still carries the stripes */
  double modulated_noise; /* the Monte Carlo noise floor of that estimate (0 for diffusion) */
  double ballistic;  /* the direct light's share of the incident light (Fresnel, Beer-Lambert) */
  guint n_planes;    /* object depths inside the medium */
  double depth_mm[DS_SLAB_MAX_PLANES];
} DsRendererScattering;
gboolean ds_renderer_scattering (const DsRenderer *r, DsRendererScattering *out);

G_END_DECLS
