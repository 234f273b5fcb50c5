/* What objects in front of the stripes do to the probe (daemon/operating/scene_probe.h), against
 * independent expectations: a closed form for the stripes' amplitude on a scene that varies across
 * the columns, and the simulator's truth (its kernel's MTF, its sensor's gain) for pilot frames
 * rendered as `descatterctl validate` takes them (daemon/ctl/sim_rig.c). */
#include <glib.h>
#include <math.h>

#include "daemon/ctl/validate.h"
#include "daemon/operating/stripe_model.h"
#include "probe_rig.h"

/* The opaque lines of a grid of pitch `pitch` and line width `line` at column x. */
static double
grid_open (double x, double pitch, double line)
{
  double u = fmod (x, pitch);
  return u < line ? 0.0 : 1.0;
}

/* A difference profile is the stripes times the columns' Ld: here sine stripes at 9.38 px (the
 * pilot's P/2 on generated scene 12-0) on a grid of 42 px with 7 px lines, whose 9th harmonic lies
 * 0.5 % from twice the stripes' frequency, so the product has a component next to the stripes'
 * own that a plain fit reads as their amplitude. The stripes' amplitude on the scene's mean
 * (mean Ld times the pattern's; the envelope is the columns' level over its mean) is the closed
 * form. The fit on the scene's envelope must read it
 * within 0.3 %, also with an even scattered light in the envelope; the plain fit is off by more
 * than 1 % (asserted, so that the case shows what it is about). */
static void
test_envelope_fit (void)
{
  const guint w = 192;
  const double P = 9.38, amp = 200;
  double profile[192], envelope[192], envelope_lg[192];
  double mean_ld = 0;
  for (guint x = 0; x < w; x++)
    mean_ld += grid_open (x + 0.5, 42, 7) * grid_open (x + 0.5, 16, 4);
  mean_ld /= w;
  double mean_env = 0, mean_env_lg = 0;
  for (guint x = 0; x < w; x++) {
    double ld = grid_open (x + 0.5, 42, 7) * grid_open (x + 0.5, 16, 4);
    profile[x] = ld * amp * cos (2 * G_PI * (x / P - 0.3));
    envelope[x] = ld;
    envelope_lg[x] = ld + 0.4 * mean_ld;   /* Ld + Lg, Lg even across the columns */
  }
  for (guint x = 0; x < w; x++) {
    mean_env += envelope[x] / w;
    mean_env_lg += envelope_lg[x] / w;
  }
  for (guint x = 0; x < w; x++) {
    envelope[x] /= mean_env;
    envelope_lg[x] /= mean_env_lg;
  }
  /* The amplitude on the level where the envelope is 1, the scene's mean. */
  double want = mean_ld * amp;
  DsStripeHarmonics plain, fitted, fitted_lg;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_stripe_harmonics_fit (profile, NULL, 0, w, P, 4, &plain, &error));
  g_assert_true (ds_stripe_harmonics_fit_envelope (profile, NULL, envelope, 0, w, P, 4, &fitted, &error));
  g_assert_true (ds_stripe_harmonics_fit_envelope (profile, NULL, envelope_lg, 0, w, P, 4, &fitted_lg, &error));
  g_assert_no_error (error);
  g_test_message ("first harmonic %.3f (closed form), plain fit %.3f, on the envelope %.3f, with Lg %.3f", want,
                  plain.amplitude[1], fitted.amplitude[1], fitted_lg.amplitude[1]);
  g_assert_cmpfloat (fabs (plain.amplitude[1] / want - 1), >, 0.01);
  g_assert_cmpfloat (fabs (fitted.amplitude[1] / want - 1), <, 0.003);
  g_assert_cmpfloat (fabs (fitted_lg.amplitude[1] / want - 1), <, 0.003);
  g_assert_cmpfloat_with_epsilon (fitted.phase[1], 0.3, 1e-3);
}

/* Generated scene 12-0: two opaque grids (42 px with 7 px lines, 16 px with 4 px lines) behind a
 * medium that scatters next to nothing (optical depth 0.08), sine stripes at 18.75 px. The probe
 * read 3.4 % of the direct light as scattered stripes at P (the grid beating with the pilot's
 * stripes at P/2), and targets the rig reaches were refused. The scattered stripes must be within
 * a factor 1.5 of the kernel's truth (0.45 %), Ld within 3 % of the truth's. */
