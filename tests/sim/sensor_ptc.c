/* The EMVA 1288 sensor model against its own definition: the photon-transfer relation
 * var_DN = K (mean_DN - dark_DN) + sigma_d^2 with sigma_d^2 = K^2 (sigma_read^2 + dark_e) + 1/12
 * (quantization), saturation at the full well or the ADC's top, determinism per seed. */
#include <math.h>
#include <string.h>

#include "drivers/sim/sensor.h"

static void
stats (const DsImage *im, double *mean, double *var)
{
  double s = 0, s2 = 0, n = (double) im->width * im->height;
  for (guint y = 0; y < im->height; y++) {
    const guint16 *r = ds_image_row (im, y);
    for (guint x = 0; x < im->width; x++) {
      s += r[x];
      s2 += (double) r[x] * r[x];
    }
  }
  *mean = s / n;
  *var = (s2 - s * s / n) / (n - 1);
}

static DsImage *
expose_flat (const DsSensorModel *m, double photons, double exposure_us, double gain_db, guint64 seed)
{
  g_autoptr (GError) error = NULL;
  DsImage *out = ds_image_new (DS_SAMPLE_U16, 512, 512, &error);
  g_assert_no_error (error);
  g_assert_true (ds_sensor_expose (m, NULL, photons, exposure_us, gain_db, seed, out, &error));
  g_assert_no_error (error);
  return out;
}

static void
test_photon_transfer (void)
{
  DsSensorModel m = { .bit_depth = 12, .quantum_efficiency = 0.5, .system_gain = 0.4, .read_noise_e = 5,
                      .dark_current_e_s = 1000, .full_well_e = 30000 };
  double exposure = 10000; /* 10 ms: 10 dark electrons */
  double dark_e = 10, k = 0.4;
  double dark_dn = k * dark_e;
  double sigma_d2 = k * k * (25 + dark_e) + 1.0 / 12;
  /* Levels from near dark to ~60 % of the ADC; 262144 pixels each: the standard error of a
   * variance is var sqrt(2/n) ~ 0.3 %, so 3 % bounds are safe and still catch a wrong K. */
  const double photons[] = { 200, 2000, 8000, 20000 };
  for (guint i = 0; i < G_N_ELEMENTS (photons); i++) {
    g_autoptr (DsImage) f = expose_flat (&m, photons[i], exposure, 0, 7 + i);
    double mean, var;
    stats (f, &mean, &var);
    double expect_mean = k * (0.5 * photons[i] + dark_e);
    g_assert_cmpfloat (fabs (mean - expect_mean), <, 0.05 + 0.002 * expect_mean);
    double expect_var = k * (mean - dark_dn) + sigma_d2;
    if (fabs (var - expect_var) > 0.03 * expect_var)
      g_error ("photons %g: var %g, photon transfer says %g", photons[i], var, expect_var);
  }
  /* Analog gain: K scales by 10^(dB/20); the relation holds with the new K. */
  g_autoptr (DsImage) f = expose_flat (&m, 4000, exposure, 6, 99);
  double mean, var, k6 = 0.4 * pow (10, 6.0 / 20);
  stats (f, &mean, &var);
  g_assert_cmpfloat (fabs (mean - k6 * (2000 + dark_e)), <, 0.01 * k6 * 2000);
  double expect_var = k6 * (mean - k6 * dark_e) + k6 * k6 * (25 + dark_e) + 1.0 / 12;
  g_assert_cmpfloat (fabs (var - expect_var), <, 0.03 * expect_var);
}

static void
test_quantization (void)
{
  /* No shot, dark or read noise: a mean of 0 photons and a fixed DN come out exactly. */
  DsSensorModel m = { .bit_depth = 8, .quantum_efficiency = 1, .system_gain = 1, .read_noise_e = 0,
                      .dark_current_e_s = 0, .full_well_e = 1e6 };
  g_autoptr (DsImage) f = expose_flat (&m, 0, 1000, 0, 1);
  double mean, var;
  stats (f, &mean, &var);
  g_assert_cmpfloat (mean, ==, 0);
  g_assert_cmpfloat (var, ==, 0);
  /* Read noise only (2 DN around 0, no shot noise): rounding to whole DN puts
   * P(round(N(0, 2)) <= 0) = P(N < 0.5) = Phi(0.25) = 0.5987 of the samples at 0 after clipping. */
  DsSensorModel m3 = { .bit_depth = 12, .quantum_efficiency = 1e-12, .system_gain = 1, .read_noise_e = 2,
                       .dark_current_e_s = 0, .full_well_e = 1e6 };
  g_autoptr (DsImage) h = expose_flat (&m3, 0, 1000, 0, 3);
  guint64 zeros = 0, n = 512 * 512;
  for (guint y = 0; y < 512; y++) {
    const guint16 *r = ds_image_row (h, y);
    for (guint x = 0; x < 512; x++)
      zeros += r[x] == 0;
  }
  double p = (double) zeros / n;
  g_assert_cmpfloat (fabs (p - 0.5987), <, 0.005);
}

