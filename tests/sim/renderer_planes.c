/* Objects inside the medium against a reference written differently: a Monte Carlo of the whole
 * scene (photons launched across it, each crossing of an object plane multiplying the photon's
 * weight by the object's transmittance there, exits tallied per pixel), against the renderer's
 * scattered truth built from kernels. Also: a fully transparent object is no object (truth and
 * frames), for milk-disc and a forward-peaked (g = 0.95) medium; and energy bookkeeping.
 *
 * The reference is 1-D: objects are half-planes with edges along y and the light is uniform, so
 * only x matters. It is its own code: trigonometric azimuths, its own Fresnel and
 * Henyey-Greenstein sampling, implicit absorption, its own random generator (splitmix64). */
#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "drivers/sim/renderer.h"

#define PITCH_MM 0.1 /* 5 um pixels at magnification 0.05 */

/* ---- reference Monte Carlo ------------------------------------------------------------- */

typedef struct {
  guint64 s;
} Rand;

static double
rand_uniform (Rand *r)
{
  guint64 z = (r->s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return ((z >> 11) + 0.5) * 0x1.0p-53; /* (0, 1) */
}

typedef struct {
  double depth_mm;
  double edge_mm;       /* transmittance t_left for x < edge, t_right from it on */
  double t_left, t_right;
} HalfPlane;

typedef struct {
  double mua, mus, g, d, n, accept_deg;
  const HalfPlane *planes;
  guint n_planes;
} RefScene;

/* Unpolarized Fresnel reflectance from index n1 into n2 at incidence cosine ci. */
static double
fresnel (double n1, double n2, double ci)
{
  double si = sqrt (MAX (0.0, 1 - ci * ci)), st = n1 / n2 * si;
  if (st >= 1)
    return 1.0;
  double ct = sqrt (1 - st * st);
  double rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct), rp = (n1 * ct - n2 * ci) / (n1 * ct + n2 * ci);
  return 0.5 * (rs * rs + rp * rp);
}

static double
plane_t (const HalfPlane *p, double x)
{
  return x < p->edge_mm ? p->t_left : p->t_right;
}

/* Scattered light leaving the far face in the cone, per pixel of the frame [x0, x0 + n pitch),
 * as a fraction of the light arriving per pixel; photons enter uniformly over
 * [x0 - reach, x0 + n pitch + reach). var: the variance of each bin's estimate. */
static void
reference (const RefScene *sc, double x0, guint n, double reach, guint64 photons, guint64 seed, double *out,
           double *var)
{
  Rand rng = { seed };
  double lo = x0 - reach, width = n * PITCH_MM + 2 * reach, mut = sc->mua + sc->mus;
  double cos_accept = cos (sc->accept_deg * G_PI / 180), r0 = (sc->n - 1) / (sc->n + 1);
  g_autofree double *sum = g_new0 (double, n), *sum2 = g_new0 (double, n);
  for (guint64 i = 0; i < photons; i++) {
    double x = lo + width * rand_uniform (&rng), z = 0, ux = 0, uy = 0, uz = 1, w = 1 - r0 * r0;
    gboolean scattered = FALSE;
    while (w > 0) {
      double s = -log (rand_uniform (&rng)) / mut;
      double zn = z + s * uz;
      gboolean leaves = zn < 0 || zn > sc->d;
      if (leaves)
        s = (uz > 0 ? sc->d - z : -z) / uz;
      /* Planes crossed on the way. */
      for (guint j = 0; j < sc->n_planes; j++) {
        double zj = sc->planes[j].depth_mm;
        if ((z < zj) != (z + s * uz < zj))
          w *= plane_t (&sc->planes[j], x + (zj - z) / uz * ux);
      }
      x += s * ux;
      z += s * uz;
      if (w <= 0)
        break;
      if (leaves) {
        if (rand_uniform (&rng) < fresnel (sc->n, 1.0, fabs (uz))) {
          uz = -uz;
          z = uz > 0 ? 0 : sc->d;
          continue;
        }
        if (uz > 0 && scattered) {
          double st = sc->n * sqrt (MAX (0.0, 1 - uz * uz));
          if (sqrt (MAX (0.0, 1 - st * st)) >= cos_accept) {
            double b = floor ((x - x0) / PITCH_MM);
            if (b >= 0 && b < n) {
              sum[(guint) b] += w;
              sum2[(guint) b] += w * w;
            }
          }
        }
        break;
      }
      w *= sc->mus / mut;
      if (w < 1e-3) {
        if (rand_uniform (&rng) > 0.1)
          break;
        w *= 10;
      }
      /* Henyey-Greenstein polar angle, uniform azimuth by its angle. */
      double g = sc->g, f = (1 - g * g) / (1 - g + 2 * g * rand_uniform (&rng));
      double ct = (1 + g * g - f * f) / (2 * g), phi = 2 * G_PI * rand_uniform (&rng);
      ct = CLAMP (ct, -1.0, 1.0);
      double stt = sqrt (1 - ct * ct), cp = cos (phi), sp = sin (phi);
      if (fabs (uz) > 0.99999) {
        ux = stt * cp;
        uy = stt * sp;
        uz = uz > 0 ? ct : -ct;
      } else {
        double q = sqrt (1 - uz * uz);
        double nx = stt * (ux * uz * cp - uy * sp) / q + ux * ct;
        double ny = stt * (uy * uz * cp + ux * sp) / q + uy * ct;
        uz = -stt * cp * q + uz * ct;
        ux = nx;
        uy = ny;
      }
      scattered = TRUE;
    }
  }
  /* Photons per pixel of the frame: photons / (width / pitch). */
  double per_px = photons * PITCH_MM / width;
  for (guint b = 0; b < n; b++) {
    out[b] = sum[b] / per_px;
    double mean = sum[b] / photons;
    var[b] = MAX (sum2[b] / photons - mean * mean, 0.0) / photons * (width / PITCH_MM) * (width / PITCH_MM);
  }
}

