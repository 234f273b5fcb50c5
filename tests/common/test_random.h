/* Random numbers for the tests' synthetic frames, shared by every test folder so that each
 * frame generator draws its noise the same way. */
#pragma once

#include <glib.h>
#include <math.h>

/* A standard normal deviate (Box-Muller, one of the pair); u stays off 0, where log diverges. */
static inline double
test_normal (GRand *r)
{
  double u = g_rand_double_range (r, 1e-12, 1), v = g_rand_double (r);
  return sqrt (-2 * log (u)) * cos (2 * G_PI * v);
}
