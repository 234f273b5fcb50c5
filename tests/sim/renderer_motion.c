/* Moving objects (docs/scene-format.md, "Motion") against independent expectations: the
 * analytic position x0 + v t of an edge in the truth and in a frame at time t for two speeds, a
 * moving object inside the medium equal to a still one declared where it has moved to, still
 * scenes unchanged to the bit, `describe` naming the stage only for a moving scene, and bad
 * velocities refused with the key and line. */
#include <glib/gstdio.h>

#include "tests/sim/renderer_fixture.h"

static DsRenderer *
renderer_of (const DsScene *s)
{
  g_autoptr (GError) error = NULL;
  DsRenderer *r = ds_renderer_new (s, NULL, &error);
  g_assert_no_error (error);
  return r;
}

static void
truth_at (const DsRenderer *r, double t_s, DsImage **t, DsImage **s)
{
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_renderer_truth_at (r, EXPOSURE_US, 0, t_s, t, s, &error));
  g_assert_no_error (error);
}

/* An opaque bar x0 <= x < x0 + w, all rows: the area it darkens in a row and the darkness's
 * centroid, from one row of a transmissive image with open level `open`. */
static void
row_darkness (const DsImage *im, guint y, double open, double *area, double *centroid)
{
  double a = 0, m = 0;
  for (guint x = 0; x < im->width; x++) {
    double d = 1.0 - px (im, x, y) / open;
    a += d;
    m += d * x;
  }
  *area = a;
  *centroid = a > 0 ? m / a : NAN;
}

/* Pixel x covers [x - 1/2, x + 1/2]; the bar [l, l + w) shades the part of it that it covers. */
static double
bar_cover (guint x, double l, double w)
{
  return MAX (0.0, MIN (x + 0.5, l + w) - MAX (x - 0.5, l));
}

#define BAR_X0 10.0
#define BAR_W 12.0

static void
test_edge_at_vt (void)
{
  /* Two speeds, times that put the edge on and between pixel boundaries. The shape is sampled
   * 4 x 4 per pixel, so a pixel's coverage is good to a quarter pixel and the centroid of the
   * bar's shadow to an eighth. */
  const double speeds[] = { 400.0, 1500.0 };
  const double times[] = { 0.0, 0.005, 0.0123, 0.02 };
  for (guint iv = 0; iv < G_N_ELEMENTS (speeds); iv++) {
    g_autofree char *obj = g_strdup_printf ("[object.bar]\nshape=rect\nposition=%g;-10\nsize=%g;100\n"
                                            "velocity = %g, 0\n", BAR_X0, BAR_W, speeds[iv]);
    g_autoptr (DsScene) s = scene_from (obj, NULL);
    g_autoptr (DsRenderer) r = renderer_of (s);
    g_assert_true (ds_renderer_has_stage (r, DS_RENDER_STAGE_MOTION));
    for (guint it = 0; it < G_N_ELEMENTS (times); it++) {
      double t = times[it], left = BAR_X0 + speeds[iv] * t;
      g_assert_cmpfloat (left + BAR_W, <, 63);
      g_autoptr (DsImage) tt = NULL;
      g_autoptr (DsImage) ts = NULL;
      truth_at (r, t, &tt, &ts);
      for (guint y = 0; y < 48; y += 7) {
        double area, centroid;
        row_darkness (tt, y, open_dn (), &area, &centroid);
        g_assert_cmpfloat (fabs (area - BAR_W), <=, 0.25 + 1e-4);
        g_assert_cmpfloat (fabs (centroid - (left + BAR_W / 2)), <=, 0.125 + 1e-3);
        for (guint x = 0; x < 64; x++) {
          double expect = open_dn () * (1.0 - bar_cover (x, left, BAR_W));
          if (fabs (px (tt, x, y) - expect) > 0.25 * open_dn () + 1e-3)
            g_error ("v %g t %g (%u, %u): %g, expected %g", speeds[iv], t, x, y, px (tt, x, y), expect);
        }
      }
      /* A frame at that time, every stripe lit, noise-free: the same edge. Its dark signal is
       * read off where the bar never reaches (column 0 when it has moved off it: the bar starts
       * at column 10). */
      DsRenderRequest req = { .illuminator_on = TRUE, .all_on = TRUE, .n_phases = 1, .exposure_us = EXPOSURE_US,
                              .time_s = t };
      g_autoptr (GError) error = NULL;
      g_autoptr (DsImage) f = ds_renderer_render_expected (r, &req, &error);
      g_assert_no_error (error);
      double dark = 1000.0 * EXPOSURE_US * 1e-6 * K; /* dark-current-e-per-s x exposure x K */
      g_assert_cmpfloat (fabs (px (f, 0, 20) - dark - open_dn ()), <, 1e-3 * open_dn ());
      g_autoptr (DsImage) lit = ds_image_new (DS_SAMPLE_F32, 64, 48, &error);
      for (guint y = 0; y < 48; y++)
        for (guint x = 0; x < 64; x++)
          ((float *) ds_image_row (lit, y))[x] = (float) (px (f, x, y) - dark);
      double area, centroid;
      row_darkness (lit, 20, open_dn (), &area, &centroid);
      g_assert_cmpfloat (fabs (centroid - (left + BAR_W / 2)), <=, 0.125 + 1e-3);
    }
  }
}