/* ---- renderer side ---------------------------------------------------------------------- */

static DsScene *
load (const char *text)
{
  g_autoptr (GError) error = NULL;
  DsScene *s = ds_scene_load_data (text, strlen (text), "planes-test.scene", &error);
  g_assert_no_error (error);
  return s;
}

/* The scattered truth as a fraction of the incident light per pixel, averaged over the rows. */
static double *
truth_profile (const DsScene *scene, const char *cache)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new (scene, cache, &error);
  g_assert_no_error (error);
  DsImage *t = NULL, *s = NULL;
  g_assert_true (ds_renderer_truth (r, 1000, 0, &t, &s, &error));
  g_autoptr (DsImage) tt = t;
  g_autoptr (DsImage) ts = s;
  /* 1 photon/um^2/ms on 100 um^2 pixels for 1 ms, x QE 0.5 x K 0.5 DN/e-. */
  double open = 1e4 * 0.5 * 0.5;
  double *p = g_new0 (double, ts->width);
  for (guint y = 0; y < ts->height; y++)
    for (guint x = 0; x < ts->width; x++)
      p[x] += ((const float *) ds_image_row (ts, y))[x] / open / ts->height;
  return p;
}

static char *
scene_text (const char *medium, guint width, const char *objects)
{
  return g_strdup_printf ("[sensor]\nwidth=%u\nheight=8\nbit-depth=16\nquantum-efficiency=0.5\nsystem-gain=0.5\n"
                          "full-well-e=1e7\n[illuminator]\nperiod-px=8\nirradiance=1\n[medium]\n%s\n%s",
                          width, medium, objects ? objects : "");
}

/* An object covering x < edge_px (in pixels of the frame) at a depth. */
static char *
half_plane (const char *name, double edge_px, double depth_mm, double t, gboolean left)
{
  double x = left ? -100000 : edge_px, w = left ? edge_px + 100000 : 100000;
  return g_strdup_printf ("[object.%s]\nshape=rect\nposition=%.17g;-100000\nsize=%.17g;200000\ndepth-mm=%g\n"
                          "transmittance=%g\n", name, x, w, depth_mm, t);
}

/* Compares the renderer's profile with the reference in bins of `bin` pixels: each within 4
 * standard errors of the reference plus `rel` of the open-field level (the renderer's own
 * kernel noise, its 0.5 % cut and the approximations of the chain). */
static void
compare (const char *what, const double *got, const double *ref, const double *var, guint n, guint bin,
         double open_level, double rel)
{
  for (guint b = 0; b + bin <= n; b += bin) {
    double g = 0, r = 0, v = 0;
    for (guint i = b; i < b + bin; i++) {
      g += got[i] / bin;
      r += ref[i] / bin;
      v += var[i] / (bin * bin);
    }
    double tol = 4 * sqrt (v) + rel * open_level;
    g_test_message ("%s: px %3u-%3u renderer %.5f reference %.5f +- %.5f", what, b, b + bin - 1, g, r, sqrt (v));
    if (fabs (g - r) > tol)
      g_error ("%s: pixels %u-%u: renderer %.5f, reference %.5f (tolerance %.5f)", what, b, b + bin - 1, g, r, tol);
  }
}

#define MEDIUM_A "thickness-mm=4\nmua=0.01\nmus=0.5\ng=0.7\nn=1.33\nphotons=400000\nseed=5\n" \
                 "[camera]\nacceptance-half-angle-deg=20\n"
