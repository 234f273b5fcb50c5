#include "tests/common/truth_check.h"

#include <math.h>
#include <string.h>

const void *
truth_payload (const DsMessage *m, const char *name, const char *dtype, guint w, guint h)
{
  for (guint i = 0; i < m->reply->n_payloads; i++)
    if (strcmp (m->reply->payloads[i].name, name) == 0) {
      g_assert_cmpstr (m->reply->payloads[i].dtype, ==, dtype);
      g_assert_cmpuint (m->reply->payloads[i].width, ==, w);
      g_assert_cmpuint (m->reply->payloads[i].height, ==, h);
      return g_bytes_get_data (m->payloads[i], NULL);
    }
  g_error ("result has no %s payload", name);
  return NULL;
}

/* Noise of one frame at a pixel with signal S DN: var = K*S + sigma_r^2 (photon transfer;
 * K in DN/e-). max - min of N/2 lit and N/2 unlit frames: each of max and min is an order
 * statistic of N/2 samples, its bias below E[max of N/2 standard normals] * sigma (1.03 for
 * N = 8, 1.77 for N = 32) and its spread below sigma. So the RMS error of Ld stays below
 * sqrt(2 (b^2 + 1)) sigma ~ 2.9 sigma for N <= 32, and of Lg = 2 min below twice that. The
 * bound allows 3 and 6 sigma of the brightest frame's noise, plus 2 % of the signal for the
 * finite stripe period (scattered light not exactly uniform across one period). */
void
truth_check (const DsMessage *m, const DsScene *scene, const DsImage *truth_t,
             const DsImage *truth_g, TruthCheck *out)
{
  guint w = truth_t->width, h = truth_t->height;
  const float *t = truth_payload (m, "transmissive", "f32", w, h);
  const float *g = truth_payload (m, "scattered", "f32", w, h);
  const guint8 *mask = truth_payload (m, "mask", "u8", w, h);
  double K = ds_scene_system_gain (scene), sr = ds_scene_read_noise_dn (scene);
  double se_t = 0, se_g = 0, al_t = 0, al_g = 0;
  memset (out, 0, sizeof *out);
  out->pixels = (guint64) w * h;
  for (guint y = 0; y < h; y++) {
    const float *tt = ds_image_row (truth_t, y), *tg = ds_image_row (truth_g, y);
    for (guint x = 0; x < w; x++) {
      gsize i = (gsize) y * w + x;
      if (mask[i] != 0)
        continue;
      double sigma = sqrt (K * (tt[x] + tg[x]) + sr * sr);
      double et = t[i] - tt[x], eg = g[i] - tg[x];
      se_t += et * et;
      se_g += eg * eg;
      al_t += pow (3 * sigma + 0.02 * (tt[x] + 0.5 * tg[x]), 2);
      al_g += pow (6 * sigma + 0.02 * (tg[x] + tt[x]), 2);
      out->valid++;
    }
  }
  double n = out->valid ? (double) out->valid : 1.0;
  out->rms_transmissive = sqrt (se_t / n);
  out->allowed_transmissive = sqrt (al_t / n);
  out->rms_scattered = sqrt (se_g / n);
  out->allowed_scattered = sqrt (al_g / n);
}

gboolean
truth_check_passed (const TruthCheck *c)
{
  return c->valid > 0 && c->rms_transmissive < c->allowed_transmissive &&
         c->rms_scattered < c->allowed_scattered;
}

void
truth_scene_load (const char *scene_path, DsScene **scene, DsImage **truth_t, DsImage **truth_g)
{
  g_autoptr (GError) error = NULL;
  *scene = ds_scene_load (scene_path, &error);
  g_assert_no_error (error);
  g_autoptr (DsRenderer) r = ds_renderer_new (*scene, NULL, &error);
  g_assert_no_error (error);
  g_assert_true (ds_renderer_truth (r, ds_scene_default_exposure_us (*scene), 0, truth_t, truth_g, &error));
}

void
truth_scene_free (DsScene *scene, DsImage *truth_t, DsImage *truth_g)
{
  ds_image_free (truth_t);
  ds_image_free (truth_g);
  ds_scene_free (scene);
}

gboolean
truth_capture (DsClient *c, JsonObject *args, const DsScene *scene, const DsImage *truth_t,
               const DsImage *truth_g, char **message, const char **code)
{
  g_autoptr (GError) error = NULL;
  gint64 t0 = g_get_monotonic_time ();
  g_autoptr (DsMessage) m = ds_client_call (c, "capture", args, NULL, NULL, &error);
  g_assert_no_error (error);
  double s = (double) (g_get_monotonic_time () - t0) / 1e6;
  if (!m->reply->ok) {
    const char *name = ds_protocol_error_name (m->reply->error_code);
    g_test_message ("set failed in %.2f s: %s: %s", s, name, m->reply->error_message);
    g_assert_cmpuint (strlen (m->reply->error_message), >, 0);
    if (message)
      *message = g_strdup (m->reply->error_message);
    if (code)
      *code = name;
    return FALSE;
  }
  TruthCheck tc;
  truth_check (m, scene, truth_t, truth_g, &tc);
  g_test_message ("set correct in %.2f s: rms %.2f/%.2f DN (allowed %.2f/%.2f)", s, tc.rms_transmissive,
                  tc.rms_scattered, tc.allowed_transmissive, tc.allowed_scattered);
  g_assert_true (truth_check_passed (&tc));
  return TRUE;
}
