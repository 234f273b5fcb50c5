#include "drivers/sim/render_cost.h"

#include <math.h>

#include "drivers/sim/sim_error.h"

/* Rates measured on the reference machine (one core of a 2-core x86-64 VM, RelWithDebInfo):
 * `descatter-sim describe` on the scenes of etc/scenes and the estimate's test scenes
 * (tests/sim/render_cost.c prints the ratio of estimate to measurement). */
#define NS_PER_INTERACTION 240.0  /* one Monte Carlo step: a free path, a weight, a new direction */
#define NS_PER_PIXEL 100.0        /* pattern, attenuation, objects and the sensor's noise */
#define NS_PER_SCATTER_PIXEL 120.0/* the scattering stage's convolutions, per plane they run at */
#define ROULETTE_LOG 9.21         /* -ln 1e-4: the weight at which the roulette starts */
#define MAX_KERNEL_RADIUS 2048.0  /* the transport's largest kernel (mc_slab.c) */
#define CORE_PX 64.0              /* the kernel core convolved at full resolution (two_scale.c) */

static guint
interior_planes (const DsSceneSpec *s)
{
  guint n = 0;
  double seen[16];
  for (guint i = 0; i < s->n_objects && n < G_N_ELEMENTS (seen); i++) {
    double z = s->objects[i].depth_mm;
    if (!(z > DS_SCENE_DEPTH_TOLERANCE_MM && z < s->thickness_mm - DS_SCENE_DEPTH_TOLERANCE_MM))
      continue;
    gboolean dup = FALSE;
    for (guint j = 0; j < n; j++)
      dup |= fabs (seen[j] - z) <= DS_SCENE_DEPTH_TOLERANCE_MM;
    if (!dup)
      seen[n++] = z;
  }
  return n;
}

void
ds_render_cost_estimate (const DsSceneSpec *s, DsRenderCost *c)
{
  *c = (DsRenderCost) { 0 };
  gboolean scatters = s->has_medium && s->mus > 0;
  guint planes = scatters ? interior_planes (s) : 0;
  /* Monte Carlo runs for the monte-carlo model, and for diffusion's object planes. */
  if (scatters && (!s->diffusion || planes > 0)) {
    double mut = s->mua + s->mus, albedo = s->mus / mut;
    double tau = mut * s->thickness_mm, tau_tr = s->mus * (1.0 - s->g) * s->thickness_mm + s->mua * s->thickness_mm;
    double absorb = albedo < 1.0 ? ROULETTE_LOG / -log (albedo) : INFINITY;
    double escape = 1.0 + tau + tau * tau_tr;
    c->interactions_per_photon = 1.0 + MIN (absorb, escape);
    c->kernel_s = (double) s->photons * c->interactions_per_photon * NS_PER_INTERACTION * 1e-9;
  }
  double margin = 0;
  if (scatters) {
    double pitch_mm = s->pixel_pitch_um * 1e-3 / s->magnification;
    margin = MIN (MAX_KERNEL_RADIUS, ceil (1.5 * s->thickness_mm / pitch_mm));
  }
  double w = s->width + 2 * margin, h = s->height + 2 * margin;
  c->frame_pixels = (guint64) (w * h);
  double px_ns = NS_PER_PIXEL * s->width * s->height;
  if (scatters) {
    /* Two scales (two_scale.h): full resolution over the sensor and the kernel's core, 8 x 8
     * blocks over the rest of the margin; each interior plane adds its steps. */
    double core = MIN (margin, CORE_PX);
    double fine = (s->width + 2 * core) * (s->height + 2 * core), coarse = w * h / 64.0;
    px_ns += NS_PER_SCATTER_PIXEL * (1.0 + 3.0 * planes) * (fine + coarse);
  }
  c->frame_s = px_ns * 1e-9;
  c->total_s = c->kernel_s + c->frame_s;
}

gboolean
ds_render_cost_check (const DsScene *scene, GError **error)
{
  const DsSceneSpec *s = ds_scene_spec (scene);
  DsRenderCost c;
  ds_render_cost_estimate (s, &c);
  if (c.total_s <= s->max_render_s)
    return TRUE;
  g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_TOO_COSTLY,
               "%s: rendering would take about %.3g s (kernels %.3g s: %" G_GUINT64_FORMAT
               " photons x %.3g interactions; a frame %.3g s: %" G_GUINT64_FORMAT
               " pixels with the margin), above [scene] max-render-s = %g; fewer [medium] photons or a smaller "
               "sensor lower it, a larger max-render-s allows it",
               s->path ? s->path : (s->name ? s->name : "scene"), c.total_s, c.kernel_s, s->photons,
               c.interactions_per_photon, c.frame_s, c.frame_pixels, s->max_render_s);
  return FALSE;
}