#define FRAME_W 160u

static char *cache_dir;

/* Opaque half-plane at mid-depth: its shadow in the scattered light, blurred by the second half
 * of the slab, as the reference has it. Then a uniform plane of transmittance 0.5, where every
 * crossing counts: total and profile alike. */
static void
test_edge_one_depth (void)
{
  g_autofree char *edge = half_plane ("edge", 79.5, 2.0, 0.0, TRUE);
  g_autofree char *text = scene_text (MEDIUM_A, FRAME_W, edge);
  g_autoptr (DsScene) scene = load (text);
  g_autofree double *got = truth_profile (scene, cache_dir);
  HalfPlane hp = { 2.0, 7.95, 0.0, 1.0 };
  RefScene ref = { 0.01, 0.5, 0.7, 4.0, 1.33, 20, &hp, 1 };
  g_autofree double *want = g_new0 (double, FRAME_W), *var = g_new0 (double, FRAME_W);
  reference (&ref, 0, FRAME_W, 40, 3000000, 17, want, var);
  /* Open-field level: far right of the reference. */
  double open = 0;
  for (guint i = FRAME_W - 20; i < FRAME_W; i++)
    open += want[i] / 20;
  compare ("opaque edge at 2 mm", got, want, var, FRAME_W, 10, open, 0.02);

  g_autofree char *grey = half_plane ("grey", 1e5, 2.0, 0.5, TRUE);
  g_autofree char *text2 = scene_text (MEDIUM_A, FRAME_W, grey);
  g_autoptr (DsScene) scene2 = load (text2);
  g_autofree double *got2 = truth_profile (scene2, cache_dir);
  HalfPlane hp2 = { 2.0, 1e9, 0.5, 0.5 };
  RefScene ref2 = { 0.01, 0.5, 0.7, 4.0, 1.33, 20, &hp2, 1 };
  reference (&ref2, 0, FRAME_W, 40, 3000000, 18, want, var);
  compare ("uniform t = 0.5 at 2 mm", got2, want, var, FRAME_W, 40, open, 0.015);
}

/* Two depths: opaque left of 5.95 mm at 1.2 mm, transmittance 0.3 right of 9.95 mm at 2.8 mm. */
static void
test_edges_two_depths (void)
{
  g_autofree char *a = half_plane ("upper", 59.5, 1.2, 0.0, TRUE);
  g_autofree char *b = half_plane ("lower", 99.5, 2.8, 0.3, FALSE);
  g_autofree char *objects = g_strconcat (a, b, NULL);
  g_autofree char *text = scene_text (MEDIUM_A, FRAME_W, objects);
  g_autoptr (DsScene) scene = load (text);
  g_autofree double *got = truth_profile (scene, cache_dir);
  HalfPlane hp[2] = { { 1.2, 5.95, 0.0, 1.0 }, { 2.8, 9.95, 1.0, 0.3 } };
  RefScene ref = { 0.01, 0.5, 0.7, 4.0, 1.33, 20, hp, 2 };
  g_autofree double *want = g_new0 (double, FRAME_W), *var = g_new0 (double, FRAME_W);
  reference (&ref, 0, FRAME_W, 40, 3000000, 19, want, var);
  HalfPlane none = { 2.0, 0, 1.0, 1.0 };
  RefScene open_ref = { 0.01, 0.5, 0.7, 4.0, 1.33, 20, &none, 1 };
  g_autofree double *open_p = g_new0 (double, FRAME_W), *open_v = g_new0 (double, FRAME_W);
  reference (&open_ref, 0, 20, 40, 1000000, 20, open_p, open_v);
  double open = 0;
  for (guint i = 0; i < 20; i++)
    open += open_p[i] / 20;
  compare ("two depths", got, want, var, FRAME_W, 10, open, 0.02);
}

/* Truth and every frame of a scene with a fully transparent object equal the scene without it
 * (float rounding), and so does a frame's scattered light far from an opaque one. */