static void
test_vertical_motion (void)
{
  /* A disc moving up and right: its shadow's centroid follows (x0 + vx t, y0 + vy t). */
  g_autoptr (DsScene) s = scene_from ("[object.d]\nshape=disc\nposition=20;30\nradius=6\nvelocity=300;-800\n", NULL);
  g_autoptr (DsRenderer) r = renderer_of (s);
  const double t = 0.0137;
  g_autoptr (DsImage) tt = NULL;
  g_autoptr (DsImage) ts = NULL;
  truth_at (r, t, &tt, &ts);
  double a = 0, mx = 0, my = 0;
  for (guint y = 0; y < 48; y++)
    for (guint x = 0; x < 64; x++) {
      double d = 1.0 - px (tt, x, y) / open_dn ();
      a += d;
      mx += d * x;
      my += d * y;
    }
  g_assert_cmpfloat (fabs (a - G_PI * 36), <, 0.02 * G_PI * 36);
  g_assert_cmpfloat (fabs (mx / a - (20 + 300 * t)), <, 0.1);
  g_assert_cmpfloat (fabs (my / a - (30 - 800 * t)), <, 0.1);
}

static void
assert_same_bits (const DsImage *a, const DsImage *b)
{
  g_assert_cmpuint (a->width, ==, b->width);
  g_assert_cmpuint (a->height, ==, b->height);
  g_assert_cmpint (a->type, ==, b->type);
  gsize row = (gsize) a->width * (a->type == DS_SAMPLE_F32 ? 4 : a->type == DS_SAMPLE_U16 ? 2 : 1);
  for (guint y = 0; y < a->height; y++)
    if (memcmp (ds_image_row (a, y), ds_image_row (b, y), row) != 0)
      g_error ("row %u differs", y);
}

/* The frames, expected frames and truth of two renderers at the given times, bit for bit. */
static void
assert_same_renders (const DsRenderer *a, double ta, const DsRenderer *b, double tb)
{
  g_autoptr (GError) error = NULL;
  for (guint k = 0; k < 4; k++) {
    DsRenderRequest ra = { .phase = k, .n_phases = 4, .illuminator_on = TRUE, .exposure_us = EXPOSURE_US,
                           .seed = 77 + k, .time_s = ta };
    DsRenderRequest rb = ra;
    rb.time_s = tb;
    g_autoptr (DsImage) fa = ds_renderer_render (a, &ra, &error);
    g_autoptr (DsImage) fb = ds_renderer_render (b, &rb, &error);
    g_assert_no_error (error);
    assert_same_bits (fa, fb);
    g_autoptr (DsImage) ea = ds_renderer_render_expected (a, &ra, &error);
    g_autoptr (DsImage) eb = ds_renderer_render_expected (b, &rb, &error);
    g_assert_no_error (error);
    assert_same_bits (ea, eb);
  }
  g_autoptr (DsImage) t1 = NULL;
  g_autoptr (DsImage) s1 = NULL;
  g_autoptr (DsImage) t2 = NULL;
  g_autoptr (DsImage) s2 = NULL;
  truth_at (a, ta, &t1, &s1);
  truth_at (b, tb, &t2, &s2);
  assert_same_bits (t1, t2);
  assert_same_bits (s1, s2);
}