static void
test_saturation (void)
{
  /* Full well 20000 e- at K 0.25 is 5000 DN, above a 12-bit ADC: the ADC clips at 4095. */
  DsSensorModel m = { .bit_depth = 12, .quantum_efficiency = 0.5, .system_gain = 0.25, .read_noise_e = 5,
                      .dark_current_e_s = 0, .full_well_e = 20000 };
  g_assert_cmpfloat (ds_sensor_saturation_dn (&m, 0), ==, 4095);
  g_autoptr (DsImage) f = expose_flat (&m, 1e6, 1000, 0, 4);
  double mean, var;
  stats (f, &mean, &var);
  g_assert_cmpfloat (mean, ==, 4095);
  g_assert_cmpuint (f->bit_depth, ==, 12);
  /* Full well below the ADC's top (K 0.1: 2000 DN): a full pixel reads exactly 2000 every time,
   * read noise included (EMVA 1288's saturation capacity: the output stops there). */
  m.system_gain = 0.1;
  g_assert_cmpfloat (ds_sensor_saturation_dn (&m, 0), ==, 2000);
  g_autoptr (DsImage) g = expose_flat (&m, 1e6, 1000, 0, 5);
  stats (g, &mean, &var);
  g_assert_cmpfloat (mean, ==, 2000);
  g_assert_cmpfloat (var, ==, 0);
  /* At 6 dB K doubles (x 1.9953): 3990.5 DN rounds to 3991, still below the ADC's 4095. */
  g_assert_cmpfloat (ds_sensor_saturation_dn (&m, 6), ==, floor (0.1 * pow (10, 6.0 / 20) * 20000 + 0.5));
  /* Just below full well (mean 19900 e-, sigma = sqrt(19900 + 25) = 141 e-): the pixels at 2000 are
   * the ones whose electrons reached the full well, P(N > 100 / 141.2) = 0.2394 (less the half
   * DN rounding up to 2000: P(N > 95 / 141.2) = 0.2504 at most); none exceeds it. */
  g_autoptr (DsImage) h = expose_flat (&m, 2 * 19900, 1000, 0, 6);
  guint64 at = 0, above = 0;
  for (guint y = 0; y < h->height; y++) {
    const guint16 *r = ds_image_row (h, y);
    for (guint x = 0; x < h->width; x++) {
      at += r[x] == 2000;
      above += r[x] > 2000;
    }
  }
  double frac = (double) at / (512.0 * 512.0);
  g_assert_cmpuint (above, ==, 0);
  g_assert_cmpfloat (frac, >, 0.2394 - 0.005);
  g_assert_cmpfloat (frac, <, 0.2504 + 0.005);
}

static void
test_deterministic (void)
{
  DsSensorModel m = { .bit_depth = 12, .quantum_efficiency = 0.5, .system_gain = 0.4, .read_noise_e = 5,
                      .dark_current_e_s = 100, .full_well_e = 30000 };
  g_autoptr (DsImage) a = expose_flat (&m, 1000, 1000, 0, 42);
  g_autoptr (DsImage) b = expose_flat (&m, 1000, 1000, 0, 42);
  g_autoptr (DsImage) c = expose_flat (&m, 1000, 1000, 0, 43);
  g_assert_cmpmem (a->data, a->stride * a->height, b->data, b->stride * b->height);
  g_assert_true (memcmp (a->data, c->data, a->stride * a->height) != 0);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/sim/sensor/photon-transfer", test_photon_transfer);
  g_test_add_func ("/sim/sensor/quantization", test_quantization);
  g_test_add_func ("/sim/sensor/saturation", test_saturation);
  g_test_add_func ("/sim/sensor/deterministic", test_deterministic);
  return g_test_run ();
}
