/* The study's rig with moving objects (daemon/ctl/sim_rig.h, ds_sim_rig_separate_at): every
 * frame is taken at its own time, so an object moving during a set is smeared over the way it
 * went, and centred where it was halfway through.
 *
 * Independent expectation: a dark bar moving at v across sine stripes, its frames at times t_i.
 * A pixel the bar covers during part of the set sees it in some phases only, so the bar's
 * shadow in the transmissive image spreads over v (t_last - t_first) beyond its width, its
 * darkness centred (phases in order, a uniform motion: symmetric about the middle) at the bar's
 * position at the mean of the frames' times. With all frames at one instant the shadow is the
 * bar itself, sharp, where it stood then. */
#include <math.h>
#include <string.h>

#include "daemon/ctl/sim_rig.h"

#define W 160
#define H 48
#define BAR_X0 20.0
#define BAR_W 10.0

static const char scene_text[] =
  "[sensor]\nwidth=160\nheight=48\nexposure-us=1000\nread-noise-e=0\ndark-current-e-per-s=0\n"
  "[illuminator]\npattern=sine\nperiod-px=8\nirradiance=1\n"
  "[object.bar]\nshape=rect\nposition=20;-20\nsize=10;100\n";

static DsSeparation *
separate (const DsSimRig *rig, guint n, const double *times)
{
  const DsScene *scene = ds_sim_rig_scene (rig);
  DsSeparationParams p;
  ds_separation_params_init (&p, n);
  p.estimator = DS_ESTIMATOR_SINE;
  p.pattern = DS_PATTERN_SINE;
  p.system_gain = ds_scene_system_gain (scene);
  p.geometry.period_px = ds_scene_period_px (scene);
  p.geometry.pixel_aperture = 1;
  DsSeparation *sep = NULL;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_sim_rig_separate_at (rig, &p, 1, 1, 1000, 0, TRUE, times, &sep, NULL, &error));
  g_assert_no_error (error);
  return sep;
}

/* The shadow in the middle row: how much darkness (pixels of full shadow), where it is centred,
 * and over how many pixels it lies (those darker than 2 % and lighter than 98 % of the open level). */
static void
shadow (const DsImage *t, double *area, double *centroid, guint *partial)
{
  const float *row = ds_image_row (t, H / 2);
  double open = 0;
  for (guint x = W - 30; x < W; x++)
    open += row[x] / 30.0;
  double a = 0, m = 0;
  *partial = 0;
  for (guint x = 0; x < W - 30; x++) {
    double d = 1.0 - row[x] / open;
    a += d;
    m += d * x;
    *partial += d > 0.02 && d < 0.98;
  }
  *area = a;
  *centroid = m / a;
}

static void
test_smeared_about_the_middle (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsSimRig) still_rig = ds_sim_rig_new_from_data (scene_text, "bar.scene", &error);
  g_assert_no_error (error);
  g_autoptr (DsSimRig) rig = ds_sim_rig_with_speed (still_rig, 500, "bar", &error);
  g_assert_no_error (error);
  const guint n = 8;
  double times[8], sum = 0;
  for (guint k = 0; k < n; k++)
    sum += times[k] = 0.002 + 0.01 * k; /* frames 10 ms apart: 5 px each at 500 px/s */
  double mean_t = sum / n, span = times[n - 1] - times[0];

  /* All frames at one instant: a sharp bar where it stood. */
  double at_once[8];
  for (guint k = 0; k < n; k++)
    at_once[k] = 0.03;
  g_autoptr (DsSeparation) sharp = separate (rig, n, at_once);
  double a, c;
  guint partial;
  shadow (sharp->transmissive, &a, &c, &partial);
  g_assert_cmpfloat (fabs (a - BAR_W), <, 0.3);
  g_assert_cmpfloat (fabs (c - (BAR_X0 + 500 * 0.03 + BAR_W / 2)), <, 0.3);
  g_assert_cmpuint (partial, <=, 2);

  /* Each frame at its time: smeared over v x span, centred at the mean time's position. */
  g_autoptr (DsSeparation) moving = separate (rig, n, times);
  shadow (moving->transmissive, &a, &c, &partial);
  double expect_c = BAR_X0 + 500 * mean_t + BAR_W / 2;
  g_test_message ("smeared: darkness %.2f px, centre %.2f (expected %.2f), %u partial pixels over a %.1f px way",
                  a, c, expect_c, partial, 500 * span);
  g_assert_cmpfloat (fabs (c - expect_c), <, 1.0);
  /* A pixel the bar passes sees it in part of the phases: partly dark over the way it went
   * (35 px here) rather than the bar's own width. */
  g_assert_cmpuint (partial, >=, (guint) (0.6 * 500 * span));
}

static void
test_speed_variant (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsSimRig) rig = ds_sim_rig_new_from_data (scene_text, "bar.scene", &error);
  g_assert_no_error (error);
  g_autoptr (DsSimRig) moved = ds_sim_rig_with_speed (rig, 250, NULL, &error);
  g_assert_no_error (error);
  g_assert_cmpfloat (ds_scene_spec (ds_sim_rig_scene (moved))->objects[0].vx, ==, 250);
  g_assert_cmpfloat (ds_scene_spec (ds_sim_rig_scene (moved))->objects[0].vy, ==, 0);
  g_autoptr (DsSimRig) none = ds_sim_rig_with_speed (rig, 250, "shark", &error);
  g_assert_null (none);
  g_assert_nonnull (error);
  g_assert_nonnull (strstr (error->message, "shark"));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/sim-rig/motion/smeared-about-the-middle", test_smeared_about_the_middle);
  g_test_add_func ("/sim-rig/motion/speed-variant", test_speed_variant);
  return g_test_run ();
}