static void
test_still_unchanged (void)
{
  /* velocity = 0, 0 is no velocity: no motion stage and the same bits as without the key; a
   * still scene renders the same bits at any time. */
  const char *objs = "[object.g]\nshape=grid\npitch=9\nline-width=2\ntransmittance=0.3\n"
                     "[object.d]\nshape=disc\nposition=30;20\nradius=7\n";
  g_autoptr (DsScene) plain = scene_from (objs, NULL);
  g_autofree char *zero_text = g_strdup_printf ("%s%s", objs, "velocity = 0, 0\n");
  g_autoptr (DsScene) zero = scene_from (zero_text, NULL);
  g_autoptr (DsRenderer) rp = renderer_of (plain);
  g_autoptr (DsRenderer) rz = renderer_of (zero);
  g_assert_false (ds_renderer_has_stage (rp, DS_RENDER_STAGE_MOTION));
  g_assert_false (ds_renderer_has_stage (rz, DS_RENDER_STAGE_MOTION));
  g_assert_cmpuint (ds_renderer_n_stages (rp), ==, ds_renderer_n_stages (rz));
  assert_same_renders (rp, 0.0, rz, 0.0);
  assert_same_renders (rp, 0.0, rp, 12.5);
  g_assert_cmpuint (ds_renderer_stage_runs (rz, DS_RENDER_STAGE_MOTION), ==, 0);
}

static void
test_still_objects_beside_moving_one (void)
{
  /* A still grid and a disc moving on the same plane: away from the disc every pixel is the
   * grid-only scene's, to the bit (the still objects' map is reused, the disc's is 1 there). */
  const char *grid = "[object.g]\nshape=grid\npitch=9\nline-width=2\ntransmittance=0.3\n";
  g_autofree char *both = g_strdup_printf ("%s[object.d]\nshape=disc\nposition=16;16\nradius=5\nvelocity=1000;0\n",
                                           grid);
  g_autoptr (DsScene) sg = scene_from (grid, NULL);
  g_autoptr (DsScene) sb = scene_from (both, NULL);
  g_autoptr (DsRenderer) rg = renderer_of (sg);
  g_autoptr (DsRenderer) rb = renderer_of (sb);
  const double t = 0.02; /* the disc's centre at x = 36 */
  g_autoptr (DsImage) tg = NULL;
  g_autoptr (DsImage) sgs = NULL;
  g_autoptr (DsImage) tb = NULL;
  g_autoptr (DsImage) sbs = NULL;
  truth_at (rg, t, &tg, &sgs);
  truth_at (rb, t, &tb, &sbs);
  guint far = 0, near_dark = 0;
  for (guint y = 0; y < 48; y++)
    for (guint x = 0; x < 64; x++) {
      double dx = x - 36.0, dy = y - 16.0, d = sqrt (dx * dx + dy * dy);
      if (d > 6.5) {
        g_assert_cmpfloat (px (tb, x, y), ==, px (tg, x, y));
        far++;
      } else if (d < 4.0)
        near_dark += px (tb, x, y) == 0.0f;
    }
  g_assert_cmpuint (far, >, 2500);
  g_assert_cmpuint (near_dark, >, 40);
  /* Where the disc stood at time 0 only the grid is left. */
  g_assert_cmpfloat (px (tb, 16, 16), ==, px (tg, 16, 16));
}

static DsScene *
milk_disc_with (const char *object)
{
  g_autofree char *path = g_strdup_printf ("%s/milk-disc.scene", DS_SCENES_DIR);
  g_autofree char *text = NULL;
  g_assert_true (g_file_get_contents (path, &text, NULL, NULL));
  g_autoptr (GKeyFile) kf = g_key_file_new ();
  g_assert_true (g_key_file_load_from_data (kf, text, (gsize) -1, G_KEY_FILE_NONE, NULL));
  g_key_file_remove_group (kf, "object.disc", NULL);
  g_autofree char *rest = g_key_file_to_data (kf, NULL, NULL);
  g_autofree char *all = g_strdup_printf ("%s\n%s", rest, object);
  g_autoptr (GError) error = NULL;
  DsScene *s = ds_scene_load_data (all, strlen (all), path, &error);
  g_assert_no_error (error);
  return s;
}

