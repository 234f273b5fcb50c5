/* The calibrator takes stripes only when they step with the phases (proc/calibration_steps.h).
 * Phase sets written here in closed form: the picture of Aravis's fake camera (arvfakecamera.c:
 * a diagonal ramp, value ((x + y + frame) mod 255) x 179 in Mono16, shifting one pixel per frame
 * whatever the illuminator does), a stripe pattern that does not move with the phases, flat
 * frames with noise, and, as the control, noisy stripes that do step (N = 3 and 8) and must pass. */
#include <glib.h>
#include <math.h>
#include <string.h>

#include "proc/calibration.h"
#include "proc/calibration_steps.h"
#include "proc/proc_error.h"
#include "tests/common/test_random.h"

#define W 512u
#define H 64u

typedef enum { RAMP, STATIC_STRIPES, FLAT, STEPPING } Picture;

/* Square stripes of period 16 px (duty 0.5) at 1000 DN over 100 DN, or the ramp. */
static DsImage *
frame (Picture what, guint k, guint n, GRand *r)
{
  DsImage *img = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  for (guint y = 0; y < H; y++) {
    guint16 *row = ds_image_row (img, y);
    for (guint x = 0; x < W; x++) {
      double v;
      if (what == RAMP) {
        v = (double) ((x + y + 7 + k) % 255) * 179;
      } else {
        double shift = what == STEPPING ? (double) k / n : 0;
        double u = (x + 0.5) / 16.0 - shift;
        gboolean on = what != FLAT && u - floor (u) < 0.5;
        v = 100 + (on ? 1000 : 0) + (what == FLAT ? 500 : 0) + 20 * test_normal (r);
      }
      row[x] = (guint16) CLAMP (lround (v), 0, 65535);
    }
  }
  return img;
}

static gboolean
calibrate (Picture what, guint n, double period, DsCalibration *out, GError **error)
{
  g_autoptr (DsCalibrator) cal = ds_calibrator_new (n, W, H, error);
  g_assert_nonnull (cal);
  GRand *r = g_rand_new_with_seed (11);
  for (guint k = 0; k < n; k++) {
    g_autoptr (DsImage) img = frame (what, k, n, r);
    g_assert_true (ds_calibrator_add (cal, k, img, NULL));
  }
  g_rand_free (r);
  DsCalibrationHints hints;
  ds_calibration_hints_init (&hints);
  hints.period_px = period;
  return ds_calibrator_finish (cal, &hints, out, error);
}

static void
assert_no_stripes (Picture what, guint n, double period, const char *source)
{
  g_autoptr (GError) error = NULL;
  DsCalibration c;
  g_assert_false (calibrate (what, n, period, &c, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY);
  g_test_message ("%s", error->message);
  g_autofree char *want = g_strdup_printf ("no stripes at the %s period", source);
  g_assert_nonnull (strstr (error->message, want));
  g_assert_nonnull (strstr (error->message, "standard errors where 5 are needed"));
}

/* The fake camera's ramp, at the configured period and at the period the detector finds in it. */
static void
test_fake_camera_ramp (void)
{
  assert_no_stripes (RAMP, 8, 16, "given");
  g_autoptr (GError) error = NULL;
  DsCalibration c;
  g_assert_false (calibrate (RAMP, 8, 0, &c, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY);
  g_test_message ("%s", error->message);
  g_assert_true (strstr (error->message, "no stripes at the measured period") ||
                 strstr (error->message, "no stripes at any period"));
}

/* Stripes that stay where they are whatever the phase: an illuminator stuck on one phase. */
static void
test_static_stripes (void)
{
  assert_no_stripes (STATIC_STRIPES, 8, 16, "given");
  assert_no_stripes (STATIC_STRIPES, 4, 16, "given");
}

static void
test_flat (void)
{
  assert_no_stripes (FLAT, 8, 16, "given");
}

/* The control: stripes that step pass, at N = 3 (the fewest the residuals can judge) and 8, with
 * the period given and measured, and the period and duty come out as drawn. */
static void
test_stepping_stripes_pass (void)
{
  const guint ns[] = { 3, 8 };
  for (guint i = 0; i < G_N_ELEMENTS (ns); i++)
    for (int measured = 0; measured < 2; measured++) {
      g_autoptr (GError) error = NULL;
      DsCalibration c;
      g_assert_true (calibrate (STEPPING, ns[i], measured ? 0 : 16, &c, &error));
      g_assert_no_error (error);
      g_assert_cmpfloat (fabs (c.period_px - 16), <, 0.01);
      g_assert_cmpfloat (fabs (c.duty - 0.5), <, 0.03);
    }
}

/* The check itself on measurements written down: phases that step by 1/N pass whatever their
 * offset; the same amplitudes at phases that do not step fail. */
static void
test_check_closed_form (void)
{
  DsStripePhase sp[6];
  DsStripeSteps st;
  for (guint k = 0; k < 6; k++) {
    memset (&sp[k], 0, sizeof sp[k]);
    sp[k].amplitude = 10;
    sp[k].mean = 100;
    sp[k].snr = 50;
    sp[k].phase = fmod (0.7 + k / 6.0 + 0.01 * (k % 2 ? 1 : -1), 1.0);
  }
  g_assert_true (ds_stripe_steps_check (sp, 6, 16, "given", &st, NULL));
  g_assert_cmpfloat (fabs (st.offset_cycles - 0.7), <, 0.01);
  g_assert_cmpfloat (st.spread_cycles, <, 0.011);
  for (guint k = 0; k < 6; k++)
    sp[k].phase = 0.7;
  g_autoptr (GError) error = NULL;
  g_assert_false (ds_stripe_steps_check (sp, 6, 16, "given", &st, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY);
  g_assert_cmpfloat (st.stepping, <, 1e-9);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/calibration-steps/fake-camera-ramp", test_fake_camera_ramp);
  g_test_add_func ("/calibration-steps/static-stripes", test_static_stripes);
  g_test_add_func ("/calibration-steps/flat", test_flat);
  g_test_add_func ("/calibration-steps/stepping-stripes-pass", test_stepping_stripes_pass);
  g_test_add_func ("/calibration-steps/check-closed-form", test_check_closed_form);
  return g_test_run ();
}
