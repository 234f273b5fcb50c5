/* The camera sensor after the EMVA 1288 linear model: photons -> electrons (quantum efficiency,
 * Poisson shot noise), dark electrons (Poisson, dark current x exposure), read noise
 * (Gaussian, electrons), the clip at the full well (saturation capacity), system gain K (DN per
 * electron, times the analog gain), rounding to whole DN and clipping to the ADC range. Pure functions: any thread. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  guint bit_depth;            /* 8..16 */
  double quantum_efficiency;  /* (0, 1] */
  double system_gain;         /* K, DN per electron at 0 dB */
  double read_noise_e;        /* sigma of the read noise, electrons */
  double dark_current_e_s;    /* electrons per second */
  double full_well_e;         /* saturation capacity, electrons */
} DsSensorModel;

/* Effective K at an analog gain in dB (amplitude: 20 log10). */
double ds_sensor_gain_dn_per_e (const DsSensorModel *m, double gain_db);
/* Mean dark electrons in an exposure. */
double ds_sensor_dark_e (const DsSensorModel *m, double exposure_us);
/* Largest DN the ADC gives. */
double ds_sensor_max_dn (const DsSensorModel *m);
/* The lowest DN that means "clipped" at this gain: the full well (EMVA 1288 saturation
 * capacity) in DN or the ADC's top, whichever is lower. A pixel that is full reads exactly
 * this; one that is not reads less (or, rounding at the very edge, this). */
double ds_sensor_saturation_dn (const DsSensorModel *m, double gain_db);

/* One noisy exposure: photons (f32, mean photons per pixel reaching the pixel during the
 * exposure; may be NULL) plus extra_photons everywhere. Writes out (u16, same size, its
 * bit_depth set). Deterministic for seed; each row has its own random stream keyed by
 * (seed, row), so rows may be done in any order. */
gboolean ds_sensor_expose (const DsSensorModel *m, const DsImage *photons, double extra_photons,
                           double exposure_us, double gain_db, guint64 seed, DsImage *out, GError **error);

/* Noise-free expectation in DN before quantization and clipping: K (QE photons + dark). */
double ds_sensor_mean_dn (const DsSensorModel *m, double photons, double exposure_us, double gain_db);

G_END_DECLS