static void
test_moving_inside_medium (void)
{
  /* Inside a scattering medium the light is followed through the object's plane: a disc that
   * has moved by (24, -8) px is a still disc declared there, in the direct and the scattered
   * light (whole-pixel displacements sample the shape at the same points). */
  g_autoptr (DsScene) moving = milk_disc_with ("[object.disc]\nshape=disc\nposition=128;96\nradius=40\n"
                                               "depth-mm=5\nvelocity=1536;-512\n");
  g_autoptr (DsScene) there = milk_disc_with ("[object.disc]\nshape=disc\nposition=152;88\nradius=40\ndepth-mm=5\n");
  g_autoptr (DsScene) start = milk_disc_with ("[object.disc]\nshape=disc\nposition=128;96\nradius=40\ndepth-mm=5\n");
  g_autoptr (DsRenderer) rm = renderer_of (moving);
  g_autoptr (DsRenderer) rt = renderer_of (there);
  g_autoptr (DsRenderer) rs = renderer_of (start);
  g_autoptr (GError) error = NULL;
  const double t = 0.015625; /* 2^-6 s: v t exact in binary */
  DsImage *a = NULL, *b = NULL, *c = NULL, *d = NULL, *e = NULL, *f = NULL;
  g_assert_true (ds_renderer_truth_at (rm, 5000, 0, t, &a, &b, &error));
  g_assert_true (ds_renderer_truth_at (rt, 5000, 0, 0, &c, &d, &error));
  g_assert_true (ds_renderer_truth_at (rs, 5000, 0, 0, &e, &f, &error));
  g_autoptr (DsImage) mt = a;
  g_autoptr (DsImage) ms = b;
  g_autoptr (DsImage) tt = c;
  g_autoptr (DsImage) ts = d;
  g_autoptr (DsImage) st = e;
  g_autoptr (DsImage) ss = f;
  double max_diff = 0, max_level = 0, max_moved = 0;
  for (guint y = 0; y < mt->height; y++)
    for (guint x = 0; x < mt->width; x++) {
      g_assert_cmpfloat (fabs (px (mt, x, y) - px (tt, x, y)), <=, 1e-6 * px (tt, 0, 0));
      max_diff = MAX (max_diff, fabs (px (ms, x, y) - px (ts, x, y)));
      max_level = MAX (max_level, px (ts, x, y));
      max_moved = MAX (max_moved, fabs (px (ms, x, y) - px (ss, x, y)));
    }
  g_assert_cmpfloat (max_diff, <=, 1e-5 * max_level);
  /* And it did move: the scattered light differs from the disc's at time 0. */
  g_assert_cmpfloat (max_moved, >, 0.05 * max_level);
  /* At time 0 the moving disc is where it was declared. */
  DsImage *g = NULL, *h = NULL;
  g_assert_true (ds_renderer_truth_at (rm, 5000, 0, 0, &g, &h, &error));
  g_autoptr (DsImage) m0t = g;
  g_autoptr (DsImage) m0s = h;
  for (guint y = 0; y < mt->height; y++)
    for (guint x = 0; x < mt->width; x++)
      g_assert_cmpfloat (fabs (px (m0s, x, y) - px (ss, x, y)), <=, 1e-5 * max_level);
}

static char *
run_describe (const char *scene_text)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-describe-XXXXXX", NULL);
  g_autofree char *path = g_build_filename (dir, "s.scene", NULL);
  g_assert_true (g_file_set_contents (path, scene_text, -1, NULL));
  const char *args[] = { DS_SIM_BIN, "describe", path, NULL };
  char *out = NULL;
  int status = -1;
  g_autoptr (GError) error = NULL;
  g_assert_true (g_spawn_sync (NULL, (char **) args, NULL, G_SPAWN_STDERR_TO_DEV_NULL, NULL, NULL, &out, NULL,
                               &status, &error));
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  g_unlink (path);
  g_rmdir (dir);
  return out;
}

