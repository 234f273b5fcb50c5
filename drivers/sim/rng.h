/* A small seedable generator: xoshiro256** (Blackman & Vigna) seeded through splitmix64.
 * Reproducible for a seed on every platform; ds_rng_seed_stream gives independent streams of
 * one seed (stream k starts 2^128 k steps ahead: sequences of different streams never
 * overlap in practice). The state is a plain value: one per thread. Not for cryptography. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

typedef struct {
  guint64 s[4];
} DsRng;

void ds_rng_seed (DsRng *rng, guint64 seed);
/* Stream `stream` of `seed`; stream 0 is ds_rng_seed (rng, seed). */
void ds_rng_seed_stream (DsRng *rng, guint64 seed, guint64 stream);
/* Advances by 2^128 steps. */
void ds_rng_jump (DsRng *rng);

/* Inline: photon transport draws dozens of numbers per photon, and a call each cost ~10 % of it. */
static inline guint64
ds_rng_next (DsRng *r)
{
  guint64 *s = r->s;
  guint64 x = s[1] * 5, result = ((x << 7) | (x >> 57)) * 9;
  guint64 t = s[1] << 17;
  s[2] ^= s[0];
  s[3] ^= s[1];
  s[1] ^= s[2];
  s[0] ^= s[3];
  s[2] ^= t;
  s[3] = (s[3] << 45) | (s[3] >> 19);
  return result;
}

/* Uniform in [0, 1) with 53 random bits. */
static inline double
ds_rng_uniform (DsRng *r)
{
  return (double) (ds_rng_next (r) >> 11) * 0x1.0p-53;
}

/* Uniform in (0, 1]: safe under log(). */
static inline double
ds_rng_uniform_open0 (DsRng *r)
{
  return (double) ((ds_rng_next (r) >> 11) + 1) * 0x1.0p-53;
}
/* Standard normal (Box-Muller). */
double ds_rng_normal (DsRng *rng);
/* Poisson with mean lambda >= 0: exact (Knuth) below 30, normal approximation with continuity
 * correction above (error far below the other noise terms there). */
double ds_rng_poisson (DsRng *rng, double lambda);

G_END_DECLS