static void
test_grids (void)
{
  static const char text[] =
    "[scene]\nname=grids\n\n"
    "[sensor]\nwidth=192\nheight=144\nbit-depth=12\npixel-pitch-um=6.99443\nquantum-efficiency=0.675275\n"
    "system-gain=0.142244\nread-noise-e=14.0065\ndark-current-e-per-s=27.0155\nfull-well-e=15729.6\n"
    "exposure-us=3995\n\n"
    "[illuminator]\npattern=sine\nperiod-px=18.75\nedge-blur-px=0.632266\nirradiance=1\n\n"
    "[medium]\nthickness-mm=11.9144\nmua=0.0502815\nmus=0.00711303\ng=0.815287\nn=1.33948\n"
    "photons=100000\nseed=743347\n\n"
    "[camera]\nmagnification=0.11067\nacceptance-half-angle-deg=12.4167\n\n"
    "[object.o0]\nshape=grid\npitch=42\nline-width=7\ndepth-mm=11.0552\ntransmittance=0\n\n"
    "[object.o1]\nshape=rect\nposition=158;53\nsize=23;19\ndepth-mm=9.67985\ntransmittance=0.361517\n\n"
    "[object.o2]\nshape=grid\npitch=16\nline-width=4\ndepth-mm=8.98971\ntransmittance=0\n";
  DsValidateScene vs;
  double truth, gain;
  probe_rig_probe_scene (text, "grids", &vs, &truth, &gain);
  double leak = ds_scene_probe_leak (&vs.probe, vs.probe.geometry.period_px, 1);
  g_test_message ("grids: scattered stripes at P %.4f (truth %.4f), Ld %.1f (truth %.1f)", leak, truth,
                  vs.probe.light.ld_mean, vs.truth_ld_mean);
  g_assert_cmpfloat (truth, <, 0.01);
  g_assert_true (vs.probe.leak.measured);
  g_assert_cmpfloat (leak, <, 1.5 * truth);
  g_assert_cmpfloat (leak, >, truth / 1.5);
  g_assert_cmpfloat (fabs (vs.probe.light.ld_mean / vs.truth_ld_mean - 1), <, 0.03);
}

/* The shot noise the probe reads on the scene (DN^2 per DN of signal) against the gain of the
 * simulator's sensor, within `tolerance` of it. */
static void
assert_shot_noise (const char *text, const char *name, double tolerance)
{
  DsValidateScene vs;
  double truth, gain;
  probe_rig_probe_scene (text, name, &vs, &truth, &gain);
  g_test_message ("%s: shot noise %.5f DN^2 per DN, the sensor's %.5f", name, vs.probe.noise.gain, gain);
  g_assert_cmpfloat (fabs (vs.probe.noise.gain / gain - 1), <, tolerance);
}

/* Generated scene 11-6: two opaque rectangles over a fifth of the frame and a grid, a 10-bit
 * sensor whose pilot frames clip over most of the lit field: what the noise is read on is mostly
 * the objects' shadows, with soft edges along y. The probe read the shot noise at 0.41 of the
 * sensor's gain (the predictions x1.6 low). It must be within 10 % of the simulator's gain. */
static void
test_shot_noise_under_objects (void)
{
  static const char text[] =
    "[scene]\nname=shadows\n\n"
    "[sensor]\nwidth=256\nheight=192\nbit-depth=10\npixel-pitch-um=5.22727\nquantum-efficiency=0.493543\n"
    "system-gain=0.0458107\nread-noise-e=13.6892\ndark-current-e-per-s=33.2621\nfull-well-e=21529\n"
    "exposure-us=146029\n\n"
    "[illuminator]\npattern=sine\nperiod-px=23.75\nblack-level=0.149753\nedge-blur-px=0.70305\nirradiance=1\n\n"
    "[medium]\nthickness-mm=3.29756\nmua=0.124595\nmus=0.146268\ng=0.407141\nn=1.37241\n"
    "photons=100000\nseed=210488\n\n"
    "[camera]\nmagnification=0.180217\nacceptance-half-angle-deg=15.3243\n\n"
    "[object.o0]\nshape=rect\nposition=76;4\nsize=101;77\ndepth-mm=0.0853433\ntransmittance=0\n\n"
    "[object.o1]\nshape=rect\nposition=92;11\nsize=127;70\ndepth-mm=1.681\ntransmittance=0\n\n"
    "[object.o2]\nshape=grid\npitch=64\nline-width=9\ndepth-mm=0.304467\ntransmittance=0.62093\n";
  assert_shot_noise (text, "shadows", 0.10);
}