static void
test_describe (void)
{
  const char *base = "[sensor]\nwidth=64\nheight=48\n[illuminator]\nperiod-px=8\nirradiance=1\n"
                     "[object.bar]\nshape=rect\nposition=4;4\nsize=8;8\n";
  g_autofree char *still = run_describe (base);
  g_assert_null (strstr (still, "motion"));
  g_autofree char *moving_text = g_strdup_printf ("%svelocity=250;-10\n", base);
  g_autofree char *moving = run_describe (moving_text);
  g_assert_nonnull (strstr (moving, "\n  motion "));
  g_assert_nonnull (strstr (moving, "bar at (250, -10) px/s"));
  /* Before the objects stage: it places what that stage shades with. */
  g_assert_true (strstr (moving, "\n  motion ") < strstr (moving, "\n  object-transmittance"));
}

static void
expect_refused (const char *velocity, const char *shape, const char *const *fragments)
{
  g_autofree char *text = g_strdup_printf ("[sensor]\nwidth=64\nheight=48\n[illuminator]\nperiod-px=8\n"
                                           "irradiance=1\n[object.o]\n%s\nvelocity = %s\n",
                                           shape ? shape : "shape=rect\nposition=4;4\nsize=8;8", velocity);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) s = ds_scene_load_data (text, strlen (text), "m.scene", &error);
  g_assert_null (s);
  g_assert_nonnull (error);
  for (guint i = 0; fragments[i]; i++)
    if (!strstr (error->message, fragments[i]))
      g_error ("message \"%s\" lacks \"%s\"", error->message, fragments[i]);
}

static void
test_bad_velocity (void)
{
  const char *const where_rect[] = { "m.scene:11", "[object.o] velocity", NULL };
  const char *const bad[] = { "fast, 0", "nan, 0", "inf, 1", "0x10, 0", "5", "1, 2, 3", "2e6, 0", "0, -1.5e6", "" };
  for (guint i = 0; i < G_N_ELEMENTS (bad); i++)
    expect_refused (bad[i], NULL, where_rect);
  /* The limits themselves are fine. */
  const char *ok = "[sensor]\nwidth=64\nheight=48\n[illuminator]\nperiod-px=8\nirradiance=1\n"
                   "[object.o]\nshape=disc\nposition=4;4\nradius=3\nvelocity = 1e6; -1e6\n";
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) s = ds_scene_load_data (ok, strlen (ok), "ok.scene", &error);
  g_assert_no_error (error);
  g_assert_cmpfloat (ds_scene_spec (s)->objects[0].vx, ==, 1e6);
  g_assert_cmpfloat (ds_scene_spec (s)->objects[0].vy, ==, -1e6);
  /* A mask does not move. */
  expect_refused ("1, 0", "shape=mask\nmask=m.png", (const char *const[]) { "m.scene:10", "[object.o] velocity",
                                                                             "not used by shape mask", NULL });
  /* A frame's time must be finite. */
  g_autoptr (DsScene) sc = scene_from ("[object.d]\nshape=disc\nposition=20;30\nradius=6\nvelocity=300;0\n", NULL);
  g_autoptr (DsRenderer) r = renderer_of (sc);
  DsRenderRequest req = { .illuminator_on = TRUE, .n_phases = 1, .exposure_us = EXPOSURE_US, .time_s = NAN };
  g_autoptr (DsImage) f = ds_renderer_render (r, &req, &error);
  g_assert_null (f);
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
  g_assert_nonnull (strstr (error->message, "time"));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/sim/motion/edge-at-x0-plus-vt", test_edge_at_vt);
  g_test_add_func ("/sim/motion/vertical", test_vertical_motion);
  g_test_add_func ("/sim/motion/still-unchanged", test_still_unchanged);
  g_test_add_func ("/sim/motion/still-beside-moving", test_still_objects_beside_moving_one);
  g_test_add_func ("/sim/motion/inside-medium", test_moving_inside_medium);
  g_test_add_func ("/sim/motion/describe", test_describe);
  g_test_add_func ("/sim/motion/bad-velocity", test_bad_velocity);
  return g_test_run ();
}
