/* `descatter-sim describe`: the stages a scene builds and why, and what its physics means for
 * the method (docs/scene-format.md). */
#include <math.h>
#include <stdio.h>

#include "drivers/sim/render_cost.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/sim_cli.h"

/* The warning threshold: above this share of the scattered light still carrying the stripes,
 * or modulated scattered light above this share of the direct light, the separation cannot
 * tell them apart (docs/scene-format.md, "What the physics does to the method"). */
#define DS_DESCRIBE_MODULATED_WARN 0.1

static void
describe_scattering (const DsScene *scene, const DsRendererScattering *sc)
{
  const DsSceneSpec *s = ds_scene_spec (scene);
  printf ("scattered light in the acceptance cone: %.4g +- %.2g of the incident light; the kernel (radius %u px = "
          "%.3g mm, margin %u px around the frame) holds %.1f %% of it\n",
          sc->scattered_in_cone, sc->se_scattered_in_cone, sc->kernel_radius_px, sc->kernel_radius_mm,
          sc->margin_px, 100 * sc->held);
  printf ("direct light: %.4g of the incident light (scattered / direct = %.3g without objects)\n", sc->ballistic,
          sc->ballistic > 0 ? sc->held * sc->scattered_in_cone / sc->ballistic : INFINITY);
  double ratio = sc->ballistic > 0 ? sc->modulated * sc->held * sc->scattered_in_cone / sc->ballistic : INFINITY;
  printf ("still modulated at the period (%g px): %.1f %% of the scattered light (the kernel's MTF at 1/period; "
          "Monte Carlo noise alone gives about %.1f %%), %.1f %% of the direct light\n", s->period_px,
          100 * sc->modulated, 100 * sc->modulated_noise, 100 * ratio);
  if (!(sc->modulated > DS_DESCRIBE_MODULATED_WARN || ratio > DS_DESCRIBE_MODULATED_WARN))
    return;
  if (sc->modulated > 2 * sc->modulated_noise)
    printf ("warning: the scattered light keeps the stripes (kernel not much wider than the %g px period): the "
            "estimators count its modulated part, %.0f %% of the direct light, as direct; a longer period keeps "
            "more of it, a period below the kernel's width (if the sensor resolves it) or a wider-spreading medium "
            "would keep less\n", s->period_px, 100 * ratio);
  else
    printf ("warning: the kernel's modulation at the period is Monte Carlo noise, yet %.0f %% of the direct light: "
            "the frames carry it; raise [medium] photons (now %" G_GUINT64_FORMAT ")\n", 100 * ratio, s->photons);
}

/* What one frame costs, measured here and now (the machine's load is in it): the render cost a
 * user of labsim or `render` meets, and the stage that takes it. */
static int
describe_cost (const DsRenderer *r, const DsScene *scene)
{
  double secs[DS_RENDER_N_STAGES] = { 0 };
  DsRenderRequest req = { .phase = 0, .n_phases = 4, .illuminator_on = TRUE,
                          .exposure_us = ds_scene_default_exposure_us (scene) };
  g_autoptr (GError) error = NULL;
  gint64 t0 = g_get_monotonic_time ();
  g_autoptr (DsImage) frame = ds_renderer_render_timed (r, &req, secs, &error);
  double total = (double) (g_get_monotonic_time () - t0) / 1e6;
  if (!frame) {
    fprintf (stderr, "descatter-sim: %s\n", error->message);
    return 1;
  }
  guint top = 0;
  for (guint s = 1; s < DS_RENDER_N_STAGES; s++)
    top = secs[s] > secs[top] ? s : top;
  printf ("render cost: one frame in %.3g s here and now (%.0f %% of it %s); %s\n", total,
          total > 0 ? 100 * secs[top] / total : 0.0, ds_render_stage_name ((DsRenderStage) top),
          ds_scene_has_motion (scene) ? "objects move: descatter-labsim renders every frame at its own time"
                                      : "descatter-labsim renders each phase and dark once per phase count and "
                                        "period, before serving and then in the background");
  DsRenderCost est;
  ds_render_cost_estimate (ds_scene_spec (scene), &est);
  printf ("estimated before rendering: a frame %.3g s, the kernels %.3g s when not cached (%.3g interactions per "
          "photon); refused above [scene] max-render-s = %g s\n", est.frame_s, est.kernel_s,
          est.interactions_per_photon, ds_scene_spec (scene)->max_render_s);
  return 0;
}

int
ds_sim_describe_main (int argc, char **argv)
{
  if (argc != 2) {
    fprintf (stderr, "usage: descatter-sim describe SCENE\n");
    return 2;
  }
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) scene = ds_scene_load (argv[1], &error);
  g_autoptr (DsRenderer) r = scene ? ds_renderer_new (scene, NULL, &error) : NULL;
  if (!r) {
    fprintf (stderr, "descatter-sim: %s\n", error->message);
    return 1;
  }
  printf ("%s: %ux%u, stages:\n", argv[1], ds_scene_width (scene), ds_scene_height (scene));
  for (guint i = 0; i < ds_renderer_n_stages (r); i++)
    printf ("  %-22s %s\n", ds_renderer_stage_name (r, i), ds_renderer_stage_reason (r, i));
  printf ("not built (not declared by the scene):");
  guint n_skipped = 0;
  /* Motion is a property of objects, not a part of the lab: a still scene does not mention it. */
  for (guint s = 0; s < DS_RENDER_N_STAGES; s++)
    if (!ds_renderer_has_stage (r, (DsRenderStage) s) && s != DS_RENDER_STAGE_MOTION) {
      printf (" %s", ds_render_stage_name ((DsRenderStage) s));
      n_skipped++;
    }
  printf ("%s\n", n_skipped ? "" : " none");
  DsRendererScattering sc;
  if (ds_renderer_scattering (r, &sc))
    describe_scattering (scene, &sc);
  return describe_cost (r, scene);
}

