#include "drivers/sim/rng.h"

#include <math.h>

static guint64
splitmix64 (guint64 *x)
{
  guint64 z = (*x += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

void
ds_rng_seed (DsRng *r, guint64 seed)
{
  guint64 x = seed;
  for (int i = 0; i < 4; i++)
    r->s[i] = splitmix64 (&x);
  /* splitmix64 never yields four zero words in a row, but keep xoshiro's one forbidden
   * state impossible by construction. */
  if ((r->s[0] | r->s[1] | r->s[2] | r->s[3]) == 0)
    r->s[0] = 1;
}

void
ds_rng_jump (DsRng *r)
{
  /* The jump polynomial of xoshiro256 for 2^128 steps. */
  static const guint64 jump[4] = { 0x180ec6d33cfd0abaull, 0xd5a61266f0c9392cull,
                                   0xa9582618e03fc9aaull, 0x39abdc4529b1661cull };
  guint64 acc[4] = { 0, 0, 0, 0 };
  for (int i = 0; i < 4; i++)
    for (int b = 0; b < 64; b++) {
      if (jump[i] & (1ull << b))
        for (int k = 0; k < 4; k++)
          acc[k] ^= r->s[k];
      ds_rng_next (r);
    }
  for (int k = 0; k < 4; k++)
    r->s[k] = acc[k];
}

void
ds_rng_seed_stream (DsRng *r, guint64 seed, guint64 stream)
{
  ds_rng_seed (r, seed);
  /* A few thousand steps per jump: streams are meant to be few (one per worker). */
  for (guint64 i = 0; i < stream; i++)
    ds_rng_jump (r);
}

double
ds_rng_normal (DsRng *r)
{
  double u1 = ds_rng_uniform_open0 (r), u2 = ds_rng_uniform (r);
  return sqrt (-2.0 * log (u1)) * cos (2.0 * G_PI * u2);
}

double
ds_rng_poisson (DsRng *r, double lambda)
{
  if (!(lambda > 0))
    return 0;
  if (lambda < 30) {
    double l = exp (-lambda), p = 1.0;
    int k = 0;
    do {
      k++;
      p *= ds_rng_uniform (r);
    } while (p > l);
    return k - 1;
  }
  double v = floor (lambda + sqrt (lambda) * ds_rng_normal (r) + 0.5);
  return v < 0 ? 0 : v;
}
