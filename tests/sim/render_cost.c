/* The render cost ceiling: a scene inside every key's range but beyond [scene] max-render-s is
 * refused by ds_renderer_new before any work (the kernel cache it was given stays empty, so no
 * Monte Carlo photon ran), with the estimate named; raising the ceiling admits it. The
 * estimate's scaling is held to the model's physics: the kernels' cost is linear in the
 * photons, a frame's in the pixels, and the interactions per photon meet the closed forms of
 * the two bounds (absorption: the weight falls by the albedo a per interaction to the roulette
 * threshold 1e-4, so ln(1e-4)/ln(a) interactions; escape: a slab of negligible optical depth is
 * crossed without one). How close the seconds come to a measurement is a benchmark's question
 * (tests/bench/render.c prints the ratio): no timing is asserted here. */
#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "drivers/sim/render_cost.h"
#include "drivers/sim/renderer.h"

static DsScene *
scene_of (const char *text)
{
  g_autoptr (GError) error = NULL;
  DsScene *s = ds_scene_load_data (text, strlen (text), "cost.scene", &error);
  g_assert_no_error (error);
  return s;
}

#define SENSOR(w, h) "[sensor]\nwidth=" #w "\nheight=" #h "\n[illuminator]\nperiod-px=8\nirradiance=1\n"
#define MEDIUM(photons) "[medium]\nthickness-mm=3\nmua=0.02\nmus=2\ng=0.8\nphotons=" #photons "\n"

static gboolean
folder_empty (const char *dir)
{
  g_autoptr (GDir) d = g_dir_open (dir, 0, NULL);
  return !d || !g_dir_read_name (d);
}

static void
expect_refused (const char *text, const char *const *fragments)
{
  g_autoptr (DsScene) scene = scene_of (text);
  g_autofree char *cache = g_dir_make_tmp ("ds-cost-cache-XXXXXX", NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new (scene, cache, &error);
  g_assert_null (r);
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_TOO_COSTLY);
  for (guint i = 0; fragments[i]; i++)
    if (!strstr (error->message, fragments[i]))
      g_error ("\"%s\" lacks \"%s\"", error->message, fragments[i]);
  g_assert_true (folder_empty (cache));
  g_rmdir (cache);
}

static void
test_refused_before_work (void)
{
  expect_refused (SENSOR (64, 48) MEDIUM (1e10), (const char *const[]) { "cost.scene", "10000000000 photons",
                                                                           "max-render-s = 20", NULL });
  expect_refused (SENSOR (16384, 16384), (const char *const[]) { "268435456 pixels", "max-render-s", NULL });
  /* the ceiling is the scene's to set: a tiny one refuses even a small scene */
  expect_refused ("[scene]\nmax-render-s=1e-9\n" SENSOR (64, 48),
                  (const char *const[]) { "max-render-s = 1e-09", NULL });
}

static void
test_ceiling_raised (void)
{
  g_autoptr (DsScene) big = scene_of ("[scene]\nmax-render-s=1e9\n" SENSOR (16384, 16384) MEDIUM (1e10));
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_render_cost_check (big, &error));
  g_assert_no_error (error);
  /* and a small scene passes the default ceiling and renders */
  g_autoptr (DsScene) small = scene_of (SENSOR (64, 48));
  g_autoptr (DsRenderer) r = ds_renderer_new (small, NULL, &error);
  g_assert_no_error (error);
  g_assert_nonnull (r);
}

static void
test_scaling (void)
{
  g_autoptr (DsScene) a = scene_of (SENSOR (64, 48) MEDIUM (100000));
  g_autoptr (DsScene) b = scene_of (SENSOR (64, 48) MEDIUM (400000));
  DsRenderCost ca, cb;
  ds_render_cost_estimate (ds_scene_spec (a), &ca);
  ds_render_cost_estimate (ds_scene_spec (b), &cb);
  g_assert_cmpfloat_with_epsilon (cb.kernel_s / ca.kernel_s, 4.0, 1e-9);
  g_assert_cmpfloat (ca.frame_s, ==, cb.frame_s);
  /* no medium: no kernels, a frame proportional to the pixels */
  g_autoptr (DsScene) c = scene_of (SENSOR (64, 48));
  g_autoptr (DsScene) d = scene_of (SENSOR (128, 96));
  DsRenderCost cc, cd;
  ds_render_cost_estimate (ds_scene_spec (c), &cc);
  ds_render_cost_estimate (ds_scene_spec (d), &cd);
  g_assert_cmpfloat (cc.kernel_s, ==, 0);
  g_assert_cmpuint (cc.frame_pixels, ==, 64 * 48);
  g_assert_cmpfloat_with_epsilon (cd.frame_s / cc.frame_s, 4.0, 1e-9);
}

static void
test_interactions_closed_forms (void)
{
  /* thick absorbing slab, albedo 1/2: the absorption bound, 1 + ln(1e-4)/ln(1/2) */
  g_autoptr (DsScene) thick = scene_of (SENSOR (64, 48) "[medium]\nthickness-mm=100\nmua=1\nmus=1\ng=0\n");
  DsRenderCost c;
  ds_render_cost_estimate (ds_scene_spec (thick), &c);
  g_assert_cmpfloat_with_epsilon (c.interactions_per_photon, 1.0 + log (1e-4) / log (0.5), 0.01);
  /* optically thin (tau = 1e-4): crossed without scattering, one step */
  g_autoptr (DsScene) thin = scene_of (SENSOR (64, 48) "[medium]\nthickness-mm=0.001\nmua=0\nmus=0.1\ng=0\n");
  ds_render_cost_estimate (ds_scene_spec (thin), &c);
  g_assert_cmpfloat_with_epsilon (c.interactions_per_photon, 2.0, 1e-3);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/sim/render-cost/refused-before-work", test_refused_before_work);
  g_test_add_func ("/sim/render-cost/ceiling-raised", test_ceiling_raised);
  g_test_add_func ("/sim/render-cost/scaling", test_scaling);
  g_test_add_func ("/sim/render-cost/interactions", test_interactions_closed_forms);
  return g_test_run ();
}
