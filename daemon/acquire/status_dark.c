/* status "dark": what a lab needs to trust the dark subtraction at a glance — which dark frame
 * the next set subtracts, and when the last one was measured and at what level. */
#include "daemon/acquire/status_dark.h"

#include "daemon/output/result_meta.h"

static JsonNode *
frame_to_json (const DsDarkFrameInfo *d, gint64 now_unix_us)
{
  if (!d->taken)
    return json_node_new (JSON_NODE_NULL);
  g_autoptr (JsonBuilder) b = json_builder_new ();
  g_autoptr (GDateTime) secs = g_date_time_new_from_unix_utc (d->taken_unix_us / G_USEC_PER_SEC);
  g_autoptr (GDateTime) t = secs ? g_date_time_add (secs, d->taken_unix_us % G_USEC_PER_SEC) : NULL;
  g_autofree char *iso = t ? g_date_time_format_iso8601 (t) : NULL;
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "source");
  json_builder_add_string_value (b, d->by_set ? "set" : "dark-command");
  json_builder_set_member_name (b, "taken_utc");
  json_builder_add_string_value (b, iso ? iso : "");
  json_builder_set_member_name (b, "age_s");
  json_builder_add_double_value (b, (double) MAX (0, now_unix_us - d->taken_unix_us) / 1e6);
  ds_json_add_double_or_null (b, "mean_dn", d->mean_dn);
  json_builder_set_member_name (b, "frames");
  json_builder_add_int_value (b, d->frames);
  json_builder_set_member_name (b, "exposure_us");
  json_builder_add_double_value (b, d->exposure_us);
  json_builder_set_member_name (b, "gain_db");
  json_builder_add_double_value (b, d->gain_db);
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

JsonNode *
ds_status_dark_to_json (const DsSequencerStatus *st, gint64 now_unix_us)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  /* per-set: every set takes and subtracts its own; stored: sets subtract the dark command's
   * (taken at their exposure and gain); none: nothing is subtracted. */
  json_builder_set_member_name (b, "mode");
  json_builder_add_string_value (b, st->per_set_dark ? "per-set" : st->stored_dark_applies ? "stored" : "none");
  json_builder_set_member_name (b, "last");
  json_builder_add_value (b, frame_to_json (&st->last_dark, now_unix_us));
  json_builder_set_member_name (b, "stored");
  json_builder_add_value (b, frame_to_json (&st->stored_dark, now_unix_us));
  json_builder_end_object (b);
  return json_builder_get_root (b);
}
