#include "drivers/sim/sensor.h"

#include <math.h>

#include "drivers/sim/sim_error.h"

/* The sensor's own small generator (xoshiro256** seeded through splitmix64): the noise of a frame
 * must not change when another module's generator does, and one stream per row keeps rows
 * independent of evaluation order. */
typedef struct {
  guint64 s[4];
  gboolean have_spare;
  double spare;
} DsSensorRng;

static guint64
splitmix64 (guint64 *x)
{
  guint64 z = (*x += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

static void
rng_seed (DsSensorRng *r, guint64 seed, guint64 stream)
{
  guint64 x = seed ^ (stream * 0xD1B54A32D192ED03ull);
  for (int i = 0; i < 4; i++)
    r->s[i] = splitmix64 (&x);
  r->have_spare = FALSE;
}

static inline guint64
rotl (guint64 x, int k)
{
  return (x << k) | (x >> (64 - k));
}

static guint64
rng_next (DsSensorRng *r)
{
  guint64 *s = r->s;
  guint64 result = rotl (s[1] * 5, 7) * 9, t = s[1] << 17;
  s[2] ^= s[0];
  s[3] ^= s[1];
  s[1] ^= s[2];
  s[0] ^= s[3];
  s[2] ^= t;
  s[3] = rotl (s[3], 45);
  return result;
}

static double
rng_uniform (DsSensorRng *r)
{
  return (double) (rng_next (r) >> 11) * 0x1.0p-53;
}

/* Marsaglia's polar method; the second deviate is kept. */
static double
rng_normal (DsSensorRng *r)
{
  if (r->have_spare) {
    r->have_spare = FALSE;
    return r->spare;
  }
  double u, v, q;
  do {
    u = 2 * rng_uniform (r) - 1;
    v = 2 * rng_uniform (r) - 1;
    q = u * u + v * v;
  } while (q >= 1 || q == 0);
  double f = sqrt (-2 * log (q) / q);
  r->spare = v * f;
  r->have_spare = TRUE;
  return u * f;
}

/* Exact (multiplication of uniforms) below 30; above, the normal approximation with
 * continuity correction, whose error in mean and variance (< 1/12 count) is far below the
 * read noise and quantization that follow. */
static double
rng_poisson (DsSensorRng *r, double lambda)
{
  if (lambda <= 0)
    return 0;
  if (lambda < 30) {
    double l = exp (-lambda), p = 1.0;
    double k = -1;
    do {
      k++;
      p *= rng_uniform (r);
    } while (p > l);
    return k;
  }
  double k = floor (lambda + sqrt (lambda) * rng_normal (r) + 0.5);
  return k < 0 ? 0 : k;
}

double
ds_sensor_gain_dn_per_e (const DsSensorModel *m, double gain_db)
{
  return m->system_gain * pow (10.0, gain_db / 20.0);
}

double
ds_sensor_dark_e (const DsSensorModel *m, double exposure_us)
{
  return m->dark_current_e_s * exposure_us * 1e-6;
}

double
ds_sensor_max_dn (const DsSensorModel *m)
{
  return (double) ((1u << m->bit_depth) - 1u);
}

double
ds_sensor_saturation_dn (const DsSensorModel *m, double gain_db)
{
  return MIN (floor (ds_sensor_gain_dn_per_e (m, gain_db) * m->full_well_e + 0.5), ds_sensor_max_dn (m));
}

double
ds_sensor_mean_dn (const DsSensorModel *m, double photons, double exposure_us, double gain_db)
{
  return ds_sensor_gain_dn_per_e (m, gain_db) * (m->quantum_efficiency * photons + ds_sensor_dark_e (m, exposure_us));
}

gboolean
ds_sensor_expose (const DsSensorModel *m, const DsImage *photons, double extra_photons, double exposure_us,
                  double gain_db, guint64 seed, DsImage *out, GError **error)
{
  if (out->type != DS_SAMPLE_U16 || (photons && (photons->type != DS_SAMPLE_F32 || photons->width != out->width ||
                                                 photons->height != out->height))) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "sensor: photons must be f32 and the frame u16 of one size");
    return FALSE;
  }
  if (m->bit_depth < 8 || m->bit_depth > 16 || !(exposure_us > 0) || !isfinite (gain_db)) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "sensor: bit depth %u (8..16), exposure %g us (> 0)",
                 m->bit_depth, exposure_us);
    return FALSE;
  }
  out->bit_depth = m->bit_depth;
  double k = ds_sensor_gain_dn_per_e (m, gain_db), dark = ds_sensor_dark_e (m, exposure_us);
  double max_dn = ds_sensor_max_dn (m);
  for (guint y = 0; y < out->height; y++) {
    DsSensorRng rng;
    rng_seed (&rng, seed, y);
    const float *ph = photons ? ds_image_row (photons, y) : NULL;
    guint16 *o = ds_image_row (out, y);
    for (guint x = 0; x < out->width; x++) {
      double p = (ph ? ph[x] : 0.0) + extra_photons;
      double e = rng_poisson (&rng, m->quantum_efficiency * (p > 0 ? p : 0)) + rng_poisson (&rng, dark);
      /* The pixel's output swing ends at the saturation capacity: a full pixel reads the same
       * value every time, so "at or above saturation_dn" is exactly "clipped". */
      e += m->read_noise_e * rng_normal (&rng);
      if (e > m->full_well_e)
        e = m->full_well_e;
      double dn = floor (k * e + 0.5);
      o[x] = (guint16) (dn < 0 ? 0 : dn > max_dn ? max_dn : dn);
    }
  }
  return TRUE;
}
