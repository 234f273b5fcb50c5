/* Every pixel format of labsim's camera through real GigE Vision: the same scene captured in
 * Mono8, Mono10, Mono12, Mono16, Mono10p, Mono12p and Mono12Packed by descatterd's Aravis
 * backend (which unpacks with proc/pixfmt.c), the phases set over Modbus. labsim runs
 * --noiseless, so each frame must equal the renderer's expected frame, computed here in-process
 * and rounded to whole DN, less the low bits the format lacks: bit for bit. The separations of
 * the formats then agree within their quantisation.
 * Usage: test_labsim_formats LABSIM SCENE. Binds UDP 3956. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "drivers/aravis/aravis_camera.h"
#include "drivers/modbus/modbus_illuminator.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"
#include "proc/pixfmt.h"
#include "proc/separation.h"

#define N_PHASES 4

static const char *labsim_path, *scene_path;

typedef struct {
  DsPixelFormat fmt;
  DsImage *transmissive, *scattered;
} Captured;

/* The renderer's noise-free frame rounded to whole DN and clipped as the sensor does. */
static guint16 *
expected_dn (const DsRenderer *r, gboolean on, guint phase, double exposure_us, guint *w, guint *h)
{
  g_autoptr (GError) error = NULL;
  DsRenderRequest req = { .phase = phase, .n_phases = N_PHASES, .illuminator_on = on, .exposure_us = exposure_us };
  g_autoptr (DsImage) e = ds_renderer_render_expected (r, &req, &error);
  g_assert_no_error (error);
  double top = ds_renderer_saturation_dn (r, 0);
  *w = e->width;
  *h = e->height;
  guint16 *q = g_new (guint16, (gsize) e->width * e->height);
  for (guint y = 0; y < e->height; y++) {
    const float *row = ds_image_row (e, y);
    for (guint x = 0; x < e->width; x++)
      q[(gsize) y * e->width + x] = (guint16) CLAMP (floor (row[x] + 0.5), 0.0, top);
  }
  return q;
}

/* Frame against expectation, pixel by pixel: the format keeps the top bits of the sensor's. */
static void
assert_frame_is (const DsImage *img, const guint16 *q, guint depth, DsPixelFormat fmt, const char *what)
{
  guint bits = ds_pixfmt_bit_depth (fmt);
  guint shift = depth > bits ? depth - bits : 0;
  guint mismatches = 0;
  for (guint y = 0; y < img->height; y++) {
    const void *row = ds_image_row (img, y);
    for (guint x = 0; x < img->width; x++) {
      guint got = img->type == DS_SAMPLE_U8 ? ((const guint8 *) row)[x] : ((const guint16 *) row)[x];
      guint want = q[(gsize) y * img->width + x] >> shift;
      if (got != want && mismatches++ < 5)
        g_test_message ("%s %s: pixel (%u, %u) is %u, expected %u", ds_pixfmt_name (fmt), what, x, y, got, want);
    }
  }
  g_assert_cmpuint (mismatches, ==, 0);
}

/* A frame that arrives whole; one the transport could not complete is taken again, as the
 * sequencer would (noiseless: the same frame). */
static DsFrame *
grab_one (DsCamera *cam)
{
  for (guint attempt = 0;; attempt++) {
    g_autoptr (GError) error = NULL;
    g_assert_true (cam->ops->trigger (cam->backend, &error));
    g_assert_no_error (error);
    DsFrame *f = cam->ops->grab (cam->backend, 5000, &error);
    if (f || attempt == 3 || !g_error_matches (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INCOMPLETE)) {
      g_assert_no_error (error);
      return f;
    }
    g_test_message ("frame taken again: %s", error->message);
    cam->ops->flush (cam->backend);
  }
}

