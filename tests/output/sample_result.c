#include "sample_result.h"

#include "daemon/output/result_meta.h"

static DsImage *
plane (DsSampleType type, guint w, guint h)
{
  DsImage *img = ds_image_new (type, w, h, NULL);
  g_assert_nonnull (img);
  return img;
}

SampleResult *
sample_result_new (guint w, guint h, guint set, gboolean with_raw, gboolean with_extrema)
{
  SampleResult *s = g_new0 (SampleResult, 1);
  DsImage *t = s->images[0] = plane (DS_SAMPLE_F32, w, h);
  DsImage *g = s->images[1] = plane (DS_SAMPLE_F32, w, h);
  DsImage *m = s->images[2] = plane (DS_SAMPLE_U8, w, h);
  DsImage *mean = with_extrema ? (s->images[3] = plane (DS_SAMPLE_F32, w, h)) : NULL;
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      float tv = 1000.0f + 10.0f * x + y + set / 4.0f, gv = 200.0f + 3.0f * x + 2.0f * y + set;
      ((float *) ds_image_row (t, y))[x] = tv;
      ((float *) ds_image_row (g, y))[x] = gv;
      ((guint8 *) ds_image_row (m, y))[x] = (guint8) ((x + 2 * y + set) % 64);
      if (mean)
        ((float *) ds_image_row (mean, y))[x] = (tv + gv) / 2.0f;
    }
  if (with_raw) {
    s->raw = ds_raw_frames_new (SAMPLE_PHASES);
    for (guint k = 0; k < SAMPLE_PHASES; k++) {
      DsImage *f = plane (DS_SAMPLE_U16, w, h);
      f->bit_depth = 12;
      for (guint y = 0; y < h; y++)
        for (guint x = 0; x < w; x++)
          ((guint16 *) ds_image_row (f, y))[x] = (guint16) (100 + x + 10 * k + set + y % 2);
      ds_raw_frames_add_owned (s->raw, k, 1000u * set + k, 5000u * k, f);
    }
    g_autoptr (DsImage) black = plane (DS_SAMPLE_U16, w, h);
    black->bit_depth = 12;
    for (guint y = 0; y < h; y++)
      for (guint x = 0; x < w; x++)
        ((guint16 *) ds_image_row (black, y))[x] = (guint16) (50 + (x + y) % 3);
    guint64 ids[2] = { 1000u * set + 900, 1000u * set + 901 };
    g_assert_true (ds_raw_frames_set_black (s->raw, black, ids, 2, NULL));
  }
  g_autofree char *meta = g_strdup_printf (
    "{\"format\": \"" DS_RESULT_FORMAT "\", \"version\": 1, \"set_id\": %u, \"time_utc\": \"2026-01-02T03:04:%02u.006Z\","
    " \"time_utc_end\": \"2026-01-02T03:04:%02u.500Z\","
    " \"width\": %u, \"height\": %u,"
    " \"producer\": {\"program\": \"sample\", \"version\": \"0.0\", \"git\": \"g\", \"host\": \"h\"},"
    " \"camera\": {\"backend\": \"test\", \"vendor\": \"V\", \"model\": \"M\", \"serial\": \"S%u\","
    " \"pixel_format\": \"Mono12\", \"bit_depth\": 12},"
    " \"pattern\": {\"kind\": \"square\", \"period_px\": 8.0, \"duty\": 0.5, \"black_level\": 0.0, \"phase_offset_cycles\": 0.25},"
    " \"settings\": {\"phases\": %u, \"exposure_us\": 1500.0, \"gain_db\": 0.0, \"estimator\": \"maxmin\"},"
    " \"separation\": {\"estimator\": \"maxmin\", \"saturation_level\": 4095.0}}",
    set + 1, set % 60, set % 60, w, h, set, SAMPLE_PHASES);
  JsonNode *node = json_from_string (meta, NULL);
  g_assert_nonnull (node);
  s->planes = (DsOutputResult){ .transmissive = t, .scattered = g, .mask = m, .mean = mean, .raw = s->raw, .meta = node };
  return s;
}

void
sample_result_free (SampleResult *s)
{
  if (!s)
    return;
  for (guint i = 0; i < G_N_ELEMENTS (s->images); i++)
    ds_image_free (s->images[i]);
  ds_raw_frames_free (s->raw);
  json_node_unref (s->planes.meta);
  g_free (s);
}