static void
assert_same_light (const DsScene *with, const DsScene *without, const char *what)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r1 = ds_renderer_new (with, cache_dir, &error);
  g_assert_no_error (error);
  g_autoptr (DsRenderer) r0 = ds_renderer_new (without, cache_dir, &error);
  g_assert_no_error (error);
  DsImage *t1 = NULL, *s1 = NULL, *t0 = NULL, *s0 = NULL;
  g_assert_true (ds_renderer_truth (r1, 2000, 0, &t1, &s1, &error));
  g_assert_true (ds_renderer_truth (r0, 2000, 0, &t0, &s0, &error));
  g_autoptr (DsImage) a = t1;
  g_autoptr (DsImage) b = s1;
  g_autoptr (DsImage) c = t0;
  g_autoptr (DsImage) d = s0;
  double worst = 0, level = 0;
  for (guint y = 0; y < b->height; y++)
    for (guint x = 0; x < b->width; x++) {
      float v1 = ((float *) ds_image_row (b, y))[x], v0 = ((float *) ds_image_row (d, y))[x];
      worst = MAX (worst, fabs (v1 - v0));
      level = MAX (level, v0);
      g_assert_cmpfloat (((float *) ds_image_row (a, y))[x], ==, ((float *) ds_image_row (c, y))[x]);
    }
  g_test_message ("%s: truth scattered differs by at most %.3g of %.4g DN", what, worst, level);
  g_assert_cmpfloat (level, >, 0);
  g_assert_cmpfloat (worst, <=, 1e-5 * level);
  for (guint k = 0; k < 3; k++) {
    DsRenderRequest req = { .phase = k, .n_phases = 3, .illuminator_on = TRUE, .exposure_us = 2000 };
    g_autoptr (DsImage) e1 = ds_renderer_render_expected (r1, &req, &error);
    g_autoptr (DsImage) e0 = ds_renderer_render_expected (r0, &req, &error);
    g_assert_no_error (error);
    for (guint y = 0; y < e1->height; y++)
      for (guint x = 0; x < e1->width; x++) {
        float v1 = ((float *) ds_image_row (e1, y))[x], v0 = ((float *) ds_image_row (e0, y))[x];
        if (fabs (v1 - v0) > 1e-5 * v0 + 1e-4)
          g_error ("%s: phase %u (%u, %u): %g with the clear object, %g without", what, k, x, y, v1, v0);
      }
  }
}

static char *
read_scene (const char *name)
{
  g_autofree char *path = g_strdup_printf ("%s/%s.scene", DS_SCENES_DIR, name);
  g_autoptr (GError) error = NULL;
  char *text = NULL;
  g_assert_true (g_file_get_contents (path, &text, NULL, &error));
  g_assert_no_error (error);
  return text;
}

static void
test_transparent_milk (void)
{
  g_autofree char *text = read_scene ("milk-disc");
  /* The disc with transmittance 1, and the scene without [object.disc] at all. */
  g_auto (GStrv) parts = g_strsplit (text, "[object.disc]", 2);
  g_assert_nonnull (parts[1]);
  const char *without = parts[0];
  g_autofree char *with = g_strconcat (without, "[object.disc]\nshape=disc\nposition=128;96\nradius=40\n"
                                                "depth-mm=5\ntransmittance=1\n", NULL);
  g_autoptr (DsScene) a = load (with);
  g_autoptr (DsScene) b = load (without);
  assert_same_light (a, b, "milk-disc");
}

static void
test_transparent_forward (void)
{
  /* g = 0.95: most scattered light keeps close to the beam, the case the old split-slab model
   * got most wrong (+44 %). Two clear planes, as a layered phantom would have. */
  const char *medium = "thickness-mm=5\nmua=0.005\nmus=0.4\ng=0.95\nn=1.33\nphotons=200000\nseed=9\n"
                       "[camera]\nacceptance-half-angle-deg=10\n";
  g_autofree char *without = scene_text (medium, 96, NULL);
  g_autofree char *with = scene_text (medium, 96, "[object.a]\nshape=disc\nposition=40;4\nradius=30\ndepth-mm=1.5\n"
                                                  "transmittance=1\n[object.b]\nshape=grid\npitch=9\ndepth-mm=3.5\n"
                                                  "transmittance=1\n");
  g_autoptr (DsScene) a = load (with);
  g_autoptr (DsScene) b = load (without);
  assert_same_light (a, b, "g = 0.95");
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_autoptr (GError) error = NULL;
  cache_dir = g_dir_make_tmp ("ds-planes-XXXXXX", &error);
  g_assert_no_error (error);
  g_test_add_func ("/sim/planes/transparent-milk-disc", test_transparent_milk);
  g_test_add_func ("/sim/planes/transparent-forward-peaked", test_transparent_forward);
  g_test_add_func ("/sim/planes/edge-one-depth", test_edge_one_depth);
  g_test_add_func ("/sim/planes/edges-two-depths", test_edges_two_depths);
  int status = g_test_run ();
  g_autoptr (GDir) d = g_dir_open (cache_dir, 0, NULL);
  for (const char *name; d && (name = g_dir_read_name (d));) {
    g_autofree char *p = g_build_filename (cache_dir, name, NULL);
    g_unlink (p);
  }
  g_rmdir (cache_dir);
  g_free (cache_dir);
  return status;
}