static void
test_formats (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) scene = ds_scene_load (scene_path, &error);
  g_assert_no_error (error);
  g_autoptr (DsRenderer) r = ds_renderer_new (scene, NULL, &error);
  g_assert_no_error (error);
  double exposure = ds_scene_default_exposure_us (scene);
  guint depth = ds_scene_bit_depth (scene), w = 0, h = 0;
  guint16 *want[N_PHASES + 1];
  for (guint k = 0; k < N_PHASES; k++)
    want[k] = expected_dn (r, TRUE, k, exposure, &w, &h);
  want[N_PHASES] = expected_dn (r, FALSE, 0, exposure, &w, &h);

  const char *args[] = { "--noiseless", NULL };
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, args);
  g_autofree char *uri = g_strdup_printf ("tcp://127.0.0.1:%u", l->modbus_port);
  DsIlluminator *ill = ds_modbus_illuminator_open (uri, 1, 300, &error);
  g_assert_no_error (error);
  DsStripePattern pattern = { .kind = ds_scene_pattern_is_sine (scene) ? DS_STRIPES_SINE : DS_STRIPES_SQUARE,
                              .period_px = ds_scene_period_px (scene), .duty = ds_scene_duty (scene),
                              .black_level = ds_scene_black_level (scene), .intensity = 1, .n_phases = N_PHASES };
  g_assert_true (ill->ops->set_pattern (ill->backend, &pattern, &error));
  DsCamera *cam = ds_aravis_camera_open ("127.0.0.1", 4, &error);
  g_assert_no_error (error);

  Captured cap[DS_PIXFMT_COUNT];
  for (guint f = 0; f < DS_PIXFMT_COUNT; f++) {
    DsPixelFormat fmt = (DsPixelFormat) f;
    DsCameraSettings s = { .exposure_us = exposure, .trigger_source = DS_CAMERA_TRIGGER_SOFTWARE };
    g_strlcpy (s.pixel_format, ds_pixfmt_name (fmt), sizeof s.pixel_format);
    g_assert_true (cam->ops->configure (cam->backend, &s, &error));
    g_assert_no_error (error);
    g_assert_true (cam->ops->start (cam->backend, &error));
    DsSeparationParams p;
    ds_separation_params_init (&p, N_PHASES);
    p.duty = ds_scene_duty (scene);
    p.black_level = ds_scene_black_level (scene);
    g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, &error);
    g_assert_no_error (error);
    for (guint k = 0; k <= N_PHASES; k++) {
      gboolean ok = k < N_PHASES ? ill->ops->set_phase (ill->backend, k, 1000, &error)
                                 : ill->ops->off (ill->backend, 1000, &error);
      g_assert_no_error (error);
      g_assert_true (ok);
      g_autoptr (DsFrame) frame = grab_one (cam);
      g_assert_cmpuint (frame->image->width, ==, w);
      g_assert_cmpuint (frame->image->height, ==, h);
      g_assert_cmpuint (frame->image->bit_depth, ==, ds_pixfmt_bit_depth (fmt));
      assert_frame_is (frame->image, want[k], depth, fmt, k < N_PHASES ? "lit" : "dark");
      if (k < N_PHASES)
        g_assert_true (ds_phase_set_accumulate (set, k, frame->image, &error));
      else
        g_assert_true (ds_phase_set_set_dark (set, frame->image, &error));
      g_assert_no_error (error);
    }
    cam->ops->stop (cam->backend);
    g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, &error);
    g_assert_no_error (error);
    cap[f].fmt = fmt;
    cap[f].transmissive = g_steal_pointer (&sep->transmissive);
    cap[f].scattered = g_steal_pointer (&sep->scattered);
    g_test_message ("%s: every frame equals the renderer's, bit for bit", ds_pixfmt_name (fmt));
  }

  /* Separations against Mono16 (all of the sensor's bits): a format with d bits fewer keeps
   * each frame's value within 2^d - 1 of it (truncation), which moves a max - min difference
   * by at most that, and the scattered estimate (twice the minimum, scaled) by at most twice. */
  const Captured *ref = &cap[DS_PIXFMT_MONO16];
  for (guint f = 0; f < DS_PIXFMT_COUNT; f++) {
    guint bits = ds_pixfmt_bit_depth (cap[f].fmt);
    double scale = depth > bits ? ldexp (1.0, (int) (depth - bits)) : 1.0;
    double step = scale - 1.0;
    double worst_t = 0, worst_g = 0;
    for (guint y = 0; y < h; y++) {
      const float *t = ds_image_row (cap[f].transmissive, y), *g = ds_image_row (cap[f].scattered, y);
      const float *rt = ds_image_row (ref->transmissive, y), *rg = ds_image_row (ref->scattered, y);
      for (guint x = 0; x < w; x++) {
        worst_t = MAX (worst_t, fabs (t[x] * scale - rt[x]));
        worst_g = MAX (worst_g, fabs (g[x] * scale - rg[x]));
      }
    }
    g_test_message ("%s: separation within %.2f / %.2f DN of Mono16's (quantisation step %.0f DN)",
                    ds_pixfmt_name (cap[f].fmt), worst_t, worst_g, scale);
    g_assert_cmpfloat (worst_t, <=, 2 * step + 1e-3);
    g_assert_cmpfloat (worst_g, <=, 4 * step + 1e-3);
  }
  for (guint f = 0; f < DS_PIXFMT_COUNT; f++) {
    ds_image_free (cap[f].transmissive);
    ds_image_free (cap[f].scattered);
  }
  for (guint k = 0; k <= N_PHASES; k++)
    g_free (want[k]);
  ds_camera_close (cam);
  ds_illuminator_close (ill);
  test_labsim_stop (l);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc < 3) {
    fprintf (stderr, "usage: test_labsim_formats LABSIM SCENE\n");
    return 2;
  }
  labsim_path = argv[1];
  scene_path = argv[2];
  g_test_add_func ("/labsim/pixel-formats", test_formats);
  return g_test_run ();
}