/* Generated scene 13-4: square stripes of duty 0.457 at 6 px on a grid of pitch 12 with opaque
 * 1 px lines and two sets of wavy lines, a dim 10-bit scene. Read on the pilot pair's difference,
 * the grid's rows (structure along y, which a second difference along y keeps) counted as noise:
 * the shot noise at 5.5 times the sensor's gain, every prediction x0.42-0.64 of the achieved
 * error. On the two pairs' sums over all columns the grid's rows still entered at the gaps the duty
 * leaves (1.28 times the gain). With this blur no column's two sums agree at 6 px (scene_probe.c:
 * sets_columns), and the pair weighted per column by its own ratio cancels the rows. */
static void
test_shot_noise_grid_rows (void)
{
  static const char text[] =
    "[scene]\nname=grid rows\n\n"
    "[sensor]\nwidth=192\nheight=144\nbit-depth=10\npixel-pitch-um=5.75371\nquantum-efficiency=0.572344\n"
    "system-gain=0.0952051\nread-noise-e=3.96982\ndark-current-e-per-s=42.0361\nfull-well-e=7504.56\n"
    "exposure-us=1083\n\n"
    "[illuminator]\npattern=square\nperiod-px=6\nduty=0.457429\nblack-level=0.0823837\nedge-blur-px=0.711843\n"
    "irradiance=1\n\n"
    "[medium]\nthickness-mm=14.0155\nmua=0.00174499\nmus=0.00615852\ng=0.828182\nn=1.38\n"
    "photons=100000\nseed=803555\n\n"
    "[camera]\nmagnification=0.0640463\nacceptance-half-angle-deg=19.2326\n\n"
    "[object.o0]\nshape=grid\npitch=12\nline-width=1\ndepth-mm=12.7323\ntransmittance=0\n\n"
    "[object.o1]\nshape=lines\npitch=24\nline-width=3\namplitude=2\ndepth-mm=4.43921\ntransmittance=0.314281\n\n"
    "[object.o2]\nshape=lines\npitch=49\nline-width=9\namplitude=3\ndepth-mm=6.03779\ntransmittance=0\n";
  assert_shot_noise (text, "grid rows", 0.15);
}

/* Square stripes far from duty 1/2 (gaps of 0.2 P, then overlaps of 0.18 P) over a disc of
 * transmittance 0.25 inside a weakly scattering slab, on an 8-bit sensor of 34 electrons per DN:
 * a pixel lit by one phase is dark in the other, so the one pair's combination carries almost no
 * shot noise, and the scene's shading along y passes for it; the two pairs' sums, read where they
 * agree, cancel the scene. */
static void
test_shot_noise_square_off_half (void)
{
  for (guint k = 0; k < 2; k++) {
    g_autofree char *text = g_strdup_printf (
      "[scene]\nname=off half\n\n"
      "[sensor]\nwidth=192\nheight=144\nbit-depth=8\npixel-pitch-um=5\nquantum-efficiency=0.5\n"
      "system-gain=0.03\nread-noise-e=6\ndark-current-e-per-s=100\nfull-well-e=7600\nexposure-us=12000\n\n"
      "[illuminator]\npattern=square\nperiod-px=%s\nduty=%s\nedge-blur-px=0.5\nirradiance=1\n\n"
      "[medium]\nthickness-mm=6\nmua=0.006\nmus=0.05\ng=0.6\nn=1.4\nphotons=100000\nseed=4242\n\n"
      "[camera]\nmagnification=0.15\nacceptance-half-angle-deg=15\n\n"
      "[object.o0]\nshape=disc\nposition=80;60\nradius=30\ndepth-mm=2\ntransmittance=0.25\n",
      k ? "17.5" : "21", k ? "0.68" : "0.3");
    assert_shot_noise (text, k ? "duty 0.68" : "duty 0.3", 0.12);
  }
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/probe-objects/envelope-fit", test_envelope_fit);
  g_test_add_func ("/probe-objects/grids", test_grids);
  g_test_add_func ("/probe-objects/shot-noise-under-objects", test_shot_noise_under_objects);
  g_test_add_func ("/probe-objects/shot-noise-grid-rows", test_shot_noise_grid_rows);
  g_test_add_func ("/probe-objects/shot-noise-square-off-half", test_shot_noise_square_off_half);
  return g_test_run ();
}
