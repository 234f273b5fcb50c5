/* A replica of a pilot pair (proc/stripe_replica.h) against its definition: each frame's pixels
 * are their column's value plus noise of the given standard deviation, so a frame less its
 * values has mean 0 and variance noise^2 (within the sampling error of W H draws), the three
 * frames' noises are independent (their covariance within that error of 0), and with no noise
 * the frames hold the values exactly. */
#include <glib.h>
#include <math.h>

#include "proc/image.h"
#include "proc/stripe_replica.h"

#include "pair_frames.h"

#define W 64u
#define H 200u

static double
value (guint x, guint phase)
{
  return 100 + 50 * cos (2 * G_PI * (x / 9.5 - 0.5 * phase));
}

typedef struct {
  double v0[W], v1[W];
  PairFrames f;
} Replica;

static void
replica_render (Replica *r, double noise, guint32 seed)
{
  for (guint x = 0; x < W; x++) {
    r->v0[x] = value (x, 0);
    r->v1[x] = value (x, 1);
  }
  pair_frames_init (&r->f, W, H);
  g_autoptr (GRand) rng = g_rand_new_with_seed (seed);
  g_assert_true (ds_stripe_replica_render (r->v0, r->v1, noise, rng, r->f.dark, r->f.l0, r->f.l1));
}

/* The frame's residual (sample less its column's value) at pixel i. */
static double
residual (const DsImage *f, const double *v, gsize i)
{
  guint x = (guint) (i % W), y = (guint) (i / W);
  const float *row = ds_image_row (f, y);
  return row[x] - (v ? v[x] : 0);
}

static void
test_noise_statistics (void)
{
  const double noise = 3.0;
  Replica r;
  replica_render (&r, noise, 7);
  const DsImage *f[3] = { r.f.dark, r.f.l0, r.f.l1 };
  const double *v[3] = { NULL, r.v0, r.v1 };
  gsize n = (gsize) W * H;
  /* the mean of n draws spreads by noise / sqrt (n), a variance's relative error by sqrt (2 / n),
   * a covariance by noise^2 / sqrt (n): five of each */
  double tol_mean = 5 * noise / sqrt ((double) n), tol_var = 5 * sqrt (2.0 / n), tol_cov = 5 / sqrt ((double) n);
  for (guint k = 0; k < 3; k++) {
    double s = 0, ss = 0, cross = 0;
    for (gsize i = 0; i < n; i++) {
      double d = residual (f[k], v[k], i);
      s += d;
      ss += d * d;
      cross += d * residual (f[(k + 1) % 3], v[(k + 1) % 3], i);
    }
    g_assert_cmpfloat (fabs (s / n), <, tol_mean);
    g_assert_cmpfloat (fabs (ss / n / (noise * noise) - 1), <, tol_var);
    g_assert_cmpfloat (fabs (cross / n / (noise * noise)), <, tol_cov);
  }
  pair_frames_clear (&r.f);
}

static void
test_no_noise (void)
{
  Replica r;
  replica_render (&r, 0, 7);
  for (guint y = 0; y < H; y++) {
    const float *rd = ds_image_row (r.f.dark, y), *r0 = ds_image_row (r.f.l0, y), *r1 = ds_image_row (r.f.l1, y);
    for (guint x = 0; x < W; x++) {
      g_assert_cmpfloat (rd[x], ==, 0);
      g_assert_cmpfloat (r0[x], ==, (float) r.v0[x]);
      g_assert_cmpfloat (r1[x], ==, (float) r.v1[x]);
    }
  }
  pair_frames_clear (&r.f);
}

/* Frames that are not float, or not of one shape, are refused. */
static void
test_refuses_shapes (void)
{
  double v[W] = { 0 };
  g_autoptr (GRand) rng = g_rand_new_with_seed (1);
  g_autoptr (DsImage) f = ds_image_new (DS_SAMPLE_F32, W, H, NULL);
  g_autoptr (DsImage) narrow = ds_image_new (DS_SAMPLE_F32, W - 1, H, NULL);
  g_autoptr (DsImage) u16 = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  g_assert_false (ds_stripe_replica_render (v, v, 1, rng, f, narrow, f));
  g_assert_false (ds_stripe_replica_render (v, v, 1, rng, u16, f, f));
  g_assert_false (ds_stripe_replica_render (v, v, 1, rng, f, f, u16));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/stripe-replica/noise-statistics", test_noise_statistics);
  g_test_add_func ("/stripe-replica/no-noise", test_no_noise);
  g_test_add_func ("/stripe-replica/refuses-shapes", test_refuses_shapes);
  return g_test_run ();
}
